"""The tactile grasp scene: a parallel gripper with taxel pads squeezing an object (ch. 6-7).

``MakeTactileGraspDiagram(config)`` wires a discrete MultibodyPlant (1 ms, hydroelastic
contact) with the gripper of :func:`mmlearn.sdf.tactile.gripper_sdf` welded at the commanded
grasp height, an object (a container of :mod:`mmlearn.models.tactile.containers`, welded upright at
the origin as if standing on a table between the open fingers, or none), a
:class:`~mmlearn.systems.tactile.sensor.TactileSensor` on both pads and the
:class:`~mmlearn.systems.tactile.grasp_controller.TactileGraspController` of Eq. 7.8.
``simulate_grasp(config)`` runs one grasp and returns a
:class:`~mmlearn.models.tactile.types.TactileGrasp` built only from the simulated sensors
(finger encoders with noise, taxel pads); the labels are attached afterwards and never
enter a reading.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from pydrake.geometry import SceneGraphConfig
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import (AddMultibodyPlant, MultibodyPlantConfig)
from pydrake.multibody.tree import (FixedOffsetFrame, PdControllerGains, PrismaticJoint,
                                    PrismaticSpring, SpatialInertia)
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput

from mmlearn.models.common.config import param, validate_fields
from mmlearn.models.tactile.containers import ContainerInstance
from mmlearn.models.tactile.pad import PAD_CH6, PAD_PR2, PadLayout
from mmlearn.models.tactile.types import TactileGrasp
from mmlearn.sdf.tactile import GripperGeometry, container_sdf, gripper_sdf, pad_z_of
from mmlearn.systems.tactile.container_wall import ContainerWallForce
from mmlearn.systems.tactile.grasp_controller import TactileGraspController
from mmlearn.systems.tactile.sensor import PadSpec, TactileSensor
from mmlearn.systems.common.wrist_force_sensor import WristForceSensor

__all__ = ["TactileGraspConfig", "MakeTactileGraspDiagram", "simulate_grasp",
           "simulate_contact_force", "AddTactileSensor", "PAD_LAYOUTS", "PALM_SLIDE_DAMPING"]

_APPROX = "sap"
#: damping of the self-centring palm slide in the ch. 7 container grasps, N s/m: the sliding
#: resistance of a free-standing container pushed by the first finger (0.2 N at the fingers'
#: 10 mm/s, below the 1 N contact threshold)
PALM_SLIDE_DAMPING = 20.0
PAD_LAYOUTS = {"pr2": PAD_PR2, "ch6": PAD_CH6}

# pad frame P in the finger body: x_P across, y_P towards the fingertip (-z), z_P inward
_R_LEFT = RotationMatrix(np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]]))
_R_RIGHT = RotationMatrix(np.array([[0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0]]))


@dataclass
class TactileGraspConfig:
    """One grasp.

    When things happen (the switching controller, ``mode="switching"``): the fingers start
    fully open (``gripper.open_gap``, 0.09 m between the pads) and close at ``v_target``, so
    the pads touch an object of width w after about ``(open_gap - w) / v_target`` s (a 7 cm
    block at 0.02 m/s: 1.0 s; a few tens of ms later the pad force passes
    ``contact_force`` and that finger switches to force control). The force then rises at
    ``force_rate`` from ``contact_force`` to ``f_target`` ((20 - 1) / 40 = 0.5 s at the
    defaults) and is held; ``hold_time`` s after *both* fingers switched, the gripper
    releases and the readings fall back to 0. So read the sensor between (touch + rise) and
    (touch + ``hold_time``) -- about 1.5-1.8 s for the 7 cm block at the defaults -- and keep
    ``duration`` beyond the release if you want the whole grasp. The controller's ``grasp``
    output's last entry is the phase (0 closing, 1 both fingers in force control, 2
    releasing); :func:`simulate_grasp` returns the whole time series.

    Attributes:
        pad: taxel layout, "pr2" (ch. 7) or "ch6".
        f_target: probing force per finger, N.
        v_target: closing speed of the finger distance, m/s.
        contact_force: switching threshold F on each pad's force, N.
        kp, kd: finger PD gains, N/m and N s/m.
        force_rate: rise of the commanded force after the switch, N/s.
        hold_time: time between both fingers in force control and the release, s.
        duration: simulated time, s.
        mode: controller mode ("switching", "force", "velocity").
        grasp_height: height of the pad centres above the object's base, m.
        offset: the object's lateral offset from the gripper centre along x, m.
        time_step: plant time step, s.
        sensor_rate: taxel and encoder sampling rate, Hz.
        taxel_noise: taxel noise, fraction of saturation.
        encoder_noise: finger-distance noise, m.
        seed: noise seed.
        gripper: gripper dimensions.
        palm_slide_damping: None (default): the palm is welded at the grasp pose and an
            object placed ``offset`` off-centre is squeezed one-sidedly by the first finger
            until the second arrives. A number (N s/m): the palm hangs on a free horizontal
            slide along the closing direction x with this viscous damping, so the gripper
            centres itself on the object as a parallel gripper does on a free-standing
            container (which slides on the table under the first finger until the second
            touches); the damping stands for that sliding resistance (at 10 mm/s, 20 N s/m
            gives 0.2 N, below the 1 N contact threshold).
        wall_model: how a container's walls resist: "pressure" (default): the shell's linear
            spring plus the content's pressure from the squeeze-volume model
            (:func:`mmlearn.models.tactile.containers.wall_forces`: the gas law of a closed headspace,
            the head and flow resistance of a liquid, all acting through the volume an
            ovalising round container loses, so they grow with the squeeze); "linear": the
            linearised constant stiffness ``ContainerInstance.k`` and damping ``c`` (that of
            the liquid-detection roll).
    """

    pad: str = param("pr2", choices=tuple(PAD_LAYOUTS))
    f_target: float = param(20.0, unit="N", gt=0)
    v_target: float = param(0.02, unit="m/s", gt=0)
    contact_force: float = param(1.0, unit="N", gt=0)
    kp: float = param(2000.0, unit="N/m", ge=0)
    kd: float = param(100.0, unit="N*s/m", ge=0)
    force_rate: float = param(40.0, unit="N/s", gt=0)
    hold_time: float = param(0.8, unit="s", ge=0)
    duration: float = param(3.5, unit="s", gt=0)
    mode: str = param("switching", choices=("switching", "force", "velocity"))
    grasp_height: float = param(0.07, unit="m")
    offset: float = param(0.0, unit="m")
    time_step: float = param(1e-3, unit="s", gt=0)
    sensor_rate: float = param(25.0, unit="Hz", gt=0)
    taxel_noise: float = param(0.003, ge=0)
    encoder_noise: float = param(5e-5, unit="m", ge=0)
    seed: int = param(0, integer=True, ge=0)
    gripper: GripperGeometry = field(default_factory=GripperGeometry)
    palm_slide_damping: float | None = param(None, unit="N*s/m", ge=0, optional=True)
    wall_model: str = param("pressure", choices=("pressure", "linear"))

    def validate(self) -> "TactileGraspConfig":
        """Raise ``ValueError`` naming the first bad field (its type, range or choice, and a
        plant time step that is longer than a sensor frame or than the run); return self."""
        validate_fields(self)
        period = 1.0 / self.sensor_rate
        if self.time_step > period:
            raise ValueError(f"TactileGraspConfig: time_step {self.time_step:g} s is longer "
                             f"than a sensor frame ({period:g} s at sensor_rate "
                             f"{self.sensor_rate:g} Hz): the sensors would sample a plant "
                             "that has not moved")
        if self.time_step > self.duration:
            raise ValueError(f"TactileGraspConfig: time_step {self.time_step:g} s is longer "
                             f"than the run (duration {self.duration:g} s)")
        return self



def AddTactileSensor(builder, plant, scene_graph, gripper, layout: PadLayout, pad_z: float, *,
                     rate_hz: float, noise: float, seed: int) -> TactileSensor:
    """Add a :class:`TactileSensor` named ``tactile_sensor`` over the two finger pads of the
    gripper model instance ``gripper`` (``sdf/tactile.gripper_sdf``: bodies
    ``left_finger`` / ``right_finger``, collision geometries ``*_pad``) of the finalised
    ``plant``, wired to its contact results and body poses.

    Args:
        layout: the pads' cell layout.
        pad_z: height of the pad centres above the finger body origin, m
            (``sdf/tactile.pad_z_of``).
        rate_hz: sensor frame rate, Hz; noise: taxel noise (normalised units); seed: noise seed.
    """
    inspector = scene_graph.model_inspector()
    pads = []
    for side, R in (("left", _R_LEFT), ("right", _R_RIGHT)):
        body = plant.GetBodyByName(f"{side}_finger", gripper)
        gids = tuple(gid for gid in plant.GetCollisionGeometriesForBody(body)
                     if inspector.GetName(gid).endswith(f"{side}_pad"))
        pads.append(PadSpec(side, layout, int(body.index()),
                            RigidTransform(R, [0.0, 0.0, -pad_z]), gids))
    sensor = builder.AddNamedSystem("tactile_sensor", TactileSensor(
        pads=pads, rate_hz=rate_hz, noise=noise, seed=seed))
    builder.Connect(plant.get_contact_results_output_port(),
                    sensor.get_contact_results_input_port())
    builder.Connect(plant.get_body_poses_output_port(), sensor.get_body_poses_input_port())
    return sensor

def MakeTactileGraspDiagram(config: TactileGraspConfig, *, container: ContainerInstance | None = None,
                            object_sdf: str | None = None, meshcat=None):
    """Build the scene; returns (diagram, parts) with parts = {"plant", "scene_graph",
    "sensor", "controller", "grasp_log", "taxel_log", "force_log", "gripper", "container",
    "meshcat_visualizer", "taxel_visualizer"} (the last two None without ``meshcat``; with
    it, the scene and the taxel pads coloured by pressure are drawn, see
    :class:`~mmlearn.systems.tactile.taxel_visualizer.TaxelPadVisualizer`).

    The object is ``container`` (a :class:`ContainerInstance`) or any SDFormat model
    ``object_sdf`` (text; its first link is welded at the origin shifted by ``offset``)."""
    if container is not None and object_sdf is not None:
        raise ValueError("give either container or object_sdf, not both")
    c = config.validate()
    layout: PadLayout = PAD_LAYOUTS[c.pad]
    g = c.gripper
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlant(
        MultibodyPlantConfig(time_step=c.time_step, contact_model="hydroelastic_with_fallback",
                             discrete_contact_approximation=_APPROX),
        SceneGraphConfig(), builder)
    parser = Parser(plant)
    gripper = parser.AddModelsFromString(gripper_sdf(layout, g), "sdf")[0]
    pad_z = pad_z_of(layout, g)
    X_WM = RigidTransform([0.0, 0.0, c.grasp_height + pad_z])
    palm = plant.GetFrameByName("palm", gripper)
    if c.palm_slide_damping is None:
        mount = plant.WeldFrames(plant.world_frame(), palm, X_WM)
    else:
        d_slide = float(c.palm_slide_damping)
        if not (np.isfinite(d_slide) and d_slide >= 0):
            raise ValueError(f"palm_slide_damping: expected a damping >= 0 N s/m or None, "
                             f"got {c.palm_slide_damping!r}")
        # a light carriage in its own model instance (the gripper's state stays the two
        # fingers) slides along x; the palm is welded to it (the wrist sensor's mount)
        inst = plant.AddModelInstance("palm_carriage")
        carriage = plant.AddRigidBody("carriage", inst,
                                      SpatialInertia.SolidBoxWithMass(0.05, 0.02, 0.02, 0.02))
        rail = plant.AddFrame(FixedOffsetFrame("palm_rail", plant.world_frame(), X_WM))
        plant.AddJoint(PrismaticJoint("palm_slide", rail, carriage.body_frame(),
                                      [1.0, 0.0, 0.0], damping=d_slide))
        mount = plant.WeldFrames(carriage.body_frame(), palm, RigidTransform())
    cont = None
    if c.wall_model not in ("pressure", "linear"):
        raise ValueError(f"wall_model: expected 'pressure' or 'linear', got {c.wall_model!r}")
    pressure = container is not None and c.wall_model == "pressure"
    if container is not None:
        # pressure model: the joint keeps the empty wall's damping, the content's flow
        # resistance comes from ContainerWallForce
        sdf_inst = dataclasses.replace(container, c=container.c_wall) if pressure else container
        cont = parser.AddModelsFromString(container_sdf(sdf_inst), "sdf")[0]
        plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("base", cont),
                         RigidTransform([c.offset, 0.0, 0.0]))
        k_spring = container.k_parts["shell"] if pressure else container.k
        for side in ("l", "r"):
            plant.AddForceElement(PrismaticSpring(
                plant.GetJointByName(f"wall_{side}_slide", cont), 0.0, k_spring))
        if container.slosh_mass > 0:
            plant.AddForceElement(PrismaticSpring(plant.GetJointByName("slosh", cont), 0.0,
                                                  container.slosh_k))
    if object_sdf is not None:
        cont = parser.AddModelsFromString(object_sdf, "sdf")[0]
        first = plant.GetBodyIndices(cont)[0]
        plant.WeldFrames(plant.world_frame(), plant.get_body(first).body_frame(),
                         RigidTransform([c.offset, 0.0, 0.0]))
    for side in ("left", "right"):
        act = plant.GetJointActuatorByName(f"{side}_slide", gripper)
        act.set_controller_gains(PdControllerGains(p=c.kp, d=c.kd))
    plant.Finalize()
    wall_force = None
    if pressure:
        joints = [plant.GetJointByName(f"wall_{side}_slide", cont) for side in ("l", "r")]
        wall_force = builder.AddNamedSystem("container_wall_force", ContainerWallForce(
            container=container, num_positions=plant.num_positions(),
            num_velocities=plant.num_velocities(),
            q_index=[j.position_start() for j in joints],
            v_index=[j.velocity_start() for j in joints]))
        builder.Connect(plant.get_state_output_port(), wall_force.get_state_input_port())
        builder.Connect(wall_force.get_generalized_force_output_port(),
                        plant.get_applied_generalized_force_input_port())
    sensor = AddTactileSensor(builder, plant, scene_graph, gripper, layout, pad_z,
                              rate_hz=c.sensor_rate, noise=c.taxel_noise, seed=c.seed)
    ctrl = builder.AddNamedSystem("grasp_controller", TactileGraspController(
        f_target=c.f_target, v_target=c.v_target, contact_force=c.contact_force, kp=c.kp,
        kd=c.kd, hold_time=c.hold_time, open_gap=g.open_gap, stroke=g.stroke, mode=c.mode,
        force_rate=c.force_rate,
        period=c.time_step))
    builder.Connect(plant.get_state_output_port(gripper), ctrl.get_gripper_state_input_port())
    builder.Connect(sensor.get_pad_force_output_port(), ctrl.get_pad_force_input_port())
    builder.Connect(ctrl.get_desired_state_output_port(),
                    plant.get_desired_state_input_port(gripper))
    # wrist force-torque sensor at the palm mount (force on the palm beyond the palm's own
    # weight: the fingers' weight is a constant offset, the grasped object's weight adds)
    wrist = builder.AddNamedSystem("wrist_force_sensor", WristForceSensor(
        plant=plant, mount_joint=mount, sigma_force=0.05, rate_hz=100.0, seed=c.seed))
    builder.Connect(plant.get_reaction_forces_output_port(),
                    wrist.get_reaction_forces_input_port())
    builder.Connect(plant.get_body_poses_output_port(), wrist.get_body_poses_input_port())
    period = 1.0 / c.sensor_rate
    grasp_log = LogVectorOutput(ctrl.get_grasp_output_port(), builder, period)
    taxel_log = LogVectorOutput(sensor.get_taxels_output_port(), builder, period)
    force_log = LogVectorOutput(sensor.get_pad_force_output_port(), builder, period)
    taxel_vis = None
    if meshcat is not None:
        from pydrake.geometry import MeshcatVisualizer

        from mmlearn.systems.tactile.taxel_visualizer import TaxelPadVisualizer

        parts_vis = MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat)
        taxel_vis = builder.AddNamedSystem("taxel_visualizer", TaxelPadVisualizer(
            meshcat=meshcat, pads=sensor.pads, period=period))
        builder.Connect(sensor.get_taxels_output_port(), taxel_vis.get_taxels_input_port())
        builder.Connect(plant.get_body_poses_output_port(),
                        taxel_vis.get_body_poses_input_port())
    diagram = builder.Build()
    return diagram, {"plant": plant, "scene_graph": scene_graph, "sensor": sensor,
                     "wrist_force_sensor": wrist, "container_wall_force": wall_force,
                     "controller": ctrl, "grasp_log": grasp_log, "taxel_log": taxel_log,
                     "force_log": force_log, "gripper": gripper, "container": cont,
                     "meshcat_visualizer": parts_vis if meshcat is not None else None,
                     "taxel_visualizer": taxel_vis}


def simulate_contact_force(config: TactileGraspConfig, *, object_sdf: str,
                           t_end: float | None = None, dt: float = 1e-3):
    """Simulate one grasp of ``object_sdf`` and read the normal contact force per finger (N)
    from the plant's hydroelastic contact results every ``dt`` s up to ``t_end`` s (default
    ``config.duration``): the impact lasts a few ms, the 25 Hz pad force would miss it.

    Returns ``(t, f, simulator, parts)``: times (T,) s, forces (T,) N, and the simulator and
    the diagram's parts at ``t_end`` (for reading the sensor afterwards)."""
    d, parts = MakeTactileGraspDiagram(config, object_sdf=object_sdf)
    sim = Simulator(d)
    sim.Initialize()
    plant = parts["plant"]
    pc = plant.GetMyContextFromRoot(sim.get_context())
    port = plant.get_contact_results_output_port()
    t_end = config.duration if t_end is None else t_end
    ts = np.arange(1, int(round(t_end / dt)) + 1) * dt
    f = np.zeros(len(ts))
    for k, t in enumerate(ts):
        sim.AdvanceTo(float(t))
        cr = port.Eval(pc)
        f[k] = sum(abs(cr.hydroelastic_contact_info(i).F_Ac_W().translational()[0])
                   for i in range(cr.num_hydroelastic_contacts())) / 2.0
    return ts, f, sim, parts


def simulate_grasp(config: TactileGraspConfig, *, container: ContainerInstance | None = None,
                   object_sdf: str | None = None, meshcat=None,
                   label: str | None = None) -> TactileGrasp:
    """Run one grasp and return what the sensors recorded (25 Hz by default): finger
    distance p (encoders + noise), its rate v, the summed pad force f, per-pad forces and
    the taxel images. ``label`` / the container's class and state are attached as labels
    only. With ``meshcat``, the grasp is shown live and recorded (scene and taxel pads; publish
    it with ``meshcat.StaticHtml()``)."""
    diagram, parts = MakeTactileGraspDiagram(config, container=container, object_sdf=object_sdf,
                                             meshcat=meshcat)
    sim = Simulator(diagram)
    vis = parts["meshcat_visualizer"]
    if vis is not None:
        vis.StartRecording(True)
    sim.Initialize()
    sim.AdvanceTo(config.duration)
    ctx = sim.get_context()
    full_scale = 1.0
    if vis is not None:
        tl = parts["taxel_log"].FindLog(ctx)
        # the recording drawn on a scale fitted to this grasp's readings (a firm grasp
        # reads far below saturation: on the sensor's own scale every cell is dark blue)
        full_scale = parts["taxel_visualizer"].recolor_recording(tl.sample_times(),
                                                                 tl.data().T)
        vis.StopRecording()
        vis.PublishRecording()
    gl = parts["grasp_log"].FindLog(ctx)
    tl = parts["taxel_log"].FindLog(ctx)
    fl = parts["force_log"].FindLog(ctx)
    n = min(gl.num_samples(), tl.num_samples(), fl.num_samples())
    t = gl.sample_times()[:n]
    data = gl.data()[:, :n]
    rng = np.random.default_rng([int(config.seed), 7])
    p = data[0] + rng.normal(0.0, config.encoder_noise, n)
    f_pad = np.maximum(fl.data()[:, :n].T, 0.0)
    pads = parts["sensor"].split(tl.data()[:, :n].T)
    kw = {}
    if container is not None:
        kw = {"container": container.name, "state": container.state,
              "label": label or f"{container.name}/{container.state}"}
    elif label is not None:
        kw = {"label": label}
    grasp = TactileGrasp(t=t, p=p, f=f_pad.sum(axis=1), finger_force=f_pad,
                         pads={k: np.clip(v, 0.0, 1.0) for k, v in pads.items()},
                         height=config.grasp_height, **kw)
    if meshcat is not None:
        _frame_and_legend(meshcat, parts, ctx, config, grasp, full_scale)
    return grasp


def _frame_and_legend(meshcat, parts, root_context, config, grasp, full_scale) -> None:
    """Frame the gripper and the object (seen obliquely, so the taxel displays on the
    fingers' outer faces show); draw a legend with the grasp's numbers."""
    from pydrake.geometry import Rgba
    from pydrake.multibody.tree import BodyIndex

    from mmlearn.systems.common.meshcat_view import draw_legend, frame_camera
    from mmlearn.systems.tactile.taxel_visualizer import taxel_colors

    plant = parts["plant"]
    pc = plant.GetMyContextFromRoot(root_context)
    origins = np.array([plant.EvalBodyPoseInWorld(pc, plant.get_body(BodyIndex(b))).translation()
                        for b in range(1, plant.num_bodies())])
    corners = np.array([[x, y, z] for x in (-0.05, 0.05) for y in (-0.05, 0.05)
                        for z in (-0.05, 0.08)])
    frame_camera(meshcat, (origins[:, None, :] + corners[None]).reshape(-1, 3),
                 view_from=(1.0, -0.6, 0.5), min_distance=0.1)
    lo, mid, hi = (Rgba(*c) for c in taxel_colors(np.array([0.0, 0.5, 1.0])))
    k = int(np.argmax(grasp.f))
    what = grasp.label or "the object"
    rows = [(lo, "box", "taxel cell reading 0: each pad's cells, on the finger's outer face"),
            (mid, "box", f"reading {full_scale / 2:.3g}"),
            (hi, "box", f"reading {full_scale:.3g} or more (colour scale 0-{full_scale:.3g}: "
                        "this grasp's largest reading, rounded up; 1 = saturated)"),
            (None, "", "a cell rises with its reading"),
            (None, "", f"peak summed pad force {grasp.f[k]:.1f} N at t = {grasp.t[k]:.2f} s, "
                       f"fingers {1000 * grasp.p[k]:.1f} mm apart"),
            (None, "", "largest cell reading then: " + (", ".join(
                f"{side} {float(np.max(img[k])):.2f}" for side, img in sorted(grasp.pads.items()))
                or "no pads")),
            (None, "", f"controller: {config.mode}, {config.f_target:g} N per finger, "
                       f"{config.v_target * 1000:g} mm/s closing")]
    draw_legend(meshcat, f"Tactile grasp of {what}", rows)
