"""The scene: floor, cabinet and a compliant arm with markers, observed by a MarkerSensor."""


from dataclasses import dataclass, field

import numpy as np

from pydrake.geometry import CollisionFilterDeclaration, GeometrySet, MeshcatVisualizer, \
    MeshcatVisualizerParams, Role
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
from pydrake.multibody.tree import JointActuatorIndex, PdControllerGains
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import MatrixGain

from mmlearn.models.common.config import param, validate_fields
from mmlearn.sdf import add_package
from mmlearn.sdf.builders import CabinetSpec, arm_sdf, arm_spec, cabinet_sdf, floor_sdf
from mmlearn.sdf.mechanisms import MechanismSpec, mechanism_sdf
from mmlearn.sdf.user_model import UserMechanism, add_user_model
from mmlearn.systems import GravityCompensation, JointFriction, MarkerSensor, \
    MarkerSensorConfig
from mmlearn.systems.common.camera_marker_sensor import CameraMarkerSensor, CameraMarkerSensorConfig
from mmlearn.systems.common.plant_helpers import STICTION_VELOCITY


@dataclass
class SceneConfig:
    """Configuration of :func:`MakeSceneDiagram` (load with ``yaml_load_typed``).

    Attributes:
        arm: "2dof", "4dof" or "7dof".
        tool: "gripper" (7-DOF only), "hook" or "none"; "auto" = gripper on the 7-DOF arm,
            none otherwise.
        mobile_base: put the arm on a planar mobile base (joints base_x, base_y, base_yaw).
        robot_pose: x, y, yaw of the robot's model frame in the world (m, m, rad).
        cabinet: add the cabinet.
        cabinet_pose: x, y, yaw of the cabinet (its front face is its local x = 0 plane).
        cabinet_spec: geometry and joint dynamics of the cabinet.
        mechanism: a single-mechanism piece of furniture (door, drawer, ...) to add, with
            its own pose (None = none); its joint is ``mechanism``. A
            :class:`~mmlearn.sdf.user_model.UserMechanism` adds the user's model file at
            its placement instead (``mechanism_state`` is then its joint's opening and
            opening rate). A revolute mechanism's joint friction is a ``DoorHinge`` force
            element of the plant, a prismatic one's a
            :class:`~mmlearn.systems.JointFriction` (the same regularised Coulomb law).
        time_step: plant discrete time step, s.
        kp_revolute, kd_revolute: PD gains of the arm's revolute joints (N*m/rad, N*m*s/rad).
        kp_prismatic, kd_prismatic: PD gains of prismatic joints (fingers), N/m and N*s/m.
        kp_base, kd_base: PD gains of the mobile base joints.
        gravity_compensation: add feed-forward gravity compensation of the arm.
        sensor: the MarkerSensor's configuration (``bodies`` empty = every part of the arm).
        marker_sensor: add the MarkerSensor (outputs ``observations`` and ``marker_stats``);
            False for a scene whose markers nobody reads (``Scene.sensor`` is then None):
            its time per frame is then not spent.
        camera_sensor: when set, the markers are read from rendered images instead: ArUco
            textures on the arm's marker squares, the configured RGB cameras and a
            :class:`~mmlearn.systems.common.camera_marker_sensor.CameraMarkerSensor` (same
            ``observations`` / ``marker_stats`` ports; ``sensor`` is then not used).
        sampled_output_ports: the plant's output ports are sampled (Drake's default: every
            step also computes and stores the reaction forces and contact results its
            outputs report; the plant then steps in an unrestricted update) or, False, live
            (computed from the current state when read: the reaction forces read at time t
            are those of the step from t, whose contact solve the step itself reuses; the
            plant steps in a discrete update). Live ports spare the plant that work at the
            steps nobody reads them.
        failure_joints: add the arm's hidden failure joints (a bendable middle link and a
            tool part on hidden joints, see ``arm_sdf``); lock them with
            :class:`mmlearn.systems.body_schema.arm_failures.PlantFailures` before simulating.
    """

    arm: str = param("7dof")
    tool: str = param("auto", choices=("auto", "gripper", "hook", "none"))
    mobile_base: bool = param(False)
    robot_pose: list[float] = param([0.0, 0.0, 0.0], unit="m, m, rad", length=3,
                                    elements=True, factory=True)
    cabinet: bool = param(True)
    cabinet_pose: list[float] = param([-1.5, 0.0, 0.0], unit="m, m, rad", length=3,
                                      elements=True, factory=True)
    cabinet_spec: CabinetSpec = param(default_factory=CabinetSpec)
    mechanism: MechanismSpec | None = param(None, optional=True)
    time_step: float = param(0.001, unit="s", gt=0)
    kp_revolute: float = param(400.0, unit="N*m/rad", ge=0)
    kd_revolute: float = param(40.0, unit="N*m*s/rad", ge=0)
    kp_prismatic: float = param(400.0, unit="N/m", ge=0)
    kd_prismatic: float = param(20.0, unit="N*s/m", ge=0)
    kp_base: float = param(4000.0, ge=0)
    kd_base: float = param(2000.0, ge=0)
    gravity_compensation: bool = param(True)
    sensor: MarkerSensorConfig = param(default_factory=MarkerSensorConfig)
    marker_sensor: bool = param(True)
    camera_sensor: CameraMarkerSensorConfig | None = param(None, optional=True)
    sampled_output_ports: bool = param(True)
    failure_joints: bool = param(False)

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first bad field (and a plant time step longer
        than a marker frame: the sensor would see a plant that has not moved)."""
        validate_fields(self)
        self.sensor.validate()
        period = 1.0 / self.sensor.rate_hz
        if self.time_step > period:
            raise ValueError(f"SceneConfig: time_step {self.time_step:g} s is longer than a "
                             f"marker frame ({period:g} s at sensor.rate_hz "
                             f"{self.sensor.rate_hz:g} Hz)")

    def resolved_tool(self) -> str:
        if self.tool != "auto":
            return self.tool
        return "gripper" if str(self.arm).lower().removesuffix("dof") == "7" else "none"


@dataclass
class Scene:
    """What :func:`MakeSceneDiagram` built: the diagram and the parts a caller needs.

    ``sensor`` is a MarkerSensor, or a CameraMarkerSensor when the scene was built with
    ``camera_sensor`` (then ``cameras`` holds its RgbdSensors), or None when it was built
    with ``marker_sensor=False``.
    ``command_names`` is the order of the diagram's ``command`` input port (commanded
    joint positions: the base's x, y, yaw first when there is a mobile base, then the arm's
    action signals q1, q2, ...); ``command_lower`` / ``command_upper`` are their limits.
    """

    diagram: object
    plant: object
    scene_graph: object
    robot: object
    cabinet: object | None
    mechanism: object | None
    sensor: MarkerSensor | CameraMarkerSensor | None
    visualizer: object | None
    command_names: list[str]
    command_lower: np.ndarray
    command_upper: np.ndarray
    arm_actions: list[str]
    joint_command: dict[str, int]
    cameras: list = field(default_factory=list)

    def set_joint_positions(self, root_context, command) -> None:
        """Put the robot's joints at the commanded positions in the root context (e.g.
        before simulating, so the PD controllers start at rest)."""
        command = np.asarray(command, float).ravel()
        if command.shape != (len(self.command_names),):
            raise ValueError(f"command needs {len(self.command_names)} values "
                             f"({self.command_names}), got {command.size}")
        ctx = self.plant.GetMyMutableContextFromRoot(root_context)
        q = self.plant.GetPositions(ctx)
        for jname, c in self.joint_command.items():
            q[self.plant.GetJointByName(jname, self.robot).position_start()] = command[c]
        self.plant.SetPositions(ctx, q)


def _finite_limits(lo, hi, default=2.6):
    lo = np.where(np.isfinite(lo), lo, -default)
    hi = np.where(np.isfinite(hi), hi, default)
    return lo, hi


def _export_user_opening(builder, plant, joint, mech) -> None:
    """Export ``mechanism_state`` of a user model: the joint's opening ``sign (q - q0)`` and
    its rate, from the plant's state."""
    from pydrake.systems.primitives import AffineSystem

    n = plant.num_positions() + plant.num_velocities()
    D = np.zeros((2, n))
    D[0, joint.position_start()] = mech.sign
    D[1, plant.num_positions() + joint.velocity_start()] = mech.sign
    y0 = np.array([-mech.sign * mech.q0, 0.0])
    opening = builder.AddNamedSystem("user_joint_opening", AffineSystem(
        np.zeros((0, 0)), np.zeros((0, n)), np.zeros(0), np.zeros((2, 0)), D, y0))
    builder.Connect(plant.get_state_output_port(), opening.get_input_port())
    builder.ExportOutput(opening.get_output_port(), "mechanism_state")


def _add_hinge_friction(plant, mechanism, spec) -> bool:
    """The friction of a revolute mechanism's joint as Drake's ``DoorHinge`` force element
    (dynamic friction only: tau = -friction * tanh(v / v_s), v_s = JointFriction's 0.02
    rad/s; no spring, catch, static or viscous term: the joint's damping stays the SDFormat
    joint's), computed inside the plant instead of by a Python system at every step. The
    same formula as :class:`~mmlearn.systems.JointFriction` (C++'s ``tanh``, which differs
    from numpy's in the last bit). Returns whether it added one (a prismatic joint keeps
    ``JointFriction``: Drake has no friction element for it)."""
    if mechanism is None:
        return False
    joint = plant.GetJointByName("mechanism", mechanism)
    if joint.type_name() != "revolute":
        return False
    from pydrake.multibody.tree import DoorHinge, DoorHingeConfig

    # catch_width only keeps the (zero) catch term finite
    plant.AddForceElement(DoorHinge(joint, DoorHingeConfig(
        spring_zero_angle_rad=0.0, spring_constant=0.0,
        dynamic_friction_torque=float(spec.friction), static_friction_torque=0.0,
        viscous_friction=0.0, catch_width=0.02, catch_torque=0.0,
        motion_threshold=HINGE_STICTION_VELOCITY)))
    return True


#: the velocity scale of the regularised Coulomb friction of a mechanism's hinge, rad/s
#: (:class:`~mmlearn.systems.JointFriction`'s default ``v_stiction``)
HINGE_STICTION_VELOCITY = STICTION_VELOCITY


def MakeSceneDiagram(config: SceneConfig | None = None, *, meshcat=None):
    """Build the scene diagram.

    Exported ports: inputs ``command`` (commanded joint positions, see
    :class:`Scene`) and ``applied_spatial_force`` (the plant's, optional); outputs
    ``observations`` (MarkerObservations) and ``marker_stats`` (unless ``marker_sensor`` is
    False),
    ``robot_state``, ``cabinet_state`` / ``mechanism_state`` (when there is one),
    ``body_poses``, ``reaction_forces``, ``query_object``.

    Returns:
        a :class:`Scene`.
    """
    cfg = config or SceneConfig()
    cfg.validate()
    tool = cfg.resolved_tool()
    spec = arm_spec(cfg.arm, tool=tool)  # validates arm / tool
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=cfg.time_step)
    plant.set_name("plant")
    if not cfg.sampled_output_ports:
        plant.SetUseSampledOutputPorts(False)
    scene_graph.set_name("scene_graph")
    parser = Parser(plant)
    add_package(parser)
    parser.AddModelsFromString(floor_sdf(), "sdf")
    x, y, yaw = cfg.robot_pose
    robot = parser.AddModelsFromString(
        arm_sdf(cfg.arm, tool=tool, mobile_base=cfg.mobile_base, model_name="robot",
                pose=(x, y, 0, 0, 0, yaw), failure_joints=cfg.failure_joints), "sdf")[0]
    cabinet = None
    if cfg.cabinet:
        cx, cy, cyaw = cfg.cabinet_pose
        cabinet = parser.AddModelsFromString(
            cabinet_sdf(cfg.cabinet_spec, pose=(cx, cy, 0, 0, 0, cyaw)), "sdf")[0]
    mechanism, user_instances, user_joint = None, [], None
    if isinstance(cfg.mechanism, UserMechanism):
        user_instances, user_joint = add_user_model(parser, cfg.mechanism)
        mechanism = user_joint.model_instance()
    elif cfg.mechanism is not None:
        mechanism = parser.AddModelsFromString(mechanism_sdf(cfg.mechanism), "sdf")[0]
    furniture = [m for m in (cabinet, mechanism) if m is not None]
    furniture += [m for m in user_instances if m not in furniture]

    # implicit PD on every actuator of the robot
    # (GetJointActuatorIndices(instance) is empty before Finalize: scan all actuators)
    for a in range(plant.num_actuators()):
        act = plant.get_mutable_joint_actuator(JointActuatorIndex(a))
        if act.model_instance() != robot:
            continue
        jname = act.joint().name()
        if jname.startswith("base_"):
            gains = PdControllerGains(p=cfg.kp_base, d=cfg.kd_base)
        elif act.joint().type_name() == "prismatic":
            gains = PdControllerGains(p=cfg.kp_prismatic, d=cfg.kd_prismatic)
        else:
            gains = PdControllerGains(p=cfg.kp_revolute, d=cfg.kd_revolute)
        act.set_controller_gains(gains)
    markers = None
    if cfg.camera_sensor is not None:
        from mmlearn.diagrams.common.marker_camera import AddArucoMarkers

        markers = AddArucoMarkers(plant, config=cfg.camera_sensor, model_instance=robot)
    hinge = _add_hinge_friction(plant, mechanism if user_joint is None else None,
                                cfg.mechanism)
    plant.Finalize()

    # collisions: nothing within the robot or a piece of furniture, nothing with the floor
    def geoms(instance):
        return GeometrySet([g for b in plant.GetBodyIndices(instance)
                            for g in plant.GetCollisionGeometriesForBody(plant.get_body(b))])

    floor_geoms = geoms(plant.GetModelInstanceByName("floor"))
    decl = CollisionFilterDeclaration()
    for inst in [robot] + furniture:
        decl = decl.ExcludeWithin(geoms(inst)).ExcludeBetween(geoms(inst), floor_geoms)
    scene_graph.collision_filter_manager().Apply(decl)

    # command vector -> desired state [qd; vd] of the robot's actuators
    command_names = (["base_x", "base_y", "base_yaw"] if cfg.mobile_base else []) + spec.actions
    acts = [plant.get_joint_actuator(a) for a in plant.GetJointActuatorIndices(robot)]
    nu = len(acts)
    G = np.zeros((2 * nu, len(command_names)))
    lower = np.zeros(len(command_names))
    upper = np.zeros(len(command_names))
    joint_command = {}
    for i, act in enumerate(acts):
        j = act.joint()
        name = spec.mimic.get(j.name(), j.name())
        if name not in command_names:
            raise RuntimeError(f"actuated joint {j.name()!r} has no command")
        c = command_names.index(name)
        joint_command[j.name()] = c
        G[i, c] = 1.0
        if name == j.name():
            lo, hi = _finite_limits(j.position_lower_limits(), j.position_upper_limits())
            lower[c], upper[c] = lo[0], hi[0]
    mapper = builder.AddNamedSystem("command_to_desired_state", MatrixGain(G))
    builder.Connect(mapper.get_output_port(), plant.get_desired_state_input_port(robot))
    builder.ExportInput(mapper.get_input_port(), "command")

    if cfg.gravity_compensation:
        gc = builder.AddNamedSystem("gravity_compensation",
                                    GravityCompensation(plant=plant, model_instance=robot))
        builder.Connect(plant.get_state_output_port(), gc.get_state_input_port())
        builder.Connect(gc.get_actuation_output_port(), plant.get_actuation_input_port(robot))
    else:
        from pydrake.systems.primitives import ConstantVectorSource
        zero = builder.AddNamedSystem("zero_actuation", ConstantVectorSource(np.zeros(nu)))
        builder.Connect(zero.get_output_port(), plant.get_actuation_input_port(robot))

    fr = {}
    if cabinet is not None:
        s = cfg.cabinet_spec
        fr.update({plant.GetJointByName(n, cabinet).velocity_start(): mu for n, mu in (
            ("left_hinge", s.door_friction), ("right_hinge", s.door_friction),
            ("drawer_slide", s.drawer_friction))})
        builder.ExportOutput(plant.get_state_output_port(cabinet), "cabinet_state")
    if user_joint is not None:
        _export_user_opening(builder, plant, user_joint, cfg.mechanism)
    elif mechanism is not None:
        if not hinge:
            fr[plant.GetJointByName("mechanism", mechanism).velocity_start()] = \
                cfg.mechanism.friction
        builder.ExportOutput(plant.get_state_output_port(mechanism), "mechanism_state")
    if fr:
        friction = builder.AddNamedSystem("furniture_friction", JointFriction(
            num_positions=plant.num_positions(), num_velocities=plant.num_velocities(),
            joints=fr))
        builder.Connect(plant.get_state_output_port(), friction.get_state_input_port())
        builder.Connect(friction.get_generalized_force_output_port(),
                        plant.get_applied_generalized_force_input_port())

    cameras, sensor = [], None
    if markers is not None:
        from mmlearn.diagrams.common.marker_camera import AddCameraMarkerSensor

        sensor, cameras = AddCameraMarkerSensor(builder, scene_graph, markers=markers,
                                                config=cfg.camera_sensor)
    elif cfg.marker_sensor:
        sensor = builder.AddNamedSystem("marker_sensor", MarkerSensor(
            plant=plant, config=cfg.sensor, model_instance=robot))
        builder.Connect(plant.get_body_poses_output_port(), sensor.get_body_poses_input_port())
        builder.Connect(scene_graph.get_query_output_port(),
                        sensor.get_query_object_input_port())
    if sensor is not None:
        builder.ExportOutput(sensor.get_observations_output_port(), "observations")
        builder.ExportOutput(sensor.get_stats_output_port(), "marker_stats")
    builder.ExportOutput(plant.get_state_output_port(robot), "robot_state")
    builder.ExportOutput(plant.get_body_poses_output_port(), "body_poses")
    builder.ExportOutput(plant.get_reaction_forces_output_port(), "reaction_forces")
    builder.ExportInput(plant.get_applied_spatial_force_input_port(), "applied_spatial_force")
    builder.ExportOutput(scene_graph.get_query_output_port(), "query_object")

    visualizer = None
    if meshcat is not None:
        visualizer = MeshcatVisualizer.AddToBuilder(
            builder, scene_graph, meshcat, MeshcatVisualizerParams(role=Role.kIllustration))
    diagram = builder.Build()
    diagram.set_name("scene")
    return Scene(diagram=diagram, plant=plant, scene_graph=scene_graph, robot=robot,
                 cabinet=cabinet, mechanism=mechanism, sensor=sensor, visualizer=visualizer,
                 command_names=command_names, command_lower=lower, command_upper=upper,
                 arm_actions=list(spec.actions), joint_command=joint_command,
                 cameras=cameras)
