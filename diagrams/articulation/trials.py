"""The articulation capability's Drake trials: opening a door or drawer while learning its
model (thesis 4.3, 4.4.2), and the structure experiments on simulated objects (thesis 4.4.1,
4.4.3).

:func:`open_mechanism` runs one trial (the robot about 1 m away with a noisy handle location
drives to a stance, hooks the handle and opens the mechanism by equilibrium-point control
while it learns the mechanism's kinematic model online from its hook's trajectory);
:func:`operate_trial` is the same trial registered for the sweep runner
(``articulation.operate``). :func:`structure_trial` (``articulation.structure``) runs one
structure experiment on a simulated object (cabinet, table, car door, garage door) or one
run of the yardstick's (Fig. 4.16-4.18), observed by the ideal marker sensor or through
rendered camera images (:func:`observe`); their tables come from
:func:`mmlearn.models.articulation.evaluation.structure_report`.
"""

from __future__ import annotations

import gc
import math
import os
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mmlearn.models.articulation.evaluation import (SUCCESS_ANGLE, SUCCESS_DISTANCE,
                                                    STRUCTURE_EXPERIMENTS, evaluate_model,
                                                    right_kind, sensor_line, sensor_stats)
from mmlearn.models.articulation.graph import (KinematicGraphEvaluator, fit_pair_models,
                                               fit_structure, search_structure,
                                               spanning_tree_edges)
from mmlearn.models.articulation.incremental import incremental_structure
from mmlearn.models.articulation.link import ObservationModel
from mmlearn.models.articulation.structure import select_link_model
from mmlearn.models.common.se3 import relative_poses
from mmlearn.models.common.progress import progress_bar
from mmlearn.models.common.trials import register_trial
from mmlearn.sdf.mechanisms import KINDS, REVOLUTE
from mmlearn.sdf.user_model import UserMechanism

__all__ = ["open_mechanism", "operate_trial", "scene_points", "draw_look", "SENSORS", "observe",
           "exp_cabinet", "exp_table", "exp_car", "exp_garage", "yardstick_row",
           "dof_progress", "search_vs_n_row", "STRUCTURE_RUNNERS", "structure_trial"]


def scene_points(op) -> np.ndarray:
    """Points (world, m) that the camera must see: the cabinet's corners, the handle over
    the front's whole travel, the robot at its start (its base, the arm up to 1.3 m) and
    its base where it will stand to open the mechanism."""
    spec = op.mechanism
    if isinstance(spec, UserMechanism):
        pts = [spec.corners_world()]
        travel = spec.travel()
    else:
        T = spec.X_WF()
        half = spec.width / 2 + 0.06 if spec.kind != "sliding_door" else spec.width + 0.06
        top = spec.bottom + spec.height + 0.03
        corners_F = np.array([[x, y, z] for x in (-spec.depth, 0.0) for y in (-half, half)
                              for z in (0.0, top)])
        pts = [corners_F @ T[:3, :3].T + T[:3, 3]]
        travel = spec.limit
    pts.append([spec.handle_world(q)[0] for q in np.linspace(0.0, travel, 5)])
    # the mobile base (0.55 m x 0.45 m, 0.3 m high, sdf/builders.py) at its start pose and
    # the arm above it
    x, y, yaw = op.start_command[:3]
    c, s = math.cos(yaw), math.sin(yaw)
    pts.append([[x + c * dx - s * dy, y + s * dx + c * dy, z] for dx in (-0.28, 0.28)
                for dy in (-0.23, 0.23) for z in (0.0, 0.3)])
    pts.append([[x, y, 1.3]])
    # ... and where it will stand, about 0.8 m in front of the handle and up to 0.3 m to
    # its side (EpcConfig.stance_distance, stance_side), at any yaw (half-diagonal 0.36 m)
    h, n = op.true_task.handle, op.true_task.normal
    n = np.array([n[0], n[1], 0.0]) / max(np.hypot(n[0], n[1]), 1e-9)
    side = np.array([-n[1], n[0], 0.0])
    for off in (-0.3, 0.3):
        c = np.array([h[0], h[1], 0.0]) + 0.8 * n + off * side
        pts.append([c + [dx, dy, z] for dx in (-0.36, 0.36) for dy in (-0.36, 0.36)
                    for z in (0.0, 0.3)])
    return np.concatenate([np.asarray(p, float) for p in pts])


def draw_look(meshcat, look) -> None:
    """The front the robot chose (its outline), the handle it derived (a sphere) and the
    head camera's position, in the true world frame."""
    from pydrake.geometry import Rgba, Sphere
    from pydrake.math import RigidTransform

    c = look.estimate.front.corners()
    meshcat.SetLineSegments("perception/front", c.T, np.roll(c, -1, axis=0).T, 3.0,
                            Rgba(0.1, 0.8, 0.1, 1))
    meshcat.SetObject("perception/handle", Sphere(0.015), Rgba(0.9, 0.1, 0.1, 1))
    meshcat.SetTransform("perception/handle", RigidTransform(look.estimate.handle))
    meshcat.SetObject("perception/camera", Sphere(0.03), Rgba(0.1, 0.1, 0.1, 1))
    meshcat.SetTransform("perception/camera", RigidTransform(look.X_WC[:3, 3]))


def open_mechanism(*, kind: str = "left_door", seed: int = 0, meshcat=None,
                   max_time: float = 60.0, sigma_pos: float | None = None,
                   show_progress: bool = True, realtime: bool = False, priors: str = "",
                   mechanism_seed: int | None = None, save_track: str = "",
                   base_noise: float | None = None, perception: str = "click",
                   on_built=None, model: str = "", joint: str = "",
                   model_pose=None, handle=None, mechanism_options: dict | None = None,
                   save_model: str = "", learn_dynamics: bool | None = None) -> dict:
    """One opening trial: the robot drives to the mechanism ``kind``, hooks its handle and
    opens it while learning its model (thesis 4.3, 4.4.2); returns the trial's record.

    Success is the thesis' criterion on the largest opening reached: more than 60 deg or
    0.3 m (``final_opening`` is the opening after the hook let go). ``right_kind`` says
    whether the model at the end was the right kind (revolute for doors, prismatic for
    drawers and sliding doors) and ``right_model_at`` the opening from which it held.

    ``sigma_pos``: position noise the estimator assumes, m (None = OperateConfig's 0.05);
    ``base_noise``: scale of the base-localisation and odometry error (None = 1, the
    defaults of ``BaseLocalizationConfig``; 0 = the base pose is known exactly);
    ``priors``: prior database to use (see ``learn_priors``); ``mechanism_seed``: fix the
    mechanism's geometry while ``seed`` varies the click and the start; ``save_track``:
    write the hook trajectory the model was learned from (x y z per line, in the robot's
    believed world frame); ``perception``: "click" (the robot is told the handle within
    2 cm) or "depth" (it looks with its head depth camera first and derives the handle from
    the detected front; a trial without a front is a failed trial, outcome "no front
    detected").

    The result holds ``perception``, ``front_found`` (always True for a click),
    ``handle_error_m`` (distance of the handle position the robot used from the true one,
    m, before its localisation error) and, for "depth", ``handle_source`` ("bar": from the
    bar's points, "rectangle": by the kind's convention), ``frames_found`` and
    ``look_frames``.

    ``model``, ``joint``: open the joint ``joint`` of the user's model file (SDFormat or
    URDF, :func:`mmlearn.sdf.user_model.load_user_mechanism`; ``kind`` and
    ``mechanism_seed`` are then not used), placed at ``model_pose`` ("x y z roll pitch yaw"
    or a 4x4 transform of the model frame; None = the default placement) with the handle at
    ``handle`` ("x y z" or a point in the model frame; None = from the geometry); the
    record's ``object`` is then ``file:joint`` and ``true_joint`` holds the joint as the
    file gives it (:meth:`~mmlearn.sdf.user_model.UserMechanism.true_joint`). A model the
    robot cannot operate raises :class:`~mmlearn.sdf.user_model.UserModelError`.

    ``learn_dynamics``: run the dynamics monitor
    (:class:`~mmlearn.systems.articulation.jam_monitor.DynamicsMonitor`: it learns the
    mechanism's damping, friction and spring while pulling, varying the pulling speed, and
    stops the pull at a jam or a latch); None = when ``mechanism_options`` or ``save_model``
    are given. Without it the record's dynamics fields are empty (``learned`` false).

    ``mechanism_options``: the mechanism's true dynamics, a jam or a latch
    (:func:`~mmlearn.diagrams.articulation.mechanism_dynamics.apply_mechanism_options`:
    damping, friction, spring, jam_at in rad or m, locked); the record's ``dynamics`` holds
    them (``true``) beside what the robot learned (``learned``: damping, friction,
    stiffness, their deviations, the friction profile along q, the force predicted for the
    second half of the pull against the measured one), ``jammed_at`` (the opening where a
    jam stopped the pull, in the record's unit), ``peak_force_N`` (the largest wrist force
    held for 0.1 s, one control period, while the hook held the handle) and
    ``peak_force_impact_N`` (the largest sample, with the spike of an impact). ``save_model``: write the learned model with
    its dynamics (.sdf, or .json / .yaml: the project's model format).

    ``meshcat``: draw the scene there and record the trial (published at the end);
    ``on_built(op)``: called with the built :class:`Operate` before the simulation starts
    (e.g. to point the viewer's camera); ``realtime``: pace the simulation at real time."""
    from mmlearn.diagrams.articulation.operate import MakeOperateDiagram
    from mmlearn.diagrams.articulation.operate_perception import NoFrontDetected

    cfg = _operate_config(kind=kind, seed=seed, max_time=max_time, sigma_pos=sigma_pos,
                          priors=priors, mechanism_seed=mechanism_seed, base_noise=base_noise,
                          perception=perception)
    if model:
        from mmlearn.diagrams.articulation.operate import check_reach
        from mmlearn.sdf.user_model import load_user_mechanism, user_model_args

        cfg.mechanism = load_user_mechanism(model, joint, **user_model_args(model_pose, handle))
        cfg.kind = cfg.mechanism.kind
        check_reach(cfg.mechanism)
        kind = cfg.mechanism.name
    cfg.mechanism_options = dict(mechanism_options or {})
    if learn_dynamics or (learn_dynamics is None and (cfg.mechanism_options or save_model)):
        from mmlearn.systems.articulation.jam_monitor import DynamicsMonitorConfig

        cfg.monitor = DynamicsMonitorConfig()
    t_build = time.perf_counter()
    try:
        op = MakeOperateDiagram(cfg, meshcat=meshcat)
    except NoFrontDetected as e:
        return _no_front_record(cfg, e.look)
    # the process' one-time costs of the estimator's refits (loading their compiled
    # kernels) are paid here, with the build, not by the simulation's first refit
    op.estimator.warm_up()
    build_seconds = time.perf_counter() - t_build
    if meshcat is not None and op.look is not None:
        draw_look(meshcat, op.look)
    if on_built is not None:
        on_built(op)
    run = _simulate(op, max_time=max_time, realtime=realtime, show_progress=show_progress,
                    label=f"{kind} seed {seed}")
    result = _trial_record(op, cfg, run, build_seconds=build_seconds, save_track=save_track)
    _add_dynamics(result, op, cfg, run, save_model)
    vis = op.scene.visualizer
    if vis is not None:
        vis.StopRecording()
        vis.PublishRecording()
    return result


def _operate_config(*, kind, seed, max_time, sigma_pos, priors, mechanism_seed, base_noise,
                    perception):
    """The :class:`OperateConfig` of one trial (checks the arguments)."""
    from mmlearn.diagrams.articulation.operate import PERCEPTIONS, OperateConfig

    if kind not in KINDS:
        raise ValueError(f"object must be one of {', '.join(KINDS)}; got {kind!r}")
    if not (max_time > 0 and math.isfinite(max_time)):
        raise ValueError(f"max_time must be a finite number of seconds > 0, got {max_time}")
    if perception not in PERCEPTIONS:
        raise ValueError(f"perception must be one of {', '.join(PERCEPTIONS)}; got "
                         f"{perception!r}")
    cfg = OperateConfig(kind=kind, seed=seed, priors=priors, mechanism_seed=mechanism_seed,
                        perception=perception)
    if sigma_pos is not None:
        cfg.sigma_pos = sigma_pos
    if base_noise is not None:
        cfg.base_noise = base_noise
    return cfg


def _object_name(cfg) -> str:
    return cfg.mechanism.name if isinstance(cfg.mechanism, UserMechanism) else cfg.kind


def _user_fields(cfg) -> dict:
    """A user model's own fields of the record."""
    m = cfg.mechanism
    if not isinstance(m, UserMechanism):
        return {}
    return {"model": m.path, "joint": m.joint, "equivalent_kind": m.kind,
            "true_joint": m.true_joint()}


def _add_dynamics(result: dict, op, cfg, run, save_model: str) -> None:
    """The record's dynamics fields (see :func:`open_mechanism`); writes ``save_model``."""
    from mmlearn.diagrams.articulation.mechanism_dynamics import (dynamics_record,
                                                                  save_learned_model)

    to_unit = math.degrees if op.mechanism.is_revolute else float
    d = dynamics_record(op, run.ctx, to_unit, cfg.mechanism_options)
    dyn = d.pop("learned_dynamics", None)
    result.update(d)
    result["model_saved"] = None
    if save_model:
        est = op.estimator.GetMyContextFromRoot(run.ctx).get_abstract_state(0).get_value()
        if est.model is not None:
            result["model_saved"] = save_learned_model(save_model, est.model, dyn)


def _no_front_record(cfg, look) -> dict:
    """The record of a trial whose robot saw no front it could open (nothing simulated)."""
    kind = cfg.kind
    return {"object": _object_name(cfg), "seed": cfg.seed, **_user_fields(cfg), "success": False, "opened": 0.0,
            "final_opening": 0.0, "unit": "deg" if kind in REVOLUTE else "m",
            "outcome": "no front detected",
            "perception": cfg.perception, "front_found": False, "handle_error_m": None,
            "handle_source": None, "frames_found": look.frames_found,
            "look_frames": look.frames, "learned_model": None, "right_kind": False,
            "base_noise": cfg.base_noise, "sigma_pos": cfg.sigma_pos,
            "track_saved": None, "sim_seconds": 0.0, "wall_seconds": 0.0,
            "cpu_seconds": 0.0,
            "true_kind": ("revolute" if kind in REVOLUTE else "prismatic")
            if not isinstance(cfg.mechanism, UserMechanism) else cfg.mechanism.joint_type,
            "html_out": None}


@dataclass
class _Run:
    """What the simulation of one trial left: its root context, the last phase, the largest
    opening reached (rad or m), the model log (time, true opening in the record's unit, kind
    of the model the controller is given; every 0.25 s from the start of the pull), the
    base-localisation errors (m), the wall time and the process' CPU time (s)."""

    ctx: object
    phase: int
    q_max: float
    model_log: list
    base_err: list
    wall: float
    cpu: float = 0.0


def _simulate(op, *, max_time, realtime, show_progress, label) -> _Run:
    """Simulate the operate diagram ``op`` until the controller is done or ``max_time``."""
    from pydrake.systems.analysis import Simulator

    from mmlearn.systems.articulation.epc_controller import DONE, PHASE_NAMES, PULL

    d = op.diagram
    simulator = Simulator(d)
    ctx = simulator.get_mutable_context()
    op.scene.set_joint_positions(ctx, op.start_command)
    if realtime:
        simulator.set_target_realtime_rate(1.0)
    if op.scene.visualizer is not None:
        op.scene.visualizer.StartRecording(False)
    simulator.Initialize()
    # the objects alive now (the modules, the diagram) are never garbage: keep the
    # collector from traversing them again and again while the Python systems allocate
    gc.collect()
    gc.freeze()
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        bar = progress_bar(int(max_time), label, unit="sim s", enabled=show_progress)
        to_unit = math.degrees if op.mechanism.is_revolute else float
        opening, model_port = d.GetOutputPort("mechanism_state"), d.GetOutputPort("object_model")
        run = _Run(ctx=ctx, phase=0, q_max=0.0, model_log=[], base_err=[], wall=0.0)
        while ctx.get_time() < max_time - 1e-9:
            simulator.AdvanceTo(min(max_time, ctx.get_time() + 0.25))
            bar.update(0.25)
            bar.set_postfix_str(PHASE_NAMES[run.phase])
            run.phase = int(d.GetOutputPort("phase").Eval(ctx)[0])
            # the largest opening reached (the thesis: "opened it through ...")
            run.q_max = max(run.q_max, float(opening.Eval(ctx)[0]))
            run.base_err.append(float(np.hypot(*d.GetOutputPort("base_error").Eval(ctx)[:2])))
            if run.phase >= PULL:
                m = model_port.Eval(ctx)
                run.model_log.append((round(float(ctx.get_time()), 3),
                                      to_unit(float(opening.Eval(ctx)[0])),
                                      m.edges[0].model.name if m is not None and m.edges
                                      else None))
            if run.phase == DONE:
                break
        bar.close()
    finally:
        gc.unfreeze()
    run.wall, run.cpu = time.perf_counter() - t0, time.process_time() - c0
    return run


def _save_track(path, track, *, kind, seed) -> None:
    from mmlearn.models.common.fileio import atomic_write_text

    atomic_write_text(path, f"# hook trajectory, {kind}, seed {seed} (x y z, m)\n"
                      + "\n".join(" ".join(f"{v:.6f}" for v in row) for row in track) + "\n")


def _trial_record(op, cfg, run: _Run, *, build_seconds, save_track) -> dict:
    """The record of a simulated trial (see :func:`open_mechanism`)."""
    from mmlearn.systems.articulation.epc_controller import P_HOOK_GRIP, PHASE_NAMES

    ctx, spec = run.ctx, op.mechanism
    q = float(op.diagram.GetOutputPort("mechanism_state").Eval(ctx)[0])
    to_unit = math.degrees if spec.is_revolute else float
    est_state = op.estimator.GetMyContextFromRoot(ctx).get_abstract_state(0).get_value()
    obj = est_state.model
    link = obj.edges[0].model if obj is not None else None
    track = est_state.poses[:, 1, :3] if est_state.poses.shape[0] else np.zeros((0, 3))
    ctrl = op.controller.state(op.controller.GetMyContextFromRoot(ctx))
    q_max = max(run.q_max, q)
    if spec.is_revolute:
        opened, unit, success = math.degrees(q_max), "deg", q_max > SUCCESS_ANGLE
    else:
        opened, unit, success = q_max, "m", q_max > SUCCESS_DISTANCE
    result = {"object": _object_name(cfg), "seed": cfg.seed, **_user_fields(cfg),
              "success": bool(success), "opened": opened,
              "final_opening": to_unit(q),
              "unit": unit, "outcome": ctrl.outcome or PHASE_NAMES[run.phase]}
    result.update(evaluate_model(link, spec))
    # the span of the track the final model was fitted to, on that model (what the legend
    # of the recording shows; "opened" is the mechanism's largest true opening)
    dof = getattr(link, "dof", 0) if link is not None else 0
    result["model_span"] = (to_unit(float(link.q_max[0] - link.q_min[0]))
                            if dof and link.name in ("revolute", "prismatic") else None)
    look = op.look
    used = (look.estimate.handle if look is not None else op.true_task.handle)
    result.update({"perception": cfg.perception, "front_found": True,
                   "handle_error_m": float(np.linalg.norm(used - spec.handle_world(0.0)[0])),
                   "handle_source": None if look is None else look.estimate.source,
                   "frames_found": None if look is None else look.frames_found,
                   "look_frames": None if look is None else look.frames,
                   "build_seconds": round(build_seconds, 3)})
    # the model's kind over the trial, and the opening from which the final right kind held
    right = "revolute" if spec.is_revolute else "prismatic"
    ok, right_at = right_kind(run.model_log, right)
    result.update({"right_kind": ok, "right_model_at": right_at, "true_kind": right,
                   "model_log": run.model_log,
                   "base_noise": cfg.base_noise, "sigma_pos": cfg.sigma_pos,
                   "base_error_max_m": max(run.base_err) if run.base_err else 0.0})
    if cfg.priors:
        result["priors"] = cfg.priors
    result["track_saved"] = None
    if save_track and track.shape[0]:
        result["track_saved"] = save_track
        _save_track(save_track, track, kind=cfg.kind, seed=cfg.seed)
    t, wall = float(ctx.get_time()), run.wall
    # the point of the hook that held the handle: its seat, or its finger's tip on a knob
    result["hook_grip"] = ("tip" if ctrl.grip.size == 3 and not np.allclose(ctrl.grip, P_HOOK_GRIP)
                           else "seat")
    result.update({"estimated_opening": ctrl.opening, "track_length": int(track.shape[0]),
                   "sim_seconds": t, "wall_seconds": round(wall, 3),
                   "realtime_factor": round(float(ctx.get_time() / wall), 2),
                   "cpu_seconds": round(run.cpu, 3),
                   "html_out": None})
    return result


_PRIORS_FILES: dict = {}  # a worker's copy of the shared prior database, written once


def _priors_file(text: str) -> str:
    """The sweep's prior database (sent once per worker as text) as a local file."""
    import hashlib
    import tempfile

    h = hashlib.sha1(text.encode()).hexdigest()[:16]
    if h not in _PRIORS_FILES:
        from mmlearn.models.common.fileio import atomic_write_text

        p = Path(tempfile.gettempdir()) / f"mmlearn-priors-{os.getpid()}-{h}.json"
        atomic_write_text(p, text)
        _PRIORS_FILES[h] = str(p)
    return _PRIORS_FILES[h]


@register_trial("articulation.operate", version=7,
                record={"object": str, "seed": int, "success": bool, "opened": (float, None),
                        "unit": str, "outcome": str, "learned_model": (str, None)})
def operate_trial(*, seed: int, kind: str, max_time: float = 60.0,
                  sigma_pos: float | None = None, mechanism_seed: int | None = None,
                  base_noise: float | None = None, save_track: str = "", priors_sha1: str = "",
                  shared=None, perception: str = "click", model: str = "", joint: str = "",
                  model_pose: str | None = None, handle: str | None = None) -> dict:
    """One opening trial of a sweep: :func:`open_mechanism` of one object and seed (or of
    the joint ``joint`` of the user's model file ``model``, see :func:`open_mechanism`).
    ``shared`` is the prior database's text when the sweep uses one (``priors_sha1`` names
    it in the trial's identity)."""
    priors = _priors_file(shared) if shared else ""
    return open_mechanism(kind=kind, seed=seed, max_time=max_time, sigma_pos=sigma_pos,
                          priors=priors, mechanism_seed=mechanism_seed, show_progress=False,
                          save_track=save_track, base_noise=base_noise, perception=perception,
                          model=model, joint=joint, model_pose=model_pose, handle=handle)


# ---------------------------------------------------------------------------- structure

PARAMETRIC = ("rigid", "prismatic", "revolute")
SENSORS = ("ideal", "camera")


def observe(track, sensor: str = "ideal", camera=None):
    """The scenario's track as ``sensor`` reports it: "ideal" = as generated (Gaussian
    noise), "camera" = rendered and read by the camera marker sensor
    (:func:`mmlearn.diagrams.common.object_tracks.camera_track`, ``camera`` its
    CameraMarkerSensorConfig, None = one automatic 1920 x 1440 camera; NaN rows where a
    marker was not detected)."""
    if sensor == "ideal":
        return track
    if sensor != "camera":
        raise ValueError(f"sensor must be one of {', '.join(SENSORS)}, got {sensor!r}")
    from mmlearn.diagrams.common.object_tracks import camera_track

    return camera_track(track, camera)


def _with_sensor(res, lines, track, sensor):
    if sensor != "ideal":
        res["sensor_stats"] = sensor_stats(track)
        lines.append(sensor_line(track.name, res["sensor_stats"]))
    return res, lines


def _relative(track, i=0, j=1) -> np.ndarray:
    """(T, 7) relative poses of part j in part i, NaN rows where either is missing."""
    a, b = track.poses[i], track.poses[j]
    ok = np.isfinite(a).all(axis=1) & np.isfinite(b).all(axis=1)
    Z = np.full((a.shape[0], 7), np.nan)
    if ok.any():
        Z[ok] = relative_poses(a[ok], b[ok]).as_array()
    return Z


def exp_cabinet(*, quick, seed, progress, sensor="ideal"):
    from mmlearn.diagrams.common.object_tracks import cabinet_scenario

    tr = observe(cabinet_scenario(20, 20 if quick else 40, rng=seed), sensor)
    obs = ObservationModel(sigma_pos=0.01, sigma_orient=np.deg2rad(2))
    hist = incremental_structure(tr.poses, tr.parts, refit_every=5, obs=obs, rng=seed,
                                 models=PARAMETRIC if quick else ("rigid", "prismatic",
                                                                  "revolute", "gp"))
    rows = [{"n": s.n, "edges": [list(e) for e in s.edges], "dof": s.dof} for s in hist]
    lines = ["Fig. 4.8  two-drawer cabinet (lower drawer alone for 20 samples, then both)",
             "   n  dof  structure"]
    for r in rows:
        lines.append(f"{r['n']:4d}  {r['dof']:3d}  " + ", ".join(
            f"{m}({a},{b})" for a, b, m in r["edges"]))
    return _with_sensor({"rows": rows}, lines, tr, sensor)


def exp_table(*, quick, seed, progress, sensor="ideal"):
    from mmlearn.diagrams.common.object_tracks import table_phases, table_scenario

    m = 12 if quick else 20
    tr = observe(table_scenario(m, rng=seed), sensor)
    names = ["still", "line", "curve", "free"]
    ends = np.cumsum([table_phases(m)[k] for k in names])
    obs = ObservationModel(sigma_pos=0.01, sigma_orient=np.deg2rad(2))
    models = ("rigid", "prismatic", "revolute", "gp", "gp2")
    Z = _relative(tr)
    rows = []
    # every 5 samples and at the end of each phase
    steps = sorted(set(range(5, Z.shape[0] + 1, 5)) | {int(e) for e in ends})
    bar = progress_bar(len(steps), "table", enabled=progress)
    rng = np.random.default_rng(seed)
    for n in steps:
        phase = names[int(np.searchsorted(ends, n))]
        Zn = Z[:n][np.isfinite(Z[:n]).all(axis=1)]  # the samples the sensor saw
        if len(Zn) < 5:
            rows.append({"n": n, "phase": phase, "selected": None, "bic": {}, "seen": len(Zn)})
            bar.update(1)
            continue
        s = select_link_model(Zn, models=models, obs=obs, rng=rng, n_hypotheses=60)
        rows.append({"n": n, "phase": phase, "selected": s.selected,
                     "bic": {k: (v if math.isfinite(v) else None) for k, v in s.bic.items()},
                     "seen": len(Zn)})
        bar.update(1)
    bar.close()
    lines = ["Fig. 4.9  table pushed on the floor (phases end at n = %s)" % ", ".join(
        str(int(e)) for e in ends),
             "   n  phase  selected  " + "  ".join(f"{k:>8s}" for k in models)]
    for r in rows:
        lines.append(f"{r['n']:4d}  {r['phase']:5s}  {r['selected'] or '-':8s}  " + "  ".join(
            f"{r['bic'][k]:8.0f}" if r["bic"].get(k) is not None else "       -"
            for k in models))
    return _with_sensor({"rows": rows, "sequence": _sequence(
        [r["selected"] for r in rows if r["selected"] is not None])}, lines, tr, sensor)


def _sequence(names):
    out = []
    for n in names:
        if not out or out[-1] != n:
            out.append(n)
    return out


def exp_car(*, quick, seed, progress, sensor="ideal"):
    from mmlearn.diagrams.common.object_tracks import car_door_scenario

    tr = observe(car_door_scenario(30 if quick else 40, 30 if quick else 40, rng=seed), sensor)
    obs = ObservationModel(sigma_pos=0.005, sigma_orient=np.deg2rad(1))
    hist = incremental_structure(tr.poses, tr.parts, refit_every=10, obs=obs, rng=seed,
                                 models=PARAMETRIC, search="local")
    rows = []
    for s in hist:
        r = s.result
        radius = None
        for (i, j) in r.best.edges:
            if "window" in (tr.parts[i], tr.parts[j]) and r.best.models[(i, j)] == "revolute":
                radius = float(r.pair_models[(i, j)].best.radius)
        rows.append({"n": s.n, "edges": [list(e) for e in s.edges], "dof": s.dof,
                     "window_radius_m": radius})
    lines = ["Fig. 4.11  car door + window on a curved guide (true r = 1.9 m)",
             "   n  dof  window r [m]  structure"]
    for r in rows:
        rr = f"{r['window_radius_m']:.2f}" if r["window_radius_m"] is not None else "-"
        lines.append(f"{r['n']:4d}  {r['dof']:3d}  {rr:>12s}  " + ", ".join(
            f"{m}({a},{b})" for a, b, m in r["edges"]))
    return _with_sensor({"rows": rows}, lines, tr, sensor)


def exp_garage(*, quick, seed, progress, sensor="ideal"):
    from mmlearn.diagrams.common.object_tracks import garage_door_scenario

    tr = observe(garage_door_scenario(40 if quick else 60, rng=seed), sensor)
    obs = ObservationModel(sigma_pos=0.01, sigma_orient=np.deg2rad(2))
    Z = _relative(tr)
    Z = Z[np.isfinite(Z).all(axis=1)]
    if len(Z) < 5:
        return _with_sensor({"selected": None, "bic": {}, "avg_pos_error_m": None,
                             "seen": len(Z)},
                            [f"Roll-up garage door: {len(Z)} samples seen, nothing selected"],
                            tr, sensor)
    s = select_link_model(Z, obs=obs, rng=seed)
    res = {"selected": s.selected,
           "bic": {k: (v if math.isfinite(v) else None) for k, v in s.bic.items()},
           "avg_pos_error_m": float(s.best.avg_pos_error_), "seen": len(Z)}
    lines = ["Roll-up garage door: selected " + s.selected + "  (BIC " + ", ".join(
        f"{k} {v:.0f}" for k, v in s.bic.items() if math.isfinite(v)) + ")"]
    return _with_sensor(res, lines, tr, sensor)


def _yardstick_obs():
    return ObservationModel(sigma_pos=0.005, sigma_orient=np.deg2rad(3))


def yardstick_row(*, closed: bool, seed: int, n: int, sensor: str = "ideal") -> dict:
    """One yardstick run of Fig. 4.16 (a trial): the open chain (3 hinges) or the closed
    loop (4 links) with ``n`` samples, fitted with the spanning tree, the local and the
    exhaustive search (DOF reduction on); BICs, DOFs, run times [s] and graphs visited."""
    from mmlearn.diagrams.common.object_tracks import yardstick_scenario

    obs = _yardstick_obs()
    tr = observe(yardstick_scenario(closed, n, rng=seed), sensor)
    t0, c0 = time.perf_counter(), time.process_time()
    pm = fit_pair_models(tr.poses, obs=obs, rng=seed)
    t_pairs, c_pairs = time.perf_counter() - t0, time.process_time() - c0
    res = {}
    for search in ("tree", "local", "exhaustive"):
        res[search] = fit_structure(tr.poses, part_names=tr.parts, search=search,
                                    reduce_dofs=True, obs=obs, pair_models=pm)
    rl, rx = res["local"], res["exhaustive"]
    chain = [(0, 1), (1, 2), (2, 3)] + ([(0, 3)] if closed else [])
    true_graph = KinematicGraphEvaluator(tr.poses, pm, obs=obs).evaluate(
        chain, reduce_dofs=True)
    row = {
        "closed": closed, "seed": seed, "n": n,
        "dof_local": rl.best.dof, "dof_exhaustive": rx.best.dof,
        "dof_tree": res["tree"].best.dof,
        "edges_local": [[tr.parts[i], tr.parts[j], rl.best.models[(i, j)]]
                        for i, j in rl.best.edges],
        "has_loop": rl.best.has_loop,
        "bic_tree": res["tree"].best.bic, "bic_local": rl.best.bic,
        "bic_exhaustive": rx.best.bic,
        "gap_local_pct": 100 * (rl.best.bic - rx.best.bic) / abs(rx.best.bic),
        "gap_tree_pct": 100 * (res["tree"].best.bic - rx.best.bic) / abs(rx.best.bic),
        "local_optimal": bool(abs(rl.best.bic - rx.best.bic) < 1e-6),
        "bic_true_graph": true_graph.bic, "dof_true_graph": true_graph.dof,
        "fit_seconds": t_pairs,
        "search_seconds_local": rl.search_seconds,
        "search_seconds_exhaustive": rx.search_seconds,
        "fit_cpu_seconds": c_pairs,
        "search_cpu_seconds_local": rl.search_cpu_seconds,
        "search_cpu_seconds_exhaustive": rx.search_cpu_seconds,
        "graphs_local": len(rl.evaluated), "graphs_exhaustive": len(rx.evaluated),
    }
    if sensor != "ideal":
        row["sensor_stats"] = sensor_stats(tr)
    return row


def dof_progress(*, closed: bool, seed: int, quick: bool, sensor: str = "ideal") -> list:
    """Fig. 4.17 for one yardstick (a trial): the open chain opened segment by segment or the
    closed loop; [n, estimated DOFs] every 20 samples."""
    from mmlearn.diagrams.common.object_tracks import yardstick_scenario

    n, step = (80, 20) if quick else (200, 20)
    obs = _yardstick_obs()
    tr = observe(yardstick_scenario(closed, n, staged=not closed, rng=seed), sensor)
    dofs = []
    for m in range(step, n + 1, step):
        r = fit_structure(tr.poses[:, :m], search="local", reduce_dofs=True, obs=obs,
                          rng=seed, models=PARAMETRIC if quick else
                          ("rigid", "prismatic", "revolute", "gp"))
        dofs.append([m, r.best.dof])
    return dofs


def search_vs_n_row(*, n: int, seed: int, sensor: str = "ideal") -> dict:
    """Fig. 4.18 at one n (a trial): closed yardstick, BIC, DOFs, graphs visited and run
    time [s] of the spanning tree, the local and the exhaustive search."""
    from mmlearn.diagrams.common.object_tracks import yardstick_scenario

    obs = _yardstick_obs()
    tr = observe(yardstick_scenario(True, n, rng=seed), sensor)
    t0 = time.perf_counter()
    pm = fit_pair_models(tr.poses, obs=obs, rng=seed)
    t_fit = time.perf_counter() - t0
    tree_edges = spanning_tree_edges(pm, 4)
    row = {"n": n, "fit_seconds": t_fit}
    for search in ("tree", "local", "exhaustive"):
        ev = KinematicGraphEvaluator(tr.poses, pm, obs=obs)
        t0 = time.perf_counter()
        best, tree, order = search_structure(ev, tree_edges, search=search, reduce_dofs=True)
        row[search] = {"bic": best.bic, "seconds": time.perf_counter() - t0,
                       "graphs": len(order), "dof": best.dof}
        if search == "exhaustive":
            row["all_bics"] = sorted(e.bic for e in order)
    return row


STRUCTURE_RUNNERS = {"fig48": exp_cabinet, "fig49": exp_table, "fig411": exp_car, "garage": exp_garage}
"""The experiments that are one trial each (their table is the trial's record)."""


@register_trial("articulation.structure", record={"experiment": str})
def structure_trial(*, seed: int, experiment: str, quick: bool = False,
                    closed: bool | None = None, n: int | None = None, sensor: str = "ideal",
                    shared=None) -> dict:
    """One trial of the structure experiments (thesis 4.4.1 / 4.4.3; the sweep's trial function): a whole experiment of
    :data:`STRUCTURE_RUNNERS` (fig48, fig49, fig411, garage: its result and table lines), one yardstick
    run of fig416 (``closed``, ``n`` samples), one yardstick of fig417 (``closed``) or one
    ``n`` of fig418. ``sensor``: see :func:`observe`."""
    if experiment in STRUCTURE_RUNNERS:
        res, lines = STRUCTURE_RUNNERS[experiment](quick=quick, seed=seed, progress=False,
                                         sensor=sensor)
        return {"experiment": experiment, "result": res, "lines": lines}
    if experiment == "fig416":
        return {"experiment": experiment, "row": yardstick_row(closed=closed, seed=seed, n=n,
                                                               sensor=sensor)}
    if experiment == "fig417":
        return {"experiment": experiment, "closed": closed,
                "dofs": dof_progress(closed=closed, seed=seed, quick=quick, sensor=sensor)}
    if experiment == "fig418":
        return {"experiment": experiment, "row": search_vs_n_row(n=n, seed=seed, sensor=sensor)}
    raise ValueError(f"unknown experiment {experiment!r}; choose from {', '.join(STRUCTURE_EXPERIMENTS)}")
