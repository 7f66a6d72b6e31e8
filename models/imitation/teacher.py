"""The teacher's demonstrations as plans: hand via points, gripper opening and the carried
cup for each task of thesis ch. 8, with seeded human-like variation.

Tasks (``TASKS``):

* ``pick_place``: from a rest pose, over the cup on table A, down to the grasp (rest while
  the fingers close), lift, carry over to table B, down to the place spot (rest while the
  fingers open), up, back to rest. The cup rides with the hand while the gripper is closed
  (opening < 0.5).
* ``whiteboard``: from rest to the board, onto the lower-left part of the area inside the
  four corner markers, a zig-zag of ``strokes`` diagonal strokes (alternately down and up,
  "the same number of ups and downs"; straight strokes: the hand comes to rest at each turn
  without pausing) across to the right side, off the board, back to rest. Via points are placed in the corner markers' frame, so a larger board gives a larger
  zig-zag. The gripper stays closed (it holds the sponge).
* ``obstacle`` / ``u_obstacle``: a reach from a rest pose to the target pad. The thesis
  demonstrated without the obstacle (it appears only when the robot reproduces the task), so
  the plans are the same; the scene of ``u_obstacle`` has the U-shaped obstacle, that of
  ``obstacle`` the box.

Variation (:class:`TeacherStyle`): the object placement (:meth:`ImitationSceneSpec.sampled`),
the mean speed and the duration of each move, the via points in free space (a few cm) and,
much less, the grasp and place points (mm), the rest times.

Plain numpy (imports the scene *spec*, a dataclass, from :mod:`mmlearn.sdf.imitation`; no
Drake). Units: metres, seconds.
"""

import dataclasses
from dataclasses import dataclass

import numpy as np

from mmlearn.models.common.config import param, validate_fields
from mmlearn.models.imitation.scene import ImitationSceneSpec

from mmlearn.models.imitation.min_jerk import MinJerkTrajectory, segment_times

__all__ = ["TASKS", "TeacherStyle", "DemoPlan", "task_scene", "plan_demonstration"]

TASKS = ("pick_place", "whiteboard", "obstacle", "u_obstacle")


@dataclass
class TeacherStyle:
    """How the teacher moves (load with ``yaml_load_typed``).

    Attributes:
        speed: mean hand speed of a move, m/s (> 0).
        speed_jitter: the demonstration's speed is ``speed`` times U(1 - j, 1 + j).
        timing_jitter: each move's duration is scaled by U(1 - j, 1 + j).
        via_jitter: via points in free space move by U(-j, j) per axis, m.
        contact_jitter: grasp and place points move by U(-j, j) in x and y, m.
        placement: amplitude of the scene variation (1 = :meth:`ImitationSceneSpec.sampled`'s
            default ranges, 0 = the nominal layout every time).
        dwell: rest time at the grasp and the place spot (and at the board), s.
        gripper_time: time the fingers take to close or open, s (< dwell).
        grasp_height: hand (tool centre point) above the cup's rim while grasping, m.
        home: rest pose of the hand for pick_place and whiteboard, m.
        reach_home: rest pose of the hand where the reaches (obstacle tasks) start, m.
        board_standoff: hand distance in front of the board's face while wiping, m.
        strokes: number of zig-zag strokes on the board (even: as many ups as downs).
        board_scale_jitter: the area inside the board's corner markers is scaled by
            U(1 - j, 1 + j) per demonstration (dimensionless, in [0, 1)): the teacher marks
            areas of somewhat different sizes, so that the hand's relation to the nearest
            corner varies less than to the far ones (the corner constraints' relative
            precisions, what lets the reproduction scale the zig-zag to another area).
        min_move: shortest duration of one move, s.
    """

    speed: float = param(0.25, unit="m/s", gt=0)
    speed_jitter: float = param(0.15, ge=0, lt=1)
    timing_jitter: float = param(0.1, ge=0, lt=1)
    via_jitter: float = param(0.02, unit="m", ge=0)
    contact_jitter: float = param(0.003, unit="m", ge=0)
    placement: float = param(1.0, ge=0)
    dwell: float = param(0.6, unit="s", gt=0)
    gripper_time: float = param(0.35, unit="s", gt=0)
    grasp_height: float = param(0.015, unit="m", ge=0)
    home: list[float] = param([0.38, 0.0, 0.60], unit="m", length=3, elements=True, factory=True)
    reach_home: list[float] = param([0.50, 0.35, 0.45], unit="m", length=3, elements=True,
                                    factory=True)
    board_standoff: float = param(0.01, unit="m", ge=0)
    strokes: int = param(6, integer=True, ge=2)
    board_scale_jitter: float = param(0.25, ge=0, lt=1)
    min_move: float = param(0.4, unit="s", gt=0)

    def validate(self) -> "TeacherStyle":
        """Raise ValueError naming the first bad field; returns self."""
        validate_fields(self)
        if self.gripper_time + 0.05 >= 0.9 * self.dwell:
            raise ValueError(f"TeacherStyle: gripper_time ({self.gripper_time} s) must end "
                             f"within the shortest rest (0.9 dwell - 0.05 s; dwell = "
                             f"{self.dwell} s)")
        if self.strokes % 2:
            raise ValueError(f"TeacherStyle: strokes must be an even integer >= 2, got "
                             f"{self.strokes!r}")
        return self


@dataclass
class DemoPlan:
    """One planned demonstration.

    Attributes:
        task: one of ``TASKS``.
        scene: the (resolved) scene layout of this demonstration.
        hand: the tool centre point's trajectory (D = 3), m.
        gripper: the gripper opening (D = 1; 0 closed .. 1 open).
        hand_axis: unit vector the hand's approach axis points along (its x8 +z), world.
        grasp_offset: cup base minus hand while the cup is held, m (None: no cup).
        seed: the seed the plan was drawn with.
    """

    task: str
    scene: ImitationSceneSpec
    hand: MinJerkTrajectory
    gripper: MinJerkTrajectory
    hand_axis: np.ndarray
    grasp_offset: np.ndarray | None
    seed: int | None = None

    @property
    def duration(self) -> float:
        """Length of the demonstration, s."""
        return max(self.hand.end_time, self.gripper.end_time)

    def times(self, rate_hz: float) -> np.ndarray:
        """Frame times 0, 1/rate, ... up to the duration, s."""
        if not rate_hz > 0:
            raise ValueError(f"DemoPlan.times: rate_hz must be > 0, got {rate_hz}")
        return np.arange(0.0, self.duration + 1e-9, 1.0 / rate_hz)

    def hand_position(self, t) -> np.ndarray:
        """(n, 3) tool centre point at times ``t``, m."""
        return self.hand.value(t)

    def opening(self, t) -> np.ndarray:
        """(n,) gripper opening at times ``t``, clipped to [0, 1]."""
        return np.clip(self.gripper.value(t)[:, 0], 0.0, 1.0)

    def cup_position(self, t) -> np.ndarray | None:
        """(n, 3) position of the cup's base centre at times ``t`` (None without a cup): at
        its start until the fingers close (opening < 0.5), then carried with the hand (held
        upright) until they open again, then left where it was put down."""
        if self.grasp_offset is None:
            return None
        t = np.atleast_1d(np.asarray(t, float))
        start = self.scene.cup_start()
        out = np.tile(start, (t.size, 1))
        # the carry interval: first closing, then the first opening after it
        fine = np.arange(0.0, self.duration + 0.01, 0.01)
        cl = self.opening(fine) < 0.5
        if not np.any(cl):
            return out
        t_close = fine[np.argmax(cl)]
        after = fine > t_close
        opened = after & ~cl
        t_open = fine[np.argmax(opened)] if np.any(opened) else np.inf
        carry = (t >= t_close) & (t < t_open)
        out[carry] = self.hand_position(t[carry]) + self.grasp_offset
        if np.isfinite(t_open):
            put = self.hand_position([t_open])[0] + self.grasp_offset
            put[2] = self.scene.table_height  # stands on the table
            out[t >= t_open] = put
        return out


def task_scene(task: str, **overrides) -> ImitationSceneSpec:
    """The nominal scene of ``task`` (which parts are present), with field overrides."""
    if task not in TASKS:
        raise ValueError(f"unknown task {task!r}; choose from {', '.join(TASKS)}")
    flags = {"pick_place": dict(tables=True, cup=True),
             "whiteboard": dict(tables=False, cup=False, board=True),
             "obstacle": dict(tables=False, cup=False, target=True, obstacle="box"),
             "u_obstacle": dict(tables=False, cup=False, target=True, obstacle="u")}[task]
    flags.update(overrides)
    return ImitationSceneSpec(**flags).validate()


def plan_demonstration(task: str, *, seed: int | np.random.Generator,
                       scene: ImitationSceneSpec | None = None,
                       style: TeacherStyle | None = None, table_shift=None) -> DemoPlan:
    """Plan one demonstration of ``task`` (see the module docstring).

    Args:
        task: one of ``TASKS``.
        seed: seed (or Generator) of the variation; the same seed gives the same plan.
        scene: the layout to vary (default: :func:`task_scene`); its ``swap_tables`` and
            ``board_scale`` are kept. Its flags must include what the task needs.
        style: how the teacher moves (default :class:`TeacherStyle`).
        table_shift: the tables' moves (see :meth:`ImitationSceneSpec.sampled`; default:
            drawn with the rest of the variation).
    """
    if task not in TASKS:
        raise ValueError(f"unknown task {task!r}; choose from {', '.join(TASKS)}")
    st = (style or TeacherStyle()).validate()
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    base = scene if scene is not None else task_scene(task)
    need = {"pick_place": ("tables", "cup"), "whiteboard": ("board",),
            "obstacle": ("target",), "u_obstacle": ("target",)}[task]
    for k in need:
        if not getattr(base, k):
            raise ValueError(f"plan_demonstration: task {task!r} needs a scene with {k}=True")
    scene_seed = int(rng.integers(2**31))
    sc = (base.sampled(scene_seed, amplitude=st.placement, table_shift=table_shift)
          if st.placement > 0
          else dataclasses.replace(base)).resolved()
    if task == "whiteboard" and st.board_scale_jitter > 0:
        # own stream, so the rest of the plan's variation is drawn as before
        j = st.board_scale_jitter
        fit = float(np.min((np.asarray(sc.board_size) - 0.06) / np.asarray(sc.board_area)))
        sc.board_scale = float(min(sc.board_scale * np.random.default_rng([scene_seed, 8])
                                   .uniform(1 - j, 1 + j), fit))  # kept on the board
        sc = sc.validate()
    speed = st.speed * rng.uniform(1 - st.speed_jitter, 1 + st.speed_jitter)

    def jit(p, j, n=3):
        return np.asarray(p, float) + rng.uniform(-j, j, n)

    grasp_offset = None
    turns = None
    if task == "pick_place":
        lift = sc.cup_height + st.grasp_height
        up = np.array([0.0, 0.0, 1.0])
        cup, place = sc.cup_start(), sc.place_spot()
        grasp = cup + lift * up + np.r_[rng.uniform(-st.contact_jitter, st.contact_jitter, 2), 0]
        put = place + lift * up + np.r_[rng.uniform(-st.contact_jitter, st.contact_jitter, 2), 0]
        home = jit(st.home, st.via_jitter)
        lifted = jit(grasp + 0.15 * up, st.via_jitter)
        above_put = jit(put + 0.12 * up, st.via_jitter)
        mid = jit((lifted + above_put) / 2 + 0.05 * up, 1.5 * st.via_jitter)
        P = np.array([home, jit(grasp + 0.12 * up, st.via_jitter), grasp, lifted, mid,
                      above_put, put, jit(put + 0.15 * up, st.via_jitter),
                      jit(st.home, st.via_jitter)])
        stops = [1, 0, 1, 0, 0, 0, 1, 0, 1]
        grasp_offset = cup - grasp
        axis = np.array([0.0, 0.0, -1.0])
    elif task == "whiteboard":
        C = sc.board_corners()
        o, eu, ev = C[0], C[1] - C[0], C[3] - C[0]  # area frame: u to the right, v up
        normal = np.array([-1.0, 0.0, 0.0])  # board face normal, towards the robot

        def on_board(u, v):
            return o + u * eu + v * ev + st.board_standoff * normal

        n = st.strokes
        us = np.linspace(0.08, 0.92, n + 1) + rng.uniform(-0.03, 0.03, n + 1)
        vs = np.where(np.arange(n + 1) % 2 == 0, 0.1, 0.9) + rng.uniform(-0.04, 0.04, n + 1)
        wipe = [on_board(u, v) for u, v in zip(np.clip(us, 0.02, 0.98),
                                               np.clip(vs, 0.03, 0.97))]
        home = jit(st.home, st.via_jitter)
        P = np.array([home, jit(wipe[0] + 0.10 * normal, st.via_jitter), *wipe,
                      jit(wipe[-1] + 0.10 * normal, st.via_jitter), jit(st.home, st.via_jitter)])
        # every turn of the zig-zag is a stop (straight strokes inside the markers, sharp
        # turns), with no rest there
        stops = [1, 0, 1] + [1] * (n - 1) + [1, 0, 1]
        turns = np.zeros(len(stops), bool)
        turns[3:3 + n - 1] = True
        axis = -normal
    else:  # a reach to the target
        tgt = np.asarray(sc.target_position, float)
        home = jit(st.reach_home, st.via_jitter)
        above = jit(tgt + [0, 0, 0.10], st.via_jitter)
        end = tgt + [0, 0, 0.03] + np.r_[rng.uniform(-st.contact_jitter, st.contact_jitter, 2), 0]
        mid = jit((home + above) / 2 + [0, 0, 0.05], 1.5 * st.via_jitter)
        P = np.array([home, mid, above, end])
        stops = [1, 0, 0, 1]
        axis = np.array([0.0, 0.0, -1.0])

    stops = np.asarray(stops, bool)
    durations = segment_times(P, speed=speed, min_duration=st.min_move)
    durations *= rng.uniform(1 - st.timing_jitter, 1 + st.timing_jitter, durations.size)
    times = np.concatenate([[0.0], np.cumsum(durations)])
    dwell = np.where(stops, st.dwell * rng.uniform(0.9, 1.1, stops.size), 0.0)
    if turns is not None:
        dwell[turns] = 0.0
    dwell[0] = 0.3  # a short rest before the movement starts
    dwell[-1] = 0.3
    hand = MinJerkTrajectory(times, P, stops=stops, dwell=dwell, optimize_times=True)

    # gripper: open, closed while the cup is held / the sponge is wiping, open
    T = hand.end_time
    if task == "pick_place":
        arrive = hand.via_times[stops]  # arrival at each stop (after earlier dwells)
        t_grasp, t_put = arrive[1], arrive[2]
        g = st.gripper_time
        gt = [0.0, t_grasp + 0.05, t_grasp + 0.05 + g, t_put + 0.05, t_put + 0.05 + g, T]
        gv = [1.0, 1.0, 0.0, 0.0, 1.0, 1.0]
    elif task == "whiteboard":
        gt, gv = [0.0, T], [0.0, 0.0]
    else:
        gt, gv = [0.0, T], [1.0, 1.0]
    gripper = MinJerkTrajectory(gt, np.asarray(gv)[:, None], stops=np.ones(len(gt), bool))
    return DemoPlan(task=task, scene=sc, hand=hand, gripper=gripper, hand_axis=axis,
                    grasp_offset=grasp_offset,
                    seed=None if isinstance(seed, np.random.Generator) else int(seed))
