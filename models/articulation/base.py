"""LinkModel: the part every articulation link model shares (thesis Sec. 4.1): fitting
(MLESAC on minimal samples, then the refinement the model class declares), evaluation
(likelihood with the configuration prior, BIC, errors, f^-1), and persistence. The link
models themselves are in models/articulation/links.py and models/articulation/gp_link.py; the
public names are re-exported by models/articulation/link.py (module docstring: the model)."""

from __future__ import annotations

import time
from dataclasses import asdict

import numpy as np
from scipy.special import ndtr
from scipy.spatial.transform import Rotation

from mmlearn.models.articulation.geom import _Data
from mmlearn.models.articulation.obs import ObservationModel, _obs_from_dict, em_gamma
from mmlearn.models.articulation.refine import refine as _run_refinement
from mmlearn.models.common.se3 import as_pose_array

# --------------------------------------------------------------------------- base class
def distinguishable_configurations(n: int, c):
    """Per DOF, how many of n estimated configurations the observation noise tells apart over
    a range of c = LinkModel.config_resolution(): min(n, max(c, 1)) (the configuration
    prior of LinkModel.config_terms is 1 / that inside a long range)."""
    return np.minimum(float(n), np.maximum(c, 1.0))


class LinkModel:
    """Common interface of the link models. Subclasses implement the parameter layout,
    minimal-sample hypotheses, batched residuals, forward, inverse and Jacobian.

    Typical use::

        m = RevoluteModel(obs=ObservationModel(sigma_pos=0.005)).fit(track, rng=0)
        m.bic_, m.gamma, m.params(), m.forward([0.3]), m.inverse(track), m.jacobian([0.3])
    """

    name = "base"
    min_samples = 1

    def __init__(self, *, obs: ObservationModel | None = None, n_hypotheses: int = 100,
                 refine: bool = True):
        self.obs = obs if obs is not None else ObservationModel()
        self.n_hypotheses = int(n_hypotheses)
        self.refine = bool(refine)
        self.fitted = False
        self.has_orientation = True
        self.theta = None
        self.gamma = 0.0
        self.n_train = 0
        self.q_min = np.zeros(self.dof)
        self.q_max = np.zeros(self.dof)
        self.log_likelihood_ = np.nan
        self.bic_ = np.nan
        self.avg_pos_error_ = np.nan
        self.avg_orient_error_ = np.nan
        self.fit_seconds_ = np.nan

    # ----- to be provided by subclasses
    dof = 0

    def num_params(self, n: int | None = None) -> int:
        raise NotImplementedError

    def _hypotheses(self, d: _Data, rng: np.random.Generator, H: int) -> np.ndarray:
        raise NotImplementedError

    #: how the best MLESAC hypothesis is refined (models/articulation/refine.py): "em"
    #: (needs _weighted_fit), "lm" (needs _residual_vectors) or "lbfgs" (needs only
    #: _residuals_batch: the generic default and the tests' reference). Each subclass says
    #: why it uses the one it sets.
    refinement = "lbfgs"

    def _residuals_batch(self, thetas: np.ndarray, d: _Data, rots: dict | None = None):
        """(H, p) parameter vectors -> squared position errors (H, n), orientation errors
        (H, n) or None, configurations (H, n, dof). ``rots``: {slot: (H, 3, 3)} rotation
        matrices to use instead of the rotation vectors in theta (the refinement's local
        parametrisation; articulation_geom._slot_rotations); None: from theta."""
        raise NotImplementedError

    def _scores_batch(self, thetas: np.ndarray, d: _Data):
        """(ep2, eo) of :meth:`_residuals_batch` (MLESAC scores the hypotheses by them; a
        model may skip the configurations there)."""
        return self._residuals_batch(thetas, d)[:2]

    def _rot_slots(self) -> list[int]:
        """Start indices of rotation-vector triples in theta."""
        return []

    def _canonicalize(self, d: _Data, inlier: np.ndarray):
        """Re-parametrise to the configuration conventions; return False if nothing changed."""
        return False

    # ----- generic machinery
    def _check_fitted(self):
        if not self.fitted:
            raise ValueError(f"{type(self).__name__} is not fitted; call fit() first")

    def _data(self, Z, what="track") -> _Data:
        d = _Data(Z, what=what)
        if self.fitted and d.has_orientation != self.has_orientation:
            if self.has_orientation:
                raise ValueError(
                    f"{what}: model was fitted to full poses, got a position-only track")
            d.R = None  # a position-only model ignores the orientation
        return d

    def fit(self, Z, *, rng=None) -> "LinkModel":
        """Fit to a track of relative poses ((n, 7), (n, 4, 4) or (n, 3); or the track's
        arrays, ``geom._Data``, which selection builds once for all its candidates) by MLESAC
        and the model's refinement (``refinement``). ``rng``: numpy Generator or seed.
        Returns self."""
        t0 = time.perf_counter()
        rng = np.random.default_rng(rng)
        d = Z if isinstance(Z, _Data) else _Data(Z)
        if d.n < max(3, self.min_samples):
            raise ValueError(
                f"{self.name}: track too short ({d.n} observations; need at least "
                f"{max(3, self.min_samples)})")
        self.fitted = False
        self._range_jac_key = self._range_jac = None
        self.has_orientation = d.has_orientation
        self.obs_fit = d.observation_model(self.obs)
        self.n_train = d.n
        self._fit_impl(d, rng)
        self.fitted = True
        self._finalize(d)
        self.fit_seconds_ = time.perf_counter() - t0
        return self

    def _fit_impl(self, d: _Data, rng):
        H = self.n_hypotheses
        thetas = self._hypotheses(d, rng, H)
        if thetas.shape[0] == 0:
            raise ValueError(f"{self.name}: all minimal samples are degenerate (track has no "
                             "usable motion for this model)")
        log_out = self.obs_fit.log_outlier(d.has_orientation)
        w = self.obs_fit.map_weight(d.n)
        ep2, eo = self._scores_batch(thetas, d)
        log_in = self.obs_fit.log_inlier(ep2, eo)
        g, ll, _ = em_gamma(log_in, log_out, w, iters=15, responsibilities=False)
        score = ll + self.obs_fit.log_gamma_prior(g, d.n)
        best = int(np.argmax(score))
        theta, gamma = thetas[best].copy(), float(g[best])
        if self.refine:
            if self.refinement != "em":
                # closed-form least-squares re-estimate on the consensus set (inlier
                # responsibility > 0.5), kept if it explains the data better. (EM skips
                # it: its first M-step is the same fit, weighted by the soft
                # responsibilities.)
                theta, gamma = self._try_consensus_fit(d, log_in[best], theta, gamma,
                                                       float(score[best]))
            theta, gamma = _run_refinement(self, theta, gamma, d)
        self.theta = theta
        self.gamma = gamma

    def _try_consensus_fit(self, d: _Data, log_in, theta, gamma, score):
        """The closed-form fit on the inliers of theta (:meth:`_consensus_fit`) if it
        scores better than ``score`` (mixture log-likelihood + log p(gamma)), else theta."""
        obs = self.obs_fit
        log_out = obs.log_outlier(d.has_orientation)
        w = obs.map_weight(d.n)
        _, _, resp = em_gamma(log_in[None], log_out, w, gamma0=gamma, iters=1)
        inl = resp[0] > 0.5
        if inl.sum() < max(3, self.min_samples):
            return theta, gamma
        cand = self._consensus_fit(d, inl, theta)
        if cand is None or not np.all(np.isfinite(cand)):
            return theta, gamma
        ep2c, eoc, _ = self._residuals_batch(cand[None], d)
        gc, llc, _ = em_gamma(obs.log_inlier(ep2c, eoc), log_out, w, gamma0=gamma, iters=15,
                            responsibilities=False)
        if llc[0] + obs.log_gamma_prior(gc[0], d.n) > score:
            return cand, float(gc[0])
        return theta, gamma

    def _residual_vectors(self, thetas: np.ndarray, d: _Data,
                          rots: dict | None = None) -> np.ndarray:
        """(H, n, 6) (or (H, n, 3) position-only) errors of f(f^-1(z)) against z, position
        divided by sigma_pos and rotation vector by sigma_orient, so that
        log_inlier = -0.5 |r|^2 + const; needed by ``refinement = "lm"``."""
        raise NotImplementedError

    def _weighted_fit(self, d: _Data, w: np.ndarray, theta: np.ndarray):
        """Closed-form parameters minimising the w-weighted (w: (n,) inlier
        responsibilities) squared errors, starting from theta; needed by
        ``refinement = "em"``."""
        raise NotImplementedError

    def _frozen(self) -> list[int]:
        """Indices of theta kept fixed in the refinement (gauge freedoms)."""
        return []

    def _consensus_fit(self, d: _Data, inl: np.ndarray, theta: np.ndarray):
        """Closed-form least-squares parameters from the inliers (or None)."""
        return None

    def _finalize(self, d: _Data):
        ep2, eo, q = self._residuals_batch(self.theta[None], d)
        li = self.obs_fit.log_inlier(ep2, eo)
        g, _, resp = em_gamma(li, self.obs_fit.log_outlier(d.has_orientation),
                              self.obs_fit.map_weight(d.n), gamma0=max(self.gamma, 1e-6))
        self.gamma = float(g[0])
        inl = resp[0] > 0.5
        if not np.any(inl):
            inl = np.ones(d.n, bool)
        if self._canonicalize(d, inl) is not False:
            ep2, eo, q = self._residuals_batch(self.theta[None], d)
        if self.dof:
            self.q_min = q[0][inl].min(axis=0)
            self.q_max = q[0][inl].max(axis=0)
        self._keep_range_jacobians()
        self.log_likelihood_ = self._log_likelihood_from(ep2, eo, d.n, d.has_orientation, q=q)
        self.bic_ = -2.0 * self.log_likelihood_ + self.num_params(d.n) * np.log(d.n)
        self.avg_pos_error_ = float(np.sqrt(ep2[0][inl]).mean())
        self.avg_orient_error_ = float(eo[0][inl].mean()) if eo is not None else None
        self.inliers_ = inl
        # per-axis rms of the inliers' residuals across the path (position, orientation):
        # the noise the data actually show, for the identifiability test of selection
        k = max(3 - self.dof, 1)
        self.residual_rms_ = (float(np.sqrt(ep2[0][inl].mean() / k)),
                              None if eo is None else float(np.sqrt((eo[0][inl] ** 2).mean() / k)))

    def path_length(self) -> tuple:
        """Length of the observed range along the first DOF: (metres of position travel,
        radians of rotation) from the model's Jacobian (0, 0 for rigid)."""
        if self.dof == 0:
            return 0.0, 0.0
        J = self._range_jacobians(self.q_min, self.q_max)[:, :, 0]
        dq = abs(float(self.q_max[0] - self.q_min[0]))
        lp = float(np.linalg.norm(J[:, :3], axis=1).mean()) * dq
        lr = float(np.linalg.norm(J[:, 3:], axis=1).mean()) * dq if J.shape[1] == 6 else 0.0
        return lp, lr

    # ----- evaluation
    def residuals(self, Z):
        """Position errors (n,) in metres and orientation errors (n,) in radians (None for
        position-only) of the projection f(f^-1(z)) against z."""
        self._check_fitted()
        d = self._data(Z)
        ep2, eo, _ = self._residuals_batch(self.theta[None], d)
        return np.sqrt(ep2[0]), (None if eo is None else eo[0])

    def project(self, Z) -> np.ndarray:
        """f(f^-1(z)): the observations projected onto the model, same format as forward()."""
        return self.forward(self.inverse(Z))

    def log_likelihood(self, Z, *, gamma: float | None = None) -> float:
        """Data log-likelihood of Eq. 4.31-4.32 including the outlier prior and the
        configuration prior (:meth:`log_config_prior`), with the model's outlier ratio (or
        ``gamma``)."""
        self._check_fitted()
        d = Z if isinstance(Z, _Data) else self._data(Z)
        g = self.gamma if gamma is None else float(gamma)
        g = float(np.clip(g, 1e-6, 1 - 1e-6))
        ep2, eo, q = self._residuals_batch(self.theta[None], d)
        return self._log_likelihood_from(ep2, eo, d.n, d.has_orientation, g, q=q)

    def _log_likelihood_from(self, ep2, eo, n, has_orientation, gamma=None, q=None, *,
                             q_range=None, gamma_prior: bool = True) -> float:
        g = float(np.clip(self.gamma if gamma is None else gamma, 1e-6, 1 - 1e-6))
        li = self.obs_fit.log_inlier(ep2[0], None if eo is None else eo[0])
        lo = self.obs_fit.log_outlier(has_orientation)
        qq = q[0] if q is not None else None
        if self.obs_fit.config_prior == "n":  # (as before 2026-11: outside the mixture)
            ll = np.logaddexp(np.log1p(-g) + li, np.log(g) + lo).sum()
            ll += self.log_config_prior(qq, n)
        else:  # the configuration is latent in the inlier component only
            ct = self.config_terms(qq, n, q_range)
            ll = np.logaddexp(np.log1p(-g) + li + ct, np.log(g) + lo).sum()
        if gamma_prior:
            ll += float(self.obs_fit.log_gamma_prior(g, n))
        return float(ll)

    def _range_jacobians(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """The model's Jacobian (16, 3 | 6, d) at 16 configurations evenly spread over
        [lo, hi]. Over the model's own range the fit keeps them (``_keep_range_jacobians``:
        the likelihood's configuration prior and the selection's identifiability test ask
        for that range again and again); evaluation stores nothing."""
        lo, hi = np.asarray(lo, float), np.asarray(hi, float)
        if (getattr(self, "_range_jac_key", None) is not None
                and self._range_jac_key == self._range_key(lo, hi)):
            return self._range_jac.copy()
        qs = lo[None] + np.linspace(0.0, 1.0, 16)[:, None] * (hi - lo)[None]
        return self.jacobian(qs)

    def _range_key(self, lo, hi):
        return (lo.tobytes(), hi.tobytes(), np.asarray(self.theta, float).tobytes())

    def _keep_range_jacobians(self):
        """Compute and keep the Jacobians over [q_min, q_max] (end of the fit)."""
        self._range_jac_key = self._range_jac = None
        if self.dof:
            J = self._range_jacobians(self.q_min, self.q_max)
            self._range_jac_key, self._range_jac = self._range_key(self.q_min, self.q_max), J

    def _noise_speed(self, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """Mean length of a unit step in q, per DOF, in noise units:
        sqrt(|dp/dq|^2 / sigma_pos^2 + |dw/dq|^2 / sigma_orient^2) averaged over 16
        configurations across [lo, hi] (the model's Jacobian)."""
        J = self._range_jacobians(lo, hi)
        g = np.einsum("mid,mid->md", J[:, :3], J[:, :3]) / self.obs_fit.sigma_pos**2
        if J.shape[1] == 6:
            g = g + np.einsum("mid,mid->md", J[:, 3:], J[:, 3:]) / self.obs_fit.sigma_orient**2
        return np.sqrt(g).mean(axis=0)

    def config_resolution(self, q_range=None) -> np.ndarray:
        """c per DOF: the observed range (or ``q_range`` = (q_lo, q_hi)) measured in noise
        units (see :meth:`_noise_speed`) and divided by sqrt(2 pi): roughly the number of
        configurations the observation noise can tell apart over the range."""
        if self.dof == 0:
            return np.zeros(0)
        lo, hi = (self.q_min, self.q_max) if q_range is None else (
            np.asarray(q_range[0], float), np.asarray(q_range[1], float))
        return self._noise_speed(lo, hi) * np.abs(hi - lo) / np.sqrt(2.0 * np.pi)

    def config_terms(self, q=None, n: int | None = None, q_range=None):
        """log p(q | M) per observation (Eq. 4.26-4.28): how much the latent configuration
        costs, on top of log p(z | f(q_hat)); an (n,) array, or a scalar for all of them.

        ``config_prior="n"``: n^-d per observation, as Eq. 4.27 writes it.

        ``"resolved"`` (default): the configurations are equally likely over the observed
        range [q_lo, q_hi] (Eq. 4.27's assumption), and Eq. 4.26's integral over q is
        evaluated rather than replaced by its value at q_hat (Eq. 4.29). Along the path, in
        noise units u (Gaussian noise of unit variance), with u_t the projection of z_t and
        U the range's length, p(z_t | M) = p(z_t | f(q_hat_t)) sqrt(2 pi) / U
        [Phi(U - u_t) - Phi(-u_t)] per DOF: log c per observation (c = U / sqrt(2 pi),
        config_resolution()) inside a long range, and the rigid model's likelihood (the
        distance to the range's centre) as U -> 0, so a 1-DOF model fitted to a part that
        never moved gains nothing from its projection. Where the n configurations are
        farther apart than the noise (n < c: few observations of a long range) the integral
        over the grid of n estimated configurations is its nearest term, n^-1 (Eq. 4.27).
        The term no longer grows with more observations of the same range, as n^-d does.

        Args:
            q: (n, d) estimated configurations of the scored observations (None: treated as
                inside a long range, i.e. the log min(n, c) limit).
            n: number of observations (default len(q)).
            q_range: (q_lo, q_hi) of the uniform prior (default the model's q_min, q_max).
        """
        if self.dof == 0:
            return 0.0
        if n is None:
            n = q.shape[0]
        if self.obs_fit.config_prior == "n":
            return float(-self.dof * np.log(n))
        lo, hi = (self.q_min, self.q_max) if q_range is None else (
            np.asarray(q_range[0], float), np.asarray(q_range[1], float))
        speed = self._noise_speed(lo, hi)
        U = speed * np.abs(hi - lo)
        c = U / np.sqrt(2.0 * np.pi)
        total = 0.0
        for j in range(self.dof):
            if n <= c[j] or q is None:  # sparse configurations, or no positions given
                total = total - np.log(distinguishable_configurations(n, c[j]))
                continue
            u = (q[:, j] - min(lo[j], hi[j])) * speed[j]
            if U[j] > 1e-6:
                mass = ndtr(U[j] - u) - ndtr(-u)
                total = total + np.log(np.maximum(mass, 1e-300)) - np.log(c[j])
            else:  # limit U -> 0: sqrt(2 pi) phi(u - U / 2)
                total = total - 0.5 * (u - 0.5 * U[j]) ** 2
        return total

    def log_config_prior(self, q=None, n: int | None = None, q_range=None) -> float:
        """Sum of :meth:`config_terms` over the observations."""
        t = self.config_terms(q, n, q_range)
        if np.ndim(t) == 0:
            return float(t) * (n if n is not None else q.shape[0])
        return float(np.sum(t))

    def log_likelihood_of_visits(self, trajectories) -> float:
        """Data log-likelihood (Eq. 4.31-4.32, as :meth:`log_likelihood`) of several tracks
        of the mechanism, each scored as one visit: its configurations uniform over the
        range that track covers (its inlier configurations under this model), not over the
        model's whole training range; the outlier prior once for all observations. Used by
        the prior merge test, where one model explains several visits."""
        self._check_fitted()
        ll, n = 0.0, 0
        for Z in trajectories:
            d = self._data(Z)
            ep2, eo, q = self._residuals_batch(self.theta[None], d)
            q_range = None
            if self.dof:
                inl = self._inlier_mask(ep2, eo, d.has_orientation)
                qq = q[0][inl] if inl.sum() >= 2 else q[0]
                q_range = (qq.min(axis=0), qq.max(axis=0))
            ll += self._log_likelihood_from(ep2, eo, d.n, d.has_orientation, q=q,
                                            q_range=q_range, gamma_prior=False)
            n += d.n
        g = float(np.clip(self.gamma, 1e-6, 1 - 1e-6))
        return float(ll + self.obs_fit.log_gamma_prior(g, n))

    def bic(self, Z=None) -> float:
        """BIC = -2 log L + k log n (Eq. 4.34) on Z (default: the training track)."""
        self._check_fitted()
        if Z is None:
            return float(self.bic_)
        d = self._data(Z)
        return float(-2 * self.log_likelihood(d) + self.num_params(self.n_train) * np.log(d.n))

    def _inlier_mask(self, ep2, eo, has_orientation: bool) -> np.ndarray:
        """(n,) True where the model classifies an observation as an inlier (responsibility
        above 0.5 at its outlier ratio); ep2, eo as returned by _residuals_batch (1, n)."""
        li = self.obs_fit.log_inlier(ep2[0], None if eo is None else eo[0])
        g = float(np.clip(self.gamma, 1e-6, 1 - 1e-6))
        return np.log1p(-g) + li > np.log(g) + self.obs_fit.log_outlier(has_orientation)

    def prediction_errors(self, Z, *, inliers_only: bool = False):
        """Averaged position (m) and orientation (rad, None for position-only) errors of
        f(f^-1(z)) against z. With inliers_only, observations the model classifies as
        outliers (responsibility < 0.5) are left out."""
        self._check_fitted()
        d = self._data(Z)
        ep2, eo, _ = self._residuals_batch(self.theta[None], d)
        mask = np.ones(d.n, bool)
        if inliers_only:
            mask = self._inlier_mask(ep2, eo, d.has_orientation)
            if not mask.any():
                mask[:] = True
        ep = float(np.sqrt(ep2[0][mask]).mean())
        return ep, (None if eo is None else float(eo[0][mask].mean()))

    @property
    def num_params_(self) -> int:
        return self.num_params(self.n_train)

    def inverse(self, Z) -> np.ndarray:
        """f^-1(z): configurations (n, d) of the observations."""
        self._check_fitted()
        d = self._data(Z)
        _, _, q = self._residuals_batch(self.theta[None], d)
        return q[0]

    def _check_q(self, q) -> np.ndarray:
        self._check_fitted()
        q = np.asarray(q, float)
        if self.dof == 0:
            m = q.shape[0] if q.ndim >= 1 else 1
            return np.zeros((max(m, 1), 0))
        if q.ndim == 0:
            q = q.reshape(1, 1)
        elif q.ndim == 1:
            q = q.reshape(-1, self.dof) if self.dof > 1 else q[:, None]
        if q.ndim != 2 or q.shape[1] != self.dof:
            raise ValueError(f"{self.name}: q must have shape (m, {self.dof}), got {q.shape}")
        if not np.all(np.isfinite(q)):
            raise ValueError(f"{self.name}: q contains NaN/inf")
        return q

    def _out(self, P, R):
        if not self.has_orientation:
            return P
        return np.hstack([P, Rotation.from_matrix(R).as_quat()])

    def forward(self, q) -> np.ndarray:
        """f(q): poses (m, 7) x y z qx qy qz qw, or (m, 3) for position-only models."""
        raise NotImplementedError

    def jacobian(self, q) -> np.ndarray:
        """df/dq: (m, 6, d) (linear; angular velocity) or (m, 3, d) position-only."""
        raise NotImplementedError

    def forward_matrices(self, q) -> np.ndarray:
        return as_pose_array(self.forward(q)).as_matrices()

    # ----- reporting / persistence
    def __repr__(self) -> str:
        if not self.fitted:
            return f"{type(self).__name__}(not fitted, sigma_pos={self.obs.sigma_pos:g} m)"

        def r(v):
            if isinstance(v, float):
                return f"{v:.4g}"
            if isinstance(v, list):
                return "[" + ", ".join(r(x) for x in v) + "]"
            return repr(v)

        ps = ", ".join(f"{k}={r(v)}" for k, v in self.params().items()
                       if not isinstance(v, list) or len(v) <= 4)
        return (f"{type(self).__name__}(n={self.n_train}, gamma={self.gamma:.3f}, "
                f"bic={float(self.bic_):.1f}{', ' + ps if ps else ''})")

    def params(self) -> dict:
        """Human-readable parameters (units in the key names)."""
        return {}

    def summary(self) -> dict:
        self._check_fitted()
        return {
            "model": self.name, "dof": self.dof, "k": self.num_params_, "n": self.n_train,
            "gamma": self.gamma, "log_likelihood": self.log_likelihood_, "bic": self.bic_,
            "avg_pos_error_m": self.avg_pos_error_,
            "avg_orient_error_rad": self.avg_orient_error_,
            "q_min": self.q_min.tolist(), "q_max": self.q_max.tolist(),
            "params": self.params(), "fit_seconds": self.fit_seconds_,
        }

    def to_dict(self) -> dict:
        """Serialisable state (see models/articulation/io.py for the schema)."""
        self._check_fitted()
        return {
            "type": self.name,
            "obs": asdict(self.obs),
            "obs_fit": asdict(self.obs_fit),
            "has_orientation": self.has_orientation,
            "theta": [float(x) for x in self.theta],
            "gamma": float(self.gamma),
            "n_train": int(self.n_train),
            "q_min": [float(x) for x in self.q_min],
            "q_max": [float(x) for x in self.q_max],
            "log_likelihood": float(self.log_likelihood_),
            "bic": float(self.bic_),
            "avg_pos_error_m": float(self.avg_pos_error_),
            "avg_orient_error_rad": (None if self.avg_orient_error_ is None
                                     else float(self.avg_orient_error_)),
            "extra": self._extra_to_dict(),
        }

    def _extra_to_dict(self) -> dict:
        return {}

    def _extra_from_dict(self, e: dict) -> None:
        pass

    @classmethod
    def _from_dict(cls, dct: dict) -> "LinkModel":
        m = cls.__new__(cls)
        LinkModel.__init__(m, obs=_obs_from_dict(dct["obs"]))
        m.obs_fit = _obs_from_dict(dct["obs_fit"])
        m.has_orientation = bool(dct["has_orientation"])
        m.theta = np.asarray(dct["theta"], float)
        m.gamma = float(dct["gamma"])
        m.n_train = int(dct["n_train"])
        m.q_min = np.asarray(dct["q_min"], float)
        m.q_max = np.asarray(dct["q_max"], float)
        m.log_likelihood_ = float(dct["log_likelihood"])
        m.bic_ = float(dct["bic"])
        m.avg_pos_error_ = float(dct["avg_pos_error_m"])
        m.avg_orient_error_ = dct["avg_orient_error_rad"]
        m._extra_from_dict(dct.get("extra", {}))
        m.fitted = True
        return m
