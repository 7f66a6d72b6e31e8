"""FingerPositionHold: latches a gripper's desired finger positions once the grasp settled."""

from __future__ import annotations

import numpy as np

from pydrake.systems.framework import LeafSystem

__all__ = ["FingerPositionHold"]


class FingerPositionHold(LeafSystem):
    """Passes a gripper controller's desired state through until ``t_latch``, then holds the
    desired finger positions it had at that instant (desired velocities 0).

    This is what a real gripper's position controller does once the grasp has settled: the
    fingers no longer yield to keep each pad's force constant (as the force control of
    :class:`~mmlearn.systems.tactile.grasp_controller.TactileGraspController` does), so a
    load that moves inside the held object (sloshing liquid) shifts the pressure from one
    pad to the other instead of moving fingers and object together.

    .. pydrake_system::

        name: FingerPositionHold
        input_ports:
        - desired_state_in
        output_ports:
        - desired_state

    ``desired_state_in`` / ``desired_state``: (q_1..q_n, v_1..v_n) of the fingers (m, m/s).
    The latched positions live in the Context's discrete state (flag, q_1..q_n).

    Args:
        num_fingers: number of finger joints n.
        t_latch: time at which the positions are latched, s.
        period: update period of the latch, s.
    """

    def __init__(self, *, num_fingers: int = 2, t_latch: float, period: float = 1e-3):
        super().__init__()
        if not (isinstance(num_fingers, int) and num_fingers >= 1):
            raise ValueError(f"FingerPositionHold: num_fingers must be an int >= 1, got "
                             f"{num_fingers!r}")
        for k, v in (("t_latch", t_latch), ("period", period)):
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"FingerPositionHold: {k} must be a finite number > 0, got "
                                 f"{v!r}")
        self._n, self._t_latch = num_fingers, float(t_latch)
        self._in = self.DeclareVectorInputPort("desired_state_in", 2 * num_fingers)
        self._state = self.DeclareDiscreteState(np.zeros(1 + num_fingers))
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)
        self._out = self.DeclareVectorOutputPort("desired_state", 2 * num_fingers, self._calc,
                                                 {self.all_state_ticket(),
                                                  self._in.ticket()})

    def get_input_port_desired(self):
        return self._in

    def get_output_port_desired(self):
        return self._out

    def _update(self, context, discrete_state):
        s = context.get_discrete_state_vector().CopyToVector()
        if s[0] == 0.0 and context.get_time() >= self._t_latch:
            x = self._in.Eval(context)
            if np.all(np.isfinite(x[:self._n])):
                s[0] = 1.0
                s[1:] = x[:self._n]
                discrete_state.set_value(s)

    def _calc(self, context, output):
        s = context.get_discrete_state_vector().CopyToVector()
        if s[0] == 0.0:
            output.SetFromVector(self._in.Eval(context))
        else:
            output.SetFromVector(np.concatenate([s[1:], np.zeros(self._n)]))
