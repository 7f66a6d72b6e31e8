"""LearnedModelVisualizer: draws the currently learned articulation model in Meshcat."""

import numpy as np

from pydrake.common.value import AbstractValue
from pydrake.geometry import Rgba, Sphere
from pydrake.math import RigidTransform
from pydrake.systems.framework import EventStatus, LeafSystem

_AXIS = Rgba(0.1, 0.4, 1.0, 1.0)
_RANGE = Rgba(1.0, 0.15, 0.1, 1.0)
_FAINT = Rgba(0.1, 0.4, 1.0, 0.5)


class LearnedModelVisualizer(LeafSystem):
    """Shows the learned model of the first link of an ``ArticulatedObject`` in Meshcat.

    Revolute: the rotation axis (blue), the circle of the tracked point (faint) and the
    observed configuration range as a red arc. Prismatic: the axis (faint) and the observed
    range (red). Rigid: the fixed position. Redrawn every ``period`` seconds when the
    model changed, under ``prefix`` in the Meshcat tree.

    .. pydrake_system::

        name: LearnedModelVisualizer
        input_ports:
        - object_model
    """

    def __init__(self, *, meshcat, period: float = 0.25, prefix: str = "learned_model"):
        super().__init__()
        if not period > 0:
            raise ValueError(f"period must be > 0, got {period}")
        self._meshcat, self._prefix = meshcat, prefix
        self._in = self.DeclareAbstractInputPort("object_model", AbstractValue.Make(None))
        self._last = None
        self.DeclarePeriodicPublishEvent(period, 0.0, self._publish)

    def get_object_model_input_port(self):
        return self._in

    def _publish(self, context):
        obj = self._in.Eval(context) if self._in.HasValue(context) else None
        link = obj.edges[0].model if obj is not None and getattr(obj, "edges", None) else None
        if link is self._last:
            return EventStatus.DidNothing()
        self._last = link
        try:
            self.draw(link)
        except (RuntimeError, ValueError, AttributeError):
            return EventStatus.DidNothing()
        return EventStatus.Succeeded()

    def draw(self, link) -> None:
        """Draw one link model (None clears the drawing)."""
        mc, pre = self._meshcat, self._prefix
        mc.Delete(pre)
        if link is None:
            return
        name = link.name
        if name == "revolute":
            a, c = np.asarray(link.axis), np.asarray(link.center)
            mc.SetLine(f"{pre}/axis", np.column_stack([c - 0.6 * a, c + 0.6 * a]), 3.0, _AXIS)
            # the observed range and the full circle of the tracked point, through the
            # model's forward kinematics
            lo, hi = float(link.q_min[0]), float(link.q_max[0])
            qs = np.linspace(lo, hi, 40)
            P = np.asarray(link.forward(qs[:, None]))[:, :3]
            mc.SetLine(f"{pre}/range", P.T, 6.0, _RANGE)
            ring = np.asarray(link.forward(np.linspace(-np.pi, np.pi, 90)[:, None]))[:, :3]
            mc.SetLine(f"{pre}/circle", ring.T, 1.5, _FAINT)
            mc.SetObject(f"{pre}/center", Sphere(0.015), _AXIS)
            mc.SetTransform(f"{pre}/center", RigidTransform(c))
        elif name == "prismatic":
            a = np.asarray(link.axis)
            lo, hi = float(link.q_min[0]), float(link.q_max[0])
            P = np.asarray(link.forward(np.array([[lo], [hi]])))[:, :3]
            mid = P.mean(axis=0)
            mc.SetLine(f"{pre}/axis", np.column_stack([mid - 0.8 * a, mid + 0.8 * a]), 1.5,
                       _FAINT)
            mc.SetLine(f"{pre}/range", P.T, 6.0, _RANGE)
        else:
            p = np.asarray(link.forward(np.zeros((1, link.dof)) if link.dof else None))[0, :3]
            mc.SetObject(f"{pre}/position", Sphere(0.02), _RANGE)
            mc.SetTransform(f"{pre}/position", RigidTransform(p))
