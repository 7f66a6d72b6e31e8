"""Tests for mmlearn.models.common.gp against scikit-learn's GaussianProcessRegressor as an oracle."""

import json

import numpy as np
import pytest
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import RBF, ConstantKernel, WhiteKernel

from mmlearn.models.common.gp import GaussianProcess


def _data(n=25, d=2, m=3, seed=0):
    rng = np.random.default_rng(seed)
    X = rng.uniform(-2, 2, size=(n, d))
    Y = np.stack([np.sin(X[:, 0] * (c + 1)) + 0.3 * c * X[:, -1] for c in range(m)], axis=1)
    Y += 0.05 * rng.standard_normal(Y.shape)
    return X, Y


def _sk_oracle(gp, c):
    ell = gp.length_scales[c]
    kern = (ConstantKernel(gp.signal_variance[c], "fixed") * RBF(ell, "fixed")
            + WhiteKernel(gp.noise_variance[c], "fixed"))
    sk = GaussianProcessRegressor(kern, alpha=0.0, optimizer=None, normalize_y=False)
    sk.fit(gp.X, gp.Y[:, c] - gp.y_mean[c])
    return sk


@pytest.mark.parametrize("ard", [True, False])
def test_matches_sklearn_oracle(ard):
    X, Y = _data()
    gp = GaussianProcess(ard=ard).fit(X, Y)
    Xs = np.random.default_rng(1).uniform(-2, 2, size=(7, 2))
    mean, var = gp.predict(Xs, return_var=True)
    lml = 0.0
    for c in range(Y.shape[1]):
        sk = _sk_oracle(gp, c)
        m_sk, s_sk = sk.predict(Xs, return_std=True)
        np.testing.assert_allclose(mean[:, c], m_sk + gp.y_mean[c], rtol=1e-6, atol=1e-8)
        # sklearn's std includes the WhiteKernel noise
        np.testing.assert_allclose(var[:, c] + gp.noise_variance[c], s_sk**2, rtol=1e-5,
                                   atol=1e-9)
        lml += sk.log_marginal_likelihood_value_
    np.testing.assert_allclose(gp.log_marginal_likelihood(), lml, rtol=1e-8)
    _, var_n = gp.predict(Xs, return_var=True, include_noise=True)
    np.testing.assert_allclose(var_n - var, np.broadcast_to(gp.noise_variance, var.shape))


def test_optimum_is_at_least_as_good_as_sklearn():
    X, Y = _data(n=30, d=2, m=1, seed=3)
    gp = GaussianProcess(ard=True).fit(X, Y)
    kern = ConstantKernel(1.0) * RBF([1.0, 1.0]) + WhiteKernel(0.01)
    sk = GaussianProcessRegressor(kern, alpha=0.0, n_restarts_optimizer=2, random_state=0)
    sk.fit(X, Y[:, 0] - gp.y_mean[0])
    assert gp.log_marginal_likelihood() >= sk.log_marginal_likelihood_value_ - 1e-3


@pytest.mark.parametrize("revolute", [False, True])
def test_lml_gradient_matches_finite_differences(revolute):
    X, Y = _data(n=15, d=2, m=2, seed=2)
    gp = GaussianProcess(ard=True, revolute=revolute)
    gp.fit(X, Y, optimize=False)
    Yc = Y - Y.mean(axis=0)
    G = gp._geom(X, X)
    row = [0, 0, 0, -3] + ([-1] if revolute else [])
    theta = np.random.default_rng(0).normal(0, 0.3, size=2 * len(row)) + np.tile(row, 2)
    f, g = gp._neg_lml_and_grad(theta, G, Yc, 2)
    eps = 1e-6
    g_fd = np.array([(gp._neg_lml_and_grad(theta + eps * e, G, Yc, 2)[0]
                      - gp._neg_lml_and_grad(theta - eps * e, G, Yc, 2)[0]) / (2 * eps)
                     for e in np.eye(theta.size)])
    np.testing.assert_allclose(g, g_fd, rtol=1e-5, atol=1e-6)


def test_predict_jacobian_matches_finite_differences():
    X, Y = _data(n=20, d=3, m=4, seed=4)
    gp = GaussianProcess().fit(X, Y)
    Xs = np.random.default_rng(5).uniform(-1, 1, size=(5, 3))
    J = gp.predict_jacobian(Xs)
    assert J.shape == (5, 4, 3)
    eps = 1e-6
    J_fd = np.stack([(gp.predict(Xs + eps * e) - gp.predict(Xs - eps * e)) / (2 * eps)
                     for e in np.eye(3)], axis=-1)
    np.testing.assert_allclose(J, J_fd, rtol=1e-5, atol=1e-7)


def test_fits_smooth_function_and_noise_level():
    rng = np.random.default_rng(6)
    X = rng.uniform(-3, 3, size=(60, 1))
    Y = np.sin(X) + 0.1 * rng.standard_normal(X.shape)
    gp = GaussianProcess().fit(X, Y)
    Xs = np.linspace(-2.5, 2.5, 50)[:, None]
    assert np.max(np.abs(gp.predict(Xs) - np.sin(Xs))) < 0.1
    assert 0.05 < np.sqrt(gp.noise_variance[0]) < 0.2


def test_zero_inputs_and_constant_outputs():
    rng = np.random.default_rng(7)
    Y = np.c_[np.full(10, 2.0), 1.0 + 0.01 * rng.standard_normal(10)]
    gp = GaussianProcess().fit(np.zeros((10, 0)), Y)
    mean, var = gp.predict(np.zeros((3, 0)), return_var=True)
    np.testing.assert_allclose(mean[:, 0], 2.0, atol=1e-6)
    np.testing.assert_allclose(mean[:, 1], Y[:, 1].mean(), atol=5e-3)
    assert np.all(var >= 0)
    assert gp.predict_jacobian(np.zeros((3, 0))).shape == (3, 2, 0)



def test_zero_inputs_optimum_is_the_bounded_maximum():
    """0 inputs: the closed-form hyper-parameters (no optimiser run) are at least as good
    as L-BFGS-B from several random starts inside the same bounds, per output, including
    outputs whose noise optimum lies on the noise floor."""
    from scipy.optimize import minimize

    rng = np.random.default_rng(3)
    for n in (2, 5, 31):
        Y = rng.normal(size=4) + np.array([0.0, 1e-5, 1e-2, 1.0]) * rng.normal(size=(n, 4))
        nm = np.array([1e-8, 1e-6, 1e-8, 1e-8])
        gp = GaussianProcess().fit(np.zeros((n, 0)), Y, noise_min=nm)
        X0 = np.zeros((n, 0))
        G, Yc = gp._geom(X0, X0), Y - Y.mean(axis=0)
        f = gp._per_output_nlml(np.c_[gp.log_sf2, gp.log_sn2].ravel(), G, Yc, 0)
        ys = np.maximum(Yc.var(axis=0), 1e-12)
        bounds = [b for c in range(4) for b in ((np.log(1e-12), np.log(1e4 * ys[c] + 1e-8)),
                                                (np.log(nm[c]),
                                                 np.log(max(1e4 * ys[c], 10 * nm[c]))))]
        for _ in range(4):
            lo, hi = np.array(bounds).T
            r = minimize(gp._neg_lml_and_grad, rng.uniform(lo, hi), args=(G, Yc, 0),
                         jac=True, method="L-BFGS-B", bounds=bounds,
                         options={"ftol": 1e-14, "gtol": 1e-10, "maxiter": 2000})
            assert np.all(f <= gp._per_output_nlml(r.x, G, Yc, 0) + 1e-7)
        # a constant and a nearly constant output: the floor binds; else sn2 = the variance
        np.testing.assert_allclose(gp.noise_variance[:2], nm[:2])
        np.testing.assert_allclose(gp.noise_variance[2:], Yc.var(axis=0)[2:], rtol=1e-3)

def test_roundtrip_json():
    X, Y = _data(n=12, d=2, m=2, seed=8)
    gp = GaussianProcess().fit(X, Y)
    gp2 = GaussianProcess.from_dict(json.loads(json.dumps(gp.to_dict())))
    Xs = np.random.default_rng(9).uniform(-2, 2, size=(4, 2))
    np.testing.assert_allclose(gp2.predict(Xs), gp.predict(Xs))
    np.testing.assert_allclose(gp2.log_marginal_likelihood(), gp.log_marginal_likelihood())


def test_bad_input_raises():
    gp = GaussianProcess()
    with pytest.raises(ValueError, match="NaN"):
        gp.fit(np.array([[0.0], [np.nan]]), np.zeros((2, 1)))
    with pytest.raises(ValueError, match="rows"):
        gp.fit(np.zeros((3, 1)), np.zeros((2, 1)))
    with pytest.raises(ValueError, match="not fitted"):
        gp.predict(np.zeros((1, 1)))
    gp.fit(np.zeros((3, 2)) + np.arange(3)[:, None], np.arange(3.0))
    with pytest.raises(ValueError, match="shape"):
        gp.predict(np.zeros((2, 3)))


def test_loo_predict_matches_refit_without_the_sample():
    X, Y = _data(n=12, d=2, m=2, seed=10)
    gp = GaussianProcess().fit(X, Y)
    mean, var = gp.loo_predict()
    for i in (0, 5, 11):
        keep = np.arange(12) != i
        g = GaussianProcess().fit(X[keep], Y[keep], optimize=False,
                                  hyperparameters=gp.hyperparameters())
        # the refit centres on its own mean: undo that difference through the kernel prior
        g.y_mean = gp.y_mean
        g._factorise()
        m_i, v_i = g.predict(X[i:i + 1], return_var=True, include_noise=True)
        np.testing.assert_allclose(mean[i], m_i[0], rtol=1e-6, atol=1e-9)
        np.testing.assert_allclose(var[i], v_i[0], rtol=1e-6, atol=1e-12)


def test_per_output_noise_floor():
    # a per-output floor keeps each column's noise variance at or above its own bound (the
    # data's noise variance 0.05^2 is below the second column's floor), and survives JSON
    X, Y = _data(n=15, d=1, m=2, seed=11)
    floor = np.array([1e-8, 1e-2])
    gp = GaussianProcess().fit(X, Y, noise_min=floor)
    assert np.all(np.exp(gp.log_sn2) >= floor * (1 - 1e-9))
    assert np.exp(gp.log_sn2[1]) == pytest.approx(1e-2, rel=1e-6)  # at the floor
    gp2 = GaussianProcess.from_dict(json.loads(json.dumps(gp.to_dict())))
    np.testing.assert_allclose(gp2.noise_min, floor)
    np.testing.assert_allclose(gp2.predict(X), gp.predict(X))
    with pytest.raises(ValueError, match="per output"):
        GaussianProcess().fit(X, Y, noise_min=np.ones(3))
    with pytest.raises(ValueError, match="positive"):
        GaussianProcess().fit(X, Y, noise_min=np.array([1e-3, 0.0]))


def test_ell_starts_never_worse_and_escape_an_ignored_input():
    # y depends weakly on x2 through a product with x1: on 30 noisy samples the jointly
    # optimised 12-output problem can end where x2's effect is explained as noise; the
    # per-output starts at shorter length scales keep the better optimum per output
    def f(X):
        return np.c_[0.5 * np.cos(X[:, 0]) + 0.05 * np.sin(X[:, 0]) * np.cos(X[:, 1]),
                     0.4 * np.sin(X[:, 0]) * np.cos(0.5 * X[:, 1])]

    gains = []
    for seed in (3, 9, 11):
        rng = np.random.default_rng(seed)
        X = rng.uniform(-1.5, 1.5, (30, 2))
        Y = f(X) + rng.normal(0, 0.01, (30, 2))
        kw = dict(noise_min=1e-5, n_restarts=1, ftol=1e-5)
        a = GaussianProcess().fit(X, Y, **kw).log_marginal_likelihood_per_output()
        b = GaussianProcess().fit(X, Y, ell_starts=(0.5,), **kw)
        lb = b.log_marginal_likelihood_per_output()
        assert np.all(lb >= a - 1e-6)
        gains.append(lb - a)
        # without optimisation the starts are not used
        c = GaussianProcess().fit(X, Y, optimize=False, ell_starts=(0.5,))
        np.testing.assert_allclose(c.log_ell, GaussianProcess().fit(X, Y, optimize=False).log_ell)
    assert np.max(gains) > 1.0


def _two_link(Q):
    """Planar two-link chain (links 1.0 and 0.6): end position and cos of the end angle."""
    a, b = Q[:, 0], Q[:, 0] + Q[:, 1]
    return np.c_[np.cos(a) + 0.6 * np.cos(b), np.sin(a) + 0.6 * np.sin(b), np.cos(b)]


def test_revolute_kernel_jacobian_and_roundtrip():
    rng = np.random.default_rng(11)
    X = rng.uniform(-1, 1, size=(20, 2))
    Y = _two_link(X) + 0.01 * rng.standard_normal((20, 3))
    gp = GaussianProcess(revolute=True).fit(X, Y)
    assert gp.log_sb2.shape == (3,) and "log_sb2" in gp.hyperparameters()
    Xs = rng.uniform(-1.5, 1.5, size=(6, 2))
    J = gp.predict_jacobian(Xs)
    eps = 1e-6
    J_fd = np.stack([(gp.predict(Xs + eps * e) - gp.predict(Xs - eps * e)) / (2 * eps)
                     for e in np.eye(2)], axis=-1)
    np.testing.assert_allclose(J, J_fd, rtol=1e-5, atol=1e-7)
    g2 = GaussianProcess.from_dict(json.loads(json.dumps(gp.to_dict())))
    np.testing.assert_allclose(g2.predict(Xs, return_var=True), gp.predict(Xs, return_var=True))
    # the posterior variance at a training-free point stays within the prior variance
    _, var = gp.predict(Xs, return_var=True)
    assert np.all(var <= np.exp(gp.log_sf2) + 4 * np.exp(gp.log_sb2) + 1e-12)


def test_revolute_kernel_extrapolates_a_revolute_chain():
    """Trained on one corner of the joint space, tested on the rest: the SE kernel reverts to
    its mean away from the samples, the revolute term spans the chain's function."""
    rng = np.random.default_rng(12)
    X = rng.uniform(-1.2, 0.2, size=(30, 2))
    Y = _two_link(X) + 0.005 * rng.standard_normal((30, 3))
    Xs = rng.uniform(-1.2, 1.2, size=(200, 2))
    Xs = Xs[np.max(Xs, axis=1) > 0.5]  # away from the training corner
    err = {rev: np.abs(GaussianProcess(revolute=rev).fit(X, Y).predict(Xs) - _two_link(Xs)).mean()
           for rev in (False, True)}
    assert err[True] < 0.25 * err[False]


def test_blas_single_thread_nests_and_restores():
    from threadpoolctl import threadpool_info

    from mmlearn.models.common.gp import blas_single_thread

    def threads():
        return [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]

    before = threads()
    with blas_single_thread():
        assert all(t == 1 for t in threads())
        with blas_single_thread():
            assert all(t == 1 for t in threads())
        assert all(t == 1 for t in threads())  # the inner exit keeps the outer limit
    assert threads() == before
    with pytest.raises(ValueError):
        with blas_single_thread():
            raise ValueError("x")
    assert threads() == before
