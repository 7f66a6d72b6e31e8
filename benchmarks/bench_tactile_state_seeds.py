"""Simulated container grasps over several grasp seeds (thesis Sec. 7.1.3, Fig. 7.7b, Table
7.2): container rate, state given container and the Odwalla probing-force sweep, per seed and
averaged, for every classifier; and how much of the container rate is noise of the 10-fold
cross-validation.

Usage::

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_tactile_state_seeds.py RESULTS.jsonl:S [...]
        [--fold-seeds 10] [--trials 16] [--f-target 20] [--sweep-trials 24]
        [--classifiers forest,tree,boost] [--wall-model pressure|linear]
        [--grasp-variation wall|shell|none] [--json [FILE]]

``RESULTS.jsonl:S``: the grasps file of ``python -m mmlearn.apps.tactile_state --f-target 20
--trials N --seed S --results RESULTS.jsonl [--f-sweep --sweep-trials M]`` (nothing is
simulated here; ``--trials`` / ``--sweep-trials`` must be the app's, default 16 / 24 as
there; a file without the sweep simply has no sweep figures). For every file and classifier
it prints the container rate of the app (fold seed S) and its mean / sd / range over fold seeds 0..N-1, the state rate given each container
(fold seed S), and with ``--sweep-trials N`` the Odwalla state rate at 17 / 20 / 23 N (Table
7.2); then the first classifier's container confusion summed over files and fold seeds, and over all
files the mean and sd of each figure (the spread between grasp sets) and, with the sweep in two
or more files, the rise of the Odwalla rate from the lowest to the highest force paired by grasp
set (mean, sd, the sets in which it rose, and a one-sided paired t-test).
"""

from __future__ import annotations

import argparse

import numpy as np

from _common import add_output_arguments, emit_json


def main(argv=None) -> int:
    from scipy.stats import ttest_rel

    from mmlearn.apps.common.sweep import TrialSpec, load_results
    from mmlearn.diagrams.tactile.trials import (SWEEP_FORCES, container_grasp_plan,
                                                 odwalla_sweep_plan)
    from mmlearn.models.tactile.containers import CONTAINER_CLASSES
    from mmlearn.models.tactile.evaluation import container_grasp_features, fold_cv
    from mmlearn.models.tactile.state import CLASSIFIERS

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("results", nargs="+", help="RESULTS.jsonl:SEED")
    ap.add_argument("--fold-seeds", type=int, default=10)
    ap.add_argument("--trials", type=int, default=16,
                    help="grasps per container and state of the app's run (its default 16)")
    ap.add_argument("--f-target", type=float, default=20.0)
    ap.add_argument("--sweep-trials", type=int, default=24,
                    help="grasps per Odwalla state and force of the app's --f-sweep (its default "
                         "24; 0: ignore the sweep)")
    ap.add_argument("--classifiers", default=",".join(CLASSIFIERS))
    ap.add_argument("--wall-model", choices=("pressure", "linear"), default="pressure",
                    help="the app's --wall-model the files were simulated with")
    ap.add_argument("--grasp-variation", choices=("wall", "shell", "none"), default="wall",
                    help="the app's --grasp-variation the files were simulated with")
    add_output_arguments(ap)
    args = ap.parse_args(argv)
    clfs = [c for c in args.classifiers.split(",") if c]
    for c in clfs:
        if c not in CLASSIFIERS:
            ap.error(f"--classifiers: unknown {c!r}; choose from {', '.join(CLASSIFIERS)}")
    def cv(X, y, clf, seed):  # 10-fold, fewer when a class has fewer grasps (as the app)
        return fold_cv(X, y, classifier=clf, folds=10, seed=seed)[0]

    rows = []  # one dict per (file, classifier)
    total, labels = None, None
    for item in args.results:
        path, _, seed = item.rpartition(":")
        if not path or not seed.isdigit():
            ap.error(f"expected RESULTS.jsonl:SEED, got {item!r}")
        seed = int(seed)
        by = load_results(path)
        specs = [TrialSpec(**d) for d in container_grasp_plan(
            list(CONTAINER_CLASSES), args.f_target, args.trials, seed, args.wall_model,
            args.grasp_variation)]
        recs = [by[s.key]["record"] for s in specs if s.key in by and by[s.key].get("record")]
        if not recs:
            ap.error(f"{path}: no grasp of seed {seed} with --trials {args.trials} "
                     f"--f-target {args.f_target:g}")
        X, yc, ys, _ = container_grasp_features(recs)
        sweep = {}
        if args.sweep_trials:
            for f in SWEEP_FORCES:
                sp = [TrialSpec(**d) for d in odwalla_sweep_plan(
                    f, args.sweep_trials, seed, args.wall_model, args.grasp_variation)]
                rs = [by[s.key]["record"] for s in sp if s.key in by and by[s.key].get("record")]
                if rs:
                    Xs, _, yss, _ = container_grasp_features(rs)
                    sweep[f] = (Xs, yss, len(sp) - len(rs))
        for clf in clfs:
            reps = [cv(X, yc, clf, fs) for fs in range(args.fold_seeds)]
            rates = np.array([r.rate for r in reps])
            own = cv(X, yc, clf, seed)
            row = {"seed": seed, "classifier": clf, "n": len(recs),
                   "failed": len(specs) - len(recs), "container_rate": own.rate,
                   "container_rate_fold_mean": float(rates.mean()),
                   "container_rate_fold_sd": float(rates.std()),
                   "container_per_class": own.per_class(), "state_rate": {}, "f_sweep": {}}
            for name in sorted(set(yc.tolist())):
                m = yc == name
                row["state_rate"][name] = cv(X[m], ys[m], clf, seed).rate
            for f, (Xs, yss, nf) in sweep.items():
                row["f_sweep"][f"{f:g}"] = cv(Xs, yss, clf, seed).rate
                row["f_sweep_failed_" + f"{f:g}"] = nf
            rows.append(row)
            print(f"grasp seed {seed} ({len(recs)} grasps, {row['failed']} failed) {clf:6s}: "
                  f"container {own.rate:.3f} (fold seeds 0-{args.fold_seeds - 1}: mean "
                  f"{rates.mean():.3f} sd {rates.std():.3f} range {rates.min():.3f}-"
                  f"{rates.max():.3f}); state | " + ", ".join(
                      f"{k} {v:.3f}" for k, v in row["state_rate"].items())
                  + ("; Odwalla at " + " / ".join(row["f_sweep"]) + " N: " + " / ".join(
                      f"{v:.3f}" for v in row["f_sweep"].values()) if row["f_sweep"] else ""))
            if clf == clfs[0]:
                C = sum(r.confusion for r in reps).astype(int)
                total = C if total is None else total + C
                labels = reps[0].labels
    print(f"{clfs[0]} container confusion summed over files and fold seeds (rows true, columns "
          f"predicted; {', '.join(labels)}):\n{total}")
    summary = {}
    for clf in clfs:
        rr = [r for r in rows if r["classifier"] == clf]
        a = np.array([r["container_rate"] for r in rr])
        m = np.array([r["container_rate_fold_mean"] for r in rr])
        sd = a.std(ddof=1) if len(a) > 1 else 0.0
        s = {"container_rate_mean": float(a.mean()), "container_rate_sd": float(sd),
             "container_rate_fold_mean": float(m.mean()),
             "state_rate_mean": {k: float(np.mean([r["state_rate"][k] for r in rr]))
                                 for k in rr[0]["state_rate"]},
             "f_sweep_mean": {k: float(np.mean([r["f_sweep"][k] for r in rr
                                                if k in r["f_sweep"]]))
                              for k in rr[0]["f_sweep"]}}
        lo, hi = f"{SWEEP_FORCES[0]:g}", f"{SWEEP_FORCES[-1]:g}"
        pairs = np.array([(r["f_sweep"][lo], r["f_sweep"][hi]) for r in rr
                          if lo in r["f_sweep"] and hi in r["f_sweep"]])
        if len(pairs) >= 2:
            d = pairs[:, 1] - pairs[:, 0]
            p = float(ttest_rel(pairs[:, 1], pairs[:, 0], alternative="greater").pvalue)
            s["f_sweep_rise"] = {"mean": float(d.mean()), "sd": float(d.std(ddof=1)),
                                 "rose": int(np.sum(d > 0)), "fell": int(np.sum(d < 0)),
                                 "sets": len(d), "p_one_sided": p}
        summary[clf] = s
        print(f"{clf}: over {len(a)} grasp sets: container {s['container_rate_mean']:.3f} sd "
              f"{sd:.3f} (fold-averaged {m.mean():.3f}); state | " + ", ".join(
                  f"{k} {v:.3f}" for k, v in s["state_rate_mean"].items())
              + ("; Odwalla at " + " / ".join(s["f_sweep_mean"]) + " N: " + " / ".join(
                  f"{v:.3f}" for v in s["f_sweep_mean"].values()) if s["f_sweep_mean"] else ""))
        if "f_sweep_rise" in s:
            r = s["f_sweep_rise"]
            print(f"{clf}: Odwalla rate {lo} -> {hi} N paired by grasp set: rise {r['mean']:+.3f} "
                  f"sd {r['sd']:.3f}, rose in {r['rose']} / fell in {r['fell']} of {r['sets']} "
                  f"sets, one-sided paired t-test p = {r['p_one_sided']:.2g}")
    emit_json(args.json, {"rows": rows, "summary": summary})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
