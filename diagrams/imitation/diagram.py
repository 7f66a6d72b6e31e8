"""Reproducing a learned task (thesis 8.1.2, 8.2): the project's 7-DOF arm with its gripper
(implicit PD actuators plus gravity compensation, base welded at the world origin), the
imitation scene (:mod:`mmlearn.sdf.imitation`: tables and cup, whiteboard, target,
obstacles), a :class:`MarkerSensor` observing the objects' markers, the
:class:`DbnReproducer` commanding the arm and the gripper, and the
:class:`GraspAttachment` that holds the cup while the gripper is closed.

Contacts: the cup's contacts with the robot are filtered out (the grasp model holds it; the
fingers would otherwise collide with a cup they close around), and so are the board's (the
hand wipes it, with a sponge in the thesis); the robot does not collide with itself or the
floor. The robot *does* collide with the tables, board and obstacles,
so a reproduction that hits them is pushed and the clearance measures it.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from pydrake.geometry import CollisionFilterDeclaration, GeometrySet, MeshcatVisualizer, \
    MeshcatVisualizerParams, Role
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
from pydrake.multibody.tree import JointActuatorIndex, PdControllerGains
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import MatrixGain

from mmlearn.sdf.builders import arm_sdf, arm_spec, floor_sdf
from mmlearn.models.common.config import param, validate_fields
from mmlearn.models.imitation.scene import ROBOT_TCP_IN_X8, ImitationSceneSpec
from mmlearn.sdf.imitation import add_imitation_scene
from mmlearn.systems import GravityCompensation, MarkerSensor, MarkerSensorConfig
from mmlearn.systems.imitation.dbn_reproducer import DbnReproducer, DbnReproducerConfig
from mmlearn.systems.imitation.dbn_visualizer import DbnVisualizer, draw_demonstrations, \
    draw_task_model
from mmlearn.systems.imitation.grasp_attachment import GraspAttachment

TASKS = ("pick_place", "whiteboard", "obstacle", "u_obstacle")
U_SHIFT = 0.05  # m, see ImitationConfig.scene_spec
BOX_DROP = 0.12  # m, see ImitationConfig.scene_spec
#: the arm's start configuration q1..q6, rad: the hand 0.3 m in front of the base at a
#: height of 0.6 m, pointing down
ROBOT_START = (0.0, 0.35, 0.0, 1.6, 0.0, 1.2)


#: points on the arm kept away from obstacles besides the hand: (body, point in its frame, m):
#: the elbow (x5's origin), the middle of the forearm x6, the wrist (x7's origin), the
#: gripper's base (x8's origin) and the closed fingertips (0.03 m beyond the TCP)
BODY_POINTS = (("x5", (0.0, 0.0, 0.0)), ("x6", (0.0, 0.0, 0.175)), ("x7", (0.0, 0.0, 0.0)),
               ("x8", (0.0, 0.0, 0.0)), ("x8", (0.0, 0.0, 0.15)))

#: the points the global plan keeps ``plan_clearance`` from obstacles: the arm's axis from
#: the elbow to the fingertips every <= 5 cm (x5 0.05 m, forearm x6 0.35 m, wrist x7 0.10 m,
#: gripper x8 + fingers 0.15 m). With BODY_POINTS' 17.5 cm spacing on the forearm an obstacle
#: edge could pass between two points each 6 cm clear and graze the 4 cm-radius link; with a
#: spacing s the link axis keeps sqrt(0.06**2 - (s / 2)**2) >= 5.4 cm from such an edge.
PLAN_BODY_POINTS = (tuple(("x5", (0.0, 0.0, z)) for z in (0.0, 0.025))
                    + tuple(("x6", (0.0, 0.0, z)) for z in np.linspace(0.0, 0.35, 8))
                    + tuple(("x7", (0.0, 0.0, z)) for z in (0.0, 0.05))
                    + tuple(("x8", (0.0, 0.0, z)) for z in (0.0, 0.05, 0.10, 0.15)))


def task_scene(task: str, *, swap_tables: bool = False, board_scale: float = 1.0
               ) -> ImitationSceneSpec:
    """The nominal scene layout of a task (before the seeded variation)."""
    if task not in TASKS:
        raise ValueError(f"task must be one of {TASKS}, got {task!r}")
    if task == "pick_place":
        return ImitationSceneSpec(tables=True, cup=True, swap_tables=swap_tables)
    if task == "whiteboard":
        return ImitationSceneSpec(tables=False, cup=False, board=True,
                                  board_scale=board_scale)
    return ImitationSceneSpec(tables=False, cup=False, target=True,
                              obstacle="box" if task == "obstacle" else "u")


@dataclass
class ImitationConfig:
    """One reproduction (load with ``yaml_load_typed``).

    Attributes:
        task: "pick_place", "whiteboard", "obstacle" or "u_obstacle".
        seed: draws the scene's variation and the marker noise.
        swap_tables: exchange the tables (pick_place; thesis Fig. 8.5).
        board_scale: scale of the area inside the board's corner markers (whiteboard).
        variation: amplitude of the seeded scene variation (0 = the nominal layout).
        scene: an explicit layout (None = ``task_scene`` varied by ``seed``).
        reproducer: the DbnReproducer's parameters (mode, damping, ...).
        sensor: the MarkerSensor's parameters (its ``bodies`` and ``seed`` are set here).
        time_step: discrete plant step, s.
        kp, kd: PD gains of the arm joints, N*m/rad and N*m*s/rad.
        kp_gripper, kd_gripper: PD gains of the fingers.
        robot_start: the arm's start configuration q1..q6, rad (empty = the configuration,
            found by damped least squares from ``ROBOT_START``, whose hand is at the
            teacher's rest pose for the task: ``TeacherStyle.home`` or ``reach_home``).
        capture_radius: grasp capture radius around the centre of the cup's rim, m (see
            GraspAttachment).
        grasp_stiffness: grasp spring, N/m.
    """

    task: str = param("pick_place", choices=TASKS)
    seed: int = param(0, integer=True, ge=0)
    swap_tables: bool = param(False)
    board_scale: float = param(1.0, gt=0)
    variation: float = param(1.0, ge=0)
    scene: ImitationSceneSpec | None = param(None, optional=True)
    reproducer: DbnReproducerConfig = param(default_factory=DbnReproducerConfig,
                                            nested=DbnReproducerConfig)
    sensor: MarkerSensorConfig = param(default_factory=lambda: MarkerSensorConfig(
        rate_hz=10.0, sigma_pos=0.005, cameras=[]), nested=MarkerSensorConfig)
    time_step: float = param(0.001, unit="s", gt=0)
    kp: float = param(400.0, unit="N*m/rad", ge=0)
    kd: float = param(40.0, unit="N*m*s/rad", ge=0)
    kp_gripper: float = param(20.0, ge=0)
    kd_gripper: float = param(1.0, ge=0)
    robot_start: list[float] = param([], unit="rad", elements=True, factory=True)
    capture_radius: float = param(0.05, unit="m", gt=0)
    grasp_stiffness: float = param(1000.0, unit="N/m", gt=0)

    def validate(self) -> None:
        validate_fields(self)
        if len(self.robot_start) not in (0, 6):
            raise ValueError(f"ImitationConfig: robot_start must be empty or 6 angles (rad), "
                             f"got {self.robot_start!r}")

    def scene_spec(self) -> ImitationSceneSpec:
        """The layout of this reproduction (``scene`` or the task's, varied by seed)."""
        if self.scene is not None:
            return self.scene.validate()
        s = task_scene(self.task, swap_tables=self.swap_tables, board_scale=self.board_scale)
        if self.task == "u_obstacle":
            # the U 5 cm further from the robot than the teacher's nominal layout: at the
            # demonstrated start the robot's forearm (radius 4 cm) then clears the U's wall
            c = list(s.obstacle_centre)
            s = dataclasses.replace(s, obstacle_centre=[c[0] + U_SHIFT, c[1], c[2]])
        elif self.task == "obstacle":
            # thesis Fig. 8.7: an obstacle in the way of the demonstrated path, which the arm
            # moves over: the box 0.12 m lower than the teacher's nominal layout, its top
            # about 4 cm under the demonstrated hand path, so the fingers would hit it
            c = list(s.obstacle_centre)
            s = dataclasses.replace(s, obstacle_centre=[c[0], c[1], c[2] - BOX_DROP])
        if self.variation > 0:
            # a seed stream apart from the teacher's demonstrations
            s = s.sampled(np.random.default_rng([self.seed, 15, 2]), amplitude=self.variation)
        return s


@dataclass
class Imitation:
    """The built diagram and its parts (returned by :func:`MakeImitationDiagram`).

    **Call** :meth:`set_start` **on the simulator's context before advancing it**: a new
    context has every arm joint at 0 and the reproducer's held command at 0, not at the start
    configuration the task model was reproduced from; without it the arm first swings from
    the zero pose. Typical use::

        im = MakeImitationDiagram(ImitationConfig(task="obstacle", seed=2), model=model)
        context = im.diagram.CreateDefaultContext()
        im.set_start(context)                    # the arm at its start configuration
        simulator = Simulator(im.diagram, context)
        simulator.AdvanceTo(im.reproducer.duration + 1.0)
        hand = im.diagram.GetOutputPort("hand").Eval(context)

    Attributes: ``diagram``; ``plant`` and ``scene_graph``; ``robot`` (the arm's model
    instance); ``scene`` (the objects' model instances and poses); ``sensor`` (the
    ``MarkerSensor`` watching the objects); ``reproducer`` (the ``DbnReproducer``);
    ``grasp`` (the ``GraspAttachment`` when there is a cup, else None); ``start_command``
    (q1..q6 and the finger angle, rad); ``tcp_body`` and ``p_tcp`` (the hand point on the
    arm); ``visualizer`` (with Meshcat).
    """

    diagram: object
    plant: object
    scene_graph: object
    robot: object
    scene: object                    # mmlearn.sdf.imitation.ImitationScene
    sensor: MarkerSensor
    reproducer: DbnReproducer
    grasp: GraspAttachment | None
    start_command: np.ndarray        # q1..q6 and the finger angle, rad
    tcp_body: str = "x8"
    p_tcp: tuple = ROBOT_TCP_IN_X8
    visualizer: object | None = None

    def set_start(self, root_context) -> None:
        """Put the arm at its start command (at rest) in ``root_context``."""
        ctx = self.plant.GetMyMutableContextFromRoot(root_context)
        full = self.plant.GetPositions(ctx)
        names = [f"q{i}" for i in range(1, 7)] + ["q7", "q7_mirror"]
        vals = list(self.start_command[:6]) + [self.start_command[6]] * 2
        for n, v in zip(names, vals):
            full[self.plant.GetJointByName(n, self.robot).position_start()] = v
        self.plant.SetPositions(ctx, full)
        rc = self.reproducer.GetMyMutableContextFromRoot(root_context)
        self.reproducer.set_initial_command(rc, self.start_command)


def home_position(task: str) -> np.ndarray:
    """The teacher's rest pose of the hand for ``task`` (where its demonstrations start), m."""
    from mmlearn.models.imitation.teacher import TeacherStyle

    st = TeacherStyle()
    return np.asarray(st.home if task in ("pick_place", "whiteboard") else st.reach_home, float)


def hand_ik(reproducer, p_hand, *, q_seed=ROBOT_START, iterations: int = 100,
            damping: float = 0.02, tol: float = 1e-4) -> np.ndarray:
    """Arm configuration (rad) whose hand is at ``p_hand`` (world, m): damped least squares
    from ``q_seed`` turned towards the hand (q1 = its azimuth, so the arm stays in the
    vertical plane through the base and the hand), with the reproducer's kinematics,
    clipped to the joint limits."""
    q = np.asarray(q_seed, float).copy()
    p_hand = np.asarray(p_hand, float)
    q[0] = math.atan2(p_hand[1], p_hand[0])
    for _ in range(iterations):
        kin = reproducer.kinematics()
        p, J = kin.hand(q), kin.jacobian(q)
        e = p_hand - p
        if np.linalg.norm(e) < tol:
            break
        q = q + J.T @ np.linalg.solve(J @ J.T + damping ** 2 * np.eye(3), e)
        q = np.clip(q, reproducer._lo, reproducer._hi)
    return q


#: seeds of the start IK (q2, q4, q6), rad: elbow lower / higher, wrist bent more / less
START_SEEDS = ((0.35, 1.6, 1.2), (0.0, 1.2, 1.9), (0.6, 1.9, 0.6), (-0.2, 1.0, 2.2),
               (0.9, 2.2, 0.0))


def start_configuration(reproducer, p_hand, boxes=()) -> np.ndarray:
    """The arm's start: the hand at ``p_hand`` (world, m) by :func:`hand_ik` from each of
    ``START_SEEDS``; with obstacle ``boxes`` (SceneBox list) the solution whose arm points
    (``BODY_POINTS`` and the hand) keep the largest clearance from them, else the first
    that reaches (within 5 mm)."""
    best, best_d = None, -np.inf
    kin = reproducer.kinematics()
    for q2, q4, q6 in START_SEEDS:
        q = hand_ik(reproducer, p_hand, q_seed=(0.0, q2, 0.0, q4, 0.0, q6))
        err = np.linalg.norm(kin.hand(q) - p_hand)
        pts = np.vstack([kin.body_points(q), kin.hand(q)[None]])
        d = min((float(np.min(np.linalg.norm(
            np.maximum(np.abs((pts - b.centre) @ b.R) - b.half_size, 0.0), axis=1)))
            for b in boxes), default=0.0) if boxes else 0.0
        score = d - (10.0 if err > 0.005 else 0.0)
        if score > best_d:
            best, best_d = q, score
        if not boxes and err <= 0.005:
            break
    return best


def ellipsoid_stride(model, shown: int = 12) -> int:
    """Draw every how-many-th slice's variance ellipsoid so that about ``shown`` per
    constraint are drawn (all of them would hide the scene)."""
    return max(1, int(round(model.S / max(int(shown), 1))))


def object_positions(plant, root_context, names) -> dict[str, np.ndarray]:
    """True world positions of the objects' markers (``<name>_marker`` frames), m."""
    ctx = plant.GetMyContextFromRoot(root_context)
    out = {}
    for n in names:
        body = plant.GetBodyByName(n)
        inst = body.model_instance()
        f = (plant.GetFrameByName(n + "_marker", inst) if plant.HasFrameNamed(n + "_marker", inst)
             else body.body_frame())
        out[n] = f.CalcPoseInWorld(ctx).translation()
    return out


def MakeImitationDiagram(config: ImitationConfig | None = None, *, model, meshcat=None,
                         demos=None) -> Imitation:
    """Build the reproduction diagram for the learned ``model``
    (:class:`~mmlearn.models.imitation.types.TaskModel`); with ``meshcat`` the scene, the
    demonstrations ``demos`` (optional), the learned model (drawn at the objects' start
    positions) and the hand trail are shown.

    Exported outputs: ``robot_state``, ``command``, ``hand``, ``target_hand``, ``status``,
    ``attached`` (when there is a cup), ``observations``, ``query_object``, ``body_poses``.

    Returns an :class:`Imitation`; call its ``set_start(context)`` on the simulator's
    context before advancing (the arm's start configuration is not the context's default).
    """
    cfg = config or ImitationConfig()
    cfg.validate()
    spec = cfg.scene_spec()
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=cfg.time_step)
    plant.set_name("plant")
    scene_graph.set_name("scene_graph")
    parser = Parser(plant)
    parser.AddModelsFromString(floor_sdf(), "sdf")
    robot = parser.AddModelsFromString(arm_sdf(7, tool="gripper", model_name="robot"),
                                       "sdf")[0]
    scene = add_imitation_scene(plant, spec)
    for a in range(plant.num_actuators()):
        act = plant.get_mutable_joint_actuator(JointActuatorIndex(a))
        if act.model_instance() != robot:
            continue
        finger = act.joint().name().startswith("q7")
        act.set_controller_gains(PdControllerGains(
            p=cfg.kp_gripper if finger else cfg.kp, d=cfg.kd_gripper if finger else cfg.kd))
    plant.Finalize()

    def geoms(bodies):
        return GeometrySet([g for b in bodies for g in plant.GetCollisionGeometriesForBody(b)])

    robot_g = geoms([plant.get_body(b) for b in plant.GetBodyIndices(robot)])
    floor_g = geoms([plant.get_body(b) for b in
                     plant.GetBodyIndices(plant.GetModelInstanceByName("floor"))])
    decl = CollisionFilterDeclaration().ExcludeWithin(robot_g).ExcludeBetween(robot_g, floor_g)
    has_cup = "cup" in scene.bodies
    if has_cup:
        decl = decl.ExcludeBetween(robot_g, geoms([plant.GetBodyByName("cup")]))
    if "board" in scene.bodies:
        # the hand wipes the board (a sponge in the thesis): no contact forces with it
        decl = decl.ExcludeBetween(robot_g, geoms([plant.GetBodyByName(b) for b in
                                                   scene.bodies if b.startswith("board")]))
    scene_graph.collision_filter_manager().Apply(decl)

    # command (q1..q6, finger angle) -> desired state of the actuators
    spec_arm = arm_spec(7)
    names = list(spec_arm.actions)
    acts = [plant.get_joint_actuator(a) for a in plant.GetJointActuatorIndices(robot)]
    G = np.zeros((2 * len(acts), len(names)))
    for i, act in enumerate(acts):
        G[i, names.index(spec_arm.mimic.get(act.joint().name(), act.joint().name()))] = 1.0
    mapper = builder.AddNamedSystem("command_to_desired_state", MatrixGain(G))
    builder.Connect(mapper.get_output_port(), plant.get_desired_state_input_port(robot))
    gc = builder.AddNamedSystem("gravity_compensation",
                                GravityCompensation(plant=plant, model_instance=robot))
    builder.Connect(plant.get_state_output_port(), gc.get_state_input_port())
    builder.Connect(gc.get_actuation_output_port(), plant.get_actuation_input_port(robot))

    sensor_cfg = MarkerSensorConfig(**{**cfg.sensor.__dict__, "bodies": list(scene.bodies),
                                       "seed": int(cfg.seed)})
    sensor = builder.AddNamedSystem("marker_sensor", MarkerSensor(plant=plant,
                                                                  config=sensor_cfg))
    builder.Connect(plant.get_body_poses_output_port(), sensor.get_body_poses_input_port())
    builder.Connect(scene_graph.get_query_output_port(), sensor.get_query_object_input_port())

    obstacles = {}
    marker = spec.obstacle_marker()
    if marker is not None:
        obstacles["obstacle"] = [(b.centre - marker, b.half_size) for b in spec.obstacle_boxes()]
    arm_joints = [plant.GetJointByName(f"q{i}", robot) for i in range(1, 7)]
    rep = builder.AddNamedSystem("dbn_reproducer", DbnReproducer(
        plant=plant, model=model, arm_joints=arm_joints,
        tcp_frame=plant.GetBodyByName("x8", robot).body_frame(), p_tcp=ROBOT_TCP_IN_X8,
        body_points=[(plant.GetBodyByName(b, robot).body_frame(), p) for b, p in BODY_POINTS],
        plan_body_points=[(plant.GetBodyByName(b, robot).body_frame(), p)
                          for b, p in PLAN_BODY_POINTS],
        obstacles=obstacles, config=cfg.reproducer))
    builder.Connect(plant.get_state_output_port(robot), rep.get_robot_state_input_port())
    builder.Connect(sensor.get_observations_output_port(), rep.get_observations_input_port())
    builder.Connect(rep.get_command_output_port(), mapper.get_input_port())

    grasp = None
    if has_cup:
        grasp = builder.AddNamedSystem("grasp", GraspAttachment(
            plant=plant, hand_body=plant.GetBodyByName("x8", robot), p_tcp=ROBOT_TCP_IN_X8,
            object_body="cup", p_object=(0.0, 0.0, spec.cup_height),
            capture_radius=cfg.capture_radius, stiffness=cfg.grasp_stiffness,
            closed_below=0.5 * cfg.reproducer.gripper_open_angle))
        pick = builder.AddNamedSystem("gripper_command", MatrixGain(np.eye(7)[6:7]))
        builder.Connect(rep.get_command_output_port(), pick.get_input_port())
        builder.Connect(pick.get_output_port(), grasp.get_gripper_angle_input_port())
        builder.Connect(plant.get_body_poses_output_port(), grasp.get_body_poses_input_port())
        builder.Connect(plant.get_body_spatial_velocities_output_port(),
                        grasp.get_body_spatial_velocities_input_port())
        builder.Connect(grasp.get_spatial_forces_output_port(),
                        plant.get_applied_spatial_force_input_port())
        builder.ExportOutput(grasp.get_attached_output_port(), "attached")

    visualizer = None
    if meshcat is not None:
        visualizer = MeshcatVisualizer.AddToBuilder(
            builder, scene_graph, meshcat, MeshcatVisualizerParams(role=Role.kIllustration))
        trail = builder.AddNamedSystem("dbn_visualizer", DbnVisualizer(
            meshcat=meshcat, period=rep.period))
        builder.Connect(rep.get_hand_output_port(), trail.get_hand_input_port())
    builder.ExportOutput(plant.get_state_output_port(robot), "robot_state")
    builder.ExportOutput(rep.get_command_output_port(), "command")
    builder.ExportOutput(rep.get_hand_output_port(), "hand")
    builder.ExportOutput(rep.get_target_hand_output_port(), "target_hand")
    builder.ExportOutput(rep.get_status_output_port(), "status")
    builder.ExportOutput(sensor.get_observations_output_port(), "observations")
    builder.ExportOutput(scene_graph.get_query_output_port(), "query_object")
    builder.ExportOutput(plant.get_body_poses_output_port(), "body_poses")
    diagram = builder.Build()
    diagram.set_name("imitation")
    if len(cfg.robot_start):
        q_start = np.asarray(cfg.robot_start, float)
    else:
        q_start = start_configuration(rep, home_position(cfg.task), spec.obstacle_boxes())
    start = np.r_[q_start, cfg.reproducer.gripper_open_angle]
    out = Imitation(diagram=diagram, plant=plant, scene_graph=scene_graph, robot=robot,
                    scene=scene, sensor=sensor, reproducer=rep, grasp=grasp,
                    start_command=start, visualizer=visualizer)
    if meshcat is not None:
        ctx = diagram.CreateDefaultContext()
        objs = object_positions(plant, ctx, scene.bodies)
        draw_task_model(meshcat, model, objs, every=ellipsoid_stride(model))
        if demos:
            draw_demonstrations(meshcat, demos)
    return out
