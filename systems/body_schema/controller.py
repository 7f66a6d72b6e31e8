"""SchemaController: moves a part of the robot (the end effector) to a target position
using only the *learned* body schema (thesis Sec. 3.2.4, Eq. 3.19): damped least squares on
the learned Jacobian, iterated on the commanded joint positions."""

from __future__ import annotations

import numpy as np

from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.framework import LeafSystem

from mmlearn.models.body_schema.schema import BodySchema

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
    joint positions (discrete state). When the target changes, the goal command is solved
    on the learned model by damped least squares (Jacobian of the learned kinematics,
    joint limits respected) from the current command and, if that leaves a predicted error
    above 5 mm, from ``restarts`` fixed configurations; the command then moves towards the
    goal by at most ``iterations * max_step`` per update (``rate_hz``). While the part is
    not in the schema's tree, or the target is not finite, the command holds.

    Args:
        part: schema index of the controlled part.
        lower, upper: joint limits (rad or m), length n_actions.
        start: initial command (default: middle of the limits).
        rate_hz: update rate, Hz.
        iterations: DLS iterations per update (>= 1).
        damping: DLS damping (m).
        max_step: largest change of a joint per iteration (rad or m).
        centering: null-space pull towards the middle of the limits (redundant arms).
        restarts: fixed restart configurations for the goal search (>= 0).
        max_iter: DLS iterations per goal search.
    """

    def __init__(self, *, part: int, lower, upper, start=None, rate_hz: float = 10.0,
                 iterations: int = 3, damping: float = 0.05, max_step: float = 0.15,
                 centering: float = 0.05, restarts: int = 6, max_iter: int = 60):
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
        self._max_iter = int(max_iter)
        if int(restarts) < 0 or self._max_iter < 1:
            raise ValueError("SchemaController: need restarts >= 0 and max_iter >= 1")
        q0 = 0.5 * (lo + hi) if start is None else np.clip(np.asarray(start, float), lo, hi)
        if q0.shape != lo.shape:
            raise ValueError("SchemaController: start has the wrong length")
        self._schema = self.DeclareAbstractInputPort(
            "schema", AbstractValue.Make(BodySchema(2, lo.size)))
        self._root = self.DeclareAbstractInputPort(
            "X_WR", AbstractValue.Make(RigidTransform()))
        self._target = self.DeclareVectorInputPort("target", 3)
        self._q = self.DeclareDiscreteState(q0)
        # [goal command (n); target the goal was solved for (3)]
        self._goal = self.DeclareDiscreteState(np.r_[q0, np.full(3, np.nan)])
        self.DeclarePeriodicDiscreteUpdateEvent(1.0 / rate_hz, 0.0, self._update)
        self._out = self.DeclareStateOutputPort("command", self._q)
        rng = np.random.default_rng(12345)
        self._starts = lo + (hi - lo) * rng.random((restarts, lo.size))

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
        q = np.clip(np.asarray(q, float), self._lo, self._hi)
        context.SetDiscreteState(self._q, q)
        context.SetDiscreteState(self._goal, np.r_[q, np.full(3, np.nan)])

    def _solve(self, schema, q, p_R):
        """Damped least squares on the learned model from the current command, and from
        the fixed restart configurations when that leaves a predicted error > 5 mm."""
        kw = dict(damping=self._damp, max_iter=self._max_iter, tol=1e-3,
                  max_step=self._step, q_low=self._lo, q_high=self._hi,
                  centering=self._center)
        best = schema.reach(q, self._part, p_R, **kw)
        for q0 in self._starts:
            if best[1]["error"] <= 5e-3:
                break
            cand = schema.reach(q0, self._part, p_R, **kw)
            if cand[1]["error"] < best[1]["error"]:
                best = cand
        return best[0]

    def _update(self, context, discrete_state):
        n = self._lo.size
        q = context.get_discrete_state(self._q).get_value().copy()
        g = context.get_discrete_state(self._goal).get_value().copy()
        goal, solved_for = g[:n], g[n:]
        try:
            schema = self._schema.Eval(context)
            tgt = np.asarray(self._target.Eval(context), float)
            X_WR = self._root.Eval(context)
            if not np.all(np.isfinite(tgt)) or self._part not in schema.nodes:
                return
            if not np.allclose(tgt, solved_for, atol=1e-9):
                # a new target: plan the goal command on the learned model
                goal = self._solve(schema, q, X_WR.inverse().multiply(tgt))
                if not np.all(np.isfinite(goal)):
                    return
                discrete_state.get_mutable_vector(self._goal).SetFromVector(np.r_[goal, tgt])
            # move the command towards the goal, at most ``iterations * max_step`` per update
            d = goal - q
            lim = self._it * self._step
            mx = np.max(np.abs(d)) if d.size else 0.0
            q = q + (d * (lim / mx) if mx > lim else d)
        except (ValueError, np.linalg.LinAlgError, IndexError):
            return
        discrete_state.get_mutable_vector(self._q).SetFromVector(np.clip(q, self._lo, self._hi))
