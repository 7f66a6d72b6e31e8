"""Why informed grasp heights (thesis Eq. 6.12-6.13, Fig. 6.7) were worse than random, and
what each part of the fix contributes, measured on simulated grasps.

Usage::

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_tactile_informed.py RESULTS.jsonl:S [...]
        [--cv-repeats 3] [--trials 100] [--T 10] [--k 50] [--alpha 0.5] [--plot FILE]

``RESULTS.jsonl:S``: the grasps file of ``python -m mmlearn.apps.tactile_recognition --seed S
--results RESULTS.jsonl`` and the seed of the splits (nothing is simulated here); several
files are evaluated one after the other, ``--plot`` draws one panel of Fig. 6.7 per file.
For each it prints

1. per grasp height (1 cm actions) on one 2-fold split: the single-grasp accuracy and the mean
   posterior of the true class on the test half, beside the expected information gain at a
   uniform belief with the thesis' plug-in entropy estimator and with the cross-entropy
   estimator, and the Spearman correlation of each estimator's gains with the accuracy;
2. the recognition rate after t = 1..T grasps (and its mean over t) for the same objects
   under: random test grasps, random heights without repeats, and the informed strategy with
   either estimator, with and without the preference for heights not yet grasped
   (:func:`mmlearn.models.tactile.evaluation.strategy_trials`), each with its distinct heights
   per recognition and a paired t-test against random.
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("results", nargs="+", help="RESULTS.jsonl:SEED")
    ap.add_argument("--cv-repeats", type=int, default=3)
    ap.add_argument("--trials", type=int, default=100, help="recognitions per fold")
    ap.add_argument("--T", type=int, default=10)
    ap.add_argument("--k", type=int, default=50)
    ap.add_argument("--alpha", type=float, default=0.5)
    ap.add_argument("--plot", default=None, help="image file of the curves")
    args = ap.parse_args(argv)
    panels = []
    for item in args.results:
        path, _, seed = item.rpartition(":")
        if not path or not seed.isdigit():
            ap.error(f"expected RESULTS.jsonl:SEED, got {item!r}")
        panels.append((path, int(seed), _one(path, int(seed), args)))
    if args.plot:
        _plot(panels, args.plot)
        print(f"plot written to {args.plot}")
    return 0


def _one(path, seed, args) -> dict:
    from scipy.stats import spearmanr, ttest_rel

    import mmlearn.models.tactile.evaluation as ev
    from mmlearn.apps.common.sweep import report_lines
    from mmlearn.models.tactile.recognition import height_actions

    t0 = time.perf_counter()
    args.seed = seed
    lines = [ln for ln in report_lines(path)
             if ln.get("record") and not ln.get("error")]
    data, groups = ev.recognition_dataset([ln["record"] for ln in lines])
    classes = sorted(groups)
    print(f"\n{path}: {len(data)} grasps with contact of {len(classes)} classes, seed "
          f"{args.seed}")
    rng = np.random.default_rng([args.seed, 17, len(classes)])
    rng_t = np.random.default_rng([args.seed, 19, len(classes)])
    variants = [("random", "random", True), ("random_heights", "random_heights", True),
                ("entropy, repeats (first version)", "informed_entropy", False),
                ("entropy, new heights first", "informed_entropy", True),
                ("cross-entropy, repeats", "informed", False),
                ("cross-entropy, new heights first (app)", "informed", True)]
    ok = {v[0]: [] for v in variants}
    dist = {v[0]: [] for v in variants}
    for rep in range(args.cv_repeats):
        A, B = ev.split_two_fold(data.labels, rng)
        for fold, (trn, te) in enumerate(((A, B), (B, A))):
            train, test = data.subset(trn), data.subset(te)
            rec, _ = ev.fit_recognizer(train, k=args.k, alpha=args.alpha, seed=args.seed)
            Ltr = rec.likelihood_loo(train)
            if rep == 0 and fold == 0:
                _per_height(rec, train, test, Ltr, height_actions, spearmanr)
            objs = [classes[j] for j in rng_t.integers(len(classes), size=args.trials)]
            for name, strategy, fresh in variants:
                o, d = ev.strategy_trials(rec, train, test, objs, args.T, rng_t,
                                          strategy=strategy, Ltr=Ltr, fresh=fresh)
                ok[name].append(o)
                dist[name].append(d)
    print(f"\nrecognition rate after t = 1..{args.T} grasps ({args.cv_repeats} x 2 folds x "
          f"{args.trials} recognitions, the same objects for every strategy):")
    base = np.concatenate(ok["random"]).mean(axis=1)
    for name, _, _ in variants:
        o = np.concatenate(ok[name])
        per = o.mean(axis=1)
        t = ""
        if name != "random" and not np.allclose(per, base):
            st, p = ttest_rel(per, base)
            t = f"  vs random {100 * (per - base).mean():+.1f} % (paired t {st:+.2f}, p {p:.2g})"
        print(f"  {name:40s} " + " ".join(f"{x:.3f}" for x in o.mean(axis=0))
              + f"  mean {o.mean():.3f}, {np.concatenate(dist[name]).mean():.1f} heights{t}")
    print(f"wall {time.perf_counter() - t0:.1f} s")
    return {name: np.concatenate(ok[name]).mean(axis=0) for name, _, _ in variants}


def _plot(panels, path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(panels), figsize=(5.5 * len(panels), 4.2), squeeze=False)
    for ax, (p, seed, curves) in zip(axes[0], panels):
        for name, v in curves.items():
            bold = name.startswith("random ") or name == "random" or "(app)" in name
            ax.plot(range(1, len(v) + 1), v, "-o" if bold else "--", ms=3,
                    lw=2 if bold else 1, label=name)
        ax.set_title(f"seed {seed}: all classes", fontsize=9)
        ax.set_xlabel("grasps t")
        ax.set_ylabel("recognition rate")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def _per_height(rec, train, test, Ltr, height_actions, spearmanr):
    from mmlearn.models.tactile.evaluation import HEIGHT_RESOLUTION

    n = len(rec.classes)
    a_tr = height_actions(train.height, resolution=HEIGHT_RESOLUTION)
    a_te = height_actions(test.height, resolution=HEIGHT_RESOLUTION)
    b = np.full(n, 1.0 / n)
    g_e = rec.information_gain(b, train, a_tr, train_likelihood=Ltr, estimator="entropy")
    g_c = rec.information_gain(b, train, a_tr, train_likelihood=Ltr, estimator="cross_entropy")
    L = rec.likelihood(test)
    P = L / L.sum(axis=1, keepdims=True)
    y = np.searchsorted(rec.classes, test.labels)
    print("one split, per height: test grasps, classes, single-grasp accuracy, mean p(true "
          "class); expected gain at a uniform belief (nats): plug-in entropy / cross-entropy")
    rows = []
    for a in sorted(set(a_te.tolist()) & set(g_e)):
        m = a_te == a
        acc = float((P[m].argmax(axis=1) == y[m]).mean())
        rows.append((acc, g_e[a], g_c[a], int(m.sum())))
        print(f"  {a:3d} cm  {m.sum():3d} grasps {len(set(y[m].tolist())):2d} classes  "
              f"acc {acc:.2f}  p(true) {P[m, y[m]].mean():.3f}   gain {g_e[a]:.3f} / "
              f"{g_c[a]:+.3f}")
    r = np.array(rows)
    w = r[:, 3] >= 3  # heights with at least 3 test grasps
    rho_e = spearmanr(r[w, 1], r[w, 0])[0]
    rho_c = spearmanr(r[w, 2], r[w, 0])[0]
    print(f"  Spearman(gain, accuracy) over heights with >= 3 test grasps: plug-in entropy "
          f"{rho_e:+.2f}, cross-entropy {rho_c:+.2f}")


if __name__ == "__main__":
    raise SystemExit(main())
