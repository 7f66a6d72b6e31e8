"""Time to record demonstrations of each imitation task (diagrams/imitation/demonstrations.py).

    python benchmarks/bench_record_demos.py [--demos 4] [--seed 0] [--quick] [--json [FILE]]

For each task: the wall time of ``record_demonstrations(task, demos, seed=...)`` (plan, the
teacher's per-sample IK, the playback simulation with the marker sensor's occlusion tests),
the demonstrated time it covers, and, for one demonstration, how much of it is the IK.
"""

import argparse
import time

import numpy as np

from _common import add_output_arguments, emit_json
from mmlearn.diagrams.imitation.demonstrations import MakeTeacherDiagram, TeacherConfig, \
    record_demonstrations
from mmlearn.models.imitation.teacher import TASKS


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--demos", type=int, default=4)
    ap.add_argument("--seed", type=int, default=0)
    add_output_arguments(ap, quick="one demonstration per task (a few seconds)")
    args = ap.parse_args(argv)
    if args.quick:
        args.demos = 1
    say = print if args.json != "-" else (lambda *a, **kw: None)  # JSON instead of a table
    rows = []
    say(f"{args.demos} demonstrations per task, seed {args.seed}")
    say(f"{'task':11s} {'record s':>9s} {'demo s':>7s} {'frames':>7s} {'hand seen':>10s} "
          f"{'IK s (1 demo)':>14s} {'IK samples':>11s}")
    for task in TASKS:
        t0 = time.perf_counter()
        demos = record_demonstrations(task, args.demos, seed=args.seed)
        wall = time.perf_counter() - t0
        dur = sum(d.duration for d in demos)
        frames = sum(d.T for d in demos)
        seen = np.mean([np.isfinite(d.hand).all(axis=1).mean() for d in demos])
        td = MakeTeacherDiagram(TeacherConfig(task=task, seed=args.seed * 1000))
        rows.append(dict(task=task, record_s=wall, demo_s=dur, frames=frames, hand_seen=seen,
                         ik_s=td.ik_seconds, ik_samples=td.q_times.size))
        say(f"{task:11s} {wall:9.2f} {dur:7.1f} {frames:7d} {100 * seen:9.0f}% "
              f"{td.ik_seconds:14.2f} {td.q_times.size:11d}")
    emit_json(args.json, dict(demos=args.demos, seed=args.seed, rows=rows,
                              figures={f"record_{r['task']}_s_per_demo": r["record_s"] / args.demos
                                       for r in rows}))


if __name__ == "__main__":
    main()
