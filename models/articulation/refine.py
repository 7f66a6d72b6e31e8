"""Refinement of a link model's best MLESAC hypothesis (thesis Sec. 4.1.1).

All refinements maximise the same objective, the mixture log-likelihood of the observation
model plus log p(gamma) (models/articulation/link.py), and return (theta, gamma). Each link
model class names one in its ``refinement`` attribute, with the reason beside it:

- ``"em"`` (rigid, prismatic): EM whose M-step is the model's closed-form weighted fit
  (``LinkModel._weighted_fit``): one residual evaluation per iteration, every iteration
  increases the objective.
- ``"lm"`` (revolute): no closed-form weighted fit (circle + axis are nonlinear in the
  data), but residual vectors (``LinkModel._residual_vectors``), so Levenberg-Marquardt
  on the responsibility-weighted residuals with gamma fixed, gamma re-estimated by EM in
  between (:func:`refine_lm`).
- ``"lbfgs"``: quasi-Newton (scipy L-BFGS-B) on the scalar objective with batched
  forward-difference gradients. Needs only ``_residuals_batch``, so it is the default of
  :class:`LinkModel` (a new model works before it has a faster path) and the reference
  the tests compare the fast paths against; on the revolute model (benchmark microwave,
  n = 30 / 200) it needs 15-19 batched residual evaluations where the LM needs 3-4.
- None (gp): nothing to refine (closed-form reduction, GP hyper-parameters by marginal
  likelihood in models/common/gp.py; gamma by EM in LinkModel._finalize).

The gradient-based refinements work in a local parametrisation (:class:`LocalParametrisation`)
in noise units about the current estimate: the rotation-vector slots of theta are
perturbed multiplicatively, R = R_base exp(u sigma), and the rotation matrices are handed to
the model's residual functions explicitly (``rots``), so nothing is stored on the model
while it is evaluated.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize

from mmlearn.models.articulation.geom import _Data, _m2rv, _rv2m
from mmlearn.models.articulation.obs import _LOG_2PI, _gamma_map, em_gamma

#: forward-difference step in the local parametrisation (noise units)
FD_STEP = 1e-6


class LocalParametrisation:
    """theta = base + u * scale on the vector entries and R = R_base exp(u * scale) on each
    rotation-vector slot (``model._rot_slots()``); u in noise units (scale sigma_pos for
    metres, sigma_orient for rotations, 0.05 rad for rotations of a position-only track).
    The gauge freedoms ``model._frozen()`` stay fixed (``free``: the other indices).
    ``steps``: (k + 1, p) rows u = 0 and one forward-difference step per free parameter,
    so that value and Jacobian come from one batched residual evaluation."""

    def __init__(self, model, theta: np.ndarray, d: _Data):
        obs = model.obs_fit
        p = theta.size
        self.slots = model._rot_slots()
        self.scale = np.full(p, obs.sigma_pos)
        for s in self.slots:
            self.scale[s:s + 3] = obs.sigma_orient if d.has_orientation else 0.05
        self.base = theta.copy()
        self.R_base = [_rv2m(theta[s:s + 3]) for s in self.slots]
        free = np.ones(p, bool)
        free[model._frozen()] = False
        self.free = np.flatnonzero(free)
        self.steps = np.zeros((self.free.size + 1, p))
        self.steps[np.arange(1, self.free.size + 1), self.free] = FD_STEP

    def decode(self, U: np.ndarray):
        """(H, p) local coordinates -> parameter vectors (H, p) and rotation matrices
        {slot: (H, 3, 3)} (None if the model has no rotation slot)."""
        U = np.atleast_2d(U)
        th = self.base[None] + U * self.scale[None]
        rots = {s: R0[None] @ _rv2m(U[:, s:s + 3] * self.scale[s:s + 3])
                for s, R0 in zip(self.slots, self.R_base)}
        return th, (rots or None)

    def theta(self, u: np.ndarray) -> np.ndarray:
        """The parameter vector (p,) at local coordinates u (p,)."""
        th, rots = self.decode(u[None])
        for s, R in (rots or {}).items():
            th[:, s:s + 3] = _m2rv(R)
        return th[0]

    def embed(self, v: np.ndarray) -> np.ndarray:
        """Local coordinates u (p,) with the free entries v (k,) and the frozen ones 0."""
        u = np.zeros(self.base.size)
        u[self.free] = v
        return u


# --------------------------------------------------------------------------- EM
def refine_em(model, theta, gamma, d: _Data, max_iter: int = 50, tol: float = 1e-3):
    """EM with the model's closed-form weighted ML fit (rigid, prismatic): E-step = inlier
    responsibilities, M-step = ``model._weighted_fit`` and MAP gamma. Each iteration
    increases the objective and costs one residual evaluation. Stops when an iteration
    gains less than ``tol`` nats."""
    obs = model.obs_fit
    log_out = obs.log_outlier(d.has_orientation)
    w = obs.map_weight(d.n)

    def score(th, g):
        ep2, eo, _ = model._residuals_batch(th[None], d)
        a = np.log1p(-g) + obs.log_inlier(ep2[0], None if eo is None else eo[0])
        lse = np.logaddexp(a, np.log(g) + log_out)
        return float(lse.sum() + obs.log_gamma_prior(g, d.n)), np.exp(a - lse)

    f, r = score(theta, gamma)
    for _ in range(max_iter):
        if not r.sum() > 1e-9:
            break
        th_new = model._weighted_fit(d, r, theta)
        g_new = float(_gamma_map(d.n - r.sum(), d.n, w))
        f_new, r_new = score(th_new, g_new)
        if not f_new >= f:  # (approximate orientation M-step) never accept a loss
            break
        theta, gamma, r = th_new, g_new, r_new
        gain, f = f_new - f, f_new
        if gain < tol:
            break
    return theta, gamma


# --------------------------------------------------------------------------- gradient-based
def alternate_refinement(model, theta, gamma, d: _Data, minimise_fixed_gamma,
                         rounds: int = 2):
    """Minimise over theta with gamma fixed (``minimise_fixed_gamma(model, par, gamma, d)
    -> theta``), re-estimate gamma by EM, repeat (at most ``rounds`` times) while gamma
    moves by 0.01 or more."""
    obs = model.obs_fit
    log_out = obs.log_outlier(d.has_orientation)
    for _ in range(rounds):
        par = LocalParametrisation(model, theta, d)
        theta = minimise_fixed_gamma(model, par, gamma, d)
        ep2, eo, _ = model._residuals_batch(theta[None], d)
        g, _, _ = em_gamma(obs.log_inlier(ep2, eo), log_out, obs.map_weight(d.n),
                           gamma0=gamma, iters=30, responsibilities=False)
        new_gamma = float(g[0])
        if abs(new_gamma - gamma) < 0.01:
            gamma = new_gamma
            break
        gamma = new_gamma
    return theta, gamma


def _lbfgs_fixed_gamma(model, par: LocalParametrisation, gamma, d: _Data):
    obs = model.obs_fit
    log_out = obs.log_outlier(d.has_orientation)
    lg1, lg = np.log1p(-gamma), np.log(gamma)

    def fg(v):
        # objective and forward-difference gradient in ONE batched residual call
        ths, rots = par.decode(par.embed(v)[None] + par.steps)
        ep2, eo, _ = model._residuals_batch(ths, d, rots)
        li = obs.log_inlier(ep2, eo)
        f = -np.logaddexp(lg1 + li, lg + log_out).sum(axis=1)
        return float(f[0]), (f[1:] - f[0]) / FD_STEP

    v0 = np.zeros(par.free.size)
    f0 = abs(fg(v0)[0])
    # stop when an iteration gains less than ~1e-3 nats (|log L| scale-free ftol)
    res = minimize(fg, v0, jac=True, method="L-BFGS-B",
                   options={"maxiter": 30, "ftol": 1e-3 / max(f0, 1.0), "gtol": 1e-3})
    return par.theta(par.embed(res.x))


def residual_terms(model, par: LocalParametrisation, gamma, d: _Data):
    """evaluate(U) -> residual vectors (H, n, m), mixture negative log-likelihoods (H,) and
    inlier responsibilities (H, n) at the local coordinates U (H, p), gamma fixed."""
    obs = model.obs_fit
    log_out = obs.log_outlier(d.has_orientation)
    lg1, lg = np.log1p(-gamma), np.log(gamma)
    const = -1.5 * (_LOG_2PI + np.log(obs.sigma_pos**2))
    if d.has_orientation:
        const += -1.5 * (_LOG_2PI + np.log(obs.sigma_orient**2))

    def evaluate(U):
        ths, rots = par.decode(U)
        r = model._residual_vectors(ths, d, rots)  # (H, n, m)
        a = lg1 + const - 0.5 * np.einsum("hnm,hnm->hn", r, r)
        lse = np.logaddexp(a, lg + log_out)
        return r, -lse.sum(axis=1), np.exp(a - lse)

    return evaluate


def _lm_fixed_gamma(model, par: LocalParametrisation, gamma, d: _Data, max_iter: int = 12,
                    tol: float = 1e-3):
    """Levenberg-Marquardt on the mixture negative log-likelihood (gamma fixed) over the
    free parameters.

    The gradient of -log L is exactly sum_t w_t J_t^T r_t (w_t: inlier responsibility, r_t
    the residual vector in noise units), and sum_t w_t J_t^T J_t is its Gauss-Newton
    Hessian (the EM M-step's), so steps are near-Newton; the weights follow every accepted
    step, and a step is kept only if -log L decreases. J by forward differences: one
    batched residual evaluation per iteration (plus one per rejected trial step).

    Measured against scipy.optimize.least_squares (``benchmarks/bench_articulation.py
    --refinement-study``, 2-core machine, CPU ms summed over the medians of 5
    revolute fits per track): least_squares as the M-step of an EM on the same
    responsibility-weighted residuals (gamma fixed, same batched forward-difference
    Jacobian, same 1e-3 nat stopping rule) reaches the same optimum on the 32 revolute
    tracks (the benchmark's microwave n = 30 / 200, simulated doors with 0-60 % outliers,
    the real doors and dishwashers at 3 noise levels: |dBIC| < 0.005 on 31, +1.14 (worse)
    on one 60 %-outlier position-only track; radius within 5e-4 relative, axis within
    0.04 deg) but takes 293 ms ("trf") / 266 ms ("lm") where this LM takes 212 ms
    (microwave n = 30: 7.3 / 6.7 vs 5.5 ms). On the 17 tracks that are not revolute
    (drawers, a curve) it follows the flat valley of an ever larger radius further (BIC
    of the wrong candidate up to 19.7 lower, up to 16 higher) at 717 / 364 ms against
    96 ms (drawer n = 30: 240 / 83 vs 7.3 ms). So the hand-written LM stays: the reason is
    speed at the same optimum (fixed weights per least_squares call need several EM
    rounds, where the LM re-weights after every step; and scipy's per-call overhead is a
    large part of a 5 ms fit)."""
    evaluate = residual_terms(model, par, gamma, d)
    u = np.zeros(par.base.size)
    lam = 1e-3
    R, F, W = evaluate(u[None] + par.steps)
    f, r, w = F[0], R[0], W[0]
    for _ in range(max_iter):
        J = (R[1:] - r[None]) / FD_STEP  # (k, n, m): d r / d u_free
        Jw = J * w[None, :, None]
        g = np.einsum("knm,nm->k", Jw, r)
        Hm = np.einsum("knm,lnm->kl", Jw, J)
        dH = np.maximum(np.diag(Hm), 1e-12)
        improved = False
        while lam < 1e10:
            try:
                step = np.linalg.solve(Hm + lam * np.diag(dH), -g)
            except np.linalg.LinAlgError:
                lam *= 10.0
                continue
            un = u.copy()
            un[par.free] += step
            R2, F2, W2 = evaluate(un[None] + par.steps)
            if F2[0] < f:
                improved = True
                lam = max(lam * 0.3, 1e-9)
                break
            lam *= 10.0
        if not improved:
            break
        gain = f - F2[0]
        u, R, f, r, w = un, R2, F2[0], R2[0], W2[0]
        if gain < tol:
            break
    return par.theta(u)


def refine_lm(model, theta, gamma, d: _Data):
    """Levenberg-Marquardt (gamma fixed) alternated with EM for gamma; needs
    ``model._residual_vectors``."""
    return alternate_refinement(model, theta, gamma, d, _lm_fixed_gamma)


def refine_lbfgs(model, theta, gamma, d: _Data):
    """L-BFGS-B (gamma fixed) alternated with EM for gamma; needs only
    ``model._residuals_batch``."""
    return alternate_refinement(model, theta, gamma, d, _lbfgs_fixed_gamma)


REFINEMENTS = {"em": refine_em, "lm": refine_lm, "lbfgs": refine_lbfgs}


def refine(model, theta, gamma, d: _Data):
    """Run the refinement the model declares: ``model.refinement`` is a name in
    REFINEMENTS or a callable (model, theta, gamma, d) -> (theta, gamma) (used by
    benchmarks/bench_articulation.py --refinement-study to compare alternatives)."""
    fn = model.refinement
    if not callable(fn):
        try:
            fn = REFINEMENTS[fn]
        except (KeyError, TypeError):
            raise ValueError(f"{type(model).__name__}.refinement must be one of "
                             f"{sorted(REFINEMENTS)} or a callable, got "
                             f"{model.refinement!r}") from None
    return fn(model, theta, gamma, d)
