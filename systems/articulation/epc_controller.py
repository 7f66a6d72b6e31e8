"""EpcController: open a door or drawer with a hook by equilibrium-point control along the
*learned* articulation model (thesis Sec. 4.3, Eq. 4.57-4.59).

The robot is a compliant arm with an L-shaped hook on a planar mobile base (joint
impedance through the plant's implicit PD actuators). The controller commands joint
positions (the equilibrium point); the hand yields to the mechanism.

Phases (``phase`` output):

0. DRIVE   move the base to a stance in front of the (noisy) handle position;
1. PREHOOK put the hook in front of the handle, beside the bar;
2. DEPTH   guarded move towards the front until the hook touches it, back off (a contact
           in front of the front is the bar: retry further to the side; no contact
           deeper than the front: the finger passed the front's edge, retry closer);
3. SLIDE   guarded sideways move: the hook's finger slides behind the bar (a slide that
           meets nothing went over the bar: retry further to the side);
4. PULL    equilibrium-point control: every period the Cartesian equilibrium point moves by
           ``step`` along the normalised Jacobian of the currently learned revolute or GP
           model at the current configuration estimate (with a prismatic model or none:
           along the handle's observed motion, at first the given initial direction), plus a proportional term that
           keeps ``force_target`` N between hook and handle perpendicular to the motion;
           the hook's orientation turns with the mechanism as the revolute model predicts
           or, without one, as the handle's motion turned;
5. RELEASE slide the hook out and back off, in the front's orientation as the handle's
           last few centimetres of motion show it;
6. DONE.

Every distance, angle, force, time, gain, threshold and count of these phases is a field
of :class:`EpcConfig` (documented there with its unit).

The hook frame: its rod is the +z axis (from the wrist to the tip), its finger points
along +x at the rod's tip. The reference point G is the hook's *seat*: where the centre of
a 2 cm handle bar sits when the bar rests against both the rod and the finger. Its
trajectory is what the estimator learns from, so the learned radius is the handle's. A
knob's stem stops the finger's tip before the rod reaches the knob (its head is too wide for
the finger to pass behind): a slide that ends well before the rod reaches the clicked
handle (``EpcConfig.tip_contact_offset``) makes the point just beyond the finger's tip the
reference point for the pull instead.
"""

import math
from dataclasses import replace

import numpy as np
from scipy.spatial.transform import Rotation

from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.tree import JacobianWrtVariable
from pydrake.systems.framework import BasicVector, EventStatus, LeafSystem, ValueProducer

# the task and the configuration are part of this module's API
from mmlearn.systems.articulation.epc_config import EpcConfig, EpcTask  # noqa: F401
# the phases are part of this module's API (the ``phase`` output's values)
from mmlearn.systems.articulation.epc_state import (  # noqa: F401
    DEPTH, DONE, DRIVE, PHASE_NAMES, PREHOOK, PULL, RELEASE, SLIDE, EpcInputs, EpcState)

#: the hook's seat (centre of a seated 2 cm bar) in the hook body frame, m
P_HOOK_GRIP = np.array([0.022, 0.0, 0.106])
#: distance of the finger's tip from the rod's axis (along the hook frame's x), m
HOOK_FINGER_TIP = 0.058


def _unit(v):
    n = np.linalg.norm(v)
    return v / n if n > 1e-12 else v


def _axis_angle(axis, angle):
    """Rotation matrix of ``angle`` about ``axis`` (any length)."""
    return Rotation.from_rotvec(_unit(np.asarray(axis, float)) * angle).as_matrix()


def _rotation_between(a, b) -> np.ndarray:
    """The smallest rotation taking direction a to direction b."""
    a, b = _unit(np.asarray(a, float)), _unit(np.asarray(b, float))
    c = np.cross(a, b)
    angle = math.atan2(np.linalg.norm(c), float(np.dot(a, b)))
    if np.linalg.norm(c) < 1e-9:
        return np.eye(3)
    return _axis_angle(c, angle)


def hook_rotation(normal, side) -> np.ndarray:
    """R_WHook with the rod pointing into the front (-normal) and the finger towards
    -side (behind the bar)."""
    z = -_unit(np.asarray(normal, float))
    x = -_unit(np.asarray(side, float) - np.dot(side, z) * z)
    y = np.cross(z, x)
    return np.column_stack([x, y, z])


class EpcController(LeafSystem):
    """Equilibrium-point controller for opening doors and drawers with a hook.

    .. pydrake_system::

        name: EpcController
        input_ports:
        - robot_state
        - force_W
        - object_model
        - supervisor (optional)
        output_ports:
        - command
        - command_segment
        - hook_position
        - phase
        - status

    ``robot_state`` is the plant's state output for the robot instance; ``force_W`` the
    wrist force on the hook (world, N); ``object_model`` the ArticulationEstimator's
    ``object_model`` output (an ``ArticulatedObject`` whose first link is the handle's
    motion relative to the world, or None). ``command`` goes to the scene's ``command`` input
    (base x, y, yaw, then q1..q6): each period's command interpolated linearly from the
    last one over the next period; ``command_segment`` is that segment ([q_from, q_to,
    t_cmd], changing only with the state), for :func:`CommandInterpolator` to interpolate
    in C++. ``hook_position`` (grip point from the robot's own forward
    kinematics, world, m) feeds the estimator. ``status`` is [opening estimate (rad or m),
    configuration estimate, done flag, success-by-model flag].

    ``supervisor`` (optional, e.g. :class:`~mmlearn.systems.articulation.jam_monitor.
    DynamicsMonitor`'s output) is [step scale, halt code]: while pulling, the equilibrium
    point advances by ``step`` times the scale; a halt code of 1 or 2 ends the pull at once
    with the outcome "jammed" or "locked" (RELEASE follows). Unconnected: scale 1, no halt.
    """

    def __init__(self, *, plant, robot, task: EpcTask, config: EpcConfig | None = None,
                 command_names: list[str]):
        super().__init__()
        cfg = config or EpcConfig()
        cfg.validate()
        self._cfg, self._task = cfg, task
        self._R_hook0 = hook_rotation(task.normal, task.side)  # hook orientation at the handle
        self._plant = plant
        self._robot = robot
        self._hook = plant.GetBodyByName("hook", robot).body_frame()
        self._names = list(command_names)
        if self._names[:3] != ["base_x", "base_y", "base_yaw"]:
            raise ValueError("EpcController needs a mobile base (commands base_x, base_y, "
                             "base_yaw first)")
        if len(cfg.ready_arm_q) != len(self._names) - 3:
            raise ValueError(f"EpcConfig.ready_arm_q needs {len(self._names) - 3} arm joint "
                             f"positions, got {len(cfg.ready_arm_q)}")
        joints = [plant.GetJointByName(n, robot) for n in self._names]
        self._qidx = np.array([j.position_start() for j in joints])
        self._lo = np.array([j.position_lower_limits()[0] for j in joints])
        self._hi = np.array([j.position_upper_limits()[0] for j in joints])
        self._nq_robot = plant.num_positions(robot)
        # index of each command in the robot instance's own position vector
        robot_q_starts = sorted(plant.get_joint(j).position_start()
                                for j in plant.GetJointIndices(robot)
                                if plant.get_joint(j).num_positions() == 1)
        self._robot_local = np.array([robot_q_starts.index(i) for i in self._qidx])
        # the commands are all of the robot's positions (the mobile hook arm): a plant
        # context's robot positions are then set in one call, without reading the rest
        self._all_commanded = (sorted(self._robot_local.tolist())
                               == list(range(self._nq_robot)))
        self._world = plant.world_frame()
        n = len(self._names)
        self._in_state = self.DeclareVectorInputPort(
            "robot_state", plant.num_positions(robot) + plant.num_velocities(robot))
        self._in_force = self.DeclareVectorInputPort("force_W", 3)
        self._in_model = self.DeclareAbstractInputPort("object_model", AbstractValue.Make(None))
        self._in_super = self.DeclareVectorInputPort("supervisor", 2)
        # the plant context at the measured configuration: a cache entry of this system's
        # context (no plant context is kept in a member; the IK makes its own per update)
        self._kin = self.DeclareCacheEntry(
            "measured_plant_context",
            ValueProducer(allocate=lambda: AbstractValue.Make(plant.CreateDefaultContext()),
                          calc=self._calc_measured_context),
            {self._in_state.ticket()})
        # the IK's plant context: scratch space of this system's context (never evaluated,
        # so never up to date; no prerequisites)
        self._ik_scratch = self.DeclareCacheEntry(
            "ik_scratch_plant_context",
            ValueProducer(allocate=lambda: AbstractValue.Make(plant.CreateDefaultContext()),
                          calc=lambda context, value: None),
            {self.nothing_ticket()})
        init = EpcState(q_from=np.zeros(n), q_to=np.zeros(n))
        self._s = self.DeclareAbstractState(AbstractValue.Make(init))
        self.DeclareInitializationUnrestrictedUpdateEvent(self._initialize)
        self.DeclarePeriodicUnrestrictedUpdateEvent(cfg.period, 0.0, self._update)
        # outputs depend on the state (and time) only, except the hook position, which is
        # forward kinematics of the measured robot state: no algebraic loop through the
        # estimator
        state_only = {self.abstract_state_ticket(self._s), self.time_ticket()}
        self._out_cmd = self.DeclareVectorOutputPort("command", BasicVector(n), self._calc_cmd,
                                                     prerequisites_of_calc=state_only)
        # the command's segment alone: changes with the state only, not at every step
        self._out_seg = self.DeclareVectorOutputPort(
            "command_segment", BasicVector(2 * n + 1), self._calc_segment,
            prerequisites_of_calc={self.abstract_state_ticket(self._s)})
        self._out_G = self.DeclareVectorOutputPort(
            "hook_position", BasicVector(3), self._calc_G,
            prerequisites_of_calc={self._kin.ticket(), self._in_force.ticket(),
                                   self.abstract_state_ticket(self._s)})
        self._out_phase = self.DeclareVectorOutputPort(
            "phase", BasicVector(1), self._calc_phase, prerequisites_of_calc=state_only)
        self._out_status = self.DeclareVectorOutputPort(
            "status", BasicVector(4), self._calc_status, prerequisites_of_calc=state_only)

    # ------------------------------------------------------------------ ports
    def get_command_output_port(self):
        return self._out_cmd

    def get_command_segment_output_port(self):
        """[q_from, q_to, t_cmd]: the segment the ``command`` output interpolates (see
        :func:`CommandInterpolator`)."""
        return self._out_seg

    def period(self) -> float:
        """The control period, s."""
        return self._cfg.period

    def get_hook_position_output_port(self):
        return self._out_G

    def get_robot_state_input_port(self):
        return self._in_state

    def get_force_input_port(self):
        return self._in_force

    def get_object_model_input_port(self):
        return self._in_model

    def get_supervisor_input_port(self):
        return self._in_super

    def _supervisor(self, context) -> tuple[float, int]:
        """(step scale, halt code) from the optional ``supervisor`` input."""
        if not self._in_super.HasValue(context):
            return 1.0, 0
        v = np.asarray(self._in_super.Eval(context), float)
        if not np.all(np.isfinite(v)):
            return 1.0, 0
        return float(np.clip(v[0], 0.0, 3.0)), int(round(v[1]))

    def state(self, context) -> EpcState:
        return context.get_abstract_state(self._s).get_value()

    # ------------------------------------------------------------------ kinematics
    def _measured_q(self, context) -> np.ndarray:
        x = self._in_state.Eval(context)
        return x[: self._nq_robot][self._robot_local]

    def _set(self, plant_context, q):
        if self._all_commanded:
            q_robot = np.empty(self._nq_robot)
            q_robot[self._robot_local] = q
            self._plant.SetPositions(plant_context, self._robot, q_robot)
            return
        full = self._plant.GetPositions(plant_context)
        full[self._qidx] = q
        self._plant.SetPositions(plant_context, full)

    def _calc_measured_context(self, context, value):
        self._set(value.get_mutable_value(), self._measured_q(context))

    def _grip_pose_in(self, plant_context, grip=P_HOOK_GRIP) -> RigidTransform:
        X = self._plant.CalcRelativeTransform(plant_context, self._world, self._hook)
        return RigidTransform(X.rotation(), X @ grip)

    @staticmethod
    def _grip(s: EpcState) -> np.ndarray:
        """The point of the hook holding the handle (hook frame): the seat unless the
        slide ended on a knob's stem (:attr:`EpcState.grip`)."""
        return s.grip if s.grip.size == 3 else P_HOOK_GRIP

    def measured_grip_pose(self, context) -> RigidTransform:
        """World pose of the grip point frame at the measured configuration (``context`` is
        this system's context); the grip point is the hook's seat, or its finger's tip
        once it holds a knob there."""
        return self._grip_pose_in(self._kin.Eval(context), self._grip(self.state(context)))

    def _measured_grip_point(self, context) -> np.ndarray:
        """``measured_grip_pose(context).translation()`` (the same floats, X @ grip),
        without making the pose."""
        X = self._plant.CalcRelativeTransform(self._kin.Eval(context), self._world, self._hook)
        return X @ self._grip(self.state(context))

    def grip_pose(self, q) -> RigidTransform:
        """World pose of the grip point frame (hook orientation) for commands q."""
        plant_context = self._plant.CreateDefaultContext()
        self._set(plant_context, q)
        return self._grip_pose_in(plant_context)

    def _ik(self, context, q0, p_des, R_des, *, base: bool,
            grip=P_HOOK_GRIP) -> np.ndarray:
        """Damped least squares on the robot's kinematics towards grip pose (p, R).

        Kept instead of Drake's DifferentialInverseKinematics / InverseKinematics, measured
        on the door task (30 targets near the pulling pose, 2 loaded cores): this DLS 1.1 ms
        per call (0.03 mm median error), ``InverseKinematics`` with the same pose
        constraints and a base-weighted cost 5.6 ms (SNOPT, 0.17 mm), 8 steps of
        ``DoDifferentialInverseKinematics`` 1.6 ms. The DLS also weights base against arm
        motion (``base_weight``; Drake's differential IK has velocity bounds and a
        nullspace centering term, no per-joint cost weights) and takes bounded steps
        (``ik_max_step``) that the compliant arm follows smoothly; the controller's phases
        are tuned on that behaviour. ``grip``: the point of the hook (its frame) to put at
        ``p_des``.
        """
        cfg = self._cfg
        # scratch: only the commanded joints' positions are ever set in it, each before use
        plant_context = self._ik_scratch.get_mutable_cache_entry_value(
            context).GetMutableValueOrThrow()
        q = np.array(q0, float)
        w = np.ones(q.size)
        w[:3] = cfg.base_weight if base else 1e6  # base fixed (a huge cost) unless allowed
        Winv = 1.0 / w
        wr = cfg.ik_rotation_weight
        lam = cfg.ik_damping
        damping = lam * lam * np.eye(6)
        plant, world = self._plant, self._world
        # (norms as sqrt(v . v): numpy's norm of a vector, without its dispatch; the clip as
        # minimum(maximum()): np.clip's values, NaN included)
        for _ in range(cfg.ik_iterations):
            self._set(plant_context, q)
            X = plant.CalcRelativeTransform(plant_context, world, self._hook)
            p = X @ grip
            R = X.rotation().matrix()
            e_p = p_des - p
            e_R = RotationMatrix(R_des @ R.T).ToAngleAxis()
            angle = e_R.angle()
            e = np.concatenate([wr * (e_R.axis() * angle), e_p])  # 1 rad ~ wr m
            if (math.sqrt(e_p.dot(e_p)) < cfg.ik_position_tolerance
                    and angle < cfg.ik_angle_tolerance):
                break
            J = plant.CalcJacobianSpatialVelocity(
                plant_context, JacobianWrtVariable.kQDot, self._hook, grip,
                world, world)[:, self._qidx]
            J[:3] *= wr
            JW = J * Winv
            dq = JW.T @ np.linalg.solve(JW @ J.T + damping, e)
            step = dq[3:]
            n = math.sqrt(step.dot(step))
            if n > cfg.ik_max_step:
                dq *= cfg.ik_max_step / n
            q = np.minimum(np.maximum(q + dq, self._lo), self._hi)
        return q

    # ------------------------------------------------------------------ events
    def _initialize(self, context, state):
        q = self._measured_q(context)
        s = EpcState(phase=DRIVE, t_phase=context.get_time(), q_from=q, q_to=q,
                     t_cmd=context.get_time(), start=q,
                     last_G=self._measured_grip_point(context))
        state.get_mutable_abstract_state(self._s).set_value(s)
        return EventStatus.Succeeded()

    def _stance(self) -> np.ndarray:
        """Base pose (x, y, yaw) in front of the handle, facing it."""
        t, cfg = self._task, self._cfg
        n = t.normal.copy()
        n[2] = 0.0
        n = _unit(n)
        side = t.side - np.dot(t.side, [0, 0, 1.0]) * np.array([0, 0, 1.0])
        # no sideways shift when side is (nearly) vertical: a horizontal bar, hooked from above
        side = _unit(side) if np.linalg.norm(side) > 0.3 else np.zeros(3)
        p = t.handle + cfg.stance_distance * n + cfg.stance_side * side
        yaw = math.atan2(-n[1], -n[0])
        return np.array([p[0], p[1], yaw])

    def _update(self, context, state):
        try:
            s = self._step(context, self.state(context))
        except (RuntimeError, ValueError, np.linalg.LinAlgError, FloatingPointError):
            # a controller step that cannot be computed holds the last command
            s = self.state(context)
            s = replace(s, q_from=s.q_to, t_cmd=context.get_time())
        state.get_mutable_abstract_state(self._s).set_value(s)
        return EventStatus.Succeeded()

    @staticmethod
    def _next_phase(s: EpcState, phase: int, t: float, start, **changes) -> EpcState:
        return replace(s, phase=phase, t_phase=t, start=start, **changes)

    def _now(self, context, s: EpcState) -> EpcInputs:
        F = np.asarray(self._in_force.Eval(context), float)
        if not np.all(np.isfinite(F)):
            F = np.zeros(3)
        t = context.get_time()
        return EpcInputs(t=t, elapsed=t - s.t_phase, F=F,
                    G=self._measured_grip_point(context))

    def _step(self, context, s: EpcState) -> EpcState:
        """One control period: the phase's own step (:attr:`_PHASES`) computes the command
        and the next state; the command is then interpolated over the next period."""
        now = self._now(context, s)
        phase = self._PHASES.get(s.phase)
        q_cmd, s_new = (s.q_to.copy(), s) if phase is None else \
            phase(self, context, s, now, s.q_to.copy())  # DONE: hold
        return replace(s_new, q_from=self._current_cmd(s, now.t),
                       q_to=np.clip(q_cmd, self._lo, self._hi), t_cmd=now.t,
                       last_G=now.G)

    # ------------------------------------------------------------------ phases
    def _drive(self, context, s: EpcState, now: EpcInputs, q_cmd):
        """DRIVE: move the base to the stance and fold the arm into its ready pose."""
        cfg = self._cfg
        goal = self._stance()
        # turn the short way (facing -x, the stance yaw may be +pi while the start is
        # near -pi: a linear blend would spin the base a full turn)
        goal[2] = s.start[2] + math.remainder(goal[2] - s.start[2], 2 * math.pi)
        dist = np.linalg.norm(goal[:2] - s.start[:2])
        T = max(cfg.drive_min_time, dist / cfg.drive_speed)
        a = min(1.0, now.elapsed / T)
        a = 0.5 - 0.5 * math.cos(math.pi * a)
        q_cmd[:3] = (1 - a) * s.start[:3] + a * goal
        ready = np.array(cfg.ready_arm_q, float)
        q_cmd[3:] = (1 - a) * s.start[3:] + a * ready
        if now.elapsed >= T + cfg.drive_settle_time:
            s = self._next_phase(s, PREHOOK, now.t, now.G)
        return q_cmd, s

    def _side_goal(self, s: EpcState, depth: float) -> np.ndarray:
        """The grip point ``depth`` in front of the clicked handle (negative: behind it),
        beside the bar by the side offset and its correction."""
        cfg, task = self._cfg, self._task
        return (task.handle + depth * task.normal
                + (cfg.side_offset + s.side_extra) * task.side)

    def _prehook(self, context, s: EpcState, now: EpcInputs, q_cmd):
        """PREHOOK: approach the point in front of the handle, beside the bar."""
        cfg = self._cfg
        goal = self._side_goal(s, cfg.prehook_distance)
        a = min(1.0, now.elapsed / cfg.approach_time)
        p = (1 - a) * s.start + a * goal
        q_cmd = self._ik(context, q_cmd, p, self._R_hook0, base=False)
        if now.elapsed >= cfg.approach_time + cfg.approach_settle_time:
            s = self._next_phase(s, DEPTH, now.t, goal)
        return q_cmd, s

    def _retry(self, context, s: EpcState, now: EpcInputs, q_cmd, *, side_shift: float,
               backoff: float, **changes):
        """Start the hooking over: back out ``backoff`` along the normal and approach again
        with the side offset corrected by ``side_shift``."""
        back = now.G + backoff * self._task.normal
        q_cmd = self._ik(context, q_cmd, back, self._R_hook0, base=False)
        return q_cmd, self._next_phase(s, PREHOOK, now.t, back, retries=s.retries + 1,
                                       side_extra=s.side_extra + side_shift, **changes)

    def _depth(self, context, s: EpcState, now: EpcInputs, q_cmd):
        """DEPTH: guarded move into the front; a contact in front of the front is the bar
        (retry further to the side), no contact deeper than the front means the finger
        passed its edge (retry closer); touching the front, back off and slide."""
        cfg, task = self._cfg, self._task
        # guarded move into the front, deeper than the clicked handle by the depth
        # margin: the handle is only known to a few cm (click and base localisation)
        margin = cfg.depth_margin
        goal = self._side_goal(s, -(cfg.depth_goal + margin))
        # the same speed as without the margin
        nominal = cfg.prehook_distance + cfg.depth_goal
        T = cfg.depth_time * (nominal + margin) / nominal
        a = min(1.0, now.elapsed / T)
        p = (1 - a) * s.start + a * goal
        touching = np.dot(now.F, task.normal) > cfg.depth_contact_force
        depth = np.dot(now.G - task.handle, task.normal)
        # the finger touches the front with the seat ~0.036 m behind the bar's centre,
        # the bar itself ~0.044 m in front of it (+-0.02 m click error): split at
        # bar_split_depth (0); a contact at the depth where the bar was met before is
        # the bar again
        on_bar = depth > cfg.bar_split_depth or (
            math.isfinite(s.bar_depth) and depth > s.bar_depth - cfg.bar_depth_tolerance)
        retry = s.retries < cfg.max_retries
        if touching and on_bar and retry:
            # hit something in front of the front: the bar itself (the click was off
            # sideways). Back out and come in again further to the side.
            return self._retry(context, s, now, q_cmd, side_shift=cfg.retry_side_shift,
                               backoff=cfg.retry_backoff)
        if not touching and depth < -cfg.edge_depth - margin and retry:
            # deeper than the front without touching it: the finger passed the front's
            # free edge. Back out and come in again closer to the bar.
            return self._retry(context, s, now, q_cmd, side_shift=-cfg.retry_side_shift,
                               backoff=cfg.edge_retry_backoff + margin)
        if touching or now.elapsed >= T:
            # back off from the front so the finger clears it and the bar
            p = now.G + cfg.front_backoff * task.normal
            return self._ik(context, q_cmd, p, self._R_hook0, base=False), \
                self._next_phase(s, SLIDE, now.t, p)
        return self._ik(context, q_cmd, p, self._R_hook0, base=False), s

    def _slide(self, context, s: EpcState, now: EpcInputs, q_cmd):
        """SLIDE: guarded sideways move until the rod touches the bar (then PULL); a slide
        that meets nothing went over the bar: retry further to the side."""
        cfg, task, G = self._cfg, self._task, now.G
        # slide until the rod touches the bar (up to slide_reach past the clicked
        # position; a sliding door moves away along -side when the rod meets its bar,
        # so the rod feels little: there the slide ends sliding_reach past the clicked
        # bar and the pull goes on in the same direction)
        pulling_out = abs(np.dot(task.pull, task.normal)) > 0.5  # more out than along
        reach = cfg.slide_reach if pulling_out else cfg.sliding_reach
        off = np.dot(s.start - task.handle, task.side)
        goal = s.start - (off + reach) * task.side
        T = cfg.slide_time * (1.0 + max(0.0, reach - cfg.sliding_reach)
                              / cfg.slide_time_distance)
        a = min(1.0, now.elapsed / T)
        p = (1 - a) * s.start + a * goal
        # the rod touches the bar: a side force once the seat is near the clicked bar
        # (friction on the front while sliding also pushes along +side), or anywhere
        # once the hook lags slide_blocked_lag behind the commanded slide (the bar
        # stops it where the click did not say)
        near = abs(np.dot(G - task.handle, task.side)) < cfg.slide_near_bar
        blocked = np.dot(G - p, task.side) > cfg.slide_blocked_lag
        contact = np.dot(now.F, task.side) > cfg.slide_contact_force and (near or blocked)
        q_cmd = self._ik(context, q_cmd, p, self._R_hook0, base=False)
        reached = abs(np.dot(G - goal, task.side)) < cfg.slide_reached_tolerance
        settled = now.elapsed >= T + cfg.slide_settle_time
        if (not contact and settled and reached and s.retries < cfg.max_retries
                and pulling_out):
            # slid past the bar without feeling it: the finger was in front of the bar
            # (the contact was the bar, not the front). Back out and come in again
            # further to the side, taking contacts at this depth for the bar.
            bar_depth = float(np.dot(s.start - task.handle, task.normal)) - cfg.front_backoff
            return self._retry(context, s, now, q_cmd, side_shift=cfg.retry_side_shift,
                               backoff=cfg.retry_backoff, bar_depth=bar_depth)
        if contact or settled:
            grip = P_HOOK_GRIP
            if contact and pulling_out and np.dot(G - task.handle, task.side) > \
                    cfg.tip_contact_offset:
                # stopped well before the rod reached the clicked handle: the finger's tip
                # met the handle's stem (a knob); the handle sits beyond the tip
                grip = np.array([HOOK_FINGER_TIP + cfg.tip_handle_offset, 0.0,
                                 P_HOOK_GRIP[2]])
                G = self._grip_pose_in(self._kin.Eval(context), grip).translation()
            s = self._next_phase(s, PULL, now.t, G, cep=G, direction=task.pull, trail_G=G,
                                 motion=task.pull, R=self._R_hook0, grip=grip)
        return q_cmd, s

    def _release(self, context, s: EpcState, now: EpcInputs, q_cmd):
        """RELEASE: unload the finger, slide the hook out sideways and back off, in the
        front's orientation as the handle's last motion shows it."""
        cfg, task = self._cfg, self._task
        # the front's current orientation from the handle's observed motion (model-free:
        # the hook's orientation may lag behind a door whose model came late)
        R_front = _rotation_between(task.pull, s.motion)
        side = R_front @ task.side
        normal = R_front @ task.normal
        a = min(1.0, now.elapsed / cfg.release_time)
        # unload the finger (back along the motion), slide out sideways, back off
        a1, a2 = cfg.release_slide_start, cfg.release_backoff_start
        p = (s.start - cfg.release_unload * min(1.0, a / a1) * s.motion
             + cfg.release_slide * float(np.clip((a - a1) / (a2 - a1), 0, 1)) * side
             + cfg.release_backoff * float(np.clip((a - a2) / (1.0 - a2), 0, 1)) * normal)
        q_cmd = self._ik(context, q_cmd, p, s.R, base=False, grip=self._grip(s))
        if now.elapsed >= cfg.release_time:
            s = self._next_phase(s, DONE, now.t, now.G)
        return q_cmd, s

    def _link_model(self, context):
        obj = self._in_model.Eval(context) if self._in_model.HasValue(context) else None
        if obj is None or not getattr(obj, "edges", None):
            return None
        link = obj.edges[0].model
        if getattr(link, "n_train", 0) < self._cfg.min_model_samples:
            return None
        return link

    def _follow_model(self, s: EpcState, link, G) -> dict:
        """What the learned model says (PULL): the pull's direction along its Jacobian, the
        configuration and opening, the hook's orientation turned towards its prediction
        at a bounded rate. Returns the state's changes."""
        ch = {"model_name": "" if link is None else link.name}
        if link is None or link.name not in ("prismatic", "revolute", "gp"):
            # no model yet: along the handle's observed motion, the hook turned with it
            ch.update(direction=self._motion(s),
                      R=self._turn_towards(s.R, self._motion_rotation(s)))
            return ch
        R_hook0 = self._R_hook0
        direction = s.direction
        q_hat = float(link.inverse(G[None])[0, 0])
        J = link.jacobian(np.array([[q_hat]]))[0, :3, 0]
        if link.name == "prismatic":
            # along the handle's observed motion: the model's line for a drawer, the door's
            # tangent while its arc still reads as a line (its first tens of degrees at
            # sigma_pos 0.05 m)
            direction = self._motion(s)
        elif np.linalg.norm(J) > 1e-9:
            d = _unit(J)
            if np.dot(d, s.direction) < 0:
                d = -d
            direction = d
        # configuration at the start of the pull, in the current model's coordinates
        q_hat0 = float(link.inverse(s.start[None])[0, 0])
        dq = q_hat - q_hat0
        if link.name == "revolute":
            dq = math.remainder(dq, 2 * math.pi)
        sign = 1.0 if np.dot(J, direction) >= 0 else -1.0
        # the hook turns with the front, as the revolute model predicts or else as the
        # handle's motion shows: a hook that kept its orientation while a door turned
        # would let the bar slide along its finger by millimetres that change along the
        # arc, which the arc's fit turns into centimetres of radius
        R_model = (_axis_angle(link.axis, dq) @ R_hook0 if link.name == "revolute"
                   else self._motion_rotation(s))
        ch.update(q_hat0=q_hat0, q_hat=q_hat, opening=sign * dq, direction=direction,
                  R=self._turn_towards(s.R, R_model))
        return ch

    def _motion(self, s: EpcState) -> np.ndarray:
        """The handle's observed motion without its part along the bar (the handle of a
        door, dishwasher, drawer or sliding door does not move along its bar; the hook
        may slide along it)."""
        bar = self._task.bar
        m = s.motion - np.dot(s.motion, bar) * bar
        return _unit(m) if np.linalg.norm(m) > 1e-9 else self._task.pull

    def _motion_rotation(self, s: EpcState) -> np.ndarray:
        """The hook's initial orientation turned, about the bar, as the handle's observed
        motion turned from the initial pulling direction (the front's orientation,
        model-free, lagging by about half of ``motion_window``)."""
        return _rotation_between(self._task.pull, self._motion(s)) @ self._R_hook0

    def _turn_towards(self, R, R_target) -> np.ndarray:
        """R turned towards R_target by at most ``max_turn``."""
        aa = RotationMatrix(R_target @ R.T).ToAngleAxis()
        turn = min(aa.angle(), self._cfg.max_turn)
        return _axis_angle(aa.axis(), turn) @ R if turn > 1e-9 else R

    def _equilibrium_point(self, s: EpcState, F, G, scale: float = 1.0) -> np.ndarray:
        """Eq. 4.58: the equilibrium point advances by ``step`` along the pull's direction,
        plus a proportional term keeping ``force_target`` between hook and handle
        perpendicular to the motion; at most ``max_lead`` ahead of the hook."""
        cfg, task, R_hook0 = self._cfg, self._task, self._R_hook0
        direction = s.direction
        # force perpendicular to the motion: the hook presses onto the handle along u
        side = s.R @ (R_hook0.T @ task.side)
        normal = s.R @ (R_hook0.T @ task.normal)
        if abs(np.dot(task.pull, task.normal)) > 0.5:  # more out of the front than along it
            u = -side  # pulling out of the front: the rod presses the bar's side
        else:
            u = -normal  # sliding: the finger presses against the front behind the bar
        u = _unit(u - np.dot(u, direction) * direction)
        f_perp = -np.dot(F, u)
        v_hook = cfg.force_gain * (cfg.force_target - f_perp) * u
        v_hook = np.clip(v_hook, -cfg.step, cfg.step)
        cep = s.cep + scale * cfg.step * direction + v_hook
        # the lead onto the handle (along u) and the rest are bounded apart: one bound on
        # the whole lead would scale the pressing term away whenever the hook lags along
        # the path, and the bar would slide along the finger, off the seat
        lead = cep - G
        press = float(np.dot(lead, u))
        rest = lead - press * u
        if np.linalg.norm(rest) > cfg.max_lead:
            rest *= cfg.max_lead / np.linalg.norm(rest)
        return G + rest + float(np.clip(press, -cfg.max_lead, cfg.max_lead)) * u

    def _stop_reason(self, s: EpcState, now: EpcInputs) -> tuple[dict, str]:
        """The stall and slack counters' changes and why the pull ends ("" while it goes
        on): target reached by the model, held back (end of the configuration range),
        no force (lost the handle) or out of time."""
        cfg, F, G = self._cfg, now.F, now.G
        # held back while the hook has not advanced since the stall began (progress over
        # the whole window, not per period: the believed hook position drifts a few
        # millimetres per period with the base localisation)
        pulling = np.dot(F, -s.direction)
        held_back = pulling > cfg.stop_force or (
            np.linalg.norm(s.cep - G) > cfg.stall_lead_fraction * cfg.max_lead
            and pulling > cfg.stall_force_fraction * cfg.stop_force)
        if not held_back:
            ch = {"stalled": 0}
        elif s.stalled == 0 or np.linalg.norm(G - s.stall_G) > cfg.step:
            ch = {"stalled": 1, "stall_G": G}
        else:
            ch = {"stalled": s.stalled + 1}
        ch["slack"] = s.slack + 1 if np.linalg.norm(F) < cfg.slack_force else 0
        target = cfg.target_angle if s.model_name == "revolute" else cfg.target_distance
        if s.model_name in ("revolute", "prismatic") and s.opening >= target:
            return ch, "target reached"
        if ch["stalled"] >= cfg.stall_periods:
            return ch, "end of the configuration range"
        if ch["slack"] >= cfg.slack_periods:
            return ch, "lost the handle"
        if now.elapsed > cfg.max_pull_time:
            return ch, "timeout"
        return ch, ""

    def _pull(self, context, s: EpcState, now: EpcInputs, q_cmd):
        """PULL: equilibrium-point control along the learned model (thesis Eq. 4.57-4.59)
        until a stop condition (:meth:`_stop_reason`) ends it."""
        G = now.G
        scale, halt = self._supervisor(context)
        if halt in (1, 2):  # the mechanism is blocked: stop pulling, let go
            s = replace(s, cep=G)
            q_cmd = self._ik(context, q_cmd, G, s.R, base=True, grip=self._grip(s))
            return q_cmd, self._next_phase(s, RELEASE, now.t, G,
                                           outcome="jammed" if halt == 1 else "locked")
        s = replace(s, **self._follow_model(s, self._link_model(context), G))
        s = replace(s, cep=self._equilibrium_point(s, now.F, G, scale))
        # direction of the handle's most recent >= motion_window of motion
        if np.linalg.norm(G - s.trail_G) >= self._cfg.motion_window:
            s = replace(s, motion=_unit(G - s.trail_G), trail_G=G)
        q_cmd = self._ik(context, q_cmd, s.cep, s.R, base=True, grip=self._grip(s))
        changes, done = self._stop_reason(s, now)
        s = replace(s, **changes)
        if done:
            s = self._next_phase(s, RELEASE, now.t, G, outcome=done)
        return q_cmd, s

    #: the step of each phase (DONE holds the last command)
    _PHASES = {DRIVE: _drive, PREHOOK: _prehook, DEPTH: _depth, SLIDE: _slide, PULL: _pull,
               RELEASE: _release}

    # ------------------------------------------------------------------ outputs
    def _current_cmd(self, s: EpcState, t: float) -> np.ndarray:
        a = min(1.0, max(0.0, (t - s.t_cmd) / self._cfg.period))
        return (1 - a) * s.q_from + a * s.q_to

    def _calc_cmd(self, context, output):
        output.SetFromVector(self._current_cmd(self.state(context), context.get_time()))

    def _calc_segment(self, context, output):
        s = self.state(context)
        output.SetFromVector(np.concatenate([s.q_from, s.q_to, [s.t_cmd]]))

    def _calc_G(self, context, output):
        # only the trajectory while the hook holds the handle is an observation of the
        # mechanism: outside the pull phase, or without contact force, the output is NaN
        # (the estimator drops it)
        if self.state(context).phase != PULL:
            output.SetFromVector(np.full(3, np.nan))
            return
        F = self._in_force.Eval(context)
        if math.sqrt(F.dot(F)) < self._cfg.contact_force:  # (numpy's norm of a vector)
            output.SetFromVector(np.full(3, np.nan))
            return
        output.SetFromVector(self._measured_grip_point(context))

    def _calc_phase(self, context, output):
        output.SetFromVector([self.state(context).phase])

    def _calc_status(self, context, output):
        s = self.state(context)
        output.SetFromVector([s.opening, s.q_hat, float(s.phase == DONE),
                              float(s.outcome == "target reached")])


def CommandInterpolator(size: int, period: float):
    """A Drake ``SymbolicVectorSystem`` (evaluated in C++) that turns an
    :class:`EpcController`'s ``command_segment`` output ([q_from, q_to, t_cmd], ``size``
    commands) into its ``command`` at time t: (1 - a) q_from + a q_to with
    a = min(1, max(0, (t - t_cmd) / ``period``)), the same floats as the controller's own
    ``command`` output. The plant reads the command at every step; the segment changes
    once per control period."""
    from pydrake.symbolic import MakeVectorVariable, Variable, max as smax, min as smin
    from pydrake.systems.primitives import SymbolicVectorSystem

    t = Variable("t")
    u = MakeVectorVariable(2 * size + 1, "segment")
    a = smin(1.0, smax(0.0, (t - u[2 * size]) / period))
    return SymbolicVectorSystem(time=t, input=u,
                                output=[(1 - a) * u[i] + a * u[size + i] for i in range(size)])

