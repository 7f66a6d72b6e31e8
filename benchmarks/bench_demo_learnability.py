"""Do the recorded pick-and-place demonstrations tell the two tables apart? (thesis Fig. 8.5/8.6)

    python benchmarks/bench_demo_learnability.py [--seeds 10] [--first-seed 0] [--demos 1,2,4]

For each seed: record ``n`` demonstrations (``record_demonstrations``), learn the task
(imit-model's ``learn_task``), and at the slice where the learned gripper opens (the place)
fuse the two table constraints as the reproduction's product of Gaussians does (the carried
cup's constraint is skipped) in a fresh layout with the tables **swapped**. Prints the xy
distance of that fused hand target from the demonstrated spot (the teacher's nominal place
offset on table B; the hand above it): the
error a reproduction inherits from the demonstrations alone (no arm, no controller).
"""

import argparse
import dataclasses

import numpy as np

from mmlearn.diagrams.imitation.demonstrations import record_demonstrations
from mmlearn.models.imitation.dbn import learn_task
from mmlearn.models.imitation.teacher import task_scene


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--demos", default="1,2,4")
    args = ap.parse_args(argv)
    for n in [int(x) for x in args.demos.split(",")]:
        errs = []
        for seed in range(args.first_seed, args.first_seed + args.seeds):
            m = learn_task(record_demonstrations("pick_place", n, seed=seed))
            g = m.mean["gripper"][:, 0]
            k = np.flatnonzero(g < 0.5)[-1]  # last closed slice: the place
            sc = task_scene("pick_place", swap_tables=True).sampled(100 + seed).resolved()
            # the demonstrated spot: the teacher's nominal place offset on table B (each
            # demonstration jitters it by up to 5 mm)
            sc = dataclasses.replace(sc, place_offset=[0.0, 0.0])
            objs = {"obj:table_a": sc.table_marker("a"), "obj:table_b": sc.table_marker("b")}
            P = sum(1.0 / m.var[c][k] for c in objs)
            target = sum((objs[c] - m.mean[c][k]) / m.var[c][k] for c in objs) / P
            want = sc.place_spot() + [0.0, 0.0, sc.cup_height + 0.015]
            errs.append(float(np.linalg.norm((target - want)[:2])))
        e = np.array(errs)
        print(f"{n} demo(s): fused place target error (xy) median {np.median(e):.3f} m, "
              f"< 0.02 m in {int((e < 0.02).sum())}/{e.size} seeds; per seed "
              f"{np.round(e, 3).tolist()}")


if __name__ == "__main__":
    main()
