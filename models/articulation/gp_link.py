"""Nonparametric link model (thesis Eq. 4.23-4.25): latent configurations by PCA or LLE,
Gaussian-process regression back to the pose. Shared fitting and evaluation in
models/articulation/base.py; public names in models/articulation/link.py."""

from __future__ import annotations

import numpy as np

from mmlearn.models.articulation.base import LinkModel
from mmlearn.models.articulation.geom import _chordal_mean, _m2rv, _rot_err, _rv2m

__all__ = ["GPModel"]


# --------------------------------------------------------------------------- GP
class GPModel(LinkModel):
    """Nonparametric link (Eq. 4.23-4.25): latent configurations by PCA (default) or LLE,
    Gaussian-process regression (squared-exponential kernel, hyper-parameters by marginal
    likelihood, models/common/gp.py) from q back to the pose.

    Outputs of the GP: the position (3) and, for full poses, the rotation vector of
    R_ref^T R (3), R_ref the mean orientation of the track. This uses 6 independent GPs
    instead of the thesis' 12 (matrix entries): half the cost, and predictions are always
    valid rotations (no SVD re-orthonormalisation needed). k = 1 + d + 6n (1 + d + 3n for
    position-only tracks), n = number of GP training points: for speed (GP cost O(n^3)) at
    most ``max_train`` observations (default 50, evenly spread along the first latent
    coordinate) train the GP; all observations enter the likelihood.

    f^-1 is the dimensionality reduction applied to the features [p, rotvec * sigma_pos /
    sigma_orient] (PCA: a linear projection; LLE: scikit-learn's ``transform``). q has the
    units of the features (metres) for PCA.
    """

    name = "gp"
    min_samples = 3
    #: none: the GP is fitted in closed form (PCA / LLE) plus marginal-likelihood
    #: hyper-parameters (models/common/gp.py) in _fit_impl, no MLESAC hypotheses to refine; gamma
    #: by EM in LinkModel._finalize.
    refinement = None

    def __init__(self, *, dof: int = 1, reduction: str = "pca", n_neighbors: int = 10,
                 max_train: int | None = 50, gp_maxiter: int = 15, **kw):
        if not 1 <= int(dof) <= 5:
            raise ValueError(f"GPModel: dof must be 1..5, got {dof}")
        if reduction not in ("pca", "lle"):
            raise ValueError(f"GPModel: reduction must be 'pca' or 'lle', got {reduction!r}")
        self.dof = int(dof)
        self.reduction = reduction
        self.n_neighbors = int(n_neighbors)
        self.max_train = None if max_train is None else int(max_train)
        self.gp_maxiter = int(gp_maxiter)
        super().__init__(**kw)
        self.name = "gp" if self.dof == 1 else f"gp{self.dof}"

    def num_params(self, n=None):
        n = self.n_train if n is None else n
        n = min(n, getattr(self, "n_gp_", n))
        return 1 + self.dof + (6 if self.has_orientation else 3) * n

    def _features(self, P, R):
        return self._features_from_targets(self._targets(P, R))

    def _features_from_targets(self, Y):
        if Y.shape[1] == 3:
            return Y
        return np.hstack([Y[:, :3], Y[:, 3:] * (self.obs.sigma_pos / self.obs.sigma_orient)])

    def _targets(self, P, R):
        if R is None:
            return P
        return np.hstack([P, _m2rv(np.einsum("ba,nbc->nac", self.R_ref, R))])

    def _fit_impl(self, d, rng):
        from mmlearn.models.common.gp import GaussianProcess, blas_single_thread

        if d.n < self.dof + 2:
            raise ValueError(f"gp: track too short ({d.n}) for d = {self.dof}")
        self.R_ref = _chordal_mean(d.R) if d.has_orientation else np.eye(3)
        Y = self._targets(d.P, d.R)
        F = self._features_from_targets(Y)
        self._fit_features = (d, F)  # for _finalize's residuals on the same track
        self.f_mean = F.mean(axis=0)
        if self.reduction == "pca":
            _, S, Vt = np.linalg.svd(F - self.f_mean, full_matrices=False)
            if S[0] < 1e-12:
                raise ValueError("gp: degenerate track (no motion)")
            self.components = Vt[: self.dof]
            Q = (F - self.f_mean) @ self.components.T
            self._lle = None
        else:
            from sklearn.manifold import LocallyLinearEmbedding

            k = min(self.n_neighbors, d.n - 1)
            self._lle = LocallyLinearEmbedding(
                n_neighbors=k, n_components=self.dof,
                random_state=int(rng.integers(2**31 - 1)))
            Q = self._lle.fit_transform(F)
            self.components = None
        if self.max_train is not None and d.n > self.max_train:
            # GP cost is O(n^3): train on max_train observations evenly spread along the
            # first latent coordinate (the others are still used for f^-1, likelihood, BIC)
            order = np.argsort(Q[:, 0], kind="stable")
            pick = order[np.round(np.linspace(0, d.n - 1, self.max_train)).astype(int)]
            Q, Y = Q[pick], Y[pick]
        self.n_gp_ = Q.shape[0]
        noise_min = self.obs.sigma_pos**2 * 1e-4
        # initial hyper-parameters from the known observation noise and the data scale
        # (better optima than a generic start, and a capped number of L-BFGS iterations)
        m_out = Y.shape[1]
        sn2 = np.r_[[self.obs.sigma_pos**2] * 3, [self.obs.sigma_orient**2] * (m_out - 3)]
        hp = {"log_ell": np.tile(np.log(np.maximum(Q.std(axis=0), 1e-6)), (m_out, 1)),
              "log_sf2": np.log(Y.var(axis=0) + 1e-12),
              "log_sn2": np.log(np.maximum(sn2, noise_min))}
        # one BLAS thread limit around the whole fit (the GP's own two nest inside it)
        with blas_single_thread():
            self.gp = GaussianProcess(ard=True).fit(Q, Y, noise_min=noise_min,
                                                    hyperparameters=hp, maxiter=self.gp_maxiter)
        self.theta = np.zeros(0)
        self.gamma = 0.0  # provisional; EM in _finalize

    def _finalize(self, d):
        try:
            super()._finalize(d)
        finally:
            self._fit_features = None

    def _inverse_raw(self, d):
        cached = getattr(self, "_fit_features", None)
        F = cached[1] if cached is not None and cached[0] is d else self._features(d.P, d.R)
        if self._lle is None:
            return (F - self.f_mean) @ self.components.T
        return self._lle.transform(F)

    def _predict(self, q):
        Y = self.gp.predict(q)
        P = Y[:, :3]
        R = _rv2m(Y[:, 3:6]) if self.has_orientation else None
        if R is not None:
            R = np.einsum("ab,nbc->nac", self.R_ref, R)
        return P, R

    def _residuals_batch(self, thetas, d, rots=None):
        q = self._inverse_raw(d)
        P, R = self._predict(q)
        diff = d.P - P
        ep2 = np.einsum("ni,ni->n", diff, diff)[None]
        eo = None
        if R is not None and d.has_orientation:
            eo = _rot_err(np.einsum("nba,nbc->nac", R, d.R))[None]
        return ep2, eo, q[None]

    def forward(self, q):
        q = self._check_q(q)
        P, R = self._predict(q)
        return self._out(P, R)

    def jacobian(self, q):
        q = self._check_q(q)
        Jy = self.gp.predict_jacobian(q)  # (m, outputs, d)
        m = q.shape[0]
        J = np.zeros((m, 6 if self.has_orientation else 3, self.dof))
        J[:, :3] = Jy[:, :3]
        if self.has_orientation:
            # angular velocity from central differences of the predicted rotation
            h = 1e-5 * max(1.0, float(np.max(np.abs(self.q_max - self.q_min))))
            for k in range(self.dof):
                dq = np.zeros(self.dof)
                dq[k] = h
                _, Rpm = self._predict(np.vstack([q + dq, q - dq]))  # one prediction
                Rp, Rm = Rpm[:m], Rpm[m:]
                J[:, 3:, k] = _m2rv(np.einsum("nab,ncb->nac", Rp, Rm)) / (2 * h)
        return J

    def params(self):
        return {"dof": self.dof, "reduction": self.reduction,
                "length_scales": self.gp.length_scales.tolist(),
                "q_min": self.q_min.tolist(), "q_max": self.q_max.tolist()}

    def _extra_to_dict(self):
        if self._lle is not None:
            raise ValueError("GP link models with LLE cannot be saved (scikit-learn's LLE "
                             "transform has no serialisable form); use reduction='pca'")
        return {"dof": self.dof, "reduction": self.reduction, "n_gp": int(self.n_gp_),
                "R_ref": self.R_ref.tolist(),
                "f_mean": self.f_mean.tolist(), "components": self.components.tolist(),
                "gp": self.gp.to_dict()}

    @classmethod
    def _from_dict(cls, dct):
        m = super()._from_dict(dct)
        m.n_neighbors = 10
        return m

    def _extra_from_dict(self, e):
        from mmlearn.models.common.gp import GaussianProcess

        self.dof = int(e["dof"])
        self.name = "gp" if self.dof == 1 else f"gp{self.dof}"
        self.reduction = e["reduction"]
        self.n_gp_ = int(e.get("n_gp", self.n_train))
        self.R_ref = np.asarray(e["R_ref"], float)
        self.f_mean = np.asarray(e["f_mean"], float)
        self.components = np.asarray(e["components"], float)
        self._lle = None
        self.gp = GaussianProcess.from_dict(e["gp"])
