"""FinitePointCloud: drops the points without a measurement from a point cloud (for display)."""

from __future__ import annotations

import numpy as np

from pydrake.common.value import AbstractValue
from pydrake.perception import BaseField, Fields, PointCloud
from pydrake.systems.framework import LeafSystem

__all__ = ["FinitePointCloud"]


class FinitePointCloud(LeafSystem):
    """Keeps the finite points of a cloud (and every ``stride``-th of them).

    ``DepthImageToPointCloud`` turns a NaN depth pixel into a NaN point and Drake's
    too-close / too-far codes into +inf points; three.js (Meshcat) computes a NaN bounding
    sphere for such a cloud and may cull all of it, and the points cost bandwidth in a
    recording. This system removes them before ``MeshcatPointCloudVisualizer``.

    .. pydrake_system::

        name: FinitePointCloud
        input_ports:
        - cloud
        output_ports:
        - cloud

    Args:
        stride: keep every ``stride``-th finite point (>= 1; 1 = all).
    """

    def __init__(self, *, stride: int = 1):
        super().__init__()
        if isinstance(stride, bool) or not isinstance(stride, (int, np.integer)) or stride < 1:
            raise ValueError(f"FinitePointCloud: stride must be an integer >= 1, got {stride!r}")
        self._stride = int(stride)
        self._in = self.DeclareAbstractInputPort("cloud", AbstractValue.Make(PointCloud()))
        self._out = self.DeclareAbstractOutputPort(
            "cloud", lambda: AbstractValue.Make(PointCloud()), self._calc)

    def get_cloud_input_port(self):
        return self._in

    def get_cloud_output_port(self):
        return self._out

    def _calc(self, context, output):
        cloud = self._in.Eval(context)
        xyz = cloud.xyzs()
        keep = np.flatnonzero(np.isfinite(xyz).all(axis=0))[::self._stride]
        fields = Fields(BaseField.kXYZs | (BaseField.kRGBs if cloud.has_rgbs() else 0))
        out = PointCloud(keep.size, fields)
        out.mutable_xyzs()[:] = xyz[:, keep]
        if cloud.has_rgbs():
            out.mutable_rgbs()[:] = cloud.rgbs()[:, keep]
        output.set_value(out)
