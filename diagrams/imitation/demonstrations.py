"""Recorded demonstrations (thesis ch. 8): a teacher with other kinematics
than the robot's performs a task in the imitation scene while the project's
:class:`~mmlearn.systems.common.marker_sensor.MarkerSensor` watches it at 5 Hz.

The teacher is a demonstration, not a learner, so the diagram plays it back kinematically:

* :func:`mmlearn.models.imitation.teacher.plan_demonstration` plans the hand's minimum-jerk path,
  the gripper opening and the cup's carry;
* per playback sample (``playback_rate_hz``) an InverseKinematics of the teacher arm puts its
  tool centre point on the path with the hand's axis along the task's direction (down for
  pick-and-place and reaches, into the board for wiping), warm-started from the previous
  sample and pulled towards it (a smooth joint path); the fingers take the planned opening;
  the cup rides with the hand while the gripper is closed;
* a ``TrajectorySource`` (zero-order hold of the whole plant's positions) feeds a
  ``MultibodyPositionToGeometryPose`` (geometry for the SceneGraph: occlusion queries and
  Meshcat) and a :class:`~mmlearn.systems.imitation.kinematic_body_poses.KinematicBodyPoses` (the body
  poses the MarkerSensor reads);
* the MarkerSensor (two cameras behind the robot, occlusion tested against the scene, noise
  ``sigma_pos``) observes the teacher's ``hand`` marker (the tool centre point), its finger
  markers and every object of the scene.

:func:`observations_to_demonstration` turns the observed frames into a
:class:`~mmlearn.models.imitation.types.Demonstration`: hand = the ``hand`` marker's
position, gripper opening = the observed distance of the two finger markers mapped through a
table of distance against opening (finger angle over the full angle; a calibration of the
teacher's hand geometry, computed once from its model), objects = their markers' positions; NaN wherever a
marker was not seen (and for the opening when a finger was not seen). Nothing is read from
the teacher's state.
"""

import dataclasses
import time as _time
from dataclasses import dataclass

import numpy as np

from pydrake.geometry import MeshcatVisualizer, MeshcatVisualizerParams, Role, SceneGraph
from pydrake.math import RigidTransform
from pydrake.multibody.inverse_kinematics import InverseKinematics
from pydrake.multibody.plant import MultibodyPlant
from pydrake.solvers import Solve
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import TrajectorySource
from pydrake.systems.rendering import MultibodyPositionToGeometryPose
from pydrake.trajectories import PiecewisePolynomial

from mmlearn.models.imitation.types import Demonstration
from mmlearn.models.common.config import param, validate_fields
from mmlearn.models.imitation.teacher import TASKS, DemoPlan, TeacherStyle, plan_demonstration, task_scene
from mmlearn.models.imitation.scene import TEACHER_OPENING, TEACHER_TCP_IN_X8, ImitationSceneSpec, stratified_table_shifts
from mmlearn.sdf.imitation import add_imitation_scene, add_teacher
from mmlearn.systems.imitation.kinematic_body_poses import KinematicBodyPoses
from mmlearn.systems.common.marker_sensor import CameraConfig, MarkerSensor, MarkerSensorConfig
from mmlearn.systems.common.observations import MarkerObservations

__all__ = ["TeacherConfig", "TeacherDiagram", "MakeTeacherDiagram", "default_sensor_config",
           "observations_to_demonstration", "record_demonstration", "record_demonstrations",
           "draw_demonstrations",
           "TeacherIKError"]

HAND, FINGERS = "hand", ("x9", "x10")


class TeacherIKError(RuntimeError):
    """The teacher arm cannot put its hand where the plan wants it."""


def default_sensor_config() -> MarkerSensorConfig:
    """The demonstrations' marker sensor: 5 Hz (the thesis), position noise 0.005 m, 2 %
    drop-out, two cameras high behind the robot (left and right) looking at the workspace,
    occlusion by the scene and the teacher's arm tested. ``max_view_angle_deg`` = 180: the
    markers count as motion-capture spheres, seen from any side (the hand marker turns with
    the hand)."""
    look = [0.55, 0.0, 0.45]
    return MarkerSensorConfig(
        rate_hz=5.0, sigma_pos=0.005, sigma_orient=0.0, dropout=0.02,
        cameras=[CameraConfig(position=[-0.6, 1.2, 1.5], look_at=look, fov_x_deg=75.0,
                              fov_y_deg=60.0, max_range=4.0),
                 CameraConfig(position=[-0.6, -1.2, 1.5], look_at=look, fov_x_deg=75.0,
                              fov_y_deg=60.0, max_range=4.0)],
        max_view_angle_deg=180.0, check_occlusion=True, occlusion_step=0.03)


@dataclass
class TeacherConfig:
    """Configuration of :func:`MakeTeacherDiagram` (load with ``yaml_load_typed``).

    Attributes:
        task: one of ``pick_place``, ``whiteboard``, ``obstacle``, ``u_obstacle``.
        seed: seed of this demonstration (the plan's variation and the sensor noise).
        scene: the layout to vary (None = :func:`mmlearn.models.imitation.teacher.task_scene`).
        style: how the teacher moves.
        sensor: the marker sensor (``bodies`` and ``seed`` are set by the diagram).
        with_obstacle: keep the obstacle of the obstacle tasks in the demonstration scene
            (default False: the thesis' obstacles appear only when the robot reproduces).
        playback_rate_hz: teacher configurations per second (IK samples; the sensor's frames
            must fall on them: a multiple of the sensor's rate).
        ik_position_tolerance: half width of the box the tool centre point must reach, m.
        ik_angle_tolerance: largest angle between the hand's axis and the task's, rad (where
            the hand cannot reach a point so, it may tilt up to 2.5 times as far).
        table_shift: the tables' moves as fractions of their range (4 numbers in [-1, 1],
            see :meth:`ImitationSceneSpec.sampled`); None = drawn from ``seed``.
        teacher_base: x, y of the teacher's base in the world, m (0.1 m in front of the
            robot's: the teacher's arm is shorter).
    """

    task: str = param("pick_place", choices=TASKS)
    seed: int = param(0, integer=True, ge=0)
    scene: ImitationSceneSpec | None = param(None, optional=True)
    style: TeacherStyle = param(default_factory=TeacherStyle, nested=TeacherStyle)
    sensor: MarkerSensorConfig = param(default_factory=default_sensor_config,
                                       nested=MarkerSensorConfig)
    with_obstacle: bool = param(False)
    playback_rate_hz: float = param(20.0, unit="Hz", gt=0)
    ik_position_tolerance: float = param(0.002, unit="m", gt=0)
    ik_angle_tolerance: float = param(0.15, unit="rad", gt=0)
    table_shift: list[float] | None = param(None, optional=True, length=4, ge=-1, le=1)
    teacher_base: list[float] = param([0.10, 0.0], unit="m", length=2, elements=True,
                                      factory=True)

    def validate(self) -> "TeacherConfig":
        validate_fields(self)
        ratio = self.playback_rate_hz / self.sensor.rate_hz
        if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
            raise ValueError(f"TeacherConfig: playback_rate_hz ({self.playback_rate_hz} Hz) "
                             f"must be a multiple of the sensor's rate_hz "
                             f"({self.sensor.rate_hz} Hz)")
        return self

    def scene_spec(self) -> ImitationSceneSpec:
        """The layout the plan varies (with the obstacle removed unless ``with_obstacle``)."""
        s = self.scene if self.scene is not None else task_scene(self.task)
        if not self.with_obstacle and s.obstacle != "none":
            s = dataclasses.replace(s, obstacle="none")
        return s.validate()


@dataclass
class TeacherDiagram:
    """What :func:`MakeTeacherDiagram` built.

    Attributes:
        diagram: the Diagram (no input ports; output ``observations``).
        plant: the kinematic plant (teacher + scene; not in the diagram, kept alive here).
        scene_graph, sensor, body_poses: the subsystems.
        plan: the demonstration's plan (the teacher's intended motion).
        q: (n_samples, plant.num_positions()) playback configurations at ``q_times``.
        q_times: playback sample times, s.
        frame_times: the sensor's frame times, s.
        objects: names of the observed scene objects.
        gripper_calibration: (31, 2) finger-marker distance (m) against opening (0..1).
        ik_seconds: time spent in the IK, s.
        visualizer: the MeshcatVisualizer (None without Meshcat).
    """

    diagram: object
    plant: MultibodyPlant
    scene_graph: SceneGraph
    sensor: MarkerSensor
    body_poses: KinematicBodyPoses
    plan: DemoPlan
    q: np.ndarray
    q_times: np.ndarray
    frame_times: np.ndarray
    objects: list[str]
    gripper_calibration: np.ndarray
    ik_seconds: float
    visualizer: object | None = None


def _finger_distance(plant, ctx, q7: float) -> float:
    for j in ("q7", "q7_mirror"):
        plant.GetJointByName(j).set_angle(ctx, q7)
    a, b = (plant.CalcRelativeTransform(ctx, plant.world_frame(),
                                        plant.GetFrameByName(f"{f}_marker")).translation()
            for f in FINGERS)
    return float(np.linalg.norm(a - b))


def _teacher_path(plan: DemoPlan, times: np.ndarray, cfg: "TeacherConfig"
                  ) -> tuple[MultibodyPlant, np.ndarray]:
    """The teacher alone (its own plant) and its (n, nq) joint positions following the plan
    at ``times``: per sample an InverseKinematics, warm-started from the previous sample and
    pulled towards it (then from a few fixed postures, then with a tilted hand)."""
    plant = MultibodyPlant(time_step=0.0)
    add_teacher(plant, base=cfg.teacher_base)
    plant.Finalize()
    nq = plant.num_positions()
    x8 = plant.GetFrameByName("x8")
    world = plant.world_frame()
    idx = np.array([plant.GetJointByName(f"q{k}").position_start() for k in range(1, 7)])
    fingers = np.array([plant.GetJointByName(j).position_start()
                        for j in ("q7", "q7_mirror")])
    P = plan.hand_position(times)
    opening = plan.opening(times)
    tol = cfg.ik_position_tolerance
    guesses = [np.array([0.0, 0.6, 0.0, 1.2, 0.0, 0.9]),
               np.array([0.0, 0.3, 0.0, 1.0, 0.0, 0.2]),
               np.array([0.5, 0.8, 0.0, 0.8, 0.0, 1.0]),
               np.array([-0.5, 0.8, 0.0, 0.8, 0.0, 1.0])]
    out = np.zeros((times.size, nq))
    prev = None
    for i, (p, t) in enumerate(zip(P, times)):
        sol, ok = None, False
        tries = [(g, cfg.ik_angle_tolerance) for g in ([prev] if prev is not None else [])
                 + guesses]
        tries += [(g, 2.5 * cfg.ik_angle_tolerance) for g, _ in tries[:2]]  # a tilted hand
        for guess, angle in tries:
            ik = InverseKinematics(plant)
            q = ik.q()
            ik.AddPositionConstraint(x8, TEACHER_TCP_IN_X8, world, p - tol, p + tol)
            ik.AddAngleBetweenVectorsConstraint(x8, [0.0, 0.0, 1.0], world, plan.hand_axis,
                                                0.0, angle)
            q0 = np.zeros(nq)
            q0[idx] = guess[idx] if guess.size == nq else guess
            prog = ik.prog()
            prog.AddQuadraticErrorCost(np.eye(6) * (10.0 if prev is not None else 0.1),
                                       q0[idx], q[idx])
            prog.SetInitialGuess(q, q0)
            r = Solve(prog)
            if r.is_success():
                sol = r.GetSolution(q)
                if prev is None or np.max(np.abs(sol[idx] - prev[idx])) < 0.8:
                    ok = True
                    break
        if not ok:
            raise TeacherIKError(
                f"the teacher cannot reach the hand position {np.round(p, 3).tolist()} m "
                f"(task {plan.task}, t = {t:.2f} s): move the scene closer to the arm's base")
        sol[fingers] = opening[i] * TEACHER_OPENING
        out[i] = sol
        prev = sol
    return plant, out


def MakeTeacherDiagram(config: TeacherConfig | None = None, *, meshcat=None) -> TeacherDiagram:
    """Plan one demonstration, solve the teacher's joint path and build the playback
    diagram watched by the MarkerSensor (see the module docstring). ``meshcat`` (optional)
    shows the teacher, the scene and the planned hand path."""
    cfg = (config or TeacherConfig()).validate()
    plan = plan_demonstration(cfg.task, seed=cfg.seed, scene=cfg.scene_spec(), style=cfg.style,
                              table_shift=cfg.table_shift)

    builder = DiagramBuilder()
    scene_graph = builder.AddNamedSystem("scene_graph", SceneGraph())
    plant = MultibodyPlant(time_step=0.0)
    plant.set_name("teacher_plant")
    plant.RegisterAsSourceForSceneGraph(scene_graph)
    teacher = add_teacher(plant, base=cfg.teacher_base)
    scene = add_imitation_scene(plant, plan.scene)
    plant.Finalize()
    ctx = plant.CreateDefaultContext()
    # finger-marker distance against opening (finger angle / full angle): the calibration
    # of the teacher's hand geometry, from its model
    grid = np.linspace(0.0, 1.0, 31)
    calib = np.array([[_finger_distance(plant, ctx, g * TEACHER_OPENING), g] for g in grid])

    # playback samples: k / rate exactly (the sensor's frame times are among them)
    n = int(np.floor(plan.duration * cfg.playback_rate_hz + 1e-9)) + 1
    q_times = np.arange(n) / cfg.playback_rate_hz
    t0 = _time.perf_counter()
    tplant, Qt = _teacher_path(plan, q_times, cfg)
    ik_seconds = _time.perf_counter() - t0
    # teacher-plant positions -> this plant's, joint by joint
    src, dst = [], []
    for j in tplant.GetJointIndices(tplant.GetModelInstanceByName("teacher")):
        jt = tplant.get_joint(j)
        if jt.num_positions() == 1:
            src.append(jt.position_start())
            dst.append(plant.GetJointByName(jt.name(), teacher).position_start())
    Q = np.zeros((n, plant.num_positions()))
    cup = plant.GetBodyByName("cup", scene.model_instance) if plan.scene.cup else None
    cup_p = plan.cup_position(q_times)
    for i in range(n):
        q = plant.GetPositions(ctx)
        q[dst] = Qt[i, src]
        plant.SetPositions(ctx, q)
        if cup is not None:
            plant.SetFreeBodyPose(ctx, cup, RigidTransform(cup_p[i]))
        Q[i] = plant.GetPositions(ctx)
    # zero-order hold, breaks 1 us early: a frame at (about) a sample time sees that sample
    breaks = q_times - 1e-6
    breaks[0] = 0.0
    traj = PiecewisePolynomial.ZeroOrderHold(np.append(breaks, breaks[-1] + 1.0),
                                             np.vstack([Q, Q[-1]]).T)
    source = builder.AddNamedSystem("teacher_playback", TrajectorySource(traj))
    to_geometry = builder.AddNamedSystem("positions_to_geometry",
                                         MultibodyPositionToGeometryPose(plant))
    builder.Connect(source.get_output_port(), to_geometry.get_input_port())
    builder.Connect(to_geometry.get_output_port(),
                    scene_graph.get_source_pose_port(plant.get_source_id()))
    poses = builder.AddNamedSystem("body_poses", KinematicBodyPoses(plant=plant))
    builder.Connect(source.get_output_port(), poses.get_positions_input_port())

    objects = list(scene.bodies)
    scfg = dataclasses.replace(cfg.sensor, bodies=[HAND, *FINGERS, *objects],
                               seed=int(cfg.seed))
    sensor = builder.AddNamedSystem("marker_sensor", MarkerSensor(plant=plant, config=scfg))
    builder.Connect(poses.get_body_poses_output_port(), sensor.get_body_poses_input_port())
    builder.Connect(scene_graph.get_query_output_port(), sensor.get_query_object_input_port())
    builder.ExportOutput(sensor.get_observations_output_port(), "observations")
    visualizer = None
    if meshcat is not None:
        visualizer = MeshcatVisualizer.AddToBuilder(
            builder, scene_graph, meshcat, MeshcatVisualizerParams(role=Role.kIllustration))
        meshcat.SetCameraPose([-0.9, 1.3, 1.3], [0.5, 0.0, 0.45])
        path = plan.hand_position(np.linspace(0, plan.duration, 200))
        from pydrake.geometry import Rgba

        meshcat.SetLine("teacher/plan", path.T, 2.0, Rgba(0.1, 0.6, 0.1, 1.0))
    diagram = builder.Build()
    diagram.set_name(f"teacher_{cfg.task}")
    frames = int(np.floor(plan.duration * scfg.rate_hz + 1e-9)) + 1
    return TeacherDiagram(diagram=diagram, plant=plant, scene_graph=scene_graph, sensor=sensor,
                          body_poses=poses, plan=plan, q=Q, q_times=q_times,
                          frame_times=np.arange(frames) / scfg.rate_hz, objects=objects,
                          gripper_calibration=calib, ik_seconds=ik_seconds,
                          visualizer=visualizer)


def observations_to_demonstration(frames: list[MarkerObservations], *, objects: list[str],
                                  gripper_calibration, meta: dict | None = None
                                  ) -> Demonstration:
    """Convert observed frames into a Demonstration (NaN where a marker was not seen).

    Args:
        frames: one :class:`MarkerObservations` per sensor frame, in time order, each with
            the markers ``hand``, ``x9``, ``x10`` and ``objects``.
        objects: the scene objects to keep.
        gripper_calibration: finger-marker distance (m) -> opening: either (closed, open)
            distances for a linear map, or an (m, 2) table of (distance, opening) rows with
            increasing distances (interpolated; clipped to [0, 1] outside).
        meta: extra JSON-able metadata.
    """
    if not frames:
        raise ValueError("observations_to_demonstration: no frames")
    cal = np.asarray(gripper_calibration, float)
    if cal.shape == (2,):
        cal = np.array([[cal[0], 0.0], [cal[1], 1.0]])
    if cal.ndim != 2 or cal.shape[1] != 2 or cal.shape[0] < 2 or \
            not np.all(np.diff(cal[:, 0]) > 0):
        raise ValueError("observations_to_demonstration: gripper_calibration must be "
                         "(closed, open) with open > closed, or (m, 2) rows (distance, "
                         "opening) with increasing distances")
    t = np.array([f.time for f in frames], float)
    names = [HAND, *FINGERS, *objects]
    A = np.full((len(frames), len(names), 3), np.nan)
    for k, f in enumerate(frames):
        arr = f.as_array()
        for j, nm in enumerate(names):
            A[k, j] = arr[f.index(nm), :3]
    dist = np.linalg.norm(A[:, 1] - A[:, 2], axis=1)
    opening = np.full(dist.shape, np.nan)
    ok = np.isfinite(dist)
    opening[ok] = np.clip(np.interp(dist[ok], cal[:, 0], cal[:, 1]), 0.0, 1.0)
    demo = Demonstration(
        t=t, hand=A[:, 0].copy(),
        objects={nm: A[:, 3 + j].copy() for j, nm in enumerate(objects)},
        gripper=opening, joints=None, meta=dict(meta or {}))
    return demo.validate()


def record_demonstration(config: TeacherConfig, *, meshcat=None,
                         record: bool = False) -> Demonstration:
    """Build the teacher diagram for ``config`` and record one demonstration; with
    ``meshcat`` and ``record``, its playback becomes Meshcat's animation (published)."""
    td = MakeTeacherDiagram(config, meshcat=meshcat)
    if td.visualizer is not None and record:
        td.visualizer.StartRecording(False)
    sim = Simulator(td.diagram)
    ctx = sim.get_mutable_context()
    port = td.diagram.GetOutputPort("observations")
    sim.Initialize()
    rate = td.sensor._cfg.rate_hz
    frames = []
    for tk in td.frame_times:
        sim.AdvanceTo(tk + 0.5 / rate)  # the update at tk is done, the next one is not
        obs = port.Eval(ctx)
        if abs(obs.time - tk) > 1e-6:  # never expected: the frame at tk must be the latest
            raise RuntimeError(f"record_demonstration: expected the frame at {tk} s, got "
                               f"{obs.time} s")
        frames.append(obs)
    if td.visualizer is not None and record:
        td.visualizer.StopRecording()
        td.visualizer.PublishRecording()
    style = dataclasses.asdict(config.style)
    meta = {"task": config.task, "seed": int(config.seed), "teacher": "human_like_7dof",
            "units": "m, s", "rate_hz": rate, "sigma_pos": td.sensor._cfg.sigma_pos,
            "scene": dataclasses.asdict(td.plan.scene), "style": style,
            "with_obstacle": bool(config.with_obstacle),
            "planned_duration": td.plan.duration}
    return observations_to_demonstration(frames, objects=td.objects,
                                         gripper_calibration=td.gripper_calibration, meta=meta)


def record_demonstrations(task: str, n: int, *, seed: int, scene: ImitationSceneSpec | None = None,
                          style: TeacherStyle | None = None,
                          sensor: MarkerSensorConfig | None = None, with_obstacle: bool = False,
                          stratify: bool = True, meshcat=None,
                          progress=None) -> list[Demonstration]:
    """Record ``n`` demonstrations of ``task``; demonstration i uses the seed
    ``seed * 1000 + i`` (plan variation and sensor noise), so the same ``seed`` gives the same
    demonstrations. ``scene`` (default: the task's nominal layout, with its ``swap_tables``
    and ``board_scale``) is varied per demonstration; with ``stratify`` (default) the tables'
    moves are spread over their range across the ``n`` demonstrations
    (:func:`~mmlearn.sdf.imitation.stratified_table_shifts`: a teacher who varies the setup
    on purpose), so the set depends on ``n`` too. ``progress`` (optional) is called with
    the index of each finished demonstration. With ``meshcat`` the last demonstration's
    playback is shown and published as Meshcat's animation, and every demonstration's
    observed hand track is drawn (``demonstrations/hand_<i>``, gaps left out)."""
    if task not in TASKS:
        raise ValueError(f"unknown task {task!r}; choose from {', '.join(TASKS)}")
    if not (isinstance(n, (int, np.integer)) and n >= 1):
        raise ValueError(f"record_demonstrations: n must be an integer >= 1, got {n!r}")
    if not (isinstance(seed, (int, np.integer)) and 0 <= seed < 2**31 // 1000):
        raise ValueError(f"record_demonstrations: seed must be an integer in [0, 2147483), "
                         f"got {seed!r}")
    shifts = stratified_table_shifts(int(n), np.random.default_rng([int(seed), 1])) \
        if stratify else [None] * int(n)
    demos = []
    for i in range(int(n)):
        cfg = TeacherConfig(task=task, seed=int(seed) * 1000 + i, scene=scene,
                            style=style or TeacherStyle(),
                            sensor=sensor or default_sensor_config(), with_obstacle=with_obstacle,
                            table_shift=None if shifts[i] is None else list(shifts[i]))
        last = i == int(n) - 1
        demos.append(record_demonstration(cfg, meshcat=meshcat if last else None,
                                          record=last))
        if progress is not None:
            progress(i)
    if meshcat is not None:
        draw_demonstrations(meshcat, demos)
    return demos


def draw_demonstrations(meshcat, demos: list[Demonstration], *, prefix: str = "demonstrations"
                        ) -> None:
    """Draw each demonstration's observed hand track as a polyline in Meshcat (one per run
    of consecutive seen frames), in a colour per demonstration."""
    from pydrake.geometry import Rgba

    meshcat.Delete(prefix)
    for i, d in enumerate(demos):
        hue = (0.15 + 0.6 * i / max(len(demos) - 1, 1))
        rgba = Rgba(1.0 - hue, 0.3, hue, 1.0)
        seen = np.isfinite(d.hand).all(axis=1)
        runs = np.split(np.arange(d.T), np.flatnonzero(np.diff(seen.astype(int))) + 1)
        for k, r in enumerate(runs):
            if seen[r[0]] and r.size >= 2:
                meshcat.SetLine(f"{prefix}/hand_{i}/{k}", d.hand[r].T, 2.0, rgba)
