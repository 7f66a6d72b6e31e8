"""Recognition rates of the ch. 7 grasp features on the real iCub grasps (prints figures).

    python benchmarks/bench_tactile_state.py [--data DIR] [--seeds 5] [--json [FILE]]

DIR defaults to ``../shared/data/icub_grasp/train`` beside the repository (10 objects x trials
1-10 after leaving out full_coke). For the decision tree (thesis) and the random forest, over
``--seeds`` seeds (fold assignment and forest):

- stratified 10-fold cross-validation on all trials (each grasp predicted by a model trained
  on ~9 trials per class);
- trained on trials 1-5, tested on 6-10, and the reverse (5 trials per class to learn from);
- leave-one-trial-number-out: for each trial number j, train on the other nine, test on j
  (the same ~9 training trials per class as CV, held out by trial number);
- the same with ``steady_average`` (steady-phase means instead of single samples);
- feature extraction and forest training time (process CPU).

None of these choose a parameter: the thresholds are fixed in models/tactile/icub_grasp.py from the
untouched fingers and the encoder resolution, not from these rates.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import time
from pathlib import Path

import numpy as np

from _common import add_output_arguments, emit_json

from mmlearn.models.tactile.icub_grasp import CONTACT_LEVEL, REST_VELOCITY, load_icub_dir
from mmlearn.models.tactile.state import cross_validate, evaluate_split, feature_matrix

DEFAULT = Path(__file__).resolve().parents[2] / "shared" / "data" / "icub_grasp" / "train"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", default=str(DEFAULT))
    ap.add_argument("--seeds", type=int, default=5)
    add_output_arguments(ap)
    ap.add_argument("--classifiers", default="tree,forest",
                    help="comma-separated: tree, forest, boost (gradient boosting)")
    args = ap.parse_args(argv)
    clfs = [c for c in args.classifiers.split(",") if c]
    trials, _ = load_icub_dir(args.data)
    y = np.array([t.label for t in trials])
    num = np.array([t.trial for t in trials])
    grasps = [t.to_grasp() for t in trials]
    res = {"n": len(trials), "classes": len(set(y.tolist()))}
    for avg in (False, True):
        c0 = time.process_time()
        X, _ = feature_matrix(grasps, contact_force=CONTACT_LEVEL, rest_velocity=REST_VELOCITY,
                              steady_average=avg)
        t_feat = (time.process_time() - c0) / len(grasps)
        key = "steady_average" if avg else "thesis_single_sample"
        res[key] = {"feature_cpu_ms_per_grasp": 1e3 * t_feat}
        for clf in clfs:
            c0 = time.process_time()
            cv = [cross_validate(X, y, classifier=clf, seed=s).rate for s in range(args.seeds)]
            t_cv = (time.process_time() - c0) / args.seeds
            a = [evaluate_split(X[num <= 5], y[num <= 5], X[num > 5], y[num > 5],
                                classifier=clf, seed=s)[0].rate for s in range(args.seeds)]
            b = [evaluate_split(X[num > 5], y[num > 5], X[num <= 5], y[num <= 5],
                                classifier=clf, seed=s)[0].rate for s in range(args.seeds)]
            lo = []
            for s in range(args.seeds):
                ok = 0
                for j in sorted(set(num.tolist())):
                    r, _ = evaluate_split(X[num != j], y[num != j], X[num == j], y[num == j],
                                          classifier=clf, seed=s)
                    ok += int(round(r.rate * (num == j).sum()))
                lo.append(ok / len(y))
            res[key][clf] = {"cv10": cv, "train1to5_test6to10": a, "train6to10_test1to5": b,
                             "leave_one_trial_out": lo, "cv_cpu_s": t_cv}
    if emit_json(args.json, res):
        return
    print(f"iCub grasps: {res['n']} trials, {res['classes']} classes, seeds 0-{args.seeds - 1}")
    for key in ("thesis_single_sample", "steady_average"):
        r = res[key]
        print(f"\n{key}  (features {r['feature_cpu_ms_per_grasp']:.2f} ms CPU per grasp)")
        for clf in clfs:
            q = r[clf]
            f = lambda v: f"{np.mean(v):.3f} [{min(v):.2f}-{max(v):.2f}]"  # noqa: E731
            print(f"  {clf:6s} 10-fold CV {f(q['cv10'])}  1-5->6-10 {f(q['train1to5_test6to10'])}"
                  f"  6-10->1-5 {f(q['train6to10_test1to5'])}  leave-one-trial-out "
                  f"{f(q['leave_one_trial_out'])}  (CV {q['cv_cpu_s']:.1f} s CPU)")


if __name__ == "__main__":
    main()
