"""Body-schema learning in the Drake scene (thesis ch. 3).

:func:`MakeBodySchemaDiagram` wires::

    MotorBabbling ----\\                                   /-> SchemaLearner --> schema, X_WR
                       PortSwitch --> JointBlocker --> scene (arm, MarkerSensor)
    SchemaController -/   (command_source)      |                    |
          ^  schema, X_WR from the learner      \\-- observations ----/

The learner sees the *commanded* joint positions (the switch's output, before the
JointBlocker) and the MarkerSensor's frames; it is never told about failures. Failures
live in the plant (hidden joints of an arm built with ``failure_joints=True``, see
:class:`~mmlearn.systems.body_schema.arm_failures.PlantFailures`) and in the JointBlocker.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from pydrake.common.value import AbstractValue
from pydrake.systems.framework import DiagramBuilder, InputPortIndex
from pydrake.systems.primitives import PortSwitch

from mmlearn.diagrams.common.scene import MakeSceneDiagram, Scene, SceneConfig
from mmlearn.models.body_schema.schema import SearchConfig
from mmlearn.models.common.config import param, validate_fields
from mmlearn.sdf.builders import arm_spec
from mmlearn.systems.body_schema.arm_failures import JointBlocker, PlantFailures
from mmlearn.systems.common.camera_marker_sensor import CameraMarkerSensorConfig
from mmlearn.systems.common.marker_sensor import MarkerSensorConfig
from mmlearn.systems.body_schema.motor_babbling import MotorBabbling
from mmlearn.systems.body_schema.controller import SchemaController
from mmlearn.systems.body_schema.learner import SchemaLearner, SchemaLearnerConfig

__all__ = ["BodySchemaDiagramConfig", "BodySchemaDiagram", "MakeBodySchemaDiagram",
           "make_target_filter", "true_structure"]


def _default_tool(arm) -> str:
    """The tool of the scene's arm: the gripper on the 7-DOF arm, none on the others."""
    return "gripper" if str(arm).lower().removesuffix("dof") == "7" else "none"


BABBLE, CONTROL = 1, 2  # input port indices of the PortSwitch (0 is its selector)


@dataclass
class BodySchemaDiagramConfig:
    """Configuration of :func:`MakeBodySchemaDiagram` (load with ``yaml_load_typed``).

    Attributes:
        arm: "2dof", "4dof" or "7dof".
        noise_pos: RMS 3-D position error of a marker observation, m (the per-axis standard
            deviation of the sensor is noise_pos / sqrt(3), as in the thesis' sigma).
        noise_orient: RMS orientation error of a marker observation, rad.
        dropout: probability a marker is missed in a frame (visibility = 1 - dropout).
        occlude: parts whose markers are never observed (e.g. ["x4"]).
        cameras: judge visibility with the scene's camera (field of view, facing, occlusion)
            instead of the random drop-out only (slower).
        sensor: "ideal" (the MarkerSensor: true poses + Gaussian noise, drop-out) or
            "camera" (ArUco markers read from rendered RGB images by a CameraMarkerSensor
            configured by ``camera``; ``noise_pos`` / ``noise_orient`` then only set what
            the learner assumes, and ``dropout`` / ``cameras`` are not used).
        camera: the camera marker sensor (cameras, resolution, markers, detector).
        seed: seeds the sensor noise and the babbling targets.
        babble_period: s per babbling target; babble_hold: fraction of it resting there.
        babble_fraction: fraction of each joint range the targets come from (joints with
            a range below 0.2 rad or m, the gripper's fingers, use their full range).
        min_height: babbling targets keep every part (origin, tip and marker) at least this
            far above the floor, m.
        failure_joints: build the arm with its hidden failure joints.
        search_min_pos, search_min_orient: floors of the learner's noise levels (m, rad);
            the learner's SearchConfig uses max(noise, floor).
        learner: the SchemaLearner's configuration (its search noise is set from the above).
        controller_rate_hz: update rate of the SchemaController, Hz.
        draw_offset: where the learned schema is drawn relative to the real arm (m).
    """

    arm: str = param("2dof")
    noise_pos: float = param(0.044, unit="m", ge=0)
    noise_orient: float = param(math.radians(3.0), unit="rad", ge=0)
    dropout: float = param(0.1, ge=0, lt=1)
    occlude: list[str] = param([], factory=True)
    cameras: bool = param(False)
    sensor: str = param("ideal", choices=("ideal", "camera"))
    camera: CameraMarkerSensorConfig = param(default_factory=CameraMarkerSensorConfig)
    seed: int = param(0, integer=True, ge=0)
    babble_period: float = param(1.0, unit="s", gt=0)
    babble_hold: float = param(0.6, ge=0, lt=1)
    babble_fraction: float = param(0.85, gt=0, le=1)
    min_height: float = param(0.05, unit="m", ge=0)
    failure_joints: bool = param(True)
    search_min_pos: float = param(0.01, unit="m", ge=0)
    search_min_orient: float = param(math.radians(3.0), unit="rad", ge=0)
    learner: SchemaLearnerConfig = param(default_factory=SchemaLearnerConfig,
                                         nested=SchemaLearnerConfig)
    controller_rate_hz: float = param(10.0, unit="Hz", gt=0)
    draw_offset: list[float] = param([0.0, 0.9, 0.0], unit="m", length=3, elements=True,
                                     factory=True)

    def validate(self) -> None:
        validate_fields(self)
        arm_spec(self.arm, tool=_default_tool(self.arm))
        if self.sensor == "camera":
            self.camera.validate()
        rest = self.babble_hold * self.babble_period
        if rest < self.learner.settle_time + 1.0 / self.learner.rate_hz:
            raise ValueError(
                f"BodySchemaDiagramConfig: the arm rests {rest:.2f} s at each babbling target "
                f"(babble_hold * babble_period), less than the learner's settle_time "
                f"{self.learner.settle_time} s plus one update: no sample would be taken")

    def search_config(self) -> SearchConfig:
        """The learner's SearchConfig: validity noise max(sqrt(2) noise, floor), the noise
        of a *relative* pose z_ij = y_i^-1 y_j (two markers, each with RMS error noise; the
        SearchConfig's sigmas are those of z_ij); the local GPs' noise variance is bounded
        below by a quarter of the known noise of z_ij (per axis 2 noise**2 / 3): translation
        outputs from noise_pos (m^2), rotation-matrix entries from noise_orient (rad^2). With
        10-20 samples a GP left free tends to explain the noise as signal."""
        s = self.learner.search
        r2 = math.sqrt(2.0)
        return SearchConfig(**{**s.__dict__,
                               "sigma_pos": max(r2 * self.noise_pos, self.search_min_pos),
                               "sigma_orient": max(r2 * self.noise_orient,
                                                   self.search_min_orient),
                               "noise_min_pos": max(s.noise_min_pos,
                                                    0.25 * 2.0 * self.noise_pos ** 2 / 3.0),
                               "noise_min_rot": max(s.noise_min_rot,
                                                    0.25 * 2.0 * self.noise_orient ** 2 / 3.0)})


@dataclass
class BodySchemaDiagram:
    """What :func:`MakeBodySchemaDiagram` built (the diagram and the parts a caller needs).

    ``parts``: the learner's part names (observed markers, in schema index order);
    ``truth``: {(a, b): frozenset of action indices on the kinematic path} for every pair of
    parts (ground truth for evaluation, from the plant's joint tree);
    ``failures``: PlantFailures (None without failure joints).
    """

    config: BodySchemaDiagramConfig
    diagram: object
    scene: Scene
    learner: SchemaLearner
    babbling: MotorBabbling
    controller: SchemaController
    blocker: JointBlocker
    failures: PlantFailures | None
    parts: list[str]
    truth: dict
    visualizer: object | None = None
    _scratch: object = None

    # -- run-time switches ---------------------------------------------------------------
    def prepare(self, root_context) -> None:
        """Put the arm at the babbling start at rest, lock the hidden joints, select
        babbling and clear the controller target (call before ``Simulator.Initialize``)."""
        q0 = self.babbling.command(0.0)
        self.scene.set_joint_positions(self.scene_context(root_context), q0)
        if self.failures is not None:
            self.failures.lock(root_context)
        self.set_mode(root_context, "babble")
        self.set_target(root_context, [np.nan] * 3)
        self.controller.set_command(root_context, q0)

    def scene_context(self, root_context):
        return root_context  # the scene's systems are direct members of this diagram

    def set_mode(self, root_context, mode: str) -> None:
        """"babble" (MotorBabbling drives the arm) or "control" (SchemaController)."""
        if mode not in ("babble", "control"):
            raise ValueError(f"mode must be 'babble' or 'control', got {mode!r}")
        self.diagram.GetInputPort("command_source").FixValue(
            root_context,
            AbstractValue.Make(InputPortIndex(BABBLE if mode == "babble" else CONTROL)))

    def set_target(self, root_context, p_W) -> None:
        """World position (3,) m the SchemaController moves the end effector to."""
        self.diagram.GetInputPort("target").FixValue(root_context, np.asarray(p_W, float))

    def true_poses(self, root_context, command) -> np.ndarray:
        """True world poses (p, 4, 4) of the learner's parts' markers if the arm were at
        ``command`` (with the current hidden-joint failures; blocked joints ignored)."""
        plant, robot = self.scene.plant, self.scene.robot
        pc = plant.GetMyContextFromRoot(root_context)
        if self._scratch is None:
            self._scratch = plant.CreateDefaultContext()
        ctx = self._scratch
        q = plant.GetPositions(pc).copy()
        command = np.asarray(command, float)
        for jname, c in self.scene.joint_command.items():
            q[plant.GetJointByName(jname, robot).position_start()] = command[c]
        plant.SetPositions(ctx, q)
        return np.array([plant.GetFrameByName(f"{p}_marker", robot)
                         .CalcPoseInWorld(ctx).GetAsMatrix4() for p in self.parts])


def true_structure(plant, robot, parts, joint_command) -> dict:
    """{(a, b): frozenset(action indices)} over all pairs of ``parts`` (indices into parts):
    the actions of the joints on the tree path between the two bodies (hidden joints and
    welds carry no action)."""
    parent = {}
    for j in plant.GetJointIndices(robot):
        joint = plant.get_joint(j)
        act = joint_command.get(joint.name())
        parent[joint.child_body().name()] = (joint.parent_body().name(), act)

    def chain(b):
        out = []
        while b in parent:
            out.append(b)
            b = parent[b][0]
        return out + [b]

    truth = {}
    for a in range(len(parts)):
        for b in range(a + 1, len(parts)):
            ca, cb = chain(parts[a]), chain(parts[b])
            common = set(ca) & set(cb)
            path = [x for x in ca if x not in common] + [x for x in cb if x not in common]
            acts = frozenset(parent[x][1] for x in path if parent.get(x, (0, None))[1]
                             is not None)
            truth[(a, b)] = acts
    return truth


def make_target_filter(scene: Scene, *, min_height: float = 0.05):
    """A predicate ``accept(command) -> bool`` for :class:`MotorBabbling`: True when, at
    that command, every arm part (origin, tip along its +z axis and marker) is at least
    ``min_height`` m above the floor and the scene reports no collision (SceneGraph
    ``HasCollisions`` on a scratch context; collisions within the robot and with the floor
    are filtered by the scene, so this catches the furniture). When the scene diagram is
    added to a larger diagram, call ``accept.set_root(root_diagram)`` after building it."""
    plant, robot = scene.plant, scene.robot
    names = [plant.get_body(j).name() for j in plant.GetBodyIndices(robot)]
    query_port = scene.diagram.GetOutputPort("query_object")
    holder = {}
    lengths = {}
    for name in names:
        if plant.HasFrameNamed(f"{name}_marker", robot):
            X = plant.GetFrameByName(f"{name}_marker", robot).GetFixedPoseInBodyFrame()
            lengths[name] = 2 * X.translation()[2]  # markers sit at mid-length
    # only parts that some commanded joint moves (the base stands on the floor)
    parent = {}
    for j in plant.GetJointIndices(robot):
        joint = plant.get_joint(j)
        parent[joint.child_body().name()] = (joint.parent_body().name(),
                                             joint.name() in scene.joint_command)

    def moved(name):
        while name in parent:
            name, act = parent[name]
            if act:
                return True
        return False

    bodies = [plant.GetBodyByName(n, robot) for n in lengths if moved(n)]

    def accept(command) -> bool:
        if "ctx" not in holder:  # the root diagram (scene.diagram or the one holding it)
            holder["ctx"] = holder.get("root", scene.diagram).CreateDefaultContext()
        ctx = holder["ctx"]
        pctx = plant.GetMyMutableContextFromRoot(ctx)
        scene.set_joint_positions(ctx, command)
        for b in bodies:
            X = plant.EvalBodyPoseInWorld(pctx, b)
            tip = X.multiply(np.array([0.0, 0.0, lengths[b.name()]]))
            mid = X.multiply(np.array([0.0, 0.0, lengths[b.name()] / 2]))
            if min(tip[2], mid[2], X.translation()[2]) < min_height:
                return False
        return not query_port.Eval(scene.diagram.GetMyContextFromRoot(ctx)).HasCollisions()

    def set_root(diagram):
        """Tell the predicate the root diagram once the scene was added to one."""
        holder.clear()
        holder["root"] = diagram

    accept.set_root = set_root
    return accept


def MakeBodySchemaDiagram(config: BodySchemaDiagramConfig | None = None, *, meshcat=None,
                          scene_config: SceneConfig | None = None) -> BodySchemaDiagram:
    """Build the body-schema diagram (see the module docstring).

    Exported inputs: ``command_source`` (PortSwitch selector: use
    :meth:`BodySchemaDiagram.set_mode`), ``target`` (controller target, m). Exported
    outputs: ``command`` (the commanded joint positions the learner sees), ``schema``,
    ``X_WE``, ``X_WR``, ``predicted_poses``, ``model_validity``, ``learner_status``,
    ``observations``, ``marker_stats``, ``robot_state``.

    ``scene_config`` overrides the scene (default: no cabinet, the arm's failure joints,
    a MarkerSensor with the configured noise, drop-out and occlusion).
    """
    cfg = config or BodySchemaDiagramConfig()
    cfg.validate()
    if scene_config is None:
        sensor = MarkerSensorConfig(
            sigma_pos=cfg.noise_pos / math.sqrt(3), sigma_orient=cfg.noise_orient / math.sqrt(3),
            dropout=cfg.dropout, seed=cfg.seed,
            cameras=None if cfg.cameras else [])
        if sensor.cameras is None:
            sensor = MarkerSensorConfig(**{**sensor.__dict__,
                                           "cameras": MarkerSensorConfig().cameras})
        camera = (dataclasses.replace(cfg.camera, bodies=list(cfg.camera.bodies))
                  if cfg.sensor == "camera" else None)
        scene_config = SceneConfig(arm=cfg.arm, cabinet=False, sensor=sensor,
                                   camera_sensor=camera, failure_joints=cfg.failure_joints)
    spec_parts = None
    if cfg.occlude:
        probe = MakeSceneDiagram(dataclasses.replace(scene_config, camera_sensor=None))
        spec_parts = list(probe.sensor.marker_ids)
        if scene_config.camera_sensor is not None and scene_config.camera_sensor.bodies:
            spec_parts = list(scene_config.camera_sensor.bodies)
        unknown = [p for p in cfg.occlude if p not in spec_parts]
        if unknown:
            raise ValueError(f"occlude: unknown parts {unknown}; parts are {spec_parts}")
        scene_config.sensor.bodies = [p for p in spec_parts if p not in cfg.occlude]
        if scene_config.camera_sensor is not None:
            scene_config.camera_sensor.bodies = list(scene_config.sensor.bodies)
    scene = MakeSceneDiagram(scene_config, meshcat=meshcat)
    parts = list(scene.sensor.marker_ids)
    n = len(scene.command_names)

    builder = DiagramBuilder()
    # the scene's subsystems are added one level down; keep the scene diagram as a block
    sd = builder.AddNamedSystem("scene", scene.diagram)
    mid = 0.5 * (scene.command_lower + scene.command_upper)
    rng_ = scene.command_upper - scene.command_lower
    # the gripper (the action driving the mirrored finger) and short-range joints babble
    # over their full range
    grip = set(arm_spec(cfg.arm, tool=_default_tool(cfg.arm)).mimic.values())
    full = (rng_ < 0.2) | np.isin(list(scene.command_names), list(grip))
    half = 0.5 * rng_ * np.where(full, 1.0, cfg.babble_fraction)
    accept = make_target_filter(scene, min_height=cfg.min_height)
    start = mid.copy()
    babbling = builder.AddNamedSystem("motor_babbling", MotorBabbling(
        lower=mid - half, upper=mid + half, period=cfg.babble_period, seed=cfg.seed,
        start=start, hold=cfg.babble_hold, accept=accept))
    lcfg = SchemaLearnerConfig(**{**cfg.learner.__dict__, "search": cfg.search_config()})
    learner = builder.AddNamedSystem("schema_learner", SchemaLearner(
        parts=parts, n_actions=n, config=lcfg))
    controller = builder.AddNamedSystem("schema_controller", SchemaController(
        part=learner.end_effector, lower=mid - half, upper=mid + half,
        start=start, rate_hz=cfg.controller_rate_hz))
    switch = builder.AddNamedSystem("command_switch", PortSwitch(n))
    in_babble = switch.DeclareInputPort("babble")
    in_control = switch.DeclareInputPort("control")
    blocker = builder.AddNamedSystem("joint_blocker", JointBlocker(size=n))
    builder.Connect(babbling.get_command_output_port(), in_babble)
    builder.Connect(controller.get_command_output_port(), in_control)
    builder.Connect(switch.get_output_port(), blocker.get_command_input_port())
    builder.Connect(blocker.get_command_output_port(), sd.GetInputPort("command"))
    builder.Connect(switch.get_output_port(), learner.get_command_input_port())
    builder.Connect(sd.GetOutputPort("observations"), learner.get_observations_input_port())
    builder.Connect(learner.get_schema_output_port(), controller.get_schema_input_port())
    builder.Connect(learner.get_X_WR_output_port(), controller.get_X_WR_input_port())
    builder.ExportInput(switch.get_port_selector_input_port(), "command_source")
    builder.ExportInput(controller.get_target_input_port(), "target")
    builder.ExportOutput(switch.get_output_port(), "command")
    for name, port in (("schema", learner.get_schema_output_port()),
                       ("X_WE", learner.get_X_WE_output_port()),
                       ("X_WR", learner.get_X_WR_output_port()),
                       ("predicted_poses", learner.get_predicted_poses_output_port()),
                       ("model_validity", learner.get_model_validity_output_port()),
                       ("learner_status", learner.get_status_output_port())):
        builder.ExportOutput(port, name)
    for name in ("observations", "marker_stats", "robot_state"):
        builder.ExportOutput(sd.GetOutputPort(name), name)
    visualizer = None
    if meshcat is not None:
        from mmlearn.systems.body_schema.visualizer import SchemaVisualizer
        visualizer = builder.AddNamedSystem("schema_visualizer", SchemaVisualizer(
            meshcat=meshcat, parts=parts, offset=cfg.draw_offset))
        builder.Connect(learner.get_predicted_poses_output_port(),
                        visualizer.get_predicted_poses_input_port())
        builder.Connect(learner.get_model_validity_output_port(),
                        visualizer.get_model_validity_input_port())
    diagram = builder.Build()
    diagram.set_name("body_schema")
    accept.set_root(diagram)
    failures = None
    if scene_config.failure_joints:
        failures = PlantFailures(plant=scene.plant, model_instance=scene.robot)
    truth = true_structure(scene.plant, scene.robot, parts, scene.joint_command)
    return BodySchemaDiagram(config=cfg, diagram=diagram, scene=scene, learner=learner,
                             babbling=babbling, controller=controller, blocker=blocker,
                             failures=failures, parts=parts, truth=truth,
                             visualizer=visualizer)
