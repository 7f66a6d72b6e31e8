"""Run every speed benchmark in its quick mode and print one table of their headline figures,
with the machine's load beside each, and a second table of the figures that have an anchor (the
camera's frame rate, published peers, the targets) with their ratio to it (prints figures;
never fails on time).

    OPENBLAS_NUM_THREADS=1 python benchmarks/run_speed.py [--json FILE] [--only a,b] [--list]
                                                          [--peer-python PYTHON]

``--peer-python``: the interpreter of an environment with ``ripl-articulation`` (see
``bench_peer_ripl.py``), passed to that benchmark (default: the environment variable
``MMLEARN_PEER_PYTHON``); without either the peer's column is skipped.
``python benchmarks/make_performance_doc.py FILE`` writes docs/performance.md's table from the
JSON.

Each benchmark runs as ``python benchmarks/<name>.py --quick --json TMP`` in its own process
(one BLAS thread); the table lists its ``figures`` (see ``_common.py``), the benchmark's wall
time and the 1-minute load average (``os.getloadavg``) when it started and ended. On a shared
machine the load says how far wall-clock figures are inflated; CPU-time figures are not.
Exit status 1 when a benchmark failed (its error is printed), else 0.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent

#: the speed benchmarks, in the order they run
SPEED = ["bench_articulation", "bench_structure", "bench_front_tracker", "bench_front_detector",
         "bench_depth_filter", "bench_depth_noise", "bench_body_schema", "bench_learner_cost",
         "bench_imitation", "bench_dbn_reproducer", "bench_record_demos", "bench_tactile_sim",
         "bench_tactile_objects", "bench_liquid_roll", "bench_sweep", "bench_peer_gp",
         "bench_peer_ripl", "bench_demo"]

#: figures with an anchor: (benchmark, figure, what the anchor is, its value, target as
#: (comparison, value) or None); ratio = figure / anchor value
ANCHORS = [
    ("bench_front_detector", "total_cpu_ms", "camera frame period, 30 Hz (ms)", 33.3,
     ("<", 33.0)),
    ("bench_front_detector", "planes_cpu_ms", "CAPE plane extraction per core (ms)", 3.3,
     ("<", 5.0)),
    ("bench_front_detector", "masks_cpu_ms", "masks target (ms)", 10.0, ("<", 10.0)),
    ("bench_articulation", "select_microwave_n30_cpu_ms", "ripl-articulation, n = 30 (ms)",
     20.0, ("<", 10.0)),
    ("bench_articulation", "select_microwave_n200_cpu_ms", "ripl-articulation, n = 200 (ms)",
     320.0, ("<", 30.0)),
    ("bench_peer_gp", "gp_ms", "scikit-learn GaussianProcessRegressor, same data (ms)", None,
     None),
    ("bench_peer_gp", "speedup", "faster than scikit-learn (x)", 6.9, (">=", 1.0)),
    ("bench_demo", "realtime_factor_cpu", "real time (x)", 1.0, (">=", 6.0)),
]


def run_one(name: str, timeout: float, extra=()) -> dict:
    """Run benchmark ``name`` quick (with the arguments ``extra``); returns {name, wall_s,
    load_start, load_end, figures, error}."""
    with tempfile.TemporaryDirectory() as d:
        out = Path(d) / "figures.json"
        env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
        load0, t0 = os.getloadavg()[0], time.perf_counter()
        try:
            p = subprocess.run([sys.executable, str(HERE / f"{name}.py"), "--quick", "--json",
                                str(out), *extra], capture_output=True, text=True, env=env,
                               timeout=timeout, cwd=d)
            error = None if p.returncode == 0 else (p.stderr.strip().splitlines() or
                                                     [f"exit status {p.returncode}"])[-1]
        except subprocess.TimeoutExpired:
            error = f"no result within {timeout:.0f} s"
        wall, load1 = time.perf_counter() - t0, os.getloadavg()[0]
        figures = {}
        if error is None:
            try:
                figures = json.loads(out.read_text())["figures"]
            except (OSError, ValueError, KeyError) as e:
                error = f"no figures in its JSON ({type(e).__name__}: {e})"
    return dict(name=name, wall_s=wall, load_start=load0, load_end=load1, figures=figures,
                error=error)


def _fmt(v) -> str:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return str(v)
    return f"{v:.4g}"


def print_table(rows: list[dict]) -> None:
    print(f"{'benchmark':22s} {'figure':38s} {'value':>10s} {'wall s':>7s} {'load':>10s}")
    for r in rows:
        load = f"{r['load_start']:.1f}-{r['load_end']:.1f}"
        items = list(r["figures"].items()) or [("ERROR: " + str(r["error"]), "")]
        for k, (fig, v) in enumerate(items):
            head = (r["name"].removeprefix("bench_"), f"{r['wall_s']:7.1f}", f"{load:>10s}") \
                if k == 0 else ("", "", "")
            print(f"{head[0]:22s} {fig:38s} {_fmt(v):>10s} {head[1]:>7s} {head[2]:>10s}")


def anchor_rows(rows: list[dict]) -> list[dict]:
    """The anchored figures of ``rows`` (run_one's): {benchmark, figure, value, anchor,
    anchor_value, ratio, target, met, load}; value None when the benchmark did not run or has
    no such figure. The sklearn anchor's value is the same run's scikit-learn time."""
    by = {r["name"]: r for r in rows}
    out = []
    for bench, fig, what, ref, target in ANCHORS:
        r = by.get(bench)
        if r is None:
            continue
        v = r["figures"].get(fig)
        if bench == "bench_peer_gp" and fig == "gp_ms":
            ref = r["figures"].get("sklearn_ms")
        ratio = None if v is None or not ref else v / ref
        met = None
        if v is not None and target is not None:
            met = v < target[1] if target[0] == "<" else v >= target[1]
        out.append(dict(benchmark=bench, figure=fig, value=v, anchor=what, anchor_value=ref,
                        ratio=ratio, target=None if target is None else f"{target[0]} "
                        f"{target[1]:g}", met=met, load=f"{r['load_start']:.1f}-"
                        f"{r['load_end']:.1f}"))
    return out


def print_anchors(arows: list[dict]) -> None:
    print(f"{'figure':44s} {'value':>9s} {'anchor':>9s} {'ratio':>7s} {'target':>8s} "
          f"{'met':>4s} {'load':>9s}  anchor")
    for a in arows:
        met = "-" if a["met"] is None else ("yes" if a["met"] else "no")
        ratio = "-" if a["ratio"] is None else f"{a['ratio']:.2f}"
        print(f"{a['benchmark'].removeprefix('bench_') + ': ' + a['figure']:44s} "
              f"{_fmt(a['value']) if a['value'] is not None else '-':>9s} "
              f"{_fmt(a['anchor_value']) if a['anchor_value'] is not None else '-':>9s} "
              f"{ratio:>7s} "
              f"{a['target'] or '-':>8s} {met:>4s} {a['load']:>9s}  {a['anchor']}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", default=None, metavar="FILE", help="also write the rows here")
    ap.add_argument("--only", default=None, help="comma-separated benchmark names")
    ap.add_argument("--timeout", type=float, default=300.0, help="per benchmark, s")
    ap.add_argument("--list", action="store_true", help="list the speed benchmarks and exit")
    ap.add_argument("--peer-python", default=os.environ.get("MMLEARN_PEER_PYTHON") or None,
                    metavar="PYTHON", help="interpreter with ripl-articulation, for "
                    "bench_peer_ripl (default: $MMLEARN_PEER_PYTHON)")
    a = ap.parse_args(argv)
    if a.list:
        print("\n".join(SPEED))
        return 0
    names = SPEED
    if a.only:
        names = [n if n.startswith("bench_") else f"bench_{n}" for n in a.only.split(",")]
        unknown = sorted(set(names) - set(SPEED))
        if unknown:
            ap.error(f"--only: not a speed benchmark: {', '.join(unknown)}")
    print(f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} at start", flush=True)
    t0 = time.perf_counter()
    rows = []
    for n in names:
        extra = (["--peer-python", a.peer_python]
                 if n == "bench_peer_ripl" and a.peer_python else [])
        rows.append(run_one(n, a.timeout, extra))
        print(f"  {n}: {rows[-1]['wall_s']:.1f} s" + (f" ERROR {rows[-1]['error']}"
                                                       if rows[-1]["error"] else ""), flush=True)
    print()
    print_table(rows)
    arows = anchor_rows(rows)
    if arows:
        print()
        print_anchors(arows)
    print(f"total {time.perf_counter() - t0:.0f} s")
    if a.json:
        from mmlearn.models.common.fileio import atomic_write_text

        atomic_write_text(a.json, json.dumps(dict(cores=os.cpu_count(), date=time.strftime(
            "%Y-%m-%d %H:%M UTC", time.gmtime()), benchmarks=rows, anchors=arows),
            indent=1) + "\n")
    return 1 if any(r["error"] for r in rows) else 0


if __name__ == "__main__":
    raise SystemExit(main())
