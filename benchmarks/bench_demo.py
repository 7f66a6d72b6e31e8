"""The README's demo as a speed benchmark: ``open_cabinet --object left_door --seed 1`` (the
robot drives to the door, hooks its handle and opens it while learning its model), timed by
its own record: the simulation's CPU seconds (``Simulator.AdvanceTo`` only, not the trial's
build) and its real-time factor on the CPU clock (simulated seconds / CPU seconds). One
whole trial runs untimed first, so loading the compiled kernels and the modules the trial
imports is not counted. Prints figures; never fails on time.

    python benchmarks/bench_demo.py [--runs N] [--quick] [--json [FILE]]
"""

from __future__ import annotations

import argparse
import statistics

from _common import add_output_arguments, emit_json

from mmlearn.diagrams.articulation.trials import open_mechanism


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--object", default="left_door", help="the mechanism (default left_door)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--runs", type=int, default=3, help="timed trials (default 3)")
    add_output_arguments(ap, quick="one timed trial")
    args = ap.parse_args()
    if args.runs < 1:
        ap.error(f"--runs must be >= 1, got {args.runs}")
    runs = 1 if args.quick else args.runs
    open_mechanism(kind=args.object, seed=args.seed, show_progress=False)
    records = [open_mechanism(kind=args.object, seed=args.seed, show_progress=False)
               for _ in range(runs)]
    cpu = statistics.median(r["cpu_seconds"] for r in records)
    sim = records[0]["sim_seconds"]
    figures = {"simulation_cpu_s": cpu, "simulated_s": sim,
               "realtime_factor_cpu": sim / cpu if cpu > 0 else None,
               "success": float(all(r["success"] for r in records))}
    if emit_json(args.json, {"object": args.object, "seed": args.seed, "runs": runs,
                             "figures": figures,
                             "cpu_seconds": [r["cpu_seconds"] for r in records]}):
        return
    each = ", ".join(f"{r['cpu_seconds']:.2f}" for r in records)
    print(f"{args.object} seed {args.seed}: {sim:.2f} s simulated; simulation CPU "
          f"{each} s (median {cpu:.2f}); "
          f"real-time factor (CPU) {figures['realtime_factor_cpu']:.2f}; "
          f"opened {sum(r['success'] for r in records)}/{runs}")


if __name__ == "__main__":
    main()
