"""Speed of the ch. 6 recognition grasps (prints figures; target: one grasp simulated
faster than real time).

One grasp per class (or ``--classes``) at the middle of its height grid, as
``apps/tactile_recognition.py`` runs them: wall time against simulated time (the grasp stops
0.3 s after both fingers are in force control) and the number of hydroelastic contact
faces of the last frame.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_tactile_objects.py [--classes a,b] [--seed 0]
        [--quick] [--json [FILE]]
"""

import argparse
import os
import time

import numpy as np

from _common import add_output_arguments, emit_json
from mmlearn.diagrams.tactile.trials import grid_heights, object_grasp_trial
from mmlearn.sdf.tactile_objects import CLASSES


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--classes", default=",".join(CLASSES))
    ap.add_argument("--seed", type=int, default=0)
    add_output_arguments(ap, quick="the first class only (a few seconds)")
    a = ap.parse_args()
    if a.quick:
        a.classes = next(iter(CLASSES))
    say = print if a.json != "-" else (lambda *args, **kw: None)  # JSON instead of a table
    say(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    rows = []
    for c in a.classes.split(","):
        hs = grid_heights(c)
        t0, c0 = time.perf_counter(), time.process_time()
        r = object_grasp_trial(seed=a.seed, cls=c, height=float(hs[len(hs) // 2]))
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        rows.append((wall, cpu, r["sim_time"]))
        say(f"{c:14s} sim {r['sim_time']:.2f} s  wall {wall:.2f} s  cpu {cpu:.2f} s  "
              f"real-time factor {r['sim_time'] / wall:.2f}  width {1000 * r['width']:.1f} mm  "
              f"force {r['force']:.1f} N  contact {r['contact']}")
    w, c, s = np.array(rows).T
    emit_json(a.json, dict(classes=a.classes.split(","), wall_s=w, cpu_s=c, sim_s=s,
                           figures={"realtime_factor_wall": s.sum() / w.sum(),
                                    "realtime_factor_cpu": s.sum() / c.sum(),
                                    "slowest_wall_s": w.max()}))
    say(f"all: {len(rows)} grasps, simulated {s.sum():.1f} s in {w.sum():.1f} s wall / "
          f"{c.sum():.1f} s CPU (real-time factor {s.sum() / w.sum():.2f} wall, "
          f"{s.sum() / c.sum():.2f} CPU); slowest {w.max():.2f} s wall")


if __name__ == "__main__":
    main()
