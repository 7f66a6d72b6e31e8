"""The Drake trials of tactile recognition and state estimation (thesis ch. 6-7): each a
pure function of its keyword parameters and a seed that returns a JSON-able record, registered
with :func:`~mmlearn.models.common.trials.register_trial` for the sweep runner
(:mod:`mmlearn.apps.common.sweep`), and the plan of each experiment's trials.

* :func:`container_grasp_trial` ("tactile.container_grasp"): one ch. 7 probing grasp of a
  container in an internal state (:mod:`mmlearn.diagrams.tactile.grasp`);
* :func:`object_grasp_trial` ("tactile.object_grasp"): one ch. 6 recognition grasp of an
  object at a commanded height (the tactile observation ``z = (Z_left, Z_right, h, w)``);
* :func:`liquid_roll_trial` ("tactile.liquid_roll"): grasp, lift and roll a container (Sec.
  7.3, :mod:`mmlearn.diagrams.tactile.liquid_roll`).

The ``*_plan`` functions list an experiment's trials as dicts ``{"fn", "seed", "params",
"label"}`` (the fields of :class:`mmlearn.apps.common.sweep.TrialSpec`). The records' metrics
are in :mod:`mmlearn.models.tactile.evaluation`.

**Object grasps** (ch. 6): the scene is
:func:`~mmlearn.diagrams.tactile.grasp.MakeTactileGraspDiagram` (the
:class:`~mmlearn.systems.tactile.sensor.TactileSensor` on both pads, the switching
:class:`~mmlearn.systems.tactile.grasp_controller.TactileGraspController` of Eq. 7.8) with a
wider gripper (:data:`GRIPPER_CH6`: 120 mm opening, for the mug with its handle) and an object
of :mod:`mmlearn.sdf.tactile_objects` welded upright at the origin, as if held in a fixture
(there is no table: the pads may reach below the object's bottom at the lowest grasps). "As
soon as the gripper has established a particular force on the object, the robot stops and
records the tactile image of both of its fingers" (Sec. 6.1): the simulation stops ``settle``
s after both fingers switched to force control (the force ramp is done by then), and the
observation is the last taxel frame (25 Hz) with the finger distance from the encoders (+
noise). A grasp that never feels both fingers within ``max_time`` s is a "no contact" record
(nothing to recognise), not an error.
"""

from __future__ import annotations

import numpy as np

from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import EventStatus

from mmlearn.diagrams.tactile.grasp import (PALM_SLIDE_DAMPING, MakeTactileGraspDiagram,
                                            TactileGraspConfig, simulate_grasp)
from mmlearn.diagrams.tactile.liquid_roll import (LiquidRollConfig, make_instance,
                                                  roll_change_windows, simulate_roll)
from mmlearn.models.common.trials import register_trial
from mmlearn.models.tactile.containers import CONTAINER_CLASSES, sample_container, states_of, \
    vary_grasp
from mmlearn.sdf.tactile import GripperGeometry
from mmlearn.sdf.tactile_objects import CLASSES, class_of, object_sdf, sample_object

__all__ = ["container_grasp_trial", "container_grasp_plan", "SWEEP_FORCES",
           "odwalla_sweep_plan", "object_grasp_trial",
           "object_grasp_plan", "GRIPPER_CH6", "grid_heights", "liquid_roll_trial",
           "liquid_roll_plan"]


# ----------------------------------------------------------------------------- ch. 7 grasps
@register_trial("tactile.container_grasp",
                record={"t": list, "p": list, "f": list, "finger_force": list,
                        "container": str, "state": str})
def container_grasp_trial(*, seed: int, container: str, state: str, f_target: float = 20.0,
                          v_target: float = 0.02, offset_sd: float = 0.001,
                          duration: float = 2.6, hold_time: float = 1.0,
                          palm_slide_damping: float | None = PALM_SLIDE_DAMPING,
                          wall_model: str = "pressure", grasp_variation: str = "wall") -> dict:
    """One ch. 7 probing grasp of a random instance of ``container`` in ``state`` (a pure
    function of its arguments, for :mod:`mmlearn.apps.common.sweep`). The instance (sizes,
    stiffnesses, fill level), its placement (lateral offset ~ N(0, ``offset_sd``) m) and
    the sensor noise are drawn from ``seed``. The gripper centres itself on the container
    (``palm_slide_damping`` N s/m, see :class:`TactileGraspConfig`; None: welded palm, the
    first finger alone squeezes an off-centre container until the second arrives).
    ``wall_model``: "pressure" (default) or "linear" (:class:`TactileGraspConfig`).
    ``grasp_variation``: "wall" (default), "shell" or "none": this grasp's draw of the wall's
    response (or of the shell stiffness alone; none: the instance as drawn) around the
    instance's (:func:`mmlearn.models.tactile.containers.vary_grasp`, the class' measured
    ``grasp_spread``), from its own stream of ``seed`` so the instance, placement and sensor
    noise stay those of the "none" grasp of the same seed. Returns a JSON-able record: the
    recorded series ``t``, ``p``, ``f``, ``finger_force`` (what the features are computed
    from), the labels ``container`` / ``state`` and the instance's parameters (for reference
    only)."""
    rng = np.random.default_rng([int(seed), 13])
    inst = sample_container(container, state, rng)
    offset = float(rng.normal(0.0, offset_sd))
    inst = vary_grasp(inst, np.random.default_rng([int(seed), 29]), mode=grasp_variation)
    cfg = TactileGraspConfig(pad="pr2", f_target=f_target, v_target=v_target,
                             duration=duration, hold_time=hold_time, offset=offset,
                             seed=int(seed), palm_slide_damping=palm_slide_damping,
                             wall_model=wall_model)
    g = simulate_grasp(cfg, container=inst)
    return {"t": g.t.tolist(), "p": g.p.tolist(), "f": g.f.tolist(),
            "finger_force": g.finger_force.tolist(), "container": container, "state": state,
            "f_target": f_target, "offset": offset, "wall_model": wall_model,
            "grasp_variation": grasp_variation, "instance": inst.as_dict()}


def container_grasp_plan(containers, f_target: float, trials: int, seed: int,
                         wall_model: str = "pressure", grasp_variation: str = "wall") -> list[dict]:
    """The grasps of the ch. 7 experiment: ``trials`` grasps of every (container class of
    ``containers``, state) at probing force ``f_target`` N with the walls ``wall_model`` and
    the per-grasp variation ``grasp_variation`` (:func:`container_grasp_trial`), each with its
    own seed derived from ``seed``."""
    specs = []
    for ci, c in enumerate(containers):
        if c not in CONTAINER_CLASSES:
            raise ValueError(f"unknown container {c!r}")
        for si, st in enumerate(states_of(c)):
            for k in range(trials):
                tseed = int(seed) * 1_000_003 + ci * 100_000 + si * 10_000 + k
                params = {"container": c, "state": st, "f_target": float(f_target),
                          "wall_model": wall_model, "grasp_variation": grasp_variation}
                specs.append({"fn": container_grasp_trial, "seed": tseed, "params": params,
                              "label": f"{c}/{st}/{f_target:g}N/{k}"})
    return specs


#: probing forces of the Odwalla sweep (Table 7.2), N
SWEEP_FORCES = (17.0, 20.0, 23.0)


def odwalla_sweep_plan(f_target: float, trials: int, seed: int, wall_model: str = "pressure",
                       grasp_variation: str = "wall") -> list[dict]:
    """The grasps of the Odwalla bottle at probing force ``f_target`` N of the Table 7.2
    sweep (:data:`SWEEP_FORCES`): :func:`container_grasp_plan` on seeds of their own."""
    return container_grasp_plan(["odwalla"], f_target, trials, int(seed) + 7919, wall_model,
                                grasp_variation)


# ----------------------------------------------------------------------------- ch. 6 grasps
#: The gripper of the ch. 6 runs: 120 mm opening (60 mm per finger).
GRIPPER_CH6 = GripperGeometry(open_gap=0.12, stroke=0.06)
#: Height grid step of the grasps (the discretised action of Sec. 6.2), m.
HEIGHT_STEP = 0.01


def grid_heights(cls: str, step: float = HEIGHT_STEP) -> np.ndarray:
    """The grasp heights (m) of class ``cls``: its object's height range on a ``step`` grid
    (absolute, so that the same action means the same height on every object)."""
    from mmlearn.sdf.tactile_objects import OBJECTS

    lo, hi = OBJECTS[class_of(cls).object].heights
    return np.round(np.arange(np.ceil(lo / step - 1e-9), np.floor(hi / step + 1e-9) + 1)
                    * step, 6)


@register_trial("tactile.object_grasp",
                record={"left": list, "right": list, "cls": str, "object": str,
                        "height": float, "force": float})
def object_grasp_trial(*, seed: int, cls: str, height: float, f_target: float = 15.0,
                       v_target: float = 0.08, height_sd: float = 0.0015,
                       offset_sd: float = 0.001, settle: float = 0.3,
                       max_time: float = 3.0, taxel_noise: float = 0.005,
                       contact_force: float = 2.0, meshcat=None, on_diagram=None) -> dict:
    """One grasp of a random instance of class ``cls`` at commanded ``height`` (m, pad
    centre above the object's bottom): a pure function of its arguments (for
    :mod:`mmlearn.apps.common.sweep`). From ``seed``: the instance (:func:`sample_object`), its
    placement (height error ~ N(0, ``height_sd``) m, lateral offset ~ N(0, ``offset_sd``) m)
    and the sensor noise. ``f_target``: grasp force per finger, N; ``v_target``: closing
    speed of the finger distance, m/s; ``contact_force``: the controller's switching
    threshold on each pad's force, N (above what the taxel noise sums to over 84 cells:
    ~0.6 N at ``taxel_noise`` 0.005); ``taxel_noise``: taxel noise, fraction of saturation.
    ``meshcat``: draw the grasp there; ``on_diagram``: called with the built diagram before
    the simulation starts (e.g. to start a Meshcat recording).

    Returns a JSON-able record: ``left`` / ``right`` (14 x 6 readings in [0, 1]),
    ``height`` (the commanded height, what the robot knows), ``width`` (finger distance from
    the encoders, m), ``contact`` (both fingers reached force control), ``sim_time`` (s),
    the labels ``cls`` / ``object`` / ``yaw`` / ``group`` and the instance (reference only;
    never used by the recogniser)."""
    oc = class_of(cls)
    for k, v in (("height", height), ("f_target", f_target), ("v_target", v_target),
                 ("settle", settle), ("max_time", max_time)):
        if not (np.isfinite(v) and v > 0):
            raise ValueError(f"{k}: expected a finite number > 0, got {v!r}")
    rng = np.random.default_rng([int(seed), 61])
    inst = sample_object(oc.object, rng, yaw=oc.yaw)
    dz = float(rng.normal(0.0, height_sd))
    offset = float(rng.normal(0.0, offset_sd))
    cfg = TactileGraspConfig(pad="ch6", f_target=f_target, v_target=v_target,
                             contact_force=contact_force, force_rate=100.0,
                             hold_time=max_time + 10.0, duration=max_time,
                             grasp_height=float(height) + dz, offset=offset,
                             taxel_noise=taxel_noise, seed=int(seed), gripper=GRIPPER_CH6)
    sdf = object_sdf(inst)
    # the SAP solver diverges in ~1 of 300 grasps on the edges of stacked rigid boxes
    # (measured: 2 of 420 grasps, block_hole at 30-40 mm, and 1 of 840 still at half the
    # time step): the same grasp is simulated again at a half, then a quarter of the step
    for k, step in enumerate((1e-3, 0.5e-3, 0.25e-3)):
        cfg.time_step = step
        try:
            sim, ctrl, sensor, t_both = _simulate_object_grasp(cfg, sdf, settle, max_time,
                                                               meshcat, on_diagram)
            break
        except RuntimeError as e:
            if "SAP" not in str(e) or k == 2:
                raise
    root = sim.get_context()
    contact = bool(t_both(root) >= 0)
    sc = sensor.GetMyContextFromRoot(root)
    img = sensor.split(sensor.get_taxels_output_port().Eval(sc))
    grasp = ctrl.get_grasp_output_port().Eval(ctrl.GetMyContextFromRoot(root))
    width = float(grasp[0] + np.random.default_rng([int(seed), 7]).normal(0.0, 5e-5))
    return {"left": np.clip(img["left"], 0, 1).round(5).tolist(),
            "right": np.clip(img["right"], 0, 1).round(5).tolist(),
            "height": float(height), "width": width, "contact": contact,
            "force": float(grasp[2]), "sim_time": float(root.get_time()),
            "time_step": cfg.time_step,
            "cls": cls, "object": oc.object, "yaw": oc.yaw, "group": oc.group,
            "height_error": dz, "offset": offset, "instance": inst.as_dict()}


def _simulate_object_grasp(cfg, sdf, settle, max_time, meshcat, on_diagram):
    """Simulate until ``settle`` s after both fingers switched to force control (or
    ``max_time``); returns (simulator, controller, sensor, t_both(root context))."""
    diagram, parts = MakeTactileGraspDiagram(cfg, object_sdf=sdf, meshcat=meshcat)
    if on_diagram is not None:
        on_diagram(diagram)
    sim = Simulator(diagram)
    ctrl, sensor = parts["controller"], parts["sensor"]

    def t_both(root):  # the controller's state entry 4: time both fingers switched, or -1
        return ctrl.GetMyContextFromRoot(root).get_discrete_state_vector().GetAtIndex(4)

    def monitor(root):
        tb = t_both(root)
        if tb >= 0 and root.get_time() >= tb + settle:
            return EventStatus.ReachedTermination(diagram, "grasp established")
        return EventStatus.DidNothing()

    sim.set_monitor(monitor)
    sim.Initialize()
    sim.AdvanceTo(max_time)
    if parts["taxel_visualizer"] is not None:  # drawn: on a scale fitted to the readings
        tl = parts["taxel_log"].FindLog(sim.get_context())
        parts["taxel_visualizer"].recolor_recording(tl.sample_times(), tl.data().T)
    return sim, ctrl, sensor, t_both


def object_grasp_plan(classes, grasps_per_class: int, *, seed: int,
                      f_target: float = 15.0) -> list[dict]:
    """The grasps of the ch. 6 experiment: grasp j of class c at grid height j mod n (bottom
    to top)."""
    specs = []
    for c in classes:
        ci = list(CLASSES).index(c)
        hs = grid_heights(c)
        for j in range(grasps_per_class):
            h = float(hs[j % len(hs)])
            specs.append({"fn": object_grasp_trial, "seed": int(seed) * 1_000_003 + ci * 1000 + j,
                          "params": {"cls": c, "height": h, "f_target": float(f_target)},
                          "label": f"{c} h={h:.2f} #{j}"})
    return specs


# ----------------------------------------------------------------------------- liquid rolls
@register_trial("tactile.liquid_roll",
                record={"t": list, "taxels": list, "wrist_force": list, "roll": list,
                        "container": str, "liquid": bool})
def liquid_roll_trial(*, seed: int, container: str, offset_sd: float = 0.001,
                      roll_cycles: float = 2.0, roll_profile: str = "sweep") -> dict:
    """One trial for :mod:`mmlearn.apps.common.sweep` (a pure function of its arguments): a random
    instance of ``container`` (see :func:`make_instance`), placed with lateral offset
    ~ N(0, ``offset_sd``) m, grasped, lifted and rolled (``roll_profile``: see
    :class:`LiquidRollConfig`; the triangle with abrupt reversals). Returns a JSON-able record
    with the recorded series (``t``, ``taxels``, ``wrist_force``, ``roll``), the windows, the roll
    command the robot knows (``roll_profile``, ``roll_cycles`` and ``roll_changes``: where
    the commanded rate changes, :func:`roll_change_windows`, None for the sine), the labels
    ``container`` / ``liquid`` and the instance's parameters (for reference only)."""
    rng = np.random.default_rng([int(seed), 17])
    inst = make_instance(container, rng)
    offset = float(rng.normal(0.0, offset_sd))
    # the pad centres at the middle of the wall patches (half the container's height, which
    # the robot sees)
    cfg = LiquidRollConfig(offset=offset, roll_cycles=roll_cycles, seed=int(seed),
                           grasp_height=inst.height / 2, roll_profile=roll_profile,
                           **({"reversal_time": 0.0} if roll_profile == "triangle" else {}))
    r = simulate_roll(cfg, container=inst)
    return {"t": r["t"].tolist(), "taxels": r["taxels"].tolist(),
            "wrist_force": r["wrist_force"].tolist(), "roll": r["roll"].tolist(),
            "roll_window": list(r["roll_window"]), "weight_window": list(r["weight_window"]),
            "roll_profile": roll_profile, "roll_cycles": float(roll_cycles),
            "roll_changes": (roll_change_windows(cfg).tolist() if roll_profile != "sine"
                             else None),
            "rate_hz": cfg.sensor_rate, "container": container,
            "liquid": bool(inst.slosh_mass > 0), "offset": offset,
            "instance": inst.as_dict()}


def liquid_roll_plan(containers, trials: int, *, seed: int, dummy: bool = True,
                     roll_cycles: float = 2.0, roll_profile: str = "sweep") -> list[dict]:
    """The rolls of the liquid-detection experiment: ``trials`` rolls of every container
    label of ``containers`` (and of the rigid dummy unless not ``dummy``)."""
    names = list(containers) + (["dummy"] if dummy else [])
    specs = []
    for k in range(trials):
        for ci, name in enumerate(names):
            specs.append({"fn": liquid_roll_trial,
                          "seed": int(seed) * 1_000_003 + k * 1000 + ci,
                          "params": {"container": name, "roll_cycles": float(roll_cycles),
                                     **({} if roll_profile == "sweep"
                                        else {"roll_profile": roll_profile})},
                          "label": f"{name}/{k}"})
    return specs
