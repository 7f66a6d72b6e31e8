"""Speed of one liquid-detection trial (grasp, lift, roll) and of the feature.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_liquid_roll.py [--cycles 2] [--time-step 0.002]
        [--container odwalla_half] [--quick] [--json [FILE]]

Prints the simulated time, the wall and CPU (process) time of the Drake simulation and their
real-time factors (simulated / elapsed: > 1 is faster than real time; on a shared machine the
CPU time is the one to compare, the wall time depends on the load, which is printed), and the
time of :func:`mmlearn.models.tactile.liquid.liquid_feature` (whole roll, the thesis') and of the
coast mask plus :func:`mmlearn.models.tactile.liquid.coast_feature` (the default) on the recorded
taxels.
"""

import argparse
import os
import time

import numpy as np

from _common import add_output_arguments, emit_json
from mmlearn.diagrams.tactile.liquid_roll import (LiquidRollConfig, make_instance, roll_change_windows,
                                                  simulate_roll)
from mmlearn.models.tactile.evaluation import COAST_DELAY
from mmlearn.models.tactile.liquid import coast_feature, coast_mask, liquid_feature


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cycles", type=float, default=2.0)
    ap.add_argument("--container", default="odwalla_half")
    ap.add_argument("--time-step", type=float, default=LiquidRollConfig.time_step)
    add_output_arguments(ap, quick="one roll cycle (a few seconds)")
    args = ap.parse_args()
    if args.quick:
        args.cycles = 1.0
    inst = make_instance(args.container, np.random.default_rng(0))
    cfg = LiquidRollConfig(roll_cycles=args.cycles, grasp_height=inst.height / 2,
                           time_step=args.time_step)
    load0 = os.getloadavg()[0]
    t0, c0 = time.perf_counter(), time.process_time()
    r = simulate_roll(cfg, container=inst)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    t = r["t"]
    m = (t >= r["roll_window"][0]) & (t <= r["roll_window"][1])
    x = r["taxels"][m]
    n = 200
    t1 = time.perf_counter()
    for _ in range(n):
        f = liquid_feature(x)
    ft = (time.perf_counter() - t1) / n
    windows = roll_change_windows(cfg)
    t2 = time.perf_counter()
    for _ in range(n):
        cm = coast_mask(t[m], windows, start=r["roll_window"][0], end=r["roll_window"][1],
                        delay=COAST_DELAY)
        fc = coast_feature(x, cm)
    fct = (time.perf_counter() - t2) / n
    res = dict(container=args.container, time_step_s=cfg.time_step, sim_s=cfg.duration,
               wall_s=wall, cpu_s=cpu, load_start=load0, load_end=os.getloadavg()[0],
               feature=f, feature_ms=1e3 * ft, coast_feature=fc, coast_feature_ms=1e3 * fct,
               figures={"realtime_factor_wall": cfg.duration / wall,
                        "realtime_factor_cpu": cfg.duration / cpu,
                        "feature_ms": 1e3 * ft, "coast_feature_ms": 1e3 * fct})
    if emit_json(args.json, res):
        return
    print(f"{args.container}, time step {1e3 * cfg.time_step:g} ms: simulated "
          f"{cfg.duration:.2f} s in {wall:.1f} s wall (real-time factor "
          f"{cfg.duration / wall:.2f}), {cpu:.1f} s CPU (real-time factor "
          f"{cfg.duration / cpu:.2f}); load average {load0:.1f} -> {os.getloadavg()[0]:.1f} "
          f"on {os.cpu_count()} cores; feature (whole roll) {f:.5f} from {x.shape} taxel "
          f"samples in {1e3 * ft:.3f} ms; coast_detrended {fc:.5f} from {int(cm.sum())} coast "
          f"samples in {1e3 * fct:.3f} ms")


if __name__ == "__main__":
    main()
