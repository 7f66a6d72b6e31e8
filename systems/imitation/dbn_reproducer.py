"""DbnReproducer: reproduce a task learned as a DBN of constraints (thesis 8.1.2) on a
Drake arm.

Every ``period`` seconds the system takes one step of the learned model (time slice k):

* ``incremental`` mode (Eq. 8.17-8.26): :func:`mmlearn.models.imitation.dbn.constraint_step`
  with the hand (tool centre point) position and its translational Jacobian computed from
  the robot plant at the commanded configuration, the objects' last good observed
  positions, and the obstacles;
* ``global`` mode (Eq. 8.27-8.28): at the first step at which every object has been seen,
  :func:`mmlearn.models.imitation.global_plan.plan_global` plans the whole joint sequence; the steps
  then follow it.

The gripper follows the learned ``gripper`` constraint's mean (0 closed .. 1 open) mapped
to the finger angle. Between two steps the command is interpolated linearly, so the
compliant (implicit PD) arm gets a smooth reference.

Bad observations never stop the simulation: a marker that is not seen, or whose pose is
not finite, keeps its last good position; the model is not stepped until every object it
needs has been seen once (``status`` counts the waiting steps), and a step whose
computation fails holds the arm where it is (counted in ``status``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pydrake.common.value import AbstractValue
from pydrake.multibody.tree import JacobianWrtVariable
from pydrake.systems.framework import BasicVector, EventStatus, LeafSystem

from mmlearn.models.common.config import param, validate_fields

from mmlearn.systems.common.observations import MarkerObservations

MODES = ("incremental", "global")
STATUS_FIELDS = ("steps", "waiting", "failed", "planned", "plan_seconds", "finished",
                 "slice_waits")


@dataclass
class DbnReproducerConfig:
    """Parameters of a :class:`DbnReproducer`.

    Attributes:
        mode: "incremental" (Eq. 8.17-8.26, one step per time slice) or "global" (a plan of
            the whole sequence at the start, Eq. 8.27-8.28).
        period: seconds between two steps (0 = the learned model's time step).
        settle_steps: extra steps on the model's last time slice after its end, so the hand
            converges to the final constraint (each step moves only part of the way).
        use_joints: use the learned joint constraints (only when the robot's and the
            teacher's kinematics are the same; thesis 8.2.1 switches them off otherwise).
        damping: damping factor lambda of the damped least squares (Eq. 8.19-8.20), m.
        gain: fraction of the fused displacement applied per step (1 = the thesis' step).
        max_joint_step: largest change of any joint per step, rad (safety bound).
        gripper_open_angle: finger angle commanded for a learned opening of 1, rad (0 =
            closed).
        obstacle_alpha: desired distance kept from an obstacle, alpha of Eq. 8.25, m.
        obstacle_beta: variance of an obstacle constraint at contact, beta of Eq. 8.26, m^2
            (smaller = stronger).
        obstacle_length: length scale of the variance's growth with the distance (Eq. 8.26),
            m.
        obstacle_range: an obstacle farther than this from the hand adds no constraint, m.
        carry_radius: an object whose learned offset from the hand is shorter than this
            while the learned gripper is closed counts as carried, m. The global plan
            always skips a carried object's constraint (it plans with the objects' start
            positions, but a carried object moves with the hand).
        plan_clearance: the global plan keeps the hand and the arm's body points this far
            from obstacles, m (the arm's links are up to 0.045 m thick around them).
        skip_carried: in incremental steps, skip the constraint of an object that is
            carried *and observed to be held*: its relation to the hand holds within
            ``carry_tolerance``. The thesis keeps it; the observed carried object then
            anchors the hand (its relation holds wherever the hand goes), so the hand
            moves towards the other constraints only by their share of the precision and
            arrives late (with swapped tables the cup was released short of the target
            table). An object the grasp missed does not hold its relation and
            keeps its constraint (the hand goes back to it).
        carry_tolerance: largest deviation of a carried object's observed relation from
            the learned one for it to count as held, m.
        held_offset_correction: while an object is held, move the hand targets of the
            other constraints by the learned minus the observed object-to-hand offset
            (measured hand), so that the *held object* (not the hand) meets the relations
            the demonstrations showed: the grasp holds the cup where the fingers closed, up
            to ``carry_tolerance`` off the learned relation, and without this the cup lands
            off the demonstrated spot by that much (with swapped tables, a share of the
            horizontal place error). Horizontal (world x, y) only: when
            the held object rests on a support its vertical offset is set by the contact,
            and a vertical correction then winds up (the hand pressed the cup into the
            table, the reproduction slowed down to the release and the cup jumped when let
            go). Thesis 8.1.2 has no such term (its
            carried-object constraint stays active; see ``skip_carried``).
        held_offset_filter: share (0, 1] of a step's newly observed correction taken into
            the applied one (first-order low-pass over steps): the observed offset carries
            the marker noise, which alone made the hand miss ``advance_tolerance`` and the
            reproduction slow down (unfiltered, the release came seconds later).
        release_in_place: in incremental steps, the step at which the learned gripper
            opens only opens it: the arm command stays where the previous step put it. The
            thesis' step moves the hand towards the next slice while the fingers open, and
            the grasp lets go half-way through that step (with swapped tables the
            held-object correction was dropped on that step and the cup landed off the
            spot).
        advance_tolerance: incremental mode moves on to the next time slice only when the
            commanded hand is within this distance of the current slice's fused target
            (or after ``max_slice_waits`` extra steps on it), m; 0 = one slice per step
            as in the thesis. A slowed-down arm (or a hand anchored by a carried object's
            constraint) then still arrives before, e.g., the gripper opens. Not used when
            there are obstacles: their attractors keep the hand off the fused target of the
            other constraints on purpose (the box-obstacle reach stalled with it).
        max_slice_waits: largest number of extra steps spent on one slice.
        step_kwargs: further keyword arguments passed to ``constraint_step`` /
            ``plan_global`` unchanged.
    """

    mode: str = param("incremental", choices=MODES)
    period: float = param(0.0, unit="s", ge=0)
    settle_steps: int = param(15, integer=True, ge=0)
    use_joints: bool = param(False)
    damping: float = param(0.05, unit="m", ge=0)
    gain: float = param(1.0, gt=0)
    max_joint_step: float = param(0.25, unit="rad", gt=0)
    gripper_open_angle: float = param(0.6, unit="rad", ge=0)
    obstacle_alpha: float = param(0.05, unit="m", ge=0)
    obstacle_beta: float = param(1e-6, unit="m^2", ge=0)
    obstacle_length: float = param(0.05, unit="m", ge=0)
    obstacle_range: float = param(0.35, unit="m", ge=0)
    carry_radius: float = param(0.1, unit="m", ge=0)
    skip_carried: bool = param(True)
    plan_clearance: float = param(0.06, unit="m", ge=0)
    carry_tolerance: float = param(0.05, unit="m", ge=0)
    held_offset_correction: bool = param(True)
    held_offset_filter: float = param(0.3, gt=0, le=1)
    release_in_place: bool = param(True)
    advance_tolerance: float = param(0.01, unit="m", ge=0)
    max_slice_waits: int = param(8, integer=True, ge=0)
    step_kwargs: dict[str, float] = param({}, factory=True)

    def validate(self) -> None:
        validate_fields(self)


class DbnReproducer(LeafSystem):
    """Joint position command of an arm (and its gripper) that reproduces a learned task.

    .. pydrake_system::

        name: DbnReproducer
        input_ports:
        - robot_state
        - observations
        output_ports:
        - command
        - target_hand
        - step
        - status
        - hand

    ``robot_state`` is the robot model instance's state [q; v] (the plant's
    ``state`` output for that instance), read at the first step (the arm starts from where
    it is). ``observations`` is a :class:`MarkerObservations` frame of the objects' markers
    (the ``MarkerSensor``'s output); ``object_markers`` names the marker of each object the
    model refers to. ``command`` holds the joint position commands in the order of
    ``arm_joints`` followed by the gripper's finger angle, rad. ``target_hand`` is the
    fused desired hand position of the last step (world, m; NaN before the first step),
    ``step`` the model time slice being reproduced, ``status`` the counters
    ``STATUS_FIELDS`` (steps taken, steps spent waiting for unseen objects, failed steps,
    1 when a global plan exists, its computing time in s, 1 when the task has ended, steps
    spent again on a slice the hand had not reached, see ``advance_tolerance``).
    ``hand`` is the tool centre point at the measured arm configuration (world, m).

    Discrete state (all that changes lives in the Context): the commands at the start and
    end of the current interpolation interval, that interval's start time, the time slice
    index, the last good position of every object and whether it was seen, the counters,
    and in global mode the plan.
    """

    def __init__(self, *, plant, model, arm_joints, tcp_frame, p_tcp=(0.0, 0.0, 0.0),
                 body_points=(), plan_body_points=None,
                 object_markers: dict[str, str] | None = None,
                 obstacles: dict[str, tuple] | None = None,
                 config: DbnReproducerConfig | None = None):
        """
        Args:
            plant: the finalized MultibodyPlant that holds the robot (scratch contexts of it
                are made per step for the kinematics).
            model: the learned :class:`~mmlearn.models.imitation.types.TaskModel`.
            arm_joints: the arm's joint objects (or names) driven by the constraints, in
                command order (one position each).
            tcp_frame: the frame (or body name) that carries the tool centre point.
            p_tcp: the tool centre point in ``tcp_frame``, m.
            body_points: further points on the arm kept away from obstacles: (frame or body
                name, point in that frame (3,), m) pairs, e.g. the elbow and the wrist (the
                incremental step gives each an obstacle attractor, the global plan checks
                them for collision).
            plan_body_points: the points the global plan checks for collision instead of
                ``body_points``, same form (default: ``body_points``): a denser set along the
                links (e.g. every 5 cm of the forearm) so that an obstacle edge cannot pass
                between two checked points; not used by the incremental step.
            object_markers: object name (as in the model's ``obj:<name>`` constraints) ->
                marker id in the observations (default: the same name).
            obstacles: obstacle marker id -> list of boxes (offset of the box centre from
                the marker in the world, m (3,), box half size, m (3,)): axis-aligned boxes
                that move with the observed marker (e.g. the three walls of a U).
            config: the reproduction parameters.
        """
        super().__init__()
        cfg = config or DbnReproducerConfig()
        cfg.validate()
        self._cfg = cfg
        self._plant = plant
        self._model = model
        self._objects = [c.split(":", 1)[1] for c in model.constraints if c.startswith("obj:")]
        markers = dict(object_markers or {})
        self._marker_of = {o: markers.get(o, o) for o in self._objects}
        self._obstacles = {str(k): [(np.asarray(b[0], float).reshape(3),
                                     np.asarray(b[1], float).reshape(3)) for b in v]
                           for k, v in (obstacles or {}).items()}
        self._tracked = list(self._objects) + [o for o in self._obstacles
                                               if o not in self._objects]
        joints = [plant.GetJointByName(j) if isinstance(j, str) else j for j in arm_joints]
        if not joints:
            raise ValueError("DbnReproducer: arm_joints is empty")
        for j in joints:
            if j.num_positions() != 1:
                raise ValueError(f"DbnReproducer: joint {j.name()!r} must have one position")
        self._qidx = np.array([j.position_start() for j in joints])
        self._lo = np.array([j.position_lower_limits()[0] for j in joints])
        self._hi = np.array([j.position_upper_limits()[0] for j in joints])
        self._lo = np.where(np.isfinite(self._lo), self._lo, -np.pi)
        self._hi = np.where(np.isfinite(self._hi), self._hi, np.pi)
        robot = joints[0].model_instance()
        self._robot = robot
        q_starts = sorted(plant.get_joint(j).position_start()
                          for j in plant.GetJointIndices(robot)
                          if plant.get_joint(j).num_positions() == 1)
        self._local = np.array([q_starts.index(i) for i in self._qidx])
        self._frame = (plant.GetBodyByName(tcp_frame).body_frame()
                       if isinstance(tcp_frame, str) else tcp_frame)
        self._p_tcp = np.asarray(p_tcp, float).reshape(3)
        self._body_points = [
            (plant.GetBodyByName(f).body_frame() if isinstance(f, str) else f,
             np.asarray(p, float).reshape(3, 1)) for f, p in body_points]
        plan_pts = body_points if plan_body_points is None else plan_body_points
        # grouped per frame: one CalcPointsPositions call per frame, (frame, (3, m) points)
        groups: dict = {}
        for f, p in plan_pts:
            fr = plant.GetBodyByName(f).body_frame() if isinstance(f, str) else f
            p = np.asarray(p, float)
            if p.shape != (3,) or not np.all(np.isfinite(p)):
                raise ValueError(f"DbnReproducer: plan_body_points point must be finite (3,), "
                                 f"got {p!r}")
            groups.setdefault(fr.index(), [fr, []])[1].append(p)
        self._plan_points = [(fr, np.array(ps).T) for fr, ps in groups.values()]
        t = np.asarray(model.t, float)
        if t.ndim != 1 or t.size < 1:
            raise ValueError("DbnReproducer: the model has no time steps")
        self._S = int(t.size)
        dt = float(np.median(np.diff(t))) if t.size > 1 else 0.2
        self._period = cfg.period if cfg.period > 0 else dt
        self._has_gripper = "gripper" in model.constraints
        n = len(joints)
        self._n = n
        m = len(self._tracked)
        nx = plant.num_positions(robot) + plant.num_velocities(robot)
        self._nq_robot = plant.num_positions(robot)
        self._in_state = self.DeclareVectorInputPort("robot_state", nx)
        self._in_obs = self.DeclareAbstractInputPort(
            "observations", AbstractValue.Make(MarkerObservations()))
        # discrete state groups
        self._g_from = self.DeclareDiscreteState(n + 1)     # command at interval start
        self._g_to = self.DeclareDiscreteState(n + 1)       # command at interval end
        self._g_clock = self.DeclareDiscreteState(4)  # [t_start, k, started, waits at k]
        self._g_obj = self.DeclareDiscreteState(4 * max(m, 1))  # xyz + seen, per object
        self._g_target = self.DeclareDiscreteState(3)
        self._g_status = self.DeclareDiscreteState(len(STATUS_FIELDS))
        self._g_held = self.DeclareDiscreteState(max(m, 1))  # 1 = object held in the hand
        self._g_shift = self.DeclareDiscreteState(3)  # filtered held-object correction, m
        self._g_plan = (self.DeclareDiscreteState(self._S * n) if cfg.mode == "global"
                        else None)
        self.DeclarePeriodicDiscreteUpdateEvent(self._period, 0.0, self._update)
        deps = {self.all_state_ticket(), self.time_ticket()}
        self._out_cmd = self.DeclareVectorOutputPort("command", BasicVector(n + 1),
                                                     self._calc_command,
                                                     prerequisites_of_calc=deps)
        self._out_target = self.DeclareStateOutputPort("target_hand", self._g_target)
        self._out_step = self.DeclareVectorOutputPort(
            "step", BasicVector(1), lambda c, o: o.SetAtIndex(
                0, c.get_discrete_state(self._g_clock).GetAtIndex(1)),
            prerequisites_of_calc={self.discrete_state_ticket(self._g_clock)})
        self._out_status = self.DeclareStateOutputPort("status", self._g_status)
        self._out_hand = self.DeclareVectorOutputPort(
            "hand", BasicVector(3), self._calc_hand,
            prerequisites_of_calc={self._in_state.ticket()})

    # ------------------------------------------------------------------ ports
    def get_robot_state_input_port(self):
        return self._in_state

    def get_observations_input_port(self):
        return self._in_obs

    def get_command_output_port(self):
        return self._out_cmd

    def get_target_hand_output_port(self):
        return self._out_target

    def get_status_output_port(self):
        return self._out_status

    def get_hand_output_port(self):
        return self._out_hand

    @property
    def period(self) -> float:
        """Seconds between two steps."""
        return self._period

    @property
    def duration(self) -> float:
        """Simulated seconds the reproduction takes without repeated slices (model steps
        plus settling), s; repeated slices (``advance_tolerance``, bounded joint steps of a
        global plan) extend it: ``status`` says when it has ended."""
        return (self._S + self._cfg.settle_steps + 1) * self._period

    def set_initial_command(self, context, q) -> None:
        """Put the arm command (and gripper angle as the last entry) in this system's
        ``context`` before simulating, so the output starts where the arm stands."""
        q = np.asarray(q, float).reshape(self._n + 1)
        context.SetDiscreteState(self._g_from, q)
        context.SetDiscreteState(self._g_to, q)
        context.SetDiscreteState(self._g_target, np.full(3, np.nan))

    # ------------------------------------------------------------------ kinematics
    def kinematics(self, plant_context=None) -> "_Kinematics":
        """Forward kinematics of the hand and of the ``body_points`` with one scratch plant
        context (a fresh one unless given): for use within one call (an update, a plan)."""
        return _Kinematics(self, plant_context or self._plant.CreateDefaultContext())

    def _kinematics(self, q):
        """(hand position (3,), translational Jacobian (3, n)) at arm joints q."""
        kin = self.kinematics()
        return kin.hand(q), kin.jacobian(q)

    def forward_kinematics(self, q) -> np.ndarray:
        """Hand (tool centre point) position in the world at arm joints q, m."""
        return self.kinematics().hand(np.asarray(q, float))

    def hand_jacobian(self, q) -> np.ndarray:
        """Translational Jacobian of the hand at arm joints q, (3, n)."""
        return self.kinematics().jacobian(np.asarray(q, float))

    # ------------------------------------------------------------------ observations
    def _read_objects(self, context, obj):
        """Update the (m, 4) rows [x, y, z, seen] with this frame's good observations."""
        try:
            obs = self._in_obs.Eval(context)
        except Exception:  # noqa: BLE001 - an unconnected or bad port: nothing seen
            return obj
        if obs is None:
            return obj
        ids = list(getattr(obs, "marker_ids", []))
        vis = np.asarray(getattr(obs, "visible", []), bool)
        poses = getattr(obs, "poses", [])
        for r, name in enumerate(self._tracked):
            marker = self._marker_of.get(name, name)
            if marker not in ids:
                continue
            i = ids.index(marker)
            if i >= vis.size or i >= len(poses) or not vis[i]:
                continue
            try:
                p = np.asarray(poses[i].translation(), float)
            except Exception:  # noqa: BLE001 - not a pose: ignore the frame
                continue
            if p.shape == (3,) and np.all(np.isfinite(p)):
                obj[r, :3] = p
                obj[r, 3] = 1.0
        return obj

    def _obstacle_boxes(self, obj):
        from mmlearn.models.imitation.types import Obstacle

        out = []
        for r, name in enumerate(self._tracked):
            if name in self._obstacles and obj[r, 3] > 0:
                for off, half in self._obstacles[name]:
                    out.append(Obstacle(centre=obj[r, :3] + off, half_size=half))
        return out

    def carried(self, k: int) -> list[str]:
        """Objects the learned model holds in the hand at slice k (see ``carry_radius``)."""
        if not self._has_gripper:
            return []
        k = min(int(k), self._S - 1)
        if float(np.asarray(self._model.mean["gripper"])[k].ravel()[0]) >= 0.5:
            return []
        return [o for o in self._objects
                if np.linalg.norm(np.asarray(self._model.mean[f"obj:{o}"])[k])
                < self._cfg.carry_radius]

    def update_held(self, k: int, hand, objects: dict, flags, *,
                    gripper_closed: bool = True) -> np.ndarray:
        """New held flags (one per tracked object): an object carried at slice k
        (``carried(k)``) becomes held when the gripper has already been commanded closed
        (``gripper_closed``) and its observed relation to the measured ``hand`` is within
        ``carry_tolerance`` of the learned one; it stays held until the learned gripper
        opens or the relation is off by more than three times that (dropped)."""
        flags = np.asarray(flags, float).copy()
        carried = set(self.carried(k))
        tol = self._cfg.carry_tolerance
        for r, name in enumerate(self._tracked):
            x = objects.get(name)
            if name not in carried or x is None or hand is None:
                flags[r] = 0.0
                continue
            mu = np.asarray(self._model.mean[f"obj:{name}"])[min(int(k), self._S - 1)]
            dev = float(np.linalg.norm(np.asarray(x) - hand - mu))
            if flags[r] == 0.0 and dev < tol and gripper_closed:
                flags[r] = 1.0
            elif flags[r] == 1.0 and dev > 3.0 * tol:
                flags[r] = 0.0
        return flags

    def gripper_angle(self, k: int) -> float:
        """Finger angle at time slice k from the learned gripper mean, rad."""
        if not self._has_gripper:
            return self._cfg.gripper_open_angle
        g = float(np.asarray(self._model.mean["gripper"])[min(k, self._S - 1)].ravel()[0])
        if not math.isfinite(g):
            g = 1.0
        return self._cfg.gripper_open_angle * (1.0 if g >= 0.5 else 0.0)

    # ------------------------------------------------------------------ events
    def _update(self, context, discrete_state):
        cfg = self._cfg
        t = context.get_time()
        clock = context.get_discrete_state(self._g_clock).get_value().copy()
        status = context.get_discrete_state(self._g_status).get_value().copy()
        q_to = context.get_discrete_state(self._g_to).get_value().copy()
        obj = context.get_discrete_state(self._g_obj).get_value().reshape(-1, 4).copy()
        obj = self._read_objects(context, obj)
        x = self._in_state.Eval(context)
        q_meas = np.asarray(x[: self._nq_robot], float)[self._local]
        if not np.all(np.isfinite(q_meas)):
            q_meas = None
        if clock[2] == 0:  # first step: start from the measured arm
            if q_meas is not None:
                q_to[: self._n] = q_meas
            clock[2] = 1.0
        q_from = q_to.copy()
        k = int(clock[1])
        target = context.get_discrete_state(self._g_target).get_value().copy()
        finished = k >= self._S - 1 + cfg.settle_steps
        needed = [r for r, name in enumerate(self._tracked) if name in self._objects]
        if finished:
            status[5] = 1.0
        elif not all(obj[r, 3] > 0 for r in needed):
            status[1] += 1
        else:
            ks = min(k + 1, self._S - 1)
            objects = {name: obj[r, :3].copy() for r, name in enumerate(self._tracked)
                       if name in self._objects}
            advance = True
            try:
                if cfg.mode == "global":
                    q_new, target, advance = self._global_step(
                        context, discrete_state, ks, q_to, objects, obj, status)
                    if not advance:
                        ks = k
                        status[6] += 1
                else:
                    held_flags = context.get_discrete_state(self._g_held).get_value()
                    # the measured hand, once per step (held test and offset correction)
                    hand_meas = (None if q_meas is None or not (
                        cfg.skip_carried or cfg.held_offset_correction)
                        else self.forward_kinematics(q_meas))
                    if cfg.skip_carried:
                        closed = q_to[self._n] < 0.5 * cfg.gripper_open_angle
                        held_flags = self.update_held(ks, hand_meas, objects, held_flags,
                                                      gripper_closed=closed)
                        discrete_state.set_value(self._g_held, held_flags)
                    held = [n for r, n in enumerate(self._tracked) if held_flags[r] > 0]
                    shift = np.zeros(3)
                    if cfg.held_offset_correction and held and q_meas is not None:
                        prev = context.get_discrete_state(self._g_shift).get_value()
                        raw = self.held_offset(ks, hand_meas, objects, held)
                        shift = prev + cfg.held_offset_filter * (raw - prev)
                        objects = {n: (x if n in held else x + shift)
                                   for n, x in objects.items()}
                    discrete_state.set_value(self._g_shift, shift)
                    stay = None
                    if (cfg.advance_tolerance > 0 and 1 <= k < self._S - 1
                            and clock[3] < cfg.max_slice_waits and not self._obstacles):
                        stay = self._incremental_step(k, q_to, objects, obj, held)
                        hand = self.forward_kinematics(q_to[: self._n])
                        if (stay[2] is None or np.linalg.norm(hand - stay[1])
                                <= cfg.advance_tolerance):
                            stay = None
                    if stay is not None:
                        advance, ks = False, k
                        q_new, target, _ = stay
                        clock[3] += 1
                        status[6] += 1
                    elif (cfg.release_in_place and self._has_gripper
                          and q_to[self._n] < 0.5 * cfg.gripper_open_angle
                          <= self.gripper_angle(ks)):
                        # the learned gripper opens at this step: open it with the arm
                        # where it stands (the object is let go where it was placed)
                        q_new = q_to[: self._n].copy()
                        clock[3] = 0
                    else:
                        q_new, target, _ = self._incremental_step(ks, q_to, objects, obj,
                                                                  held)
                        clock[3] = 0
                q_to[: self._n] = q_new
                q_to[self._n] = self.gripper_angle(ks)
                clock[1] = k + 1 if advance else k
                status[0] += 1
            except Exception:  # noqa: BLE001 - a failed step holds the arm, never crashes
                status[2] += 1
        clock[0] = t
        discrete_state.set_value(self._g_from, q_from)
        discrete_state.set_value(self._g_to, q_to)
        discrete_state.set_value(self._g_clock, clock)
        discrete_state.set_value(self._g_obj, obj.ravel())
        discrete_state.set_value(self._g_target, np.asarray(target, float).reshape(3))
        discrete_state.set_value(self._g_status, status)
        return EventStatus.Succeeded()

    def held_offset(self, k: int, hand, objects: dict, held) -> np.ndarray:
        """Mean over the ``held`` objects of the learned minus the observed object-to-hand
        offset at slice k in the horizontal plane (z = 0), m (3,); its length is capped
        at ``carry_tolerance``."""
        k = min(int(k), self._S - 1)
        devs = [np.asarray(self._model.mean[f"obj:{n}"])[k] - (np.asarray(objects[n]) - hand)
                for n in held if n in objects]
        if not devs:
            return np.zeros(3)
        d = np.mean(devs, axis=0)
        d[2] = 0.0
        nd = float(np.linalg.norm(d))
        if not math.isfinite(nd):  # a bad observation: no correction
            return np.zeros(3)
        tol = self._cfg.carry_tolerance
        return d * (tol / nd) if nd > tol else d

    def _correct_for_held(self, k, hand, objects, held):
        """The objects (other than the held ones) shifted by :meth:`held_offset`: their
        constraints' hand targets then place the held object as demonstrated."""
        shift = self.held_offset(k, hand, objects, held)
        return {n: (x if n in held else x + shift) for n, x in objects.items()}

    def _incremental_step(self, ks, q_to, objects, obj, held=()):
        from mmlearn.models.imitation.dbn import constraint_step

        cfg = self._cfg
        q = q_to[: self._n]
        kin = self.kinematics()
        hand, J = kin.hand(q), kin.jacobian(q)
        gripper = q_to[self._n] / max(cfg.gripper_open_angle, 1e-9)
        obstacles = self._near(self._obstacle_boxes(obj), hand)
        points = kin.point_jacobians(q) if obstacles else []
        kw = dict(hand=hand, objects=objects, J=J, q=q, gripper=gripper,
                  use_joints=cfg.use_joints, damping=cfg.damping, gain=cfg.gain,
                  obstacles=obstacles, obstacle_points=points,
                  obstacle_alpha=cfg.obstacle_alpha, obstacle_beta=cfg.obstacle_beta,
                  obstacle_length=cfg.obstacle_length,
                  carried=list(held))
        kw.update(cfg.step_kwargs)
        res = constraint_step(self._model, ks, **kw)
        dq = np.asarray(res.dq, float).reshape(self._n)
        if not np.all(np.isfinite(dq)):
            raise FloatingPointError("non-finite joint step")
        big = np.max(np.abs(dq))
        if big > cfg.max_joint_step:
            dq *= cfg.max_joint_step / big
        target = (np.full(3, np.nan) if res.target_hand is None
                  else np.asarray(res.target_hand, float))
        return np.clip(q + dq, self._lo, self._hi), target, res.target_hand

    def _near(self, boxes, hand):
        """The obstacles within ``obstacle_range`` of the hand (all when there are body
        points: the arm may be near an obstacle the hand is far from)."""
        if self._body_points:
            return list(boxes)
        rng = self._cfg.obstacle_range
        return [b for b in boxes if float(b.signed_distance(hand)) < rng]

    def _global_step(self, context, discrete_state, ks, q_to, objects, obj, status):
        import time

        from mmlearn.models.imitation.global_plan import plan_global

        plan = context.get_discrete_state(self._g_plan).get_value().reshape(self._S, self._n)
        if status[3] == 0:
            t0 = time.perf_counter()
            kin = self.kinematics()
            kw = dict(q0=q_to[: self._n].copy(), objects=objects,
                      fk=kin.hand, jacobian=kin.jacobian,
                      body_points=kin.plan_points if self._plan_points else None,
                      obstacles=self._obstacle_boxes(obj), use_joints=self._cfg.use_joints,
                      q_lower=self._lo, q_upper=self._hi, carry_radius=self._cfg.carry_radius,
                      clearance=self._cfg.plan_clearance, seed=0)
            kw.update(self._cfg.step_kwargs)
            plan = np.asarray(plan_global(self._model, **kw), float)
            if plan.shape != (self._S, self._n) or not np.all(np.isfinite(plan)):
                raise ValueError(f"plan_global returned shape {plan.shape}")
            plan = np.clip(plan, self._lo, self._hi)
            status[3] = 1.0
            status[4] = time.perf_counter() - t0
            discrete_state.set_value(self._g_plan, plan.ravel())
        # along the plan's straight joint-space edge, at most max_joint_step per step: the
        # slice advances when its configuration is reached (the plan checked that edge for
        # collisions; a fast jump would make the compliant arm cut the corner)
        q = q_to[: self._n]
        d = plan[ks] - q
        big = float(np.max(np.abs(d)))
        if big > self._cfg.max_joint_step:
            q_new = q + d * (self._cfg.max_joint_step / big)
            return q_new, self.forward_kinematics(plan[ks]), False
        return plan[ks].copy(), self.forward_kinematics(plan[ks]), True

    def _calc_hand(self, context, output):
        x = self._in_state.Eval(context)
        output.SetFromVector(self.forward_kinematics(np.asarray(x[: self._nq_robot],
                                                                float)[self._local]))

    def _calc_command(self, context, output):
        q0 = context.get_discrete_state(self._g_from).get_value()
        q1 = context.get_discrete_state(self._g_to).get_value()
        t0 = context.get_discrete_state(self._g_clock).GetAtIndex(0)
        s = min(max((context.get_time() - t0) / self._period, 0.0), 1.0)
        output.SetFromVector(q0 + s * (q1 - q0))


class _Kinematics:
    """Hand and body-point kinematics of a DbnReproducer's arm on one scratch plant
    context (not shared beyond the call that made it)."""

    def __init__(self, rep: DbnReproducer, plant_context):
        self._r = rep
        self._ctx = plant_context
        self._full = rep._plant.GetPositions(plant_context)

    def _set(self, q):
        self._full[self._r._qidx] = q
        self._r._plant.SetPositions(self._ctx, self._full)

    def hand(self, q) -> np.ndarray:
        r = self._r
        self._set(q)
        return r._plant.CalcPointsPositions(self._ctx, r._frame, r._p_tcp.reshape(3, 1),
                                            r._plant.world_frame()).ravel()

    def jacobian(self, q) -> np.ndarray:
        r = self._r
        self._set(q)
        return self._point_jacobian(r._frame, r._p_tcp.reshape(3, 1))

    def _point_jacobian(self, frame, p):
        plant = self._r._plant
        return plant.CalcJacobianTranslationalVelocity(
            self._ctx, JacobianWrtVariable.kQDot, frame, p, plant.world_frame(),
            plant.world_frame())[:, self._r._qidx]

    def body_points(self, q) -> np.ndarray:
        """(m, 3) world positions of the body points at q, m."""
        r = self._r
        self._set(q)
        return np.array([r._plant.CalcPointsPositions(self._ctx, f, p,
                                                      r._plant.world_frame()).ravel()
                         for f, p in r._body_points]).reshape(-1, 3)

    def plan_points(self, q) -> np.ndarray:
        """(m, 3) world positions of the global plan's collision points at q, m."""
        r = self._r
        self._set(q)
        return np.concatenate([r._plant.CalcPointsPositions(self._ctx, f, P,
                                                            r._plant.world_frame()).T
                               for f, P in r._plan_points], axis=0)

    def point_jacobians(self, q) -> list[tuple[np.ndarray, np.ndarray]]:
        """[(position (3,), Jacobian (3, n))] of the body points at q."""
        r = self._r
        self._set(q)
        return [(r._plant.CalcPointsPositions(self._ctx, f, p, r._plant.world_frame()).ravel(),
                 self._point_jacobian(f, p)) for f, p in r._body_points]
