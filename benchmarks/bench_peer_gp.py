"""The GP (models/common/gp.py) side by side with scikit-learn's ``GaussianProcessRegressor``
on the same data and model (prints figures; never fails on time).

    python benchmarks/bench_peer_gp.py [--n 30] [--outputs 12] [--repeats 5] [--seeds 5]
                                       [--quick] [--json [FILE]]

Data: a link's GP as the articulation models use it: one input q in [0, 1.5] (n samples), 12
outputs (the entries of a 3 x 4 relative transform along a curved path: smooth functions of q
with different amplitudes) plus Gaussian noise 0.005. The same model on both sides: per output
a zero-mean GP (the column mean subtracted) with kernel sf2 exp(-(q - q')^2 / (2 ell^2)) + sn2,
hyper-parameters fitted by maximising the log marginal likelihood from the same data-scale
start, L-BFGS-B, no restarts. scikit-learn fits one ``GaussianProcessRegressor`` per output
(``ConstantKernel * RBF + WhiteKernel``; its multi-output mode shares one kernel across the
outputs, a different model); ours fits all outputs in one vectorised problem.

Figures: CPU time of the fit (median over ``--repeats``, per data set; median over
``--seeds`` data sets), the ratio, and the log marginal likelihood reached (sum over the
outputs, and the largest per-output difference: "at the same optimum" when it is ~0).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import argparse
import time
import warnings

import numpy as np

from _common import add_output_arguments, emit_json

from mmlearn.models.common.gp import GaussianProcess


def data(n, m, seed):
    rng = np.random.default_rng(seed)
    q = np.sort(rng.uniform(0.0, 1.5, n))
    k = np.arange(m)
    Y = (0.05 + 0.3 * (k % 4)) * np.sin((1.0 + 0.5 * (k // 4)) * q[:, None] + k)
    return q[:, None], Y + rng.normal(0.0, 0.005, Y.shape)


def fit_ours(X, Y):
    gp = GaussianProcess(ard=True).fit(X, Y, noise_min=1e-6)
    return gp.log_marginal_likelihood_per_output()


def fit_sklearn(X, Y):
    from sklearn.exceptions import ConvergenceWarning
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import ConstantKernel, RBF, WhiteKernel
    out = []
    Yc = Y - Y.mean(axis=0)
    for c in range(Y.shape[1]):
        v = float(np.var(Yc[:, c])) or 1.0
        kern = (ConstantKernel(v, (1e-12, 1e6)) * RBF(float(np.std(X)) or 1.0, (1e-4, 1e4))
                + WhiteKernel(0.1 * v, (1e-6, 1e2)))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            g = GaussianProcessRegressor(kern, alpha=0.0, normalize_y=False,
                                         n_restarts_optimizer=0).fit(X, Yc[:, c])
        out.append(g.log_marginal_likelihood_value_)
    return np.array(out)


def _cpu(fn, repeats):
    ts, res = [], None
    for _ in range(repeats):
        c0 = time.process_time()
        res = fn()
        ts.append(time.process_time() - c0)
    return float(np.median(ts)), res


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, default=30)
    ap.add_argument("--outputs", type=int, default=12)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--seeds", type=int, default=5)
    add_output_arguments(ap, quick="2 data sets, 3 repeats")
    a = ap.parse_args(argv)
    if min(a.n, a.outputs, a.repeats, a.seeds) < 1:
        ap.error("--n, --outputs, --repeats and --seeds must be >= 1")
    if a.quick:
        a.seeds, a.repeats = 2, 3
    try:
        import sklearn  # noqa: F401
    except ImportError as e:
        raise SystemExit(f"bench_peer_gp: scikit-learn does not import ({e})")
    rows = []
    for seed in range(a.seeds):
        X, Y = data(a.n, a.outputs, seed)
        t_o, l_o = _cpu(lambda: fit_ours(X, Y), a.repeats)
        t_s, l_s = _cpu(lambda: fit_sklearn(X, Y), a.repeats)
        rows.append(dict(seed=seed, ours_ms=1e3 * t_o, sklearn_ms=1e3 * t_s,
                         ratio=t_s / max(t_o, 1e-12), lml_ours=float(l_o.sum()),
                         lml_sklearn=float(l_s.sum()),
                         lml_max_diff=float(np.max(np.abs(l_o - l_s)))))
    figures = dict(gp_ms=float(np.median([r["ours_ms"] for r in rows])),
                   sklearn_ms=float(np.median([r["sklearn_ms"] for r in rows])),
                   speedup=float(np.median([r["ratio"] for r in rows])),
                   lml_max_diff=float(np.max([r["lml_max_diff"] for r in rows])))
    if emit_json(a.json, dict(n=a.n, outputs=a.outputs, rows=rows, figures=figures)):
        return
    print(f"GP fit, {a.outputs} outputs, n = {a.n} (CPU ms, median of {a.repeats})")
    print(f"{'seed':>4s} {'mmlearn':>9s} {'sklearn':>9s} {'ratio':>7s} {'LML ours':>10s} "
          f"{'LML sklearn':>12s} {'max |dLML| per output':>22s}")
    for r in rows:
        print(f"{r['seed']:4d} {r['ours_ms']:9.2f} {r['sklearn_ms']:9.2f} {r['ratio']:6.1f}x "
              f"{r['lml_ours']:10.2f} {r['lml_sklearn']:12.2f} {r['lml_max_diff']:22.2e}")
    print(f"median: mmlearn {figures['gp_ms']:.2f} ms, scikit-learn {figures['sklearn_ms']:.2f} ms,"
          f" {figures['speedup']:.1f}x")


if __name__ == "__main__":
    main()
