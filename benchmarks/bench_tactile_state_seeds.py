"""How much of the simulated container-class rate (thesis Sec. 7.2, target 0.939) is noise
of the 10-fold cross-validation and how much differs between grasp sets.

Usage::

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_tactile_state_seeds.py RESULTS.jsonl:S [...]
        [--fold-seeds 10] [--trials 10] [--f-target 20]

``RESULTS.jsonl:S``: the grasps file of ``python -m mmlearn.apps.tactile_state --f-target 20
--trials 10 --seed S --results RESULTS.jsonl`` (nothing is simulated here). For every file it
prints the container rate of the app (fold seed S) and its mean / sd / range over fold seeds
0..N-1 for the random forest and the decision tree, the forest's confusion matrix summed over
the fold seeds, and over all files the mean and sd of both (the spread between grasp sets).
"""

from __future__ import annotations

import argparse

import numpy as np


def main(argv=None) -> int:
    from mmlearn.apps._sweep import load_results
    from mmlearn.apps.tactile_state import _sim_features, _sim_specs
    from mmlearn.models.containers import CONTAINER_CLASSES
    from mmlearn.models.tactile_state import cross_validate

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("results", nargs="+", help="RESULTS.jsonl:SEED")
    ap.add_argument("--fold-seeds", type=int, default=10)
    ap.add_argument("--trials", type=int, default=10)
    ap.add_argument("--f-target", type=float, default=20.0)
    args = ap.parse_args(argv)
    app_rate = {"forest": [], "tree": []}
    fold_mean = {"forest": [], "tree": []}
    total = None
    for item in args.results:
        path, _, seed = item.rpartition(":")
        if not path or not seed.isdigit():
            ap.error(f"expected RESULTS.jsonl:SEED, got {item!r}")
        seed = int(seed)
        by = load_results(path)
        specs = _sim_specs(list(CONTAINER_CLASSES), args.f_target, args.trials, seed)
        recs = [by[s.key]["record"] for s in specs if s.key in by and by[s.key].get("record")]
        if not recs:
            ap.error(f"{path}: no grasp of seed {seed} with --trials {args.trials} "
                     f"--f-target {args.f_target:g}")
        X, yc, _, _ = _sim_features(recs)
        for clf in ("forest", "tree"):
            reps = [cross_validate(X, yc, classifier=clf, folds=10, seed=fs)
                    for fs in range(args.fold_seeds)]
            rates = np.array([r.rate for r in reps])
            own = cross_validate(X, yc, classifier=clf, folds=10, seed=seed).rate
            app_rate[clf].append(own)
            fold_mean[clf].append(rates.mean())
            print(f"grasp seed {seed} ({len(recs)} grasps) {clf:6s}: app (fold seed {seed}) "
                  f"{own:.3f}; fold seeds 0-{args.fold_seeds - 1}: mean {rates.mean():.3f} sd "
                  f"{rates.std():.3f} range {rates.min():.3f}-{rates.max():.3f}")
            if clf == "forest":
                C = sum(r.confusion for r in reps).astype(int)
                total = C if total is None else total + C
                labels = reps[0].labels
    print(f"forest confusion summed over files and fold seeds (rows true, columns predicted; "
          f"{', '.join(labels)}):\n{total}")
    if len(args.results) > 1:
        for clf in ("forest", "tree"):
            a, m = np.array(app_rate[clf]), np.array(fold_mean[clf])
            print(f"{clf}: over {len(a)} grasp sets: app rate mean {a.mean():.3f} sd "
                  f"{a.std(ddof=1):.3f}; fold-averaged mean {m.mean():.3f} sd {m.std(ddof=1):.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
