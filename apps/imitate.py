"""Learn a task from a teacher's demonstrations and reproduce it with the 7-DOF arm
(thesis ch. 8).

    python -m mmlearn.apps.imitate --task pick_place --demos 4 --swap-tables --seed 3 --json
    python -m mmlearn.apps.imitate --task u_obstacle --global --seed 1 --html-out run.html

The teacher (a human-like arm with other link lengths, :mod:`mmlearn.diagrams.imitation.demonstrations`)
shows the task ``--demos`` times in seeded variations of the scene, observed through a
``MarkerSensor``; or the demonstrations are loaded with ``--demos-file`` (the JSON of
:func:`mmlearn.models.imitation.types.save_demonstrations`). The DBN of constraints is
learned (:func:`mmlearn.models.imitation.dbn.learn_task`, joint constraints off: the bodies
differ) and reproduced in a new variation of the scene (drawn from ``--seed``) by the
:class:`~mmlearn.systems.imitation.dbn_reproducer.DbnReproducer`, incrementally or with ``--global``.

Success (the task's goal met in the simulation):

* pick_place: the cup ends released, upright, on the target table (table B), its marker
  within 2 cm (horizontally) of the demonstrated spot, i.e. of the demonstrations' mean
  final cup-minus-table-B marker offset applied to this scene's table B (``place_error_m``);
* whiteboard: the area inside the four corner markers is covered: the share of a 1 cm grid
  of that area that the hand passed within ``SPONGE_RADIUS`` of (in the board plane) while
  within the demonstrations' distance from the board (+2 cm) is at least 90 % of the
  demonstrations' own mean coverage (``coverage``, ``demo_coverage``);
* obstacle / u_obstacle: the hand ends within 3 cm of the demonstrated final spot relative
  to the target (``reach_error_m``) and the arm never touched the obstacle
  (``min_obstacle_clearance_m`` > 0).

``min_obstacle_clearance_m`` is the smallest signed distance between any collision geometry
of the arm (and the cup) and the obstacle's, from SceneGraph's
``ComputeSignedDistancePairClosestPoints``, sampled every 0.05 s (null without obstacle).
"""

from __future__ import annotations

import json
import math
import sys
import time
from dataclasses import replace

import numpy as np

from mmlearn.apps.common.cli import (ArgumentParser, UsageError, check_in_file, check_out_file,
                                     fail, json_clean, nonneg_float, nonneg_int, pos_float,
                                     pos_int)
from mmlearn.diagrams.imitation.diagram import TASKS

SPONGE_RADIUS = 0.04  # m, the hand's cleaning radius on the board
SAMPLE_DT = 0.05      # s, clearance and trail sampling period
PLACE_TOL = 0.02      # m
REACH_TOL = 0.03      # m
RELEASE_S = 1.0       # s simulated after the reproduction's last step
MAX_TIME_FACTOR = 2.0  # the simulation stops at this times the nominal duration
#: Parzen window width h of ``learn_task`` per task, s (default 0.2 s, the thesis'). The
#: zig-zag's turns are ~0.7 s apart and the sensor sees the hand at 5 Hz: a 0.2 s window
#: (one sample period) averages each turn with the neighbouring mid-strokes and shrinks the
#: learned zig-zag (point-hand reproduction, seeds 1-3, area scale 1.0: coverage 0.66-0.76
#: at h = 0.2 s, 0.82-0.87 at 0.1 s, 0.85-0.89 at 0.05 s; the demonstrations 0.88-0.90).
PARZEN_H = {"whiteboard": 0.05}
PARZEN_H_DEFAULT = 0.2


# ----------------------------------------------------------------------------- demonstrations
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


def _final(track) -> np.ndarray:
    """Last finite row of a (T, D) track."""
    a = np.asarray(track, float)
    ok = np.all(np.isfinite(a), axis=1)
    return a[np.flatnonzero(ok)[-1]]


# ----------------------------------------------------------------------------- evaluation
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


def _coverage(hand, corners, *, plane_tol: float) -> float:
    """Share of a 1 cm grid of the quadrilateral ``corners`` (4, 3) the hand path passed
    within SPONGE_RADIUS of (in the board plane, x = const) while closer to the board than
    ``plane_tol``."""
    hand = np.asarray(hand, float)
    hand = hand[np.all(np.isfinite(hand), axis=1)]
    c = np.asarray(corners, float)
    x_board = float(np.mean(c[:, 0]))
    on = hand[np.abs(hand[:, 0] - x_board) <= plane_tol]
    ys = np.arange(c[:, 1].min(), c[:, 1].max() + 1e-9, 0.01)
    zs = np.arange(c[:, 2].min(), c[:, 2].max() + 1e-9, 0.01)
    Y, Z = np.meshgrid(ys, zs)
    grid = np.column_stack([Y.ravel(), Z.ravel()])
    if on.shape[0] == 0:
        return 0.0
    # densify the path so that fast strokes between samples count
    path = on[:, 1:]
    from scipy.spatial import cKDTree

    tree = cKDTree(path)
    d, _ = tree.query(grid)
    return float(np.mean(d <= SPONGE_RADIUS))


def _plane_distance(demos) -> float:
    """Median distance of the demonstrations' hand from the board plane (x), m."""
    ds = []
    for d in demos:
        h = np.asarray(d.hand, float)
        c = np.array([_final(d.objects[f"board_c{k}"]) for k in range(4)])
        h = h[np.all(np.isfinite(h), axis=1)]
        inside = ((h[:, 1] >= c[:, 1].min()) & (h[:, 1] <= c[:, 1].max())
                  & (h[:, 2] >= c[:, 2].min()) & (h[:, 2] <= c[:, 2].max()))
        if inside.any():
            ds.append(np.median(np.abs(h[inside, 0] - np.mean(c[:, 0]))))
    return float(np.median(ds)) if ds else 0.02


def _densify(path, step=0.005):
    """Points every ``step`` m along a polyline (N, 3)."""
    out = [path[:1]]
    for a, b in zip(path[:-1], path[1:]):
        n = max(int(np.linalg.norm(b - a) / step), 1)
        s = np.linspace(0, 1, n + 1)[1:, None]
        out.append(a + s * (b - a))
    return np.vstack(out)


# ----------------------------------------------------------------------------- the run
def run(*, task: str = "pick_place", demos: int = 4, seed: int = 0, swap_tables: bool = False,
        board_scale: float = 1.0, global_mode: bool = False, demos_file: str = "",
        placement: float = PLACEMENT,
        meshcat=None, html_out: str = "", show_progress: bool = True, config=None) -> dict:
    """Record (or load) demonstrations, learn, reproduce in a new scene; returns the JSON
    record (see the module docstring). ``config`` is an optional
    :class:`~mmlearn.diagrams.imitation.diagram.ImitationConfig` whose task / seed / swap / board /
    mode fields are overridden by the keyword arguments."""
    from pydrake.systems.analysis import Simulator

    from mmlearn.diagrams.imitation.diagram import ImitationConfig, MakeImitationDiagram, \
        object_positions
    from mmlearn.models.imitation.dbn import learn_task
    from mmlearn.models.imitation.types import load_demonstrations

    if task not in TASKS:
        raise ValueError(f"task must be one of {', '.join(TASKS)}, got {task!r}")
    if demos_file:
        demo_list = load_demonstrations(demos_file)
        if not demo_list:
            raise ValueError(f"{demos_file}: holds no demonstration")
    else:
        if demos < 1:
            raise ValueError(f"demos must be >= 1, got {demos}")
        demo_list = record_demos(task, demos, seed=seed, board_scale=1.0,
                                 placement=placement)
    t0 = time.perf_counter()
    model = learn_task(demo_list, use_joints=False, h=PARZEN_H.get(task, PARZEN_H_DEFAULT))
    learn_s = time.perf_counter() - t0

    cfg = config or ImitationConfig()
    cfg = replace(cfg, task=task, seed=seed, swap_tables=swap_tables, board_scale=board_scale,
                  reproducer=replace(cfg.reproducer,
                                     mode="global" if global_mode else "incremental"))
    im = MakeImitationDiagram(cfg, model=model, meshcat=meshcat, demos=demo_list)
    diagram = im.diagram
    ctx = diagram.CreateDefaultContext()
    im.set_start(ctx)
    objs0 = object_positions(im.plant, ctx, im.scene.bodies)
    sim = Simulator(diagram, ctx)
    sim.Initialize()
    if meshcat is not None:
        im.visualizer.StartRecording(False)
    mine, obst = _clearance_pairs(im)
    qport = diagram.GetOutputPort("query_object")
    hport = diagram.GetOutputPort("hand")
    # until the reproducer has stepped through every slice (it may spend extra steps on a
    # slice, see DbnReproducerConfig.advance_tolerance) plus RELEASE_S for the cup to settle,
    # at most MAX_TIME_FACTOR times the nominal duration
    nominal = im.reproducer.duration
    max_time = MAX_TIME_FACTOR * nominal + RELEASE_S
    clearance, closest, t_closest = math.inf, None, None
    hand_trail = []
    t_wall = time.perf_counter()
    t = 0.0
    t_end = None
    sport = diagram.GetOutputPort("status")
    from mmlearn.apps.common.cli import progress_bar

    bar = progress_bar(int(math.ceil(max_time / SAMPLE_DT)), "reproducing", unit="step",
                       enabled=show_progress)
    while t < (t_end if t_end is not None else max_time) - 1e-9:
        t = min(t + SAMPLE_DT, max_time)
        sim.AdvanceTo(t)
        hand_trail.append(np.array(hport.Eval(ctx), float))
        if mine:
            q = qport.Eval(ctx)
            d, who = _min_clearance(q, mine, obst)
            if d < clearance:
                clearance, t_closest = d, t
                closest = q.inspector().GetName(who)
        if t_end is None and sport.Eval(ctx)[5] > 0:
            t_end = min(t + RELEASE_S, max_time)
        bar.update(1)
    bar.close()
    duration = t
    repro_s = time.perf_counter() - t_wall
    if meshcat is not None:
        im.visualizer.StopRecording()
        im.visualizer.PublishRecording()
        if html_out:
            from mmlearn.apps.common.cli import save_html

            save_html(meshcat, html_out)
    status = np.asarray(diagram.GetOutputPort("status").Eval(ctx), float)
    objs = object_positions(im.plant, ctx, im.scene.bodies)
    hand = np.array(hand_trail)
    rec = {"task": task, "seed": seed, "demos": len(demo_list), "swap_tables": swap_tables,
           "placement": None if demos_file else placement,
           "board_scale": board_scale, "mode": cfg.reproducer.mode,
           "learn_seconds": learn_s, "reproduction_seconds": repro_s,
           "simulated_seconds": duration, "finished": bool(t_end is not None),
           "min_obstacle_clearance_m": clearance if mine else None,
           "closest_geometry": closest, "closest_time_s": t_closest,
           "steps": int(status[0]), "waiting_steps": int(status[1]),
           "failed_steps": int(status[2]),
           "plan_seconds": float(status[4]) if cfg.reproducer.mode == "global" else None,
           "place_error_m": None}
    if task == "pick_place":
        rec.update(_eval_pick_place(im, ctx, demo_list, objs))
    elif task == "whiteboard":
        plane = _plane_distance(demo_list) + 0.02
        corners = np.array([objs[f"board_c{k}"] for k in range(4)])
        cov = _coverage(_densify(hand), corners, plane_tol=plane)
        demo_cov = []
        for d in demo_list:
            h = np.asarray(d.hand, float)
            h = h[np.all(np.isfinite(h), axis=1)]
            c = np.array([_final(d.objects[f"board_c{k}"]) for k in range(4)])
            demo_cov.append(_coverage(_densify(h), c, plane_tol=plane))
        rec.update(coverage=cov, demo_coverage=float(np.mean(demo_cov)),
                   success=bool(cov >= 0.9 * float(np.mean(demo_cov))))
    else:
        spot = np.mean([_final(d.hand) - _final(d.objects["target"]) for d in demo_list],
                       axis=0)
        err = float(np.linalg.norm(hand[-1] - (objs["target"] + spot)))
        rec.update(reach_error_m=err,
                   success=bool(err <= REACH_TOL and (not mine or clearance > 0)))
    rec["objects_start"] = {k: v.tolist() for k, v in objs0.items()}
    return json_clean(rec)


def _eval_pick_place(im, ctx, demos, objs) -> dict:
    offs = [_final(d.objects["cup"]) - _final(d.objects["table_b"]) for d in demos]
    spot = objs["table_b"] + np.mean(offs, axis=0)
    err = float(np.linalg.norm((objs["cup"] - spot)[:2]))
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


# ----------------------------------------------------------------------------- command line
def main(argv=None) -> int:
    ap = ArgumentParser(prog="python -m mmlearn.apps.imitate",
                        description="Learn a task from demonstrations (a DBN of constraints, "
                                    "thesis ch. 8) and reproduce it with the 7-DOF arm.")
    ap.add_argument("--task", choices=TASKS, default="pick_place")
    ap.add_argument("--demos", type=pos_int, default=4,
                    help="number of demonstrations the teacher gives (default 4; ignored with "
                         "--demos-file)")
    ap.add_argument("--demos-file", default="",
                    help="load the demonstrations from this JSON file instead of recording")
    ap.add_argument("--swap-tables", action="store_true",
                    help="exchange the two tables in the reproduction (pick_place)")
    ap.add_argument("--board-scale", type=pos_float, default=1.0,
                    help="scale of the board area in the reproduction (whiteboard)")
    ap.add_argument("--global", dest="global_mode", action="store_true",
                    help="plan the whole reproduction at the start (roadmap + A*) instead of "
                         "the incremental steps")
    ap.add_argument("--placement", type=nonneg_float, default=PLACEMENT,
                    help="amplitude of the teacher's scene variation between demonstrations "
                         f"(1 = tables +-4 cm; default {PLACEMENT})")
    ap.add_argument("--seed", type=nonneg_int, default=0)
    ap.add_argument("--meshcat", action="store_true", help="live view in Meshcat")
    ap.add_argument("--html-out", default="", help="write the Meshcat recording as HTML")
    ap.add_argument("--json", action="store_true", help="print the record as JSON")
    args = ap.parse_args(argv)
    try:
        check_in_file("--demos-file", args.demos_file)
        check_out_file("--html-out", args.html_out)
    except UsageError as e:
        return fail(ap.prog, str(e))
    meshcat = None
    if args.meshcat or args.html_out:
        from mmlearn.apps.common.cli import make_meshcat

        meshcat = make_meshcat(announce=args.meshcat)
    try:
        rec = run(task=args.task, demos=args.demos, seed=args.seed,
                  swap_tables=args.swap_tables, board_scale=args.board_scale,
                  global_mode=args.global_mode, demos_file=args.demos_file, meshcat=meshcat,
                  html_out=args.html_out, show_progress=not args.json,
                  placement=args.placement)
    except ValueError as e:
        where = "--demos-file: " if args.demos_file and args.demos_file in str(e) else ""
        return fail(ap.prog, where + " ".join(str(e).split()))
    if args.json:
        print(json.dumps(rec))
    else:
        keys = ("task", "mode", "demos", "success", "place_error_m", "coverage",
                "reach_error_m", "min_obstacle_clearance_m", "learn_seconds",
                "reproduction_seconds")
        for k in keys:
            if k in rec and rec[k] is not None:
                v = rec[k]
                print(f"{k:26s} {v:.4f}" if isinstance(v, float) else f"{k:26s} {v}")
    if meshcat is not None:
        from mmlearn.apps.common.cli import finish_viewing

        # with --json, stdout holds the JSON only
        finish_viewing(html_out=None if args.json else args.html_out, live=args.meshcat)
    return 0


if __name__ == "__main__":
    sys.exit(main())
