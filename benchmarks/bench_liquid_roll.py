"""Speed of one liquid-detection trial (grasp, lift, roll) and of the feature.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_liquid_roll.py [--cycles 2]

Prints the simulated time, the wall time, the real-time factor of the Drake simulation, and
the time of :func:`mmlearn.models.liquid.liquid_feature` on the recorded taxels.
"""

import argparse
import time

import numpy as np

from mmlearn.diagrams.liquid_roll import LiquidRollConfig, make_instance, simulate_roll
from mmlearn.models.liquid import liquid_feature


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cycles", type=float, default=2.0)
    ap.add_argument("--container", default="odwalla_half")
    args = ap.parse_args()
    inst = make_instance(args.container, np.random.default_rng(0))
    cfg = LiquidRollConfig(roll_cycles=args.cycles, grasp_height=inst.height / 2)
    t0 = time.perf_counter()
    r = simulate_roll(cfg, container=inst)
    wall = time.perf_counter() - t0
    t = r["t"]
    m = (t >= r["roll_window"][0]) & (t <= r["roll_window"][1])
    x = r["taxels"][m]
    n = 200
    t1 = time.perf_counter()
    for _ in range(n):
        f = liquid_feature(x)
    ft = (time.perf_counter() - t1) / n
    print(f"{args.container}: simulated {cfg.duration:.2f} s in {wall:.1f} s wall "
          f"(real-time factor {cfg.duration / wall:.2f}); feature {f:.4f} from {x.shape} "
          f"taxel samples in {1e3 * ft:.3f} ms")


if __name__ == "__main__":
    main()
