"""The sweep runner's overhead per trial, local pool vs Ray (apps/common/sweep.py).

    python benchmarks/bench_sweep.py [--trials 40] [--sleep 2.0] [--jobs 2] [--quick]
    python benchmarks/bench_sweep.py --real 8 [--jobs 2] [--kind drawer]
    ... [--json [FILE]]

Default: runs ``probe_trial`` (sleeps ``--sleep`` s) through both executors and prints the
throughput and the overhead per trial: (wall time x jobs / trials - sleep) / sleep, i.e. the
share of a trial's time the runner adds (process start-up, scheduling, result transport, the
results file). Ray's start-up (``ray.init``) is printed separately: it is paid once per sweep.

``--real N``: the cost of where a real trial runs. N ``operate_trials`` trials (``--kind``,
seeds 0..N-1), each run once in each of: a local spawn pool of ``--jobs`` workers (``local``),
Ray tasks whose trial runs in the Ray worker's child process (``ray``, the runner's way) and
Ray tasks whose trial runs in the Ray worker process itself (``ray-direct``), ``--jobs``
trials at a time, the three ways taking turns in rotating order so that all see the same
machine load (every worker is warmed up with one trial first). Prints each trial's wall and
CPU time [s] (measured where the trial ran: ``wall_s``, ``cpu_s`` of its results line), the
throughput of each way (trials / the summed wall time of its turns, scheduling and transport
included) and the mean of (executor / local - 1) over the trials, i.e. how much longer the
same trial takes under that executor.
"""

import argparse
import multiprocessing as mp
import os
import statistics as st
import tempfile
import time
from dataclasses import asdict
from pathlib import Path

from _common import add_output_arguments, emit_json
from mmlearn.apps.common.sweep import (TrialSpec, _init_worker, _local_worker, _ray_execute,
                                       probe_trial, run_sweep)
from mmlearn.diagrams.articulation.trials import operate_trial


def probe(args):
    specs = [TrialSpec(fn=probe_trial, seed=i,
                       params={"sleep_s": args.sleep, "payload": args.payload})
             for i in range(args.trials)]
    print(f"{args.trials} trials of {args.sleep} s, {args.jobs} jobs")
    print(f"{'executor':9s} {'wall s':>8s} {'trials/min':>11s} {'overhead/trial':>15s}")
    out = {}
    for ex in ("local",) if args.quick else ("local", "ray"):
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
        out[ex] = dict(wall_s=wall, trials_per_min=60 * args.trials / wall, overhead=over,
                       init_s=extra)
        print(f"{ex:9s} {wall:8.2f} {60 * args.trials / wall:11.1f} {100 * over:14.1f}%"
              + (f"   (+ ray.init {extra:.1f} s once)" if ex == "ray" else ""))
        if ex == "ray":
            ray.shutdown()
    return dict(trials=args.trials, sleep_s=args.sleep, jobs=args.jobs, executors=out,
                figures={f"{ex}_overhead_per_trial": v["overhead"] for ex, v in out.items()})


def real(args):
    import ray

    modes = ("local", "ray", "ray-direct")
    jobs = args.jobs

    def spec(seed):
        s = TrialSpec(fn=operate_trial, seed=seed,
                      params={"kind": args.kind}, label=f"{args.kind} {seed}")
        return dict(asdict(s), key=s.key)

    ray.init(num_cpus=jobs, include_dashboard=False, log_to_driver=False)
    task = ray.remote(num_cpus=1, max_retries=0)(_ray_execute)
    pool = mp.get_context("spawn").Pool(jobs, initializer=_init_worker, initargs=(None,))

    def go(mode, specs):
        """``jobs`` trials at once, as the runner runs them; their lines and the wall time."""
        t0 = time.perf_counter()
        if mode == "local":
            lines = pool.map(_local_worker, specs, chunksize=1)
        else:
            lines = ray.get([task.remote(s, [], mode == "ray") for s in specs])
        return lines, time.perf_counter() - t0

    load0 = os.getloadavg()
    for m in modes:  # warm-up: every worker imports and builds its first diagrams
        go(m, [spec(1000 + j) for j in range(jobs)])
    rows = {m: [] for m in modes}
    walls = {m: 0.0 for m in modes}
    for i in range(0, args.real, jobs):
        order = modes[(i // jobs) % 3:] + modes[:(i // jobs) % 3]
        for m in order:
            lines, w = go(m, [spec(j) for j in range(i, min(i + jobs, args.real))])
            assert all(ln["error"] is None for ln in lines), [ln["error"] for ln in lines]
            rows[m] += lines
            walls[m] += w
    pool.close()
    ray.shutdown()
    n = len(rows["local"])
    print(f"{n} {args.kind} trials, {jobs} at a time, rotating order; load average "
          f"{load0[0]:.1f} at the start, {os.getloadavg()[0]:.1f} at the end, "
          f"{os.cpu_count()} cores")
    print(f"{'seed':>4s} " + " ".join(f"{m + ' wall':>15s} {m + ' cpu':>14s}" for m in modes)
          + "  outcome")
    for i in range(n):
        outs = {(rows[m][i]["record"]["success"], rows[m][i]["record"]["opened"])
                for m in modes}
        print(f"{i:4d} " + " ".join(f"{rows[m][i]['wall_s']:15.2f} {rows[m][i]['cpu_s']:14.2f}"
                                    for m in modes)
              + ("  identical" if len(outs) == 1 else f"  DIFFERENT {outs}"))
    print(f"{'mean':>4s} " + " ".join(
        f"{st.mean(ln['wall_s'] for ln in rows[m]):15.2f} "
        f"{st.mean(ln['cpu_s'] for ln in rows[m]):14.2f}" for m in modes))
    for m in modes:
        print(f"{m:10s} {n} trials in {walls[m]:6.1f} s: {60 * n / walls[m]:5.2f} trials/min"
              + ("" if m == "local" else f"  ({100 * (walls[m] / walls['local'] - 1):+.1f} % "
                                         "time vs local)"))
    for m in modes[1:]:
        for key in ("wall_s", "cpu_s"):
            rat = [b[key] / a[key] - 1 for a, b in zip(rows["local"], rows[m])]
            print(f"{m:10s} {key[:-2]:4s} per trial vs local: mean {100 * st.mean(rat):+5.1f} % "
                  f"(per trial {' '.join(f'{100 * x:+.1f}' for x in rat)})")
    return dict(kind=args.kind, jobs=jobs, trials=rows, walls_s=walls)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=40)
    ap.add_argument("--sleep", type=float, default=2.0, help="seconds per trial")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--payload", type=int, default=1000, help="numbers in each record")
    ap.add_argument("--real", type=int, default=0,
                    help="instead: N real operate_trials trials, local vs Ray, paired")
    ap.add_argument("--kind", default="drawer", help="the object of the --real trials")
    add_output_arguments(ap, quick="8 trials of 0.5 s, the local pool only (a few seconds)")
    args = ap.parse_args(argv)
    if args.quick:
        args.trials, args.sleep = 8, 0.5
    emit_json(args.json, real(args) if args.real else probe(args))


if __name__ == "__main__":
    main()
