"""TactileGraspController: the switching velocity-force grasp controller of Eq. 7.8."""

from __future__ import annotations

import numpy as np

from pydrake.systems.framework import BasicVector, LeafSystem

__all__ = ["TactileGraspController", "GRASP_MODES"]

GRASP_MODES = ("switching", "force", "velocity")

# discrete state layout
_QD, _MODE, _T_BOTH, _T_SW = slice(0, 2), slice(2, 4), 4, slice(5, 7)
_VEL, _FORCE, _RELEASE = 0.0, 1.0, 2.0


class TactileGraspController(LeafSystem):
    """Closes a two-finger parallel gripper on an object, probes it, holds and releases.

    The fingers are the plant's PD-controlled prismatic joints (closure q >= 0 per finger,
    effort-limited); this system outputs their desired state ``(q_d, v_d)``:

    * **velocity control** (Eq. 7.8, while the finger feels no force): ``q_d`` moves inward
      at ``v_target / 2`` per finger (so the finger distance shrinks at ``v_target``), ``v_d
      = v_target / 2``: the PD actuator tracks the ramp;
    * **force control** (once the finger's pad force exceeds ``contact_force``): ``q_d = q +
      f_cmd / kp``, ``v_d = 0``: the actuator pushes with ``f_cmd`` (N) minus its damping
      ``kd * v`` -- the motor-effort force control of a gripper such as the PR2's. ``f_cmd``
      starts at ``contact_force`` and rises at ``force_rate`` (N/s) to ``f_target`` (the
      seamless switch of Eq. 7.8: the force at the switch equals the contact force; None
      or inf: a step to ``f_target``);
    * ``hold_time`` s after both fingers switched to force control the gripper **releases**
      (opens at ``v_target``).

    ``mode="switching"`` is Eq. 7.8; ``"force"`` is the pure force controller (force control
    from the start: the fingers accelerate into the object, Fig. 7.5's impact spike);
    ``"velocity"`` the pure velocity controller (never switches: crushes). Each finger
    switches on its own pad force (two independently actuated fingers; Eq. 7.8's 1-DOF PR2
    gripper switches both at once on the summed force).

    .. pydrake_system::

        name: TactileGraspController
        input_ports:
        - gripper_state
        - pad_force
        output_ports:
        - desired_state
        - grasp

    ``gripper_state``: (q_left, q_right, v_left, v_right) closures (m, m/s). ``pad_force``:
    normal force on each pad, N (from a ``TactileSensor``). ``desired_state`` goes to the
    plant's desired-state input of the gripper. ``grasp``: (p, v, f, phase): finger
    distance p = open_gap - q_left - q_right (m), its rate (m/s), the summed pad force (N),
    and the phase (0 closing, 1 both fingers in force control, 2 releasing).
    """

    def __init__(self, *, f_target: float, v_target: float = 0.02, contact_force: float = 1.0,
                 kp: float = 2000.0, kd: float = 100.0, hold_time: float = 1.0,
                 open_gap: float = 0.09, stroke: float = 0.045, mode: str = "switching",
                 force_rate: float | None = 40.0, period: float = 1e-3):
        super().__init__()
        for k, v in (("f_target", f_target), ("v_target", v_target), ("kp", kp),
                     ("hold_time", hold_time), ("open_gap", open_gap), ("period", period)):
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"TactileGraspController: {k} must be a finite number > 0, "
                                 f"got {v!r}")
        if not (np.isfinite(contact_force) and contact_force >= 0):
            raise ValueError(f"TactileGraspController: contact_force must be >= 0, got "
                             f"{contact_force!r}")
        if mode not in GRASP_MODES:
            raise ValueError(f"TactileGraspController: mode must be one of {GRASP_MODES}, "
                             f"got {mode!r}")
        self._f, self._v, self._F = float(f_target), float(v_target), float(contact_force)
        self._kp, self._kd, self._hold = float(kp), float(kd), float(hold_time)
        self._gap, self._stroke, self._mode, self._dt = open_gap, stroke, mode, period
        if force_rate is not None and not force_rate > 0:
            raise ValueError(f"TactileGraspController: force_rate must be > 0 or None, got "
                             f"{force_rate!r}")
        self._rate = np.inf if force_rate is None else float(force_rate)
        if mode == "force":  # the pure force controller commands f_target from the start
            self._rate = np.inf
        self._q = self.DeclareVectorInputPort("gripper_state", 4)
        self._force = self.DeclareVectorInputPort("pad_force", 2)
        init = np.zeros(7)
        init[_MODE] = _FORCE if mode == "force" else _VEL
        init[_T_BOTH] = -1.0
        self._state = self.DeclareDiscreteState(init)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)
        self._desired = self.DeclareVectorOutputPort("desired_state", 4, self._calc_desired,
                                                     {self.all_state_ticket(),
                                                      self._q.ticket()})
        self._grasp = self.DeclareVectorOutputPort("grasp", BasicVector(4), self._calc_grasp)

    def get_gripper_state_input_port(self):
        return self._q

    def get_pad_force_input_port(self):
        return self._force

    def get_desired_state_output_port(self):
        return self._desired

    def get_grasp_output_port(self):
        return self._grasp

    def _update(self, context, discrete_state):
        s = context.get_discrete_state_vector().CopyToVector()
        x = self._q.Eval(context)
        fp = self._force.Eval(context)
        t = context.get_time()
        qd, mode = s[_QD].copy(), s[_MODE].copy()
        if not np.all(np.isfinite(fp)):
            fp = np.zeros(2)
        if s[_T_BOTH] < 0:
            if self._mode == "switching":
                sw = (mode == _VEL) & (fp > self._F)
                mode[sw] = _FORCE
                s[_T_SW] = np.where(sw, t, s[_T_SW])
            if self._mode == "velocity":
                if np.all(fp > self._F):
                    s[_T_BOTH] = t
            elif np.all(mode == _FORCE) and np.all(fp > self._F):
                s[_T_BOTH] = t
        elif t >= s[_T_BOTH] + self._hold:
            if not np.all(mode == _RELEASE):
                qd = np.clip(x[:2], 0.0, self._stroke)
            mode[:] = _RELEASE
        step = 0.5 * self._v * self._dt
        qd = np.where(mode == _VEL, np.minimum(qd + step, self._stroke), qd)
        qd = np.where(mode == _RELEASE, np.maximum(qd - step, 0.0), qd)
        s[_QD], s[_MODE] = qd, mode
        discrete_state.set_value(s)

    def _calc_desired(self, context, output):
        s = context.get_discrete_state_vector().CopyToVector()
        x = self._q.Eval(context)
        qd, mode = s[_QD], s[_MODE]
        half = 0.5 * self._v
        f_cmd = np.minimum(self._f, self._F + self._rate * np.maximum(
            context.get_time() - s[_T_SW], 0.0)) if np.isfinite(self._rate) else self._f
        q_force = x[:2] + f_cmd / self._kp
        q = np.where(mode == _FORCE, q_force, qd)
        v = np.where(mode == _VEL, half, np.where(mode == _RELEASE, -half, 0.0))
        output.SetFromVector(np.concatenate([q, v]))

    def _calc_grasp(self, context, output):
        s = context.get_discrete_state_vector().CopyToVector()
        x = self._q.Eval(context)
        fp = self._force.Eval(context)
        phase = 2.0 if np.all(s[_MODE] == _RELEASE) else (1.0 if s[_T_BOTH] >= 0 else 0.0)
        output.SetFromVector([self._gap - x[0] - x[1], -(x[2] + x[3]),
                              float(np.sum(np.maximum(fp, 0.0))), phase])
