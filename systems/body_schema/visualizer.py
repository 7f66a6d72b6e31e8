"""SchemaVisualizer: draws a learned body schema in Meshcat next to the real arm."""

from __future__ import annotations

import numpy as np

from pydrake.common.value import AbstractValue
from pydrake.geometry import Cylinder, Rgba, Sphere
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.systems.framework import EventStatus, LeafSystem

__all__ = ["SchemaVisualizer"]


class SchemaVisualizer(LeafSystem):
    """Draws the predicted part poses of a learned body schema as coordinate frames and the
    learned structure (the tree's local models) as lines between them, shifted by
    ``offset`` so they stand next to the real arm. Lines are green for a valid local
    model, red for an invalid one. Transforms go into the Meshcat recording too (when one
    is active) at the simulation time.

    .. pydrake_system::

        name: SchemaVisualizer
        input_ports:
        - predicted_poses
        - model_validity

    ``predicted_poses``: list (one entry per part) of RigidTransform or None (a
    SchemaLearner's output); ``model_validity``: list of dicts with ``a``, ``b``,
    ``valid``, ``in_tree`` (a SchemaLearner's output).

    Args:
        meshcat: the Meshcat instance.
        parts: part names, in the order of ``predicted_poses``.
        offset: translation (3,) m of the drawing relative to the world.
        rate_hz: publish rate, Hz (> 0).
        prefix: Meshcat path.
        axis_length: length of a frame's axes, m.
    """

    def __init__(self, *, meshcat, parts, offset=(0.0, 0.9, 0.0), rate_hz: float = 10.0,
                 prefix: str = "/body_schema", axis_length: float = 0.08):
        super().__init__()
        if not rate_hz > 0 or not axis_length > 0:
            raise ValueError("SchemaVisualizer: rate_hz and axis_length must be > 0")
        off = np.asarray(offset, float).ravel()
        if off.shape != (3,) or not np.all(np.isfinite(off)):
            raise ValueError("SchemaVisualizer: offset must be 3 finite numbers (m)")
        self._mc, self._parts, self._prefix = meshcat, list(parts), prefix
        self._X_off = RigidTransform(off)
        self._pred = self.DeclareAbstractInputPort(
            "predicted_poses", AbstractValue.Make([None] * len(self._parts)))
        self._valid = self.DeclareAbstractInputPort("model_validity", AbstractValue.Make([]))
        self.DeclarePeriodicPublishEvent(1.0 / rate_hz, 0.0, self._publish)
        L, r = axis_length, axis_length / 20
        for name in self._parts:
            base = f"{prefix}/parts/{name}"
            for ax, rpy, col in (("x", (0, np.pi / 2, 0), Rgba(0.9, 0.1, 0.1, 1)),
                                 ("y", (-np.pi / 2, 0, 0), Rgba(0.1, 0.8, 0.1, 1)),
                                 ("z", (0, 0, 0), Rgba(0.1, 0.2, 0.9, 1))):
                meshcat.SetObject(f"{base}/{ax}", Cylinder(r, L), col)
                R = RollPitchYaw(*rpy).ToRotationMatrix()
                meshcat.SetTransform(f"{base}/{ax}",
                                     RigidTransform(R, R.multiply([0.0, 0.0, L / 2])))
            meshcat.SetObject(f"{base}/origin", Sphere(1.5 * r), Rgba(0.2, 0.2, 0.2, 1))
            meshcat.SetProperty(base, "visible", False)

    def get_predicted_poses_input_port(self):
        return self._pred

    def get_model_validity_input_port(self):
        return self._valid

    def _publish(self, context):
        t = context.get_time()
        try:
            poses = self._pred.Eval(context)
            rows = self._valid.Eval(context) if self._valid.HasValue(context) else []
        except RuntimeError:
            return EventStatus.DidNothing()
        where = {}
        for name, X in zip(self._parts, poses):
            base = f"{self._prefix}/parts/{name}"
            shown = X is not None
            self._mc.SetProperty(base, "visible", shown)
            if shown:
                X_draw = self._X_off @ X
                self._mc.SetTransform(base, X_draw, t)
                where[name] = X_draw.translation()
        self._mc.Delete(f"{self._prefix}/tree")
        for k, row in enumerate(r for r in rows if r.get("in_tree")):
            a, b = where.get(row["a"]), where.get(row["b"])
            if a is None or b is None:
                continue
            col = Rgba(0.1, 0.7, 0.2, 1) if row.get("valid") else Rgba(0.9, 0.1, 0.1, 1)
            self._mc.SetLine(f"{self._prefix}/tree/{row['a']}_{row['b']}",
                             np.column_stack([a, b]), 3.0, col)
        return EventStatus.Succeeded()
