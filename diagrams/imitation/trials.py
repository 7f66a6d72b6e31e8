"""The Drake trial of imitation learning (thesis ch. 8): a teacher demonstrates a task, the DBN
of constraints is learned and the 7-DOF arm reproduces it in a new variation of the scene.

:func:`reproduce_task` runs one reproduction: the teacher (a human-like arm with other link
lengths, :mod:`mmlearn.diagrams.imitation.demonstrations`) shows the task ``demos`` times in
seeded variations of the scene, observed through a ``MarkerSensor`` (or the demonstrations
are given); the DBN is learned (:func:`mmlearn.models.imitation.dbn.learn_task`, joint
constraints off: the bodies differ) and reproduced in a new variation of the scene (drawn
from ``seed``) by the :class:`~mmlearn.systems.imitation.dbn_reproducer.DbnReproducer`,
incrementally or globally. Its record is scored by :mod:`mmlearn.models.imitation.evaluation`.

``min_obstacle_clearance_m`` is the smallest signed distance between any collision geometry
of the arm (and the cup) and the obstacle's, from SceneGraph's
``ComputeSignedDistancePairClosestPoints``, sampled every :data:`SAMPLE_DT` s (null without
obstacle).

:func:`reproduction_trial` ("imitation.reproduce") is the same for the sweep runner
(:mod:`mmlearn.apps.common.sweep`); :func:`reproduction_plan` lists an experiment's trials.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

from mmlearn.diagrams.imitation.diagram import TASKS
from mmlearn.models.common.trials import register_trial
from mmlearn.models.imitation.evaluation import (PLACE_TOL, place_spot, reach_score,
                                                 whiteboard_score)

__all__ = ["reproduce_task", "reproduction_trial", "reproduction_plan", "record_demos",
           "PLACEMENT", "PARZEN_H", "PARZEN_H_DEFAULT", "SAMPLE_DT", "RELEASE_S",
           "MAX_TIME_FACTOR"]

SAMPLE_DT = 0.05      # s, clearance and trail sampling period
RELEASE_S = 1.0       # s simulated after the reproduction's last step
MAX_TIME_FACTOR = 2.0  # the simulation stops at this times the nominal duration
#: Parzen window width h of ``learn_task`` per task, s (default 0.2 s, the thesis'). The
#: zig-zag's turns are ~0.7 s apart and the sensor sees the hand at 5 Hz: a 0.2 s window
#: (one sample period) averages each turn with the neighbouring mid-strokes and shrinks the
#: learned zig-zag (point-hand reproduction, seeds 1-3, area scale 1.0: coverage 0.66-0.76
#: at h = 0.2 s, 0.82-0.87 at 0.1 s, 0.85-0.89 at 0.05 s; the demonstrations 0.88-0.90).
PARZEN_H = {"whiteboard": 0.05}
PARZEN_H_DEFAULT = 0.2
#: amplitude of the teacher's scene variation between demonstrations (1 = the scene's
#: default ranges, :meth:`ImitationSceneSpec.sampled`). The thesis: generalisation depends on
#: the variation in the demonstrations (the tables must move enough between them for the
#: learner to see which table matters when).
PLACEMENT = 1.0


def record_demos(task: str, n: int, *, seed: int, board_scale: float = 1.0,
                 placement: float = PLACEMENT):
    """``n`` demonstrations of ``task`` by the teacher (seeded), the scene varied with
    amplitude ``placement`` between them."""
    from mmlearn.diagrams.imitation.demonstrations import record_demonstrations
    from mmlearn.models.imitation.teacher import TeacherStyle, task_scene

    return record_demonstrations(task, n, seed=seed, style=TeacherStyle(placement=placement),
                                 scene=task_scene(task, board_scale=board_scale))


def _clearance_pairs(im):
    """(arm + cup geometry ids, obstacle geometry ids) for the signed-distance queries."""
    plant = im.plant
    if "obstacle" not in im.scene.bodies:
        return [], []
    mine = [g for b in plant.GetBodyIndices(im.robot)
            for g in plant.GetCollisionGeometriesForBody(plant.get_body(b))]
    if "cup" in im.scene.bodies:
        mine += plant.GetCollisionGeometriesForBody(plant.GetBodyByName("cup"))
    obst = plant.GetCollisionGeometriesForBody(plant.GetBodyByName("obstacle"))
    return mine, obst


def _min_clearance(query, mine, obst) -> tuple[float, object]:
    """(smallest signed distance, m, the arm / cup geometry id it was measured for)."""
    d, who = math.inf, None
    for a in mine:
        for b in obst:
            x = float(query.ComputeSignedDistancePairClosestPoints(a, b).distance)
            if x < d:
                d, who = x, a
    return d, who


#: the observed objects a task's evaluation reads from the demonstrations
TASK_NEEDS = {"pick_place": ("cup", "table_b")}


def _check_task(demo_list, task: str, path) -> None:
    """ValueError (naming the file) unless the loaded demonstrations are of ``task``: their
    ``meta["task"]`` (when recorded) and the objects the task's evaluation needs."""
    for i, d in enumerate(demo_list):
        got = d.meta.get("task") if isinstance(d.meta, dict) else None
        if got is not None and got != task:
            raise ValueError(f"{path}: demonstration {i} is of task {got!r}, not {task!r} "
                             "(give --task or another file)")
        missing = [o for o in TASK_NEEDS.get(task, ()) if o not in d.objects]
        if missing:
            raise ValueError(f"{path}: demonstration {i} lacks the object(s) "
                             f"{', '.join(missing)} the {task} task needs")


def _demonstrations(task, demos, seed, demos_file, placement):
    from mmlearn.models.imitation.types import load_demonstrations

    if task not in TASKS:
        raise ValueError(f"task must be one of {', '.join(TASKS)}, got {task!r}")
    if demos_file:
        demo_list = load_demonstrations(demos_file)
        if not demo_list:
            raise ValueError(f"{demos_file}: holds no demonstration")
        _check_task(demo_list, task, demos_file)
        return demo_list
    if demos < 1:
        raise ValueError(f"demos must be >= 1, got {demos}")
    return record_demos(task, demos, seed=seed, board_scale=1.0, placement=placement)


def _simulate(im, ctx, *, record: bool = False, progress=None, monitor=None,
              stop_when_unsure: bool = False) -> dict:
    """Run the reproduction until the reproducer has stepped through every slice (it may
    spend extra steps on a slice, see DbnReproducerConfig.advance_tolerance) plus RELEASE_S
    for the cup to settle, at most MAX_TIME_FACTOR times the nominal duration; sample the
    hand and the obstacle clearance every SAMPLE_DT s (``progress(k, n)`` after each of at
    most n samples; ``record``: into the Meshcat visualizer's recording). ``monitor`` (a
    :class:`~mmlearn.models.imitation.confidence.SurpriseMonitor`) is given every sample's
    slice, hand and objects; with ``stop_when_unsure`` the run stops once it flags."""
    from pydrake.systems.analysis import Simulator

    diagram = im.diagram
    sim = Simulator(diagram, ctx)
    sim.Initialize()
    if record:
        im.visualizer.StartRecording(False)
    mine, obst = _clearance_pairs(im)
    qport = diagram.GetOutputPort("query_object")
    hport = diagram.GetOutputPort("hand")
    sport = diagram.GetOutputPort("status")
    max_time = MAX_TIME_FACTOR * im.reproducer.duration + RELEASE_S
    out = {"clearance": math.inf, "closest": None, "t_closest": None, "obstacle": bool(mine)}
    hand_trail = []
    t, t_end = 0.0, None
    n_max, k = int(math.ceil(max_time / SAMPLE_DT)), 0
    if monitor is not None:
        from mmlearn.diagrams.imitation.diagram import object_positions

        rep = im.reproducer
        step_port = rep.GetOutputPort("step")
        rep_ctx = rep.GetMyContextFromRoot(ctx)
    out["stopped_unsure"] = False
    while t < (t_end if t_end is not None else max_time) - 1e-9:
        t = min(t + SAMPLE_DT, max_time)
        sim.AdvanceTo(t)
        hand_trail.append(np.array(hport.Eval(ctx), float))
        if monitor is not None and t_end is None:
            unsure = monitor.update(int(step_port.Eval(rep_ctx)[0]), hand_trail[-1],
                                    object_positions(im.plant, ctx, im.scene.bodies))
            if unsure and stop_when_unsure:
                out["stopped_unsure"] = True
                break
        if mine:
            q = qport.Eval(ctx)
            d, who = _min_clearance(q, mine, obst)
            if d < out["clearance"]:
                out["clearance"], out["t_closest"] = d, t
                out["closest"] = q.inspector().GetName(who)
        if t_end is None and sport.Eval(ctx)[5] > 0:
            t_end = min(t + RELEASE_S, max_time)
        k += 1
        if progress is not None:
            progress(k, n_max)
    out.update(hand=np.array(hand_trail), duration=t, finished=t_end is not None)
    return out


def _eval_pick_place(im, ctx, demos, objs) -> dict:
    err = float(np.linalg.norm((objs["cup"] - place_spot(demos, objs["table_b"]))[:2]))
    plant = im.plant
    pc = plant.GetMyContextFromRoot(ctx)
    X = plant.EvalBodyPoseInWorld(pc, plant.GetBodyByName("cup"))
    upright = float(X.rotation().matrix()[2, 2])
    spec = im.scene.spec
    base = X.translation()
    half = np.asarray(spec.table_size) / 2
    on_b = bool(np.all(np.abs(base[:2] - np.asarray(spec.table_b)) <= half)
                and abs(base[2] - spec.table_height) < 0.01)
    attached = bool(im.diagram.GetOutputPort("attached").Eval(ctx)[0] > 0.5)
    ok = bool(err < PLACE_TOL and upright > 0.95 and on_b and not attached)
    return {"place_error_m": err, "cup_upright": upright, "cup_on_table_b": on_b,
            "cup_held_at_end": attached, "success": ok}


def reproduce_task(*, task: str = "pick_place", demos: int = 4, seed: int = 0,
                   swap_tables: bool = False, board_scale: float = 1.0,
                   global_mode: bool = False, demos_file: str = "",
                   placement: float = PLACEMENT, meshcat=None, progress=None,
                   config=None, demonstrations=None, confidence=None,
                   stop_when_unsure: bool = False, isotropic_prior: float = 0.0) -> dict:
    """Record (or load from ``demos_file``) demonstrations, learn, reproduce in a new scene;
    returns the JSON-able record: the settings, ``learn_seconds``, ``reproduction_seconds``,
    ``simulated_seconds``, ``finished``, ``min_obstacle_clearance_m``, the reproducer's step
    counts, the task's scores (:mod:`mmlearn.models.imitation.evaluation`) with ``success``
    and ``objects_start`` (the objects' positions at the start, m). ``config`` is an optional
    :class:`~mmlearn.diagrams.imitation.diagram.ImitationConfig` whose task / seed / swap /
    board / mode fields are overridden by the keyword arguments. With ``meshcat`` the
    reproduction is drawn and recorded there; ``progress(k, n)`` is called after each
    simulated sample k of at most n. ``demonstrations`` (a list of
    :class:`~mmlearn.models.imitation.types.Demonstration`) replaces recording or loading.
    ``confidence`` (a :class:`~mmlearn.models.imitation.confidence.ConfidenceConfig`) watches
    the reproduction's surprise under the learned model (record ``"confidence"``: reference,
    threshold, peak, ``unsure`` and ``unsure_at_s``); with ``stop_when_unsure`` the
    reproduction stops once it is unsure (``"stopped_unsure"``; the task is then scored where
    it stopped). ``isotropic_prior`` is :func:`~mmlearn.models.imitation.dbn.learn_task`'s
    (0 = the thesis' learner)."""
    from mmlearn.diagrams.imitation.diagram import ImitationConfig, MakeImitationDiagram, \
        object_positions
    from mmlearn.models.imitation.dbn import learn_task

    demo_list = (list(demonstrations) if demonstrations is not None
                 else _demonstrations(task, demos, seed, demos_file, placement))
    if not demo_list:
        raise ValueError("reproduce_task: no demonstration given")
    t0 = time.perf_counter()
    model = learn_task(demo_list, use_joints=False, h=PARZEN_H.get(task, PARZEN_H_DEFAULT),
                       isotropic_prior=isotropic_prior)
    learn_s = time.perf_counter() - t0
    monitor = None
    if confidence is not None or stop_when_unsure:
        from mmlearn.models.imitation.confidence import SurpriseMonitor

        monitor = SurpriseMonitor(model, demo_list, sample_period=SAMPLE_DT, config=confidence)

    cfg = config or ImitationConfig()
    cfg = replace(cfg, task=task, seed=seed, swap_tables=swap_tables, board_scale=board_scale,
                  reproducer=replace(cfg.reproducer,
                                     mode="global" if global_mode else "incremental"))
    im = MakeImitationDiagram(cfg, model=model, meshcat=meshcat, demos=demo_list)
    ctx = im.diagram.CreateDefaultContext()
    im.set_start(ctx)
    objs0 = object_positions(im.plant, ctx, im.scene.bodies)
    t_wall = time.perf_counter()
    run = _simulate(im, ctx, record=meshcat is not None, progress=progress, monitor=monitor,
                    stop_when_unsure=stop_when_unsure)
    repro_s = time.perf_counter() - t_wall
    if meshcat is not None:
        im.visualizer.StopRecording()
        im.visualizer.PublishRecording()
    status = np.asarray(im.diagram.GetOutputPort("status").Eval(ctx), float)
    objs = object_positions(im.plant, ctx, im.scene.bodies)
    clearance = run["clearance"] if run["obstacle"] else None
    rec = {"task": task, "seed": seed, "demos": len(demo_list), "swap_tables": swap_tables,
           "placement": None if demos_file else placement,
           "board_scale": board_scale, "mode": cfg.reproducer.mode,
           "isotropic_prior": float(isotropic_prior),
           "learn_seconds": learn_s, "reproduction_seconds": repro_s,
           "simulated_seconds": run["duration"], "finished": bool(run["finished"]),
           "min_obstacle_clearance_m": clearance,
           "closest_geometry": run["closest"], "closest_time_s": run["t_closest"],
           "steps": int(status[0]), "waiting_steps": int(status[1]),
           "failed_steps": int(status[2]),
           "plan_seconds": float(status[4]) if cfg.reproducer.mode == "global" else None,
           "place_error_m": None}
    if task == "pick_place":
        rec.update(_eval_pick_place(im, ctx, demo_list, objs))
    elif task == "whiteboard":
        rec.update(whiteboard_score(run["hand"], objs, demo_list))
    else:
        rec.update(reach_score(run["hand"][-1], objs["target"], demo_list,
                               clearance=clearance))
    rec["objects_start"] = {k: v.tolist() for k, v in objs0.items()}
    if monitor is not None:
        rec["confidence"] = monitor.summary(SAMPLE_DT)
        rec["stopped_unsure"] = bool(run["stopped_unsure"])
    if meshcat is not None:
        _frame_and_legend(meshcat, model, demo_list, objs0, run["hand"], rec)
    return rec


def _frame_and_legend(meshcat, model, demos, objects, hand, rec) -> None:
    """Frame the arm, the objects and the hand's paths; draw a legend naming the
    demonstrations, each constraint's learned path and ellipsoids and the reproduction."""
    from pydrake.geometry import Rgba

    from mmlearn.diagrams.imitation.diagram import ellipsoid_stride
    from mmlearn.systems.common.meshcat_view import draw_legend, frame_camera
    from mmlearn.systems.imitation.dbn_visualizer import PALETTE

    paths = [np.asarray(d.hand, float) for d in demos] + [np.asarray(hand, float)]
    # the markers, with room for the bodies around them (tables, cup), and the arm
    box = np.array([[x, y, z] for x in (-0.15, 0.15) for y in (-0.15, 0.15)
                    for z in (-0.15, 0.1)])
    marks = np.array([v for v in objects.values()])
    P = np.concatenate([p[np.all(np.isfinite(p), axis=1)] for p in paths if p.ndim == 2]
                       + [(marks[:, None, :] + box[None]).reshape(-1, 3),
                          [[0.0, 0.0, 0.0], [0.0, 0.0, 1.1]]])  # the arm's base and top
    centre = P.mean(axis=0)
    side = np.cross([0.0, 0.0, 1.0], [centre[0], centre[1], 0.0])
    side = side / (np.linalg.norm(side) or 1.0)
    frame_camera(meshcat, P, view_from=-side + [0.0, 0.0, 1.0], margin=1.15)
    stride = ellipsoid_stride(model)
    rows = [(Rgba(0.3, 0.3, 0.3, 0.8), "thin", f"{len(demos)} demonstrated hand paths (as "
                                               f"the marker sensor saw them)")]
    cart = [c for c in model.constraints if c.startswith("obj:")]
    for i, name in enumerate(cart):
        col = PALETTE[i % len(PALETTE)]
        solid = Rgba(col.r(), col.g(), col.b(), 0.9)
        rows.append((solid, "line", f"learned hand path relative to the {name[4:]} "
                                    f"({model.S} slices)"))
        rows.append((Rgba(col.r(), col.g(), col.b(), 0.4), "box",
                     f"  its 2-sigma ellipsoids, one slice in {stride} (Open Controls "
                     f"hides them)"))
    rows.append((Rgba(0.1, 0.1, 0.9, 1.0), "dots", "the reproduction's hand trail"))
    verdict = "succeeded" if rec.get("success") else "failed"
    if rec.get("place_error_m") is not None:
        verdict += f", cup placed {1000 * rec['place_error_m']:.0f} mm from the demonstrated spot"
    elif rec.get("reach_error_m") is not None:
        verdict += f", reach error {1000 * rec['reach_error_m']:.0f} mm"
    rows.append((None, "", f"reproduction {verdict}"))
    draw_legend(meshcat, f"Imitation: {rec['task']} learned from {len(demos)} "
                         f"demonstrations", rows)


@register_trial("imitation.reproduce",
                record={"task": str, "success": bool, "finished": bool,
                        "learn_seconds": float, "reproduction_seconds": float})
def reproduction_trial(*, seed: int, task: str, demos: int = 4, swap_tables: bool = False,
                       board_scale: float = 1.0, global_mode: bool = False,
                       isotropic_prior: float = 0.0, shared=None) -> dict:
    """One reproduction (:func:`reproduce_task`) for the sweep runner, without the objects'
    start positions."""
    rec = reproduce_task(task=task, demos=demos, seed=seed, swap_tables=swap_tables,
                         board_scale=board_scale, global_mode=global_mode,
                         isotropic_prior=isotropic_prior)
    rec.pop("objects_start", None)
    return rec


def reproduction_plan(conditions, seeds: int, seed: int) -> list[dict]:
    """The trials of an experiment: ``seeds`` reproductions (seeds ``seed``, ``seed + 1``, ..)
    of every (label, trial parameters[, trial function; default :func:`reproduction_trial`])
    of ``conditions``, as dicts ``{"fn", "seed",
    "params", "label"}`` (the fields of :class:`mmlearn.apps.common.sweep.TrialSpec`; the
    label ends in ``" seed N"``, :func:`mmlearn.models.imitation.evaluation.condition_table`
    groups by the rest)."""
    out = []
    for cond in conditions:
        label, params = cond[0], cond[1]
        fn = cond[2] if len(cond) > 2 else reproduction_trial
        out += [{"fn": fn, "seed": seed + i, "params": params,
                 "label": f"{label} seed {seed + i}"} for i in range(seeds)]
    return out
