"""What the first call of a process costs: the compiled (numba) kernels of the front detector
and of link-model selection are compiled on their first call in a fresh environment, and
loaded from the on-disk cache by the first call of every later process.

    python benchmarks/bench_first_call.py [--json [FILE]]

For each workload (``detector``: ``detect_fronts`` on one synthetic 640 x 480 frame;
``selection``: ``select_link_model`` with its four candidates on a simulated microwave door,
n = 30) three child processes run it twice each, with ``NUMBA_CACHE_DIR`` pointing at a new
empty folder: the first process compiles (its first call), the later ones load the cache (their
first call); the second call of a process is the steady cost. Reported: the CPU seconds of
each (the median of the two cached processes), and the compile and load costs (first call
less the steady call).
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import json
import subprocess
import sys
import tempfile
import time

from _common import add_output_arguments, emit_json

WORKLOADS = ("detector", "selection")


def _workload(name):
    """A function of no arguments running one call of the workload."""
    import numpy as np

    if name == "detector":
        from bench_front_detector import synthetic_frames

        from mmlearn.models.perception.detection import FrontDetectorConfig, detect_fronts

        fr = synthetic_frames(1, 0)[0]
        cfg = FrontDetectorConfig()
        return lambda: detect_fronts(fr["depth"], fr["K"], fr["X_WC"], cfg, rng=0)
    from mmlearn.models.articulation.link import ObservationModel
    from mmlearn.models.articulation.sim import simulate_link
    from mmlearn.models.articulation.structure import select_link_model

    tr = simulate_link("microwave", 30, rng=0)
    obs = ObservationModel(sigma_pos=0.002, sigma_orient=np.deg2rad(2.0))
    return lambda: select_link_model(tr.Z, obs=obs, rng=0)


def child(name):
    """Run the workload twice in this process; print the CPU seconds of both calls."""
    run = _workload(name)
    out = []
    for _ in range(2):
        c0 = time.process_time()
        run()
        out.append(time.process_time() - c0)
    print(json.dumps({"first_s": out[0], "second_s": out[1]}))


def measure(name, cache_dir):
    env = dict(os.environ, NUMBA_CACHE_DIR=cache_dir, OPENBLAS_NUM_THREADS="1")
    runs = []
    for _ in range(3):
        r = subprocess.run([sys.executable, __file__, "--child", name], env=env,
                           capture_output=True, text=True)
        if r.returncode != 0:
            sys.exit(f"bench_first_call: the {name} process failed: "
                     f"{(r.stderr.strip().splitlines() or ['?'])[-1]}")
        runs.append(json.loads(r.stdout.strip().splitlines()[-1]))
    cached = sorted(runs[1:], key=lambda r: r["first_s"])
    steady = sorted(r["second_s"] for r in runs)[1]
    first_cached = (cached[0]["first_s"] + cached[1]["first_s"]) / 2
    return dict(compile_first_call_s=runs[0]["first_s"], cached_first_call_s=first_cached,
                steady_call_s=steady, compile_s=runs[0]["first_s"] - steady,
                load_s=first_cached - steady)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--child", choices=WORKLOADS, help=argparse.SUPPRESS)
    add_output_arguments(ap)
    args = ap.parse_args(argv)
    if args.child:
        child(args.child)
        return
    out = {}
    for name in WORKLOADS:
        with tempfile.TemporaryDirectory() as cache:
            out[name] = measure(name, cache)
    if emit_json(args.json, dict(workloads=out, cores=os.cpu_count(),
                                 load=os.getloadavg()[0])):
        return
    for name, r in out.items():
        print(f"{name:10s} compiling first call {r['compile_first_call_s']:6.2f} s CPU, cached "
              f"first call {r['cached_first_call_s']:5.2f} s, steady {r['steady_call_s']:6.3f} s")


if __name__ == "__main__":
    main()
