"""SchemaController: moves a part of the robot (the end effector) to a target position
using only the *learned* body schema (thesis Sec. 3.2.4, Eq. 3.19): damped least squares on
the learned Jacobian, iterated on the commanded joint positions."""

from __future__ import annotations

import numpy as np

from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.framework import BasicVector, LeafSystem

from mmlearn.models.body_schema import BodySchema

__all__ = ["SchemaController"]


class SchemaController(LeafSystem):
    """Commands joint positions that bring ``part`` to ``target`` according to the schema.

    .. pydrake_system::

        name: SchemaController
        input_ports:
        - schema
        - X_WR
        - target
        output_ports:
        - command

    ``schema``: abstract :class:`BodySchema` (e.g. a SchemaLearner's output); ``X_WR``: the
    world pose of the schema's root part (RigidTransform; the learner's ``X_WR``);
    ``target``: desired world position of the part (3,), m. ``command``: the commanded
    joint positions (discrete state), updated at ``rate_hz`` by ``iterations`` damped
    least-squares steps on the learned model (joint limits respected, steps at most
    ``max_step``). While the part is not in the schema's tree, or the target is not finite,
    the command holds.

    Args:
        part: schema index of the controlled part.
        lower, upper: joint limits (rad or m), length n_actions.
        start: initial command (default: middle of the limits).
        rate_hz: update rate, Hz.
        iterations: DLS iterations per update (>= 1).
        damping: DLS damping (m).
        max_step: largest change of a joint per iteration (rad or m).
        centering: null-space pull towards the middle of the limits (redundant arms).
    """

    def __init__(self, *, part: int, lower, upper, start=None, rate_hz: float = 10.0,
                 iterations: int = 3, damping: float = 0.05, max_step: float = 0.15,
                 centering: float = 0.05):
        super().__init__()
        lo, hi = np.asarray(lower, float).ravel(), np.asarray(upper, float).ravel()
        if lo.shape != hi.shape or lo.size == 0 or np.any(hi < lo) or \
                not np.all(np.isfinite(lo) & np.isfinite(hi)):
            raise ValueError("SchemaController: lower/upper must be finite, equal length, "
                             "lower <= upper")
        if not rate_hz > 0 or int(iterations) < 1 or not damping > 0 or not max_step > 0:
            raise ValueError("SchemaController: need rate_hz > 0, iterations >= 1, "
                             "damping > 0, max_step > 0")
        if int(part) < 0:
            raise ValueError(f"SchemaController: part must be >= 0, got {part}")
        self._part, self._lo, self._hi = int(part), lo, hi
        self._it, self._damp, self._step, self._center = int(iterations), damping, \
            max_step, centering
        q0 = 0.5 * (lo + hi) if start is None else np.clip(np.asarray(start, float), lo, hi)
        if q0.shape != lo.shape:
            raise ValueError("SchemaController: start has the wrong length")
        self._schema = self.DeclareAbstractInputPort(
            "schema", AbstractValue.Make(BodySchema(2, lo.size)))
        self._root = self.DeclareAbstractInputPort(
            "X_WR", AbstractValue.Make(RigidTransform()))
        self._target = self.DeclareVectorInputPort("target", 3)
        self._q = self.DeclareDiscreteState(q0)
        self.DeclarePeriodicDiscreteUpdateEvent(1.0 / rate_hz, 0.0, self._update)
        self._out = self.DeclareStateOutputPort("command", self._q)

    def get_schema_input_port(self):
        return self._schema

    def get_X_WR_input_port(self):
        return self._root

    def get_target_input_port(self):
        return self._target

    def get_command_output_port(self):
        return self._out

    def set_command(self, context, q) -> None:
        """Reset the commanded joint positions (this system's or the root context)."""
        try:
            context = self.GetMyMutableContextFromRoot(context)
        except (RuntimeError, ValueError):
            pass
        context.SetDiscreteState(self._q, np.clip(np.asarray(q, float), self._lo, self._hi))

    def _update(self, context, discrete_state):
        q = context.get_discrete_state(self._q).get_value().copy()
        try:
            schema = self._schema.Eval(context)
            tgt = np.asarray(self._target.Eval(context), float)
            X_WR = self._root.Eval(context)
            if not np.all(np.isfinite(tgt)) or self._part not in schema.nodes:
                return
            p_R = X_WR.inverse().multiply(tgt)
            for _ in range(self._it):
                dq = schema.dls_step(q, self._part, p_R, damping=self._damp,
                                     max_step=self._step, q_low=self._lo, q_high=self._hi,
                                     centering=self._center)
                if not np.all(np.isfinite(dq)):
                    return
                q = np.clip(q + dq, self._lo, self._hi)
        except (ValueError, np.linalg.LinAlgError, IndexError):
            return
        discrete_state.get_mutable_vector(self._q).SetFromVector(q)
