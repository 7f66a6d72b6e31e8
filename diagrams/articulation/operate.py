"""Opening a door or drawer: mobile robot with a hook, a randomised mechanism, a wrist
force sensor, the ArticulationEstimator learning the mechanism online from the hook's
trajectory, and the EpcController moving along the learned model (thesis 4.3, 4.4.2)."""

import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import Adder

from mmlearn.models.articulation.link import ObservationModel
from mmlearn.models.articulation.priors import PriorDatabase
from mmlearn.models.common.config import param, validate_fields
from mmlearn.sdf.mechanisms import KINDS, MechanismSpec, sample_mechanism
from mmlearn.sdf.user_model import UserMechanism
from mmlearn.systems.articulation.estimator import ArticulationEstimator
from mmlearn.systems.articulation.base_localization import (FRAMES, BaseLocalization,
                                                            BaseLocalizationConfig,
                                                            believed_from_true, initial_error,
                                                            rotate_yaw)
from mmlearn.systems.articulation.epc_controller import (CommandInterpolator, EpcConfig,
                                                        EpcController, EpcTask)
from mmlearn.systems.articulation.jam_monitor import (DynamicsMonitor, DynamicsMonitorConfig,
                                                     HaltGate)
from mmlearn.systems.articulation.model_visualizer import LearnedModelVisualizer
from mmlearn.systems.articulation.prior_selector import PriorModelSelector
from mmlearn.systems.common.wrist_force_sensor import WristForceSensor

from mmlearn.diagrams.articulation.operate_perception import LookAtFront, LookConfig, LookResult, NoFrontDetected
from mmlearn.diagrams.common.scene import MakeSceneDiagram, SceneConfig

PERCEPTIONS = ("click", "depth")
ARM_START = (0.0, 0.3, 0.0, 1.2, 0.0, 0.0)  # the arm's joint commands at the start, rad
#: the wrist force sensor's sample period, s (its 100 Hz)
WRIST_PERIOD = 0.01
#: the wrist force sensor's samples whose noise is drawn when the trial is built (164 s at
#: its 100 Hz, longer than a trial's 60 s default): a table read instead of a new random
#: generator per sample
WRIST_NOISE_SAMPLES = 1 << 14
#: the estimator's refit interval on a long track, as a fraction of the samples it fitted
#: last (``OperateConfig.refit_fraction``'s default without a dynamics monitor)
REFIT_FRACTION = 0.1


@dataclass
class OperateConfig:
    """One trial of the opening task.

    Attributes:
        kind: mechanism kind (left_door, right_door, dishwasher, drawer, sliding_door).
        seed: draws the mechanism, the handle-click error and the robot's start.
        click_error: largest error of the clicked handle position, m.
        start_distance: distance of the robot's start from the handle, m.
        sigma_pos: position noise the estimator assumes for the hook trajectory, m
            (thesis: 0.05 m, which covers base localisation, hooking and forward-kinematics
            errors).
        estimator_period: hook positions are sampled at this period, s.
        refit_every: the estimator refits after this many new samples.
        refit_fraction: on a longer track the estimator waits instead for this fraction of
            the samples it fitted last, and refits once more when the track ends
            (``ArticulationEstimator(refit_fraction=...)``): a refit's cost grows with the
            track while a few more samples change a long track's model little. None (the
            default): :data:`REFIT_FRACTION` without a dynamics ``monitor``, 0 (every
            ``refit_every`` samples) with one (the monitor's regression reads the model, and
            the damping it learns moves with the times the model changes).
        models: the estimator's candidate link models (thesis: rigid, prismatic, revolute
            and GP).
        sigma_force: wrist force sensor noise, N.
        time_step: the plant's discrete time step, s. 2.5 ms (the scene's default is
            1 ms): 40 % of the simulation's steps, the trials' outcomes those of 1 ms within
            their seed-to-seed spread (docs/performance_articulation.md). The periods of the
            controller, the estimator, the localisation, the wrist sensor and the dynamics
            monitor are multiples of it (a step they are not multiples of adds simulator
            steps of its own).
        sampled_output_ports: the plant's output ports sampled at every step (True) or
            live (False; see :class:`~mmlearn.diagrams.common.scene.SceneConfig`). None (the
            default): live without a dynamics ``monitor``, sampled with one (the damping the
            monitor learns on one door moves markedly with any change of the
            wrist force's noise or of the order of the updates, so its trials keep the
            sampled ports and per-sample noise their results were made with:
            docs/performance_articulation.md). Live, the plant computes
            the reaction forces only at the steps the wrist sensor reads them: at its
            sample instants, one event per sample, the forces of the step that starts there
            (those sampled ports give it) turned with the tool's pose at the step's start
            (sampled ports: its end). The plant's step is then a discrete update rather than
            an unrestricted one, so it runs after the controller's and the estimator's
            updates at the same instant instead of beside them: the localisation samples
            the base pose at the step's start rather than its end, and the plant sees a
            new command segment (whose first value is the old segment's last) or a halt at
            the instant it is made (docs/performance_articulation.md).
        wrist_noise_samples: the wrist sensor's samples whose noise is drawn when the
            trial is built (``WristForceSensor(noise_samples=...)``, a table instead of a
            new random generator per sample); None (the default): :data:`WRIST_NOISE_SAMPLES`
            without a dynamics ``monitor``, 0 (every sample's noise drawn from (seed,
            sample index)) with one.
        base_noise: scale of the base-localisation and odometry error (see
            :class:`~mmlearn.systems.articulation.base_localization.BaseLocalizationConfig`; 1 = its
            defaults: 0.05 m RMS horizontal, 1.1 deg heading, drifting with a 60 s time
            constant, plus odometry error; 0 = the robot knows its base pose exactly).
        base_localization: the error model's parameters before scaling (its seed is
            replaced by one drawn from ``seed`` and ``kind``).
        frame: the frame the robot's software (controller, estimator, monitor) works in:
            "odometry" (its dead reckoning since the start, anchored at its localisation's
            belief then: the hook's track drifts only by the odometry's error over the
            pull) or "map" (its localisation's belief, which drifts by centimetres over a
            pull); see :mod:`~mmlearn.systems.articulation.base_localization`.
        epc: the controller's parameters.
        mechanism: the mechanism (None = drawn from kind and ``mechanism_seed``), or a
            :class:`~mmlearn.sdf.user_model.UserMechanism` (a user's model file; ``kind``
            is then its ``kind``).
        mechanism_seed: seed of the mechanism's geometry (None = ``seed``); with a fixed
            value, trials differ only in the handle click and the robot's start, as when a
            robot operates the same door again.
        priors: path of a prior database (JSON, see ``models/articulation/priors.py``) to
            use while learning ("" = learn from scratch only).
        perception: how the robot learns where the handle is: "click" (told, within
            ``click_error``) or "depth" (it looks with its head depth camera, detects the
            front and derives the handle, :mod:`mmlearn.diagrams.articulation.operate_perception`).
        look: the depth camera, detector and handle derivation for ``perception="depth"``.
        mechanism_options: the mechanism's true dynamics, a jam or a latch, written into
            the drawn (or given) mechanism: the keywords of
            :func:`~mmlearn.diagrams.articulation.mechanism_dynamics.apply_mechanism_options`
            (damping, friction, spring, jam_at, locked; SI units, rad or m).
        monitor: the mechanism-dynamics monitor (learns damping, friction and spring while
            pulling, stops a pull against a jammed or locked mechanism; its ``joint``,
            ``open_enough`` and ``pull`` are set from ``kind`` and the task); None = no
            monitor.
    """

    kind: str = param("left_door", choices=KINDS)
    seed: int = param(0, integer=True, ge=0)
    click_error: float = param(0.02, unit="m", ge=0, lt=0.1)
    start_distance: float = param(1.0, unit="m")
    sigma_pos: float = param(0.05, unit="m", gt=0)
    estimator_period: float = param(0.03, unit="s", gt=0)
    refit_every: int = param(10, integer=True, ge=1)
    refit_fraction: float | None = param(None, optional=True, ge=0, le=1)
    models: list[str] = param(["rigid", "prismatic", "revolute", "gp"], factory=True)
    sigma_force: float = param(0.3, unit="N", ge=0)
    time_step: float = param(0.0025, unit="s", gt=0, le=0.01)
    sampled_output_ports: bool | None = param(None, optional=True)
    wrist_noise_samples: int | None = param(None, optional=True, integer=True, ge=0)
    base_noise: float = param(1.0, ge=0)
    base_localization: BaseLocalizationConfig = param(default_factory=BaseLocalizationConfig,
                                                      nested=BaseLocalizationConfig)
    frame: str = param("odometry", choices=FRAMES)
    epc: EpcConfig = param(default_factory=EpcConfig, nested=EpcConfig)
    mechanism: MechanismSpec | None = param(None, optional=True)
    mechanism_seed: int | None = param(None, optional=True, integer=True, ge=0)
    priors: str = param("")
    perception: str = param("click", choices=PERCEPTIONS)
    look: LookConfig = param(default_factory=LookConfig)
    mechanism_options: dict = param({}, factory=True)
    monitor: DynamicsMonitorConfig | None = param(None, optional=True)

    def validate(self):
        validate_fields(self)
        if self.perception == "depth":
            self.look.validate()
        if self.priors and not Path(self.priors).is_file():
            raise ValueError(f"OperateConfig: priors: prior database not found: {self.priors}")
        steps = WRIST_PERIOD / self.time_step
        if not self.sampled_ports() and (abs(steps - round(steps)) > 1e-6
                                              or round(steps) < 1):
            # live ports: the sensor's instants must be the plant's steps (a reading between
            # them would make the plant solve a step it never takes)
            raise ValueError(f"OperateConfig: time_step {self.time_step:g} s must divide the "
                             f"wrist sensor's {WRIST_PERIOD:g} s period with live output "
                             f"ports (sampled_output_ports=False)")


    def sampled_ports(self) -> bool:
        """Whether the plant's output ports are sampled (``sampled_output_ports``, or by
        default whether there is a dynamics monitor)."""
        if self.sampled_output_ports is None:
            return self.monitor is not None
        return bool(self.sampled_output_ports)

    def scene_config(self, mechanism) -> SceneConfig:
        """The scene of the trial: the mobile hook arm before ``mechanism`` (a mechanism
        spec), at this configuration's plant step and output ports."""
        return SceneConfig(arm="7dof", tool="hook", mobile_base=True, cabinet=False,
                           mechanism=mechanism, time_step=self.time_step,
                           marker_sensor=False, sampled_output_ports=self.sampled_ports())

    def estimator_refit_fraction(self) -> float:
        """The estimator's ``refit_fraction`` (``refit_fraction``, or its default)."""
        if self.refit_fraction is None:
            return 0.0 if self.monitor is not None else REFIT_FRACTION
        return float(self.refit_fraction)

    def noise_samples(self) -> int:
        """The wrist sensor's ``noise_samples`` (``wrist_noise_samples``, or its default)."""
        if self.wrist_noise_samples is None:
            return 0 if self.monitor is not None else WRIST_NOISE_SAMPLES
        return int(self.wrist_noise_samples)


@dataclass
class Operate:
    """The built diagram and its parts."""

    diagram: object
    scene: object
    mechanism: MechanismSpec
    task: EpcTask
    controller: EpcController
    estimator: ArticulationEstimator
    force_sensor: WristForceSensor
    start_command: np.ndarray
    prior_selector: PriorModelSelector | None = None
    monitor: DynamicsMonitor | None = None
    localization: BaseLocalization | None = None
    true_task: EpcTask | None = None
    look: LookResult | None = None


def make_task(spec: MechanismSpec, rng: np.random.Generator, click_error: float) -> EpcTask:
    """What the robot is told: a noisy handle click plus the front's orientation (for a
    :class:`~mmlearn.sdf.user_model.UserMechanism` its side and pulling direction come from
    its geometry)."""
    p, n, b = spec.handle_world(0.0)
    err = rng.normal(size=3)
    err *= rng.uniform(0, click_error) / max(np.linalg.norm(err), 1e-12)
    R_WF = spec.X_WF()[:3, :3]
    if isinstance(spec, UserMechanism):
        side, pull = spec.task_directions()
        return EpcTask(handle=p + err, normal=n, bar=b, pull=pull, side=side)
    if spec.kind == "left_door":
        side = R_WF @ np.array([0, 1.0, 0])   # towards the free edge
    elif spec.kind == "right_door":
        side = R_WF @ np.array([0, -1.0, 0])
    elif spec.kind == "sliding_door":
        side = R_WF @ np.array([0, 1.0, 0])   # the rod pushes the bar towards -y
    else:
        side = np.array([0, 0, 1.0])           # horizontal bar: from above
    pull = -side if spec.kind == "sliding_door" else n
    return EpcTask(handle=p + err, normal=n, bar=b, pull=pull, side=side)


HANDLE_HEIGHTS = (0.30, 1.10)
"""Heights above the floor (m) of the handles the hook arm reaches from its stance: the arm
(sdf/builders.py: 1.25 m of links on the base's top at 0.30 m) holds the hook level at
``EpcConfig.stance_distance`` (0.78 m) in front of the base between about these heights (the
drawer test model, tests/data/user_models, opened with its handle at 0.31 m and at 1.09 m)."""


def check_reach(spec) -> None:
    """Raise :class:`~mmlearn.sdf.user_model.UserModelError` when the handle of a user's
    model is out of the arm's reach (:data:`HANDLE_HEIGHTS`), saying how far."""
    from mmlearn.sdf.user_model import UserModelError

    z = float(spec.handle_world(0.0)[0][2])
    lo, hi = HANDLE_HEIGHTS
    if z > hi or z < lo:
        off = f"{z - hi:.2f} m above" if z > hi else f"{lo - z:.2f} m below"
        raise UserModelError(f"the handle ({spec.handle_source}) is {z:.2f} m above the floor, "
                             f"{off} the arm's reach (handles {lo:.2f}-{hi:.2f} m high)")


def task_from_look(kind: str, look: LookResult) -> EpcTask:
    """The task (true world frame) from what the robot saw: the handle estimate, the
    detected front's normal, and the bar / side / pull directions by the kind's convention
    (as :func:`make_task`, with the front's horizontal axis for the furniture's +y)."""
    e = look.estimate
    up = np.array([0, 0, 1.0])
    side = {"left_door": e.e_y, "right_door": -e.e_y, "sliding_door": e.e_y}.get(kind, up)
    pull = -side if kind == "sliding_door" else e.normal
    return EpcTask(handle=np.asarray(e.handle, float), normal=e.normal, bar=e.bar, pull=pull,
                   side=side)


def MakeOperateDiagram(config: OperateConfig | None = None, *, meshcat=None) -> Operate:
    """Build the opening-task diagram (see the module docstring).

    Exported outputs: ``mechanism_state``, ``robot_state`` (true), ``phase``, ``status``,
    ``hook_position`` (in the robot's believed world frame), ``force_W`` (true world frame),
    ``estimator_stats``, ``object_model`` (the model the controller uses), ``base_error``
    (believed minus true base x, y, yaw: m, m, rad, of the belief the robot works with:
    ``frame``).

    With ``perception="depth"`` the robot first looks at the mechanism from its start
    (:func:`~mmlearn.diagrams.articulation.operate_perception.LookAtFront`) and is given the handle it
    derived instead of the click; raises :class:`NoFrontDetected` when it found no front.
    """
    cfg = config or OperateConfig()
    cfg.validate()
    rng = np.random.default_rng([cfg.seed, KINDS.index(cfg.kind)])
    if cfg.mechanism is not None:
        spec = cfg.mechanism
    elif cfg.mechanism_seed is not None:
        spec = sample_mechanism(
            cfg.kind, np.random.default_rng([cfg.mechanism_seed, KINDS.index(cfg.kind)]))
    else:
        spec = sample_mechanism(cfg.kind, rng)
    if cfg.mechanism_options:
        from mmlearn.diagrams.articulation.mechanism_dynamics import apply_mechanism_options

        spec = apply_mechanism_options(spec, **cfg.mechanism_options)
    true_task = make_task(spec, rng, cfg.click_error)
    # the robot starts about start_distance in front of the handle, roughly facing it
    n = true_task.normal.copy()
    n[2] = 0
    n /= np.linalg.norm(n)
    lateral = np.array([-n[1], n[0], 0.0]) * rng.uniform(-0.2, 0.2)
    p0 = spec.handle_world(0.0)[0] + cfg.start_distance * n + lateral
    yaw0 = math.atan2(-n[1], -n[0]) + rng.uniform(-0.3, 0.3)
    start = np.array([p0[0], p0[1], yaw0, *ARM_START])
    look = None
    seen_task = true_task
    if cfg.perception == "depth":
        look = LookAtFront(spec, start, config=cfg.look,
                           seed=cfg.seed * len(KINDS) + KINDS.index(cfg.kind))
        if not look.found:
            raise NoFrontDetected(look)
        seen_task = task_from_look(cfg.kind, look)
    # the click is made relative to the robot at its start and stored in its believed
    # world frame (localisation error at time 0): what the robot is told
    loc_cfg = replace(cfg.base_localization.scaled(cfg.base_noise),
                      seed=cfg.seed * len(KINDS) + KINDS.index(cfg.kind))
    e0 = initial_error(loc_cfg)
    base0 = np.array([p0[0], p0[1], yaw0])
    task = EpcTask(handle=believed_from_true(seen_task.handle, base0, e0),
                   normal=rotate_yaw(seen_task.normal, e0[2]),
                   bar=rotate_yaw(seen_task.bar, e0[2]),
                   pull=rotate_yaw(seen_task.pull, e0[2]),
                   side=rotate_yaw(seen_task.side, e0[2]))
    scene = MakeSceneDiagram(cfg.scene_config(spec), meshcat=meshcat)
    plant = scene.plant
    builder = DiagramBuilder()
    sd = builder.AddNamedSystem("scene", scene.diagram)
    force = builder.AddNamedSystem("wrist_force_sensor", WristForceSensor(
        plant=plant, mount_joint=plant.GetJointByName("hook_mount", scene.robot),
        sigma_force=cfg.sigma_force, rate_hz=1.0 / WRIST_PERIOD, seed=cfg.seed,
        noise_samples=cfg.noise_samples()))
    builder.Connect(sd.GetOutputPort("reaction_forces"), force.get_reaction_forces_input_port())
    builder.Connect(sd.GetOutputPort("body_poses"), force.get_body_poses_input_port())
    force_port = force.get_force_output_port()
    estimator = builder.AddNamedSystem("articulation_estimator", ArticulationEstimator(
        mode="pose", pose_size=3, period=cfg.estimator_period, refit_every=cfg.refit_every,
        min_observations=10, max_observations=400,
        obs=ObservationModel(sigma_pos=cfg.sigma_pos), models=tuple(cfg.models),
        seed=cfg.seed, refit_fraction=cfg.estimator_refit_fraction()))
    epc = builder.AddNamedSystem("epc_controller", EpcController(
        plant=plant, robot=scene.robot, task=task, config=cfg.epc,
        command_names=scene.command_names))
    # the robot's software sees its base pose, hence the hook and the wrist force in the
    # world, through its (drifting) localisation; its base commands are realised relative
    # to that belief
    robot_q_starts = sorted(plant.get_joint(j).position_start()
                            for j in plant.GetJointIndices(scene.robot)
                            if plant.get_joint(j).num_positions() == 1)
    base_idx = [robot_q_starts.index(plant.GetJointByName(nm, scene.robot).position_start())
                for nm in ("base_x", "base_y", "base_yaw")]
    loc = builder.AddNamedSystem("base_localization", BaseLocalization(
        config=loc_cfg, base_position_indices=base_idx,
        state_size=plant.num_positions(scene.robot) + plant.num_velocities(scene.robot),
        num_commands=len(scene.command_names), frame=cfg.frame))
    builder.Connect(sd.GetOutputPort("robot_state"), loc.get_robot_state_input_port())
    builder.Connect(force_port, loc.get_force_input_port())
    builder.Connect(loc.get_believed_robot_state_output_port(),
                    epc.get_robot_state_input_port())
    builder.Connect(loc.get_believed_force_output_port(), epc.get_force_input_port())
    model_port = estimator.get_object_model_output_port()
    selector = None
    if cfg.priors:
        selector = builder.AddNamedSystem("prior_model_selector", PriorModelSelector(
            db=PriorDatabase.load(cfg.priors), period=cfg.estimator_period, seed=cfg.seed))
        builder.Connect(epc.get_hook_position_output_port(),
                        selector.get_hook_position_input_port())
        builder.Connect(model_port, selector.get_object_model_input_port())
        model_port = selector.GetOutputPort("object_model")
        builder.ExportOutput(selector.GetOutputPort("prior_cluster"), "prior_cluster")
    builder.Connect(model_port, epc.get_object_model_input_port())
    monitor = None
    if cfg.monitor is not None:
        from mmlearn.models.articulation.evaluation import SUCCESS_ANGLE, SUCCESS_DISTANCE

        revolute = spec.is_revolute
        monitor = builder.AddNamedSystem("dynamics_monitor", DynamicsMonitor(replace(
            cfg.monitor, joint="revolute" if revolute else "prismatic",
            open_enough=SUCCESS_ANGLE if revolute else SUCCESS_DISTANCE,
            pull=[float(x) for x in task.pull])))
        builder.Connect(epc.get_hook_position_output_port(),
                        monitor.get_hook_position_input_port())
        builder.Connect(loc.get_believed_force_output_port(), monitor.get_force_input_port())
        builder.Connect(model_port, monitor.get_object_model_input_port())
        builder.Connect(monitor.get_supervisor_output_port(),
                        epc.get_supervisor_input_port())
        builder.ExportOutput(monitor.get_dynamics_output_port(), "dynamics")
    builder.Connect(epc.get_hook_position_output_port(),
                    estimator.get_pose_input_port())
    # the controller's command interpolated in C++ (the same floats as its own command
    # output): the plant reads it at every step, the segment changes once a period
    interp = builder.AddNamedSystem("command_interpolator", CommandInterpolator(
        len(scene.command_names), epc.period()))
    builder.Connect(epc.get_command_segment_output_port(), interp.get_input_port())
    command = interp.get_output_port()
    builder.Connect(command, loc.get_command_input_port())
    # the localisation's plant_command, added in C++: the offset changes only with the
    # localisation's updates, the command at every plant step
    to_plant = builder.AddNamedSystem("plant_command", Adder(2, len(scene.command_names)))
    builder.Connect(command, to_plant.get_input_port(0))
    builder.Connect(loc.get_command_offset_output_port(), to_plant.get_input_port(1))
    plant_command = to_plant.get_output_port()
    if cfg.monitor is not None:
        # a halt relaxes the arm at once (the robot's measured joint positions as commands)
        cmd_idx = [robot_q_starts.index(plant.GetJointByName(nm, scene.robot).position_start())
                   for nm in scene.command_names]
        gate = builder.AddNamedSystem("halt_gate", HaltGate(
            command_positions=cmd_idx,
            state_size=plant.num_positions(scene.robot) + plant.num_velocities(scene.robot)))
        builder.Connect(plant_command, gate.get_command_input_port())
        builder.Connect(sd.GetOutputPort("robot_state"), gate.get_robot_state_input_port())
        builder.Connect(monitor.get_halted_since_output_port(),
                        gate.get_halted_since_input_port())
        plant_command = gate.GetOutputPort("command")
    builder.Connect(plant_command, sd.GetInputPort("command"))
    if meshcat is not None:
        vis = builder.AddNamedSystem("learned_model_visualizer",
                                     LearnedModelVisualizer(meshcat=meshcat))
        builder.Connect(model_port, vis.get_object_model_input_port())
    builder.ExportOutput(sd.GetOutputPort("mechanism_state"), "mechanism_state")
    builder.ExportOutput(sd.GetOutputPort("robot_state"), "robot_state")
    builder.ExportOutput(epc.GetOutputPort("phase"), "phase")
    builder.ExportOutput(epc.GetOutputPort("status"), "status")
    builder.ExportOutput(epc.get_hook_position_output_port(), "hook_position")
    builder.ExportOutput(force_port, "force_W")
    builder.ExportOutput(estimator.get_stats_output_port(), "estimator_stats")
    builder.ExportOutput(model_port, "object_model")
    builder.ExportOutput(loc.get_error_output_port(), "base_error")
    diagram = builder.Build()
    diagram.set_name("operate")
    if start.size != len(scene.command_names):
        raise RuntimeError(f"the start pose has {start.size} values, the scene's commands "
                           f"are {scene.command_names}")
    return Operate(diagram=diagram, scene=scene, mechanism=spec, task=task, controller=epc,
                   estimator=estimator, force_sensor=force, start_command=start,
                   prior_selector=selector, localization=loc, true_task=true_task,
                   look=look, monitor=monitor)
