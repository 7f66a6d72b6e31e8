"""Learn a task from a teacher's demonstrations and reproduce it with the 7-DOF arm
(thesis ch. 8).

    python -m mmlearn.apps.imitate --task pick_place --demos 4 --swap-tables --seed 3 --json
    python -m mmlearn.apps.imitate --task u_obstacle --global --seed 1 --html-out run.html
    python -m mmlearn.apps.imitate --task pick_place --interactive --swap-tables --seed 3 --json

``--interactive`` teaches interactively
(:func:`mmlearn.diagrams.imitation.teaching.teach_interactively`): the robot reproduces the
task after the first demonstration and the teacher demonstrates again, in that situation,
only when a reproduction fails or the robot flags it as unsure (its trajectory's surprise
under the learned DBN far above the demonstrations', :mod:`mmlearn.models.imitation.confidence`),
up to ``--max-demos``; then the taught robot is tested once in the situation ``--seed`` gives
a batch reproduction. The JSON has ``success``, ``demos_used``, ``rounds`` (each round's
outcome: success, failed or unsure), ``asked_before_failing``, ``failed_unflagged``, ``test``
and ``test_success``.

The reproduction is :func:`mmlearn.diagrams.imitation.trials.reproduce_task`, scored by
:mod:`mmlearn.models.imitation.evaluation`. The teacher (a human-like arm with other link
lengths, :mod:`mmlearn.diagrams.imitation.demonstrations`) shows the task ``--demos`` times in
seeded variations of the scene, observed through a ``MarkerSensor``; or the demonstrations
are loaded with ``--demos-file`` (the JSON of
:func:`mmlearn.models.imitation.types.save_demonstrations`). The DBN of constraints is learned
(:func:`mmlearn.models.imitation.dbn.learn_task`, joint constraints off: the bodies differ) and
reproduced in a new variation of the scene (drawn from ``--seed``) by the
:class:`~mmlearn.systems.imitation.dbn_reproducer.DbnReproducer`, incrementally or with
``--global``.

Meshcat (``--meshcat`` live, ``--html-out`` recording): the arm and the scene framed by the
camera, the demonstrated hand paths (grey), per object constraint the learned hand path and
translucent 2-sigma ellipsoids at about a dozen slices (a group of their own that Meshcat's
controls can hide), the reproduction's hand trail (blue dots) and a legend saying which is
which with the outcome.

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
import sys

from mmlearn.apps.common.cli import (ArgumentParser, UsageError, check_in_file, check_out_file,
                                     fail, json_clean, nonneg_float, nonneg_int, pos_float,
                                     pos_int)
from mmlearn.diagrams.imitation.diagram import TASKS
from mmlearn.diagrams.imitation.trials import PLACEMENT, reproduce_task

__all__ = ["run", "main"]


def run(*, task: str = "pick_place", demos: int = 4, seed: int = 0, swap_tables: bool = False,
        board_scale: float = 1.0, global_mode: bool = False, demos_file: str = "",
        placement: float = PLACEMENT,
        meshcat=None, html_out: str = "", show_progress: bool = True, config=None) -> dict:
    """Record (or load) demonstrations, learn, reproduce in a new scene
    (:func:`mmlearn.diagrams.imitation.trials.reproduce_task`); returns the JSON record (see
    the module docstring). ``config`` is an optional
    :class:`~mmlearn.diagrams.imitation.diagram.ImitationConfig` whose task / seed / swap /
    board / mode fields are overridden by the keyword arguments."""
    from mmlearn.apps.common.cli import progress_bar

    bar = []

    def progress(k, n):
        if not bar:
            bar.append(progress_bar(n, "reproducing", unit="step", enabled=show_progress))
        bar[0].update(1)

    try:
        rec = reproduce_task(task=task, demos=demos, seed=seed, swap_tables=swap_tables,
                             board_scale=board_scale, global_mode=global_mode,
                             demos_file=demos_file, placement=placement, meshcat=meshcat,
                             progress=progress, config=config)
    finally:
        if bar:
            bar[0].close()
    if meshcat is not None and html_out:
        from mmlearn.apps.common.cli import save_html

        save_html(meshcat, html_out)
    return json_clean(rec)


def _interactive(ap, args) -> int:
    from mmlearn.diagrams.imitation.teaching import teach_interactively

    def progress(r, outcome):
        if not args.json:
            print(f"round {r}: {outcome}", flush=True)

    try:
        rec = teach_interactively(task=args.task, seed=args.seed, max_demos=args.max_demos,
                                  swap_tables=args.swap_tables, board_scale=args.board_scale,
                                  global_mode=args.global_mode, placement=args.placement,
                                  progress=progress)
    except ValueError as e:
        return fail(ap.prog, " ".join(str(e).split()))
    rec = json_clean(rec)
    if args.json:
        print(json.dumps(rec))
    else:
        print(f"{'success':26s} {rec['success']}")
        print(f"{'demos_used':26s} {rec['demos_used']}")
        print(f"{'asked_before_failing':26s} {rec['asked_before_failing']}")
        print(f"{'failed_unflagged':26s} {rec['failed_unflagged']}")
        print(f"{'test_success':26s} {rec['test_success']}")
    return 0


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
    ap.add_argument("--interactive", action="store_true",
                    help="teach interactively: the teacher demonstrates again only where a "
                         "reproduction fails or the robot is unsure (--demos is then unused)")
    ap.add_argument("--max-demos", type=pos_int, default=6,
                    help="most demonstrations the teacher gives with --interactive (default 6)")
    ap.add_argument("--seed", type=nonneg_int, default=0)
    ap.add_argument("--meshcat", action="store_true", help="live view in Meshcat")
    ap.add_argument("--html-out", default="", help="write the Meshcat recording as HTML")
    ap.add_argument("--json", action="store_true", help="print the record as JSON")
    args = ap.parse_args(argv)
    try:
        check_in_file("--demos-file", args.demos_file)
        check_out_file("--html-out", args.html_out)
        if args.interactive and (args.demos_file or args.meshcat or args.html_out):
            raise UsageError("--interactive records its own demonstrations and draws nothing: "
                             "drop --demos-file, --meshcat and --html-out")
    except UsageError as e:
        return fail(ap.prog, str(e))
    if args.interactive:
        return _interactive(ap, args)
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
