"""LASA handwriting benchmark: the thesis' method (ch. 8) beside the naive baseline, a dynamic
movement primitive and a probabilistic movement primitive from ``movement-primitives``, on the
same leave-one-out folds, scored by the same code (:mod:`mmlearn.models.imitation.lasa`).

Usage::

    pip install 'mmlearn[bench-lasa]'     # movement-primitives (+ pytransform3d), benchmark only
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_lasa.py [--shapes all] [--folds 0,..]
        [--weights 20] [--json OUT.json] [--methods thesis,target_start,...]

Methods (every one learns from the 6 training demonstrations of a fold and starts at the held-
out demonstration's start; the reproductions are resampled on the held-out time stamps):

* ``thesis``: :class:`mmlearn.models.imitation.lasa.ThesisReproducer` (defaults: target, start-marker,
  start-frame, scale-only start-frame and duration-frame constraints, h 0.02 s, dt 0.02 s, full
  covariances shrunk half-way to their diagonal).
* ``target_start``: the default without the start-frame constraints (objects target, start;
  covariances shrunk half-way to the diagonal as in the default).
* ``baseline``: :func:`mmlearn.models.imitation.lasa.naive_baseline`.
* ``dmp``: ``movement_primitives.dmp.DMP`` (Ijspeert et al. 2013 formulation), fitted to each
  training demonstration on a normalised time 0..1 with ``--weights`` basis functions per
  dimension; the weights are averaged over the 6 fits; rolled out from the held-out start to
  the goal (the origin) over the normalised time.
* ``promp``: ``movement_primitives.promp.ProMP`` with ``--weights`` basis functions per
  dimension, learned from the 6 training demonstrations on a normalised time 0..1 (EM),
  conditioned on the held-out start at t = 0; its conditioned mean is the reproduction.

Prints a table per shape (rmse_mm / end_error_mm for each method) and the means per group
(all, single-mode, held-back single-mode, development, multi-mode), with the seconds each
method took.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings

import numpy as np

from mmlearn.models.imitation.lasa import (DEVELOPMENT_SHAPES, LASA_SHAPES, MULTI_MODE_SHAPES,
                                           ThesisReproducer, baseline_reproducer, evaluate_shape,
                                           load_shape, summarise)


def _normalised(d, n):
    s = np.linspace(0.0, 1.0, n)
    u = (d.t - d.t[0]) / d.duration
    return s, np.stack([np.interp(s, u, d.hand[:, c]) for c in range(d.D)], axis=1)


class DmpReproducer:
    name = "dmp"

    def __init__(self, *, n_weights: int = 20, n: int = 500):
        self.n_weights, self.n = n_weights, n

    def __call__(self, train, held):
        from movement_primitives.dmp import DMP

        dt = 1.0 / (self.n - 1)
        ws = []
        for d in train:
            s, y = _normalised(d, self.n)
            dmp = DMP(n_dims=d.D, execution_time=1.0, dt=dt, n_weights_per_dim=self.n_weights)
            dmp.imitate(s, y)
            ws.append(dmp.get_weights())
        dmp = DMP(n_dims=held.D, execution_time=1.0, dt=dt, n_weights_per_dim=self.n_weights)
        dmp.imitate(*_normalised(train[0], self.n))
        dmp.set_weights(np.mean(ws, axis=0))
        dmp.configure(start_y=held.hand[0], goal_y=held.objects["target"][0])
        t, y = dmp.open_loop()
        return np.asarray(t) * held.duration, np.asarray(y)


class PrompReproducer:
    name = "promp"

    def __init__(self, *, n_weights: int = 20, n: int = 500):
        self.n_weights, self.n = n_weights, n

    def __call__(self, train, held):
        from movement_primitives.promp import ProMP

        Ts, Ys = [], []
        for d in train:
            s, y = _normalised(d, self.n)
            Ts.append(s)
            Ys.append(y)
        p = ProMP(n_dims=held.D, n_weights_per_dim=self.n_weights)
        p.imitate(np.array(Ts), np.array(Ys))
        c = p.condition_position(held.hand[0], y_cov=np.eye(held.D) * 1e-6, t=0.0, t_max=1.0)
        s = np.linspace(0.0, 1.0, self.n)
        return s * held.duration, c.mean_trajectory(s)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--shapes", default="all", help="comma-separated names, or all (default)")
    ap.add_argument("--folds", default=None, help="held-out indices 0..6 (default all)")
    ap.add_argument("--weights", type=int, default=20, help="DMP/ProMP basis functions per dimension")
    ap.add_argument("--methods", default="thesis,target_start,baseline,dmp,promp")
    ap.add_argument("--json", default=None, help="also write the results to this JSON file")
    a = ap.parse_args(argv)
    shapes = list(LASA_SHAPES) if a.shapes == "all" else [s.strip() for s in a.shapes.split(",")]
    bad = [s for s in shapes if s not in LASA_SHAPES]
    if bad:
        ap.error(f"unknown shapes {bad}")
    folds = None if a.folds is None else [int(x) for x in a.folds.split(",")]
    makers = {"thesis": lambda: ThesisReproducer(),
              "target_start": lambda: ThesisReproducer(objects=("target", "start")),
              "baseline": lambda: baseline_reproducer,
              "dmp": lambda: DmpReproducer(n_weights=a.weights),
              "promp": lambda: PrompReproducer(n_weights=a.weights)}
    methods = [m.strip() for m in a.methods.split(",")]
    unknown = [m for m in methods if m not in makers]
    if unknown:
        ap.error(f"unknown methods {unknown}; choose from {sorted(makers)}")
    if {"dmp", "promp"} & set(methods):
        import importlib.util

        if importlib.util.find_spec("movement_primitives") is None:
            ap.error("the dmp / promp columns need movement-primitives: pip install 'mmlearn[bench-lasa]' "
                     "(or leave them out with --methods thesis,baseline)")
    res = {m: [] for m in methods}
    secs = {m: 0.0 for m in methods}
    for name in shapes:
        demos = load_shape(name)
        for m in methods:
            t0 = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                res[m].append(evaluate_shape(name, makers[m](), demos=demos, folds=folds))
            secs[m] += time.perf_counter() - t0
        row = "  ".join(f"{m} {r[-1].rmse_mm:6.3f}/{r[-1].end_error_mm:6.3f}" for m, r in res.items())
        tag = "M" if name in MULTI_MODE_SHAPES else ("D" if name in DEVELOPMENT_SHAPES else " ")
        print(f"{name:17s} {tag} {row}", flush=True)
    print("\nrmse_mm / end_error_mm, leave-one-out over "
          f"{'all 7' if folds is None else len(folds)} folds; D = development shape, M = multi-mode")
    sums = {m: summarise(r) for m, r in res.items()}
    print(f"{'group':24s} {'n':>3s} " + " ".join(f"{m:>15s}" for m in methods))
    for suffix, label in (("", "all"), ("_single_mode", "single-mode"),
                          ("_held_back_single_mode", "held-back single-mode"),
                          ("_development", "development"), ("_multi_mode", "multi-mode")):
        n = sums[methods[0]][f"n_shapes{suffix}"]
        if not n:
            continue
        cells = " ".join(f"{sums[m][f'mean_rmse_mm{suffix}']:7.3f}/{sums[m][f'mean_end_error_mm{suffix}']:7.3f}"
                         for m in methods)
        print(f"{label:24s} {n:3d} {cells}")
    nf = sum(len(r.folds) for r in res[methods[0]])
    print("seconds: " + ", ".join(f"{m} {secs[m]:.1f} ({secs[m] / max(nf, 1):.2f} per fold)" for m in methods))
    if a.json:
        from mmlearn.models.common.fileio import atomic_write_text

        atomic_write_text(a.json, json.dumps({m: {"summary": sums[m],
                                                  "shapes": [r.to_dict() for r in res[m]],
                                                  "seconds": secs[m]} for m in methods}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
