"""The sweep runner's overhead per trial, local pool vs Ray (apps/_sweep.py).

    python benchmarks/bench_sweep.py [--trials 40] [--sleep 2.0] [--jobs 2]

Runs ``probe_trial`` (sleeps ``--sleep`` s) through both executors and prints the throughput
and the overhead per trial: (wall time x jobs / trials - sleep) / sleep, i.e. the share of a
trial's time the runner adds (process start-up, scheduling, result transport, the results
file). Ray's start-up (``ray.init``) is printed separately: it is paid once per sweep.
"""

import argparse
import tempfile
import time
from pathlib import Path

from mmlearn.apps._sweep import TrialSpec, run_sweep


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=40)
    ap.add_argument("--sleep", type=float, default=2.0, help="seconds per trial")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--payload", type=int, default=1000, help="numbers in each record")
    args = ap.parse_args(argv)
    specs = [TrialSpec(fn="mmlearn.apps._sweep:probe_trial", seed=i,
                       params={"sleep_s": args.sleep, "payload": args.payload})
             for i in range(args.trials)]
    print(f"{args.trials} trials of {args.sleep} s, {args.jobs} jobs")
    print(f"{'executor':9s} {'wall s':>8s} {'trials/min':>11s} {'overhead/trial':>15s}")
    for ex in ("local", "ray"):
        extra = 0.0
        if ex == "ray":
            try:
                import ray
            except ImportError:
                print("ray: not installed (pip install 'mmlearn[ray]')")
                continue
            t0 = time.perf_counter()
            ray.init(num_cpus=args.jobs, include_dashboard=False, log_to_driver=False)
            extra = time.perf_counter() - t0
        with tempfile.TemporaryDirectory() as d:
            t0 = time.perf_counter()
            res = run_sweep(specs, results=Path(d) / "r.jsonl", executor=ex, jobs=args.jobs,
                            show_progress=False)
            wall = time.perf_counter() - t0
        assert len(res.records) == args.trials
        over = (wall * args.jobs / args.trials - args.sleep) / args.sleep
        print(f"{ex:9s} {wall:8.2f} {60 * args.trials / wall:11.1f} {100 * over:14.1f}%"
              + (f"   (+ ray.init {extra:.1f} s once)" if ex == "ray" else ""))
        if ex == "ray":
            ray.shutdown()


if __name__ == "__main__":
    main()
