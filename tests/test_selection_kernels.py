"""The compiled inner loops of link-model fitting (models/articulation/kernels.py,
models/common/gp_kernel.py) against the numpy forms they replace, and selection on the real
tracks against the recorded selections (tests/data/articulation_selections.json: model, BIC
of every candidate, axis and radius of the selected model)."""

import json
from pathlib import Path

import numpy as np
import pytest

from mmlearn.models.articulation.geom import (_Data, _frame_with_z, _frame_with_z_numpy, _log_rot,
                                              _m2rv, _m2rv_numpy, _pair_mul, _rot_err, _rv2m,
                                              _weighted_rotation_mean,
                                              _weighted_rotation_mean_numpy)
from mmlearn.models.articulation.kernels import rotation_errors, weighted_log_mean
from mmlearn.models.articulation.link import ObservationModel, em_gamma, make_model
from mmlearn.models.articulation.obs import _gamma_map
from mmlearn.models.articulation.refine import LocalParametrisation
from mmlearn.models.articulation.sim import simulate_link
from mmlearn.models.articulation.structure import select_link_model
from mmlearn.models.common.gp import GaussianProcess
from mmlearn.models.common.gp_kernel import neg_lml_and_grad
from mmlearn.models.common.track_io import read_track

DATA = Path(__file__).parent / "data"
OBS = ObservationModel(sigma_pos=0.002, sigma_orient=np.deg2rad(2.0))


def _rotations(rng, k):
    return _rv2m(rng.normal(0.0, 1.0, (k, 3)))


@pytest.mark.parametrize("position_only", [False, True])
def test_revolute_kernel_matches_numpy(position_only):
    tr = simulate_link("microwave", 40, rng=3)
    Z = tr.Z[:, :3] if position_only else tr.Z
    m = make_model("revolute", obs=OBS).fit(Z, rng=0)
    d = _Data(Z)
    th = m._hypotheses(d, np.random.default_rng(1), 60)
    for a, b in zip(m._residuals_batch(th, d), m._residuals_batch_numpy(th, d)):
        if b is None:
            assert a is None
        else:
            assert np.allclose(a, b, rtol=1e-12, atol=1e-12)
    assert np.allclose(m._residual_vectors(th, d), m._residual_vectors_numpy(th, d),
                       rtol=1e-10, atol=1e-9)
    for a, b in zip(m._scores_batch(th, d), m._residuals_batch(th, d)[:2]):
        assert (a is None and b is None) or np.array_equal(a, b)
    # with the refinement's rotations passed explicitly (local parametrisation)
    par = LocalParametrisation(m, m.theta, d)
    U = np.random.default_rng(2).normal(0.0, 3.0, (5, m.theta.size))
    ths, rots = par.decode(U)
    assert np.allclose(m._residual_vectors(ths, d, rots), m._residual_vectors_numpy(ths, d, rots),
                       rtol=1e-10, atol=1e-9)


def test_rotation_kernels_match_numpy():
    rng = np.random.default_rng(4)
    Ra, R = _rotations(rng, 7), _rotations(rng, 50)
    R[3] = Ra[2]  # an exact zero error
    assert np.allclose(rotation_errors(Ra, R), _rot_err(_pair_mul(np.swapaxes(Ra, 1, 2), R)),
                       rtol=1e-12, atol=1e-14)
    w = rng.uniform(0.0, 1.0, 50)
    R0 = Ra[0]
    ref = w @ _log_rot(np.einsum("ba,nbc->nac", R0, R)) / w.sum()
    assert np.allclose(weighted_log_mean(R0, R, w), ref, rtol=1e-12, atol=1e-14)


def _em_gamma_reference(log_in, log_out, w, iters, gamma0=0.3, tol=1e-7):
    g = np.full(log_in.shape[0], gamma0)
    L = np.exp(np.clip(log_in - log_out, -700.0, 700.0))
    for _ in range(iters):
        A = np.sum(g[:, None] / ((1.0 - g)[:, None] * L + g[:, None]), axis=1)
        g_new = _gamma_map(A, log_in.shape[1], w)
        done = np.max(np.abs(g_new - g)) < tol
        g = g_new
        if done:
            break
    a = np.log1p(-g)[:, None] + log_in
    lse = np.logaddexp(a, np.log(g)[:, None] + log_out)
    return g, lse.sum(axis=1), np.exp(a - lse)


@pytest.mark.parametrize("w", [0.0, 92.0 * 30])
def test_em_gamma_matches_numpy(w):
    rng = np.random.default_rng(5)
    log_in = rng.normal(0.0, 4.0, (20, 30))
    log_in[:, :5] = -50.0  # a few clear outliers
    got = em_gamma(log_in, -2.0, w, iters=30)
    for a, b in zip(got, _em_gamma_reference(log_in, -2.0, w, 30)):
        assert np.allclose(a, b, rtol=1e-12, atol=1e-14)
    g, ll, resp = em_gamma(log_in, -2.0, w, iters=30, responsibilities=False)
    assert resp is None and np.array_equal(g, got[0]) and np.array_equal(ll, got[1])


@pytest.mark.parametrize("ard,revolute", [(True, False), (False, False), (True, True)])
def test_gp_compiled_objective_matches_numpy_and_finite_differences(ard, revolute):
    rng = np.random.default_rng(6)
    X = rng.uniform(0.0, 2.0, (35, 2))
    Y = np.c_[np.sin(2 * X[:, 0]), X[:, 1] ** 2, X.sum(axis=1)] + 0.01 * rng.normal(size=(35, 3))
    gp = GaussianProcess(ard=ard, revolute=revolute)
    G, Yc = gp._geom(X, X), Y - Y.mean(axis=0)
    d_ell = 2 if ard else 1
    w = gp._width(d_ell, 2)
    th = rng.normal(0.0, 0.3, 3 * w)
    th[d_ell::w] -= 1.0
    th[d_ell + 1::w] -= 5.0
    f, g = gp._neg_lml_and_grad(th, G, Yc, d_ell)
    f0, g0 = gp._neg_lml_and_grad_numpy(th, G, Yc, d_ell)
    assert f == pytest.approx(f0, rel=1e-12)
    assert np.allclose(g, g0, rtol=1e-9, atol=1e-9 * np.abs(g0).max())
    h = 1e-6
    fd = np.array([(gp._neg_lml_and_grad(th + h * e, G, Yc, d_ell)[0]
                    - gp._neg_lml_and_grad(th - h * e, G, Yc, d_ell)[0]) / (2 * h)
                   for e in np.eye(th.size)])
    assert np.allclose(g, fd, rtol=1e-5, atol=1e-5 * np.abs(fd).max())


def test_gp_objective_falls_back_where_the_kernel_is_singular():
    X = np.zeros((6, 1))  # all inputs equal: K = sf2 11^T + sn2 I, singular as sn2 -> 0
    Y = np.arange(6.0)[:, None]
    gp = GaussianProcess()
    G, Yc = gp._geom(X, X), Y - Y.mean()
    th = np.array([0.0, 0.0, -800.0])  # sn2 = exp(-800) = 0
    assert not neg_lml_and_grad(th, G[0], np.zeros((1, 1)), Yc, 1, 3, True, False)[2]
    f, g = gp._neg_lml_and_grad(th, G, Yc, 1)
    f0, g0 = gp._neg_lml_and_grad_numpy(th, G, Yc, 1)
    assert f == f0 and np.array_equal(g, g0)


@pytest.mark.parametrize("position_only", [False, True])
def test_hypotheses_and_prismatic_errors_match_numpy(position_only):
    Z = simulate_link("microwave", 40, rng=3).Z
    d = _Data(Z[:, :3] if position_only else Z)
    rev = make_model("revolute", obs=OBS)
    a = rev._point_hypotheses(d, np.random.default_rng(1), 100)
    b = rev._point_hypotheses_numpy(d, np.random.default_rng(1), 100)
    assert a.shape == b.shape and a.shape[0] > 50
    assert np.allclose(a, b, rtol=1e-12, atol=1e-12)
    pri = make_model("prismatic", obs=OBS).fit(d, rng=0)
    th = pri._hypotheses(d, np.random.default_rng(2), 60)
    for x, y in zip(pri._residuals_batch(th, d), pri._residuals_batch_numpy(th, d)):
        assert (x is None and y is None) or np.allclose(x, y, rtol=1e-12, atol=1e-14)


def test_rotation_helpers_match_numpy():
    rng = np.random.default_rng(8)
    rv = rng.normal(0.0, 1.0, (400, 3))
    rv *= (rng.uniform(0.0, np.pi, 400) / np.linalg.norm(rv, axis=1))[:, None]
    rv[:50] *= ((np.pi - rng.uniform(0.0, 1e-6, 50)) / np.linalg.norm(rv[:50], axis=1))[:, None]
    M = _rv2m(rv)
    M[0], M[1] = np.diag([1.0, -1.0, -1.0]), np.eye(3)  # exactly pi and 0
    assert np.array_equal(_m2rv(M), _m2rv_numpy(M))
    assert np.array_equal(_m2rv(M[7]), _m2rv_numpy(M[7]))
    w = rng.uniform(0.0, 1.0, 400)
    assert np.allclose(_weighted_rotation_mean(M[50:], w[50:]),
                       _weighted_rotation_mean_numpy(M[50:], w[50:]), atol=1e-14)
    axis, hint = rng.normal(size=(30, 3)), rng.normal(size=(30, 3))
    hint[:3] = 2.0 * axis[:3]  # no perpendicular part: the fallback direction
    axis[1] = [0.95, 0.1, 0.0]
    assert np.allclose(_frame_with_z(axis, hint), _frame_with_z_numpy(axis, hint), atol=1e-15)


def test_gp_factorisation_matches_numpy():
    Z = simulate_link("microwave", 30, rng=1).Z
    gp = make_model("gp", obs=OBS).fit(Z, rng=0).gp
    L, alpha, lml = gp._L, gp._alpha, gp._lml
    n = gp.X.shape[0]
    K = gp._kernel(gp._geom(gp.X, gp.X), gp.log_ell, gp.log_sf2, gp.log_sb2)
    gp._factorise_numpy(K + np.exp(gp.log_sn2)[:, None, None] * np.eye(n))
    # (to rounding, amplified by the kernel matrices' conditioning: sn2 ~ sigma^2)
    assert np.allclose(L, gp._L, rtol=0.0, atol=1e-11 * np.abs(L).max())
    assert np.allclose(alpha, gp._alpha, rtol=0.0, atol=1e-8 * np.abs(alpha).max())
    assert np.allclose(lml, gp._lml, rtol=1e-10)


def test_range_jacobians_follow_a_refit():
    m = make_model("prismatic", obs=OBS)
    m.fit(simulate_link("drawer", 30, rng=0).Z, rng=0)
    J1 = m._range_jacobians(m.q_min, m.q_max)
    assert np.array_equal(m._range_jacobians(m.q_min, m.q_max), J1)
    Z = simulate_link("drawer", 30, rng=0).Z.copy()
    Z[:, :3] = Z[:, :3] @ _rv2m(np.array([0.0, 0.0, 1.0])).T  # the same drawer, turned
    m.fit(Z, rng=0)
    assert not np.allclose(m._range_jacobians(m.q_min, m.q_max), J1)
    assert np.allclose(m._range_jacobians(m.q_min, m.q_max),
                       m.jacobian(m.q_min + np.linspace(0, 1, 16)[:, None] * (m.q_max - m.q_min)))


def test_real_tracks_reproduce_the_recorded_selections():
    recorded = json.loads((DATA / "articulation_selections.json").read_text())
    assert len(recorded) == 31
    for r in recorded:
        s = select_link_model(read_track(DATA / r["track"]).poses, rng=0,
                              obs=ObservationModel(r["sigma_pos"], np.deg2rad(5.0)))
        where = (r["track"], r["sigma_pos"])
        assert s.selected == r["selected"], where
        for k, v in r["bic"].items():
            assert s.bic[k] == pytest.approx(v, abs=1e-3), (where, k)
        assert s.best.gamma == pytest.approx(r["gamma"], abs=1e-6), where
        if "axis" in r:
            assert abs(np.dot(s.best.axis, r["axis"])) > np.cos(1e-5), where
        if "radius_m" in r:
            assert s.best.radius == pytest.approx(r["radius_m"], rel=1e-6), where


def test_lbfgsb_driver_takes_scipys_iterates(monkeypatch):
    from scipy.optimize import minimize

    from mmlearn.models.common import gp as gp_module

    def scipy_minimize(fun, x0, args, bounds, maxiter, ftol, gtol):
        return minimize(fun, x0, args=args, jac=True, method="L-BFGS-B", bounds=bounds,
                        options={"maxiter": maxiter, "ftol": ftol, "gtol": gtol})

    Z = simulate_link("microwave", 60, rng=2).Z
    fitted = []
    for driver in (gp_module._minimize_lbfgsb, scipy_minimize):
        monkeypatch.setattr(gp_module, "_minimize_lbfgsb", driver)
        fitted.append(make_model("gp", obs=OBS).fit(Z, rng=0))
    a, b = fitted
    assert np.array_equal(a.gp.log_ell, b.gp.log_ell)
    assert np.array_equal(a.gp.log_sf2, b.gp.log_sf2)
    assert np.array_equal(a.gp.log_sn2, b.gp.log_sn2)
    assert a.bic_ == b.bic_
