"""Bag-of-tactile-features recognition (thesis ch. 6) on synthetic tactile data (prints figures).

    python benchmarks/bench_tactile_recognition.py [--seed 0] [--trials 300] [--quick] [--json [FILE]]

The data are the controllable stand-in of models/tactile/synth.py, not physics (the Drake
tactile sensor will produce the simulated grasps): 11 "household" objects with independent
patterns and widths over 10 grasp heights, and 5 "industrial" objects that share 70 % of their
heights (same pattern and width) and differ in the rest, 5 grasps per object and height
(800 grasps, 16 classes). Randomised 2-fold split as the thesis (train on one half, test on
the other). Printed:

- vocabulary clustering: kmedoids (FasterPAM, if installed) vs the numpy k-medoids (build +
  alternate, the default without it) vs agglomerative (average linkage + medoids):
  fit CPU time and the T = 10 recognition rate;
- the recognition rate after T = 1..10 random test grasps (overall, household, industrial);
- Table 6.1 / 6.2 analogues: the T = 10 rate over k = 10..50 and alpha = 0..1;
- informed (expected information gain, Eq. 6.13) vs random grasp heights: rate after each
  grasp, averaged over ``--trials`` objects, on all objects and on the industrial ones.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import time

import numpy as np

from _common import add_output_arguments, emit_json

from mmlearn.models.tactile.recognition import (TactileRecognitionConfig, TactileRecognizer,
                                                height_actions, kmedoids_available, posterior)
from mmlearn.models.tactile.synth import make_objects, sample_grasps

N_HOUSE, N_IND, N_HEIGHTS, PER = 11, 5, 10, 5
LOO = True


def make_data(seed):
    rng = np.random.default_rng(seed)
    house = make_objects(N_HOUSE, N_HEIGHTS, rng=rng)
    ind = make_objects(N_IND, N_HEIGHTS, rng=rng, shared=0.7)
    objs = {k: np.concatenate([house[k], ind[k]]) for k in house}
    n = N_HOUSE + N_IND
    names = [f"house{i}" for i in range(N_HOUSE)] + [f"ind{i}" for i in range(N_IND)]
    cl = np.repeat(np.arange(n), N_HEIGHTS * PER)
    hh = np.tile(np.repeat(np.arange(N_HEIGHTS), PER), n)
    data = sample_grasps(objs, cl, hh, rng=rng, names=names)
    perm = rng.permutation(len(cl))
    half = len(cl) // 2
    return data.subset(np.sort(perm[:half])), data.subset(np.sort(perm[half:])), names


def rate_random(rec, test, objects, T, trials, rng):
    """Rate after t = 1..T random test grasps of a random object among ``objects``."""
    L = np.log(np.maximum(rec.likelihood(test), 1e-300))
    cls = list(rec.classes)
    ok = np.zeros(T)
    for _ in range(trials):
        o = objects[rng.integers(len(objects))]
        idx = np.flatnonzero(test.labels == o)
        pick = rng.choice(idx, T, replace=False)
        for t in range(1, T + 1):
            ok[t - 1] += np.argmax(posterior(L[pick[:t]])) == cls.index(o)
    return ok / trials


def rate_informed(rec, train, test, objects, T, trials, rng, *, weighting="belief"):
    """Rate after each grasp when every next height maximises the expected gain."""
    L = np.log(np.maximum(rec.likelihood(test), 1e-300))
    Ltr = rec.likelihood_loo(train) if LOO else rec.likelihood(train)
    acts_tr = height_actions(train.height, resolution=0.01)
    acts_te = height_actions(test.height, resolution=0.01)
    cls = list(rec.classes)
    ok = np.zeros(T)
    for _ in range(trials):
        o = objects[rng.integers(len(objects))]
        belief = np.full(len(cls), 1.0 / len(cls))
        used = []
        for t in range(T):
            gains = rec.information_gain(belief, train, acts_tr, train_likelihood=Ltr,
                                         weighting=weighting)
            order = sorted(gains, key=lambda a: -gains[a])
            for a in order:  # the best height that still has an unused test grasp
                cand = np.flatnonzero((test.labels == o) & (acts_te == a))
                cand = np.setdiff1d(cand, used)
                if len(cand):
                    break
            j = int(rng.choice(cand))
            used.append(j)
            belief = posterior(L[used])
            ok[t] += np.argmax(belief) == cls.index(o)
    return ok / trials


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--trials", type=int, default=300)
    add_output_arguments(ap, quick="fewer trials, no sweeps")
    args = ap.parse_args(argv)
    trials = 60 if args.quick else args.trials
    train, test, names = make_data(args.seed)
    house = [n for n in names if n.startswith("house")]
    ind = [n for n in names if n.startswith("ind")]
    rng = np.random.default_rng(args.seed + 1)
    out = {"n_train": len(train), "n_test": len(test), "classes": len(names)}

    methods = ["agglomerative", "medoids"] + (["kmedoids"] if kmedoids_available() else [])
    out["clustering"] = {}
    recs = {}
    for m in methods:
        c0 = time.process_time()
        rec = TactileRecognizer(TactileRecognitionConfig(k=50, alpha=0.5, clustering=m,
                                                         seed=args.seed)).fit(train)
        fit_s = time.process_time() - c0
        recs[m] = rec
        r = rate_random(rec, test, names, 10, trials, rng)
        out["clustering"][m] = {"fit_cpu_s": fit_s, "rate_T10": float(r[-1]),
                                "rate_T1": float(r[0])}
    rec = recs["kmedoids" if "kmedoids" in recs else "medoids"]
    out["vocabulary_used"] = rec.clustering_used
    out["rate_by_T"] = {"all": rate_random(rec, test, names, 10, trials, rng).tolist(),
                        "household": rate_random(rec, test, house, 10, trials, rng).tolist(),
                        "industrial": rate_random(rec, test, ind, 10, trials, rng).tolist()}
    if not args.quick:
        out["k_sweep"] = {}
        for k in (10, 20, 30, 40, 50):
            r = TactileRecognizer(TactileRecognitionConfig(k=k, clustering=rec.clustering_used,
                                                           seed=args.seed)).fit(train)
            out["k_sweep"][k] = float(rate_random(r, test, names, 10, trials, rng)[-1])
        out["alpha_sweep"] = {}
        for a in (0.0, 0.25, 0.5, 0.75, 1.0):
            r = TactileRecognizer(TactileRecognitionConfig(k=50, alpha=a,
                                                           clustering=rec.clustering_used,
                                                           seed=args.seed)).fit(train)
            out["alpha_sweep"][a] = float(rate_random(r, test, names, 10, trials, rng)[-1])
    c0 = time.process_time()
    out["informed"] = {
        "all": {"random": rate_random(rec, test, names, 10, trials, rng).tolist(),
                "informed_belief": rate_informed(rec, train, test, names, 10, trials, rng).tolist(),
                "informed_count": rate_informed(rec, train, test, names, 10, trials, rng,
                                                weighting="count").tolist()},
        "industrial": {"random": rate_random(rec, test, ind, 10, trials, rng).tolist(),
                       "informed_belief": rate_informed(rec, train, test, ind, 10, trials,
                                                        rng).tolist(),
                       "informed_count": rate_informed(rec, train, test, ind, 10, trials, rng,
                                                       weighting="count").tolist()}}
    out["informed_cpu_ms_per_decision"] = 1e3 * (time.process_time() - c0) / (4 * trials * 10)
    if emit_json(args.json, out):
        return
    print(f"synthetic tactile data: {out['classes']} classes, {out['n_train']} train / "
          f"{out['n_test']} test grasps, {trials} recognition trials per figure")
    for m, d in out["clustering"].items():
        print(f"  vocabulary {m:13s}: fit {d['fit_cpu_s']:.2f} s CPU, rate T=1 {d['rate_T1']:.3f}, "
              f"T=10 {d['rate_T10']:.3f}")
    print(f"rate after T grasps ({out['vocabulary_used']}):")
    for k, v in out["rate_by_T"].items():
        print(f"  {k:10s} " + " ".join(f"{x:.3f}" for x in v))
    if "k_sweep" in out:
        print("k sweep (T=10):     " + "  ".join(f"k={k}: {v:.3f}" for k, v in out["k_sweep"].items()))
        print("alpha sweep (T=10): " + "  ".join(f"a={k}: {v:.3f}" for k, v in out["alpha_sweep"].items()))
    print(f"informed vs random grasp heights ({out['informed_cpu_ms_per_decision']:.2f} ms CPU "
          f"per decision incl. bookkeeping):")
    for grp, d in out["informed"].items():
        for k, v in d.items():
            print(f"  {grp:10s} {k:16s} " + " ".join(f"{x:.3f}" for x in v) +
                  f"   mean {np.mean(v):.3f}")


if __name__ == "__main__":
    main()
