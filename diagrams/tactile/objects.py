"""One ch. 6 recognition grasp in Drake: the parallel gripper with the 14 x 6 taxel pads of
ch. 6 closes on an object of :mod:`mmlearn.sdf.tactile_objects` at a commanded height and
records the tactile observation ``z = (Z_left, Z_right, h, w)`` (thesis Sec. 6.1).

The scene is :func:`mmlearn.diagrams.tactile.grasp.MakeTactileGraspDiagram` (the
:class:`~mmlearn.systems.tactile.sensor.TactileSensor` on both pads, the switching
:class:`~mmlearn.systems.tactile.grasp_controller.TactileGraspController` of Eq. 7.8) with a
wider gripper (:data:`GRIPPER_CH6`: 120 mm opening, for the mug with its handle) and the
object welded upright at the origin, as if held in a fixture (there is no table: the pads
may reach below the object's bottom at the lowest grasps).

"As soon as the gripper has established a particular force on the object, the robot stops
and records the tactile image of both of its fingers" (Sec. 6.1): the simulation stops
``settle`` s after both fingers switched to force control (the force ramp is done by then),
and the observation is the last taxel frame (25 Hz) with the finger distance from the
encoders (+ noise). A grasp that never feels both fingers within ``max_time`` s is a "no
contact" record (nothing to recognise), not an error.
"""

from __future__ import annotations

import numpy as np

from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import EventStatus

from mmlearn.diagrams.tactile.grasp import MakeTactileGraspDiagram, TactileGraspConfig
from mmlearn.sdf.tactile import GripperGeometry
from mmlearn.sdf.tactile_objects import class_of, object_sdf, sample_object
from mmlearn.models.common.trials import register_trial

__all__ = ["GRIPPER_CH6", "object_grasp_trial", "observation_from_record",
           "grid_heights"]

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


@register_trial("tactile.object_grasp")
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
            sim, ctrl, sensor, t_both = _simulate(cfg, sdf, settle, max_time, meshcat,
                                                  on_diagram)
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


def _simulate(cfg, sdf, settle, max_time, meshcat, on_diagram):
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
    return sim, ctrl, sensor, t_both


def observation_from_record(rec: dict):
    """The :class:`~mmlearn.models.tactile.types.TactileObservation` of a trial record
    (label = the record's class)."""
    from mmlearn.models.tactile.types import TactileObservation

    return TactileObservation(rec["left"], rec["right"], rec["height"], rec["width"],
                              rec["cls"])
