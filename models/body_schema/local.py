"""Local models of the body schema (thesis Sec. 3.2.1, Eq. 3.5-3.10).

A local model ``M_ij`` maps the subset ``Q`` of the commanded action signals onto the relative
transform ``z_ij = y_i^-1 y_j`` between the observed poses of body parts ``i`` and ``j``. It is
12 independent GPs (squared-exponential kernel, hyper-parameters by marginal likelihood) on the
upper 3x4 block of the homogeneous matrix; the predicted rotation block is re-orthonormalised
with an SVD.

Pose arrays are (n, 4, 4) homogeneous matrices (metres); orientation errors are radians.
Action arrays are always the *full* commanded action vector (n, m); a model picks its columns Q.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from mmlearn.models.common.gp import GaussianProcess
from mmlearn.models.common.se3 import project_to_so3

__all__ = [
    "LocalModel",
    "EngineeredModel",
    "se3_inv",
    "orthonormalize",
    "pose_errors",
    "log_likelihood",
    "relative_poses",
    "visible_mask",
    "poses_from_xyzquat",
]


# ---------------------------------------------------------------------------- SE(3) helpers
def se3_inv(T: np.ndarray) -> np.ndarray:
    """Inverse of rigid transforms (..., 4, 4)."""
    R = T[..., :3, :3]
    Ti = np.zeros_like(T)
    Rt = np.swapaxes(R, -1, -2)
    Ti[..., :3, :3] = Rt
    Ti[..., :3, 3] = -(Rt @ T[..., :3, 3:4])[..., 0]
    Ti[..., 3, 3] = 1.0
    return Ti


def orthonormalize(T: np.ndarray) -> np.ndarray:
    """Homogeneous transforms from (..., 4, 4) matrices: the 3x3 block projected onto SO(3)
    (se3.project_to_so3), the last row set to (0, 0, 0, 1)."""
    out = T.copy()
    out[..., :3, :3] = project_to_so3(T[..., :3, :3])
    out[..., 3, :] = (0.0, 0.0, 0.0, 1.0)
    return out


def pose_errors(T_pred: np.ndarray, T_obs: np.ndarray):
    """Translational (m) and rotational (rad) error between pose stacks (n, 4, 4)."""
    dp = np.linalg.norm(T_pred[..., :3, 3] - T_obs[..., :3, 3], axis=-1)
    M = np.swapaxes(T_pred[..., :3, :3], -1, -2) @ T_obs[..., :3, :3]
    c = (np.trace(M, axis1=-2, axis2=-1) - 1.0) / 2.0
    return dp, np.arccos(np.clip(c, -1.0, 1.0))


def log_likelihood(pos_err, rot_err, sigma_pos: float, sigma_orient: float) -> np.ndarray:
    """Per-observation log-likelihood of Eq. 3.10: a 6-D Gaussian with covariance
    diag(sigma_pos^2 I3, sigma_orient^2 I3) on the translational / rotational error."""
    pos_err = np.asarray(pos_err, float)
    rot_err = np.asarray(rot_err, float)
    norm = -0.5 * (6 * np.log(2 * np.pi) + 6 * np.log(sigma_pos) + 6 * np.log(sigma_orient))
    return norm - 0.5 * ((pos_err / sigma_pos) ** 2 + (rot_err / sigma_orient) ** 2)


def poses_from_xyzquat(P) -> np.ndarray:
    """(..., 7) poses ``x y z qx qy qz qw`` (the log format) -> (..., 4, 4); NaN stays NaN."""
    P = np.asarray(P, float)
    if P.shape[-1] != 7:
        raise ValueError(f"expected (..., 7) poses x y z qx qy qz qw, got {P.shape}")
    ok = np.all(np.isfinite(P), axis=-1)
    T = np.full(P.shape[:-1] + (4, 4), np.nan)
    if np.any(ok):
        Q = P[ok]
        n = np.linalg.norm(Q[:, 3:], axis=-1)
        if np.any(n == 0):
            raise ValueError("poses: zero quaternion (x y z qx qy qz qw needs a unit quaternion)")
        T[ok] = 0.0
        T[ok, :3, :3] = Rotation.from_quat(Q[:, 3:]).as_matrix()  # normalises
        T[ok, :3, 3] = Q[:, :3]
        T[ok, 3, 3] = 1.0
    return T


def visible_mask(poses: np.ndarray) -> np.ndarray:
    """(t, p) True where the pose (t, p, 4, 4) is fully finite (the marker was seen)."""
    return np.all(np.isfinite(poses.reshape(poses.shape[:2] + (-1,))), axis=-1)


def relative_poses(poses: np.ndarray, i: int, j: int, mask: np.ndarray | None = None):
    """Rows where both i and j are seen and ``z_ij = y_i^-1 y_j`` for them: (rows, (r, 4, 4))."""
    if mask is None:
        mask = visible_mask(poses)
    rows = np.flatnonzero(mask[:, i] & mask[:, j])
    return rows, se3_inv(poses[rows, i]) @ poses[rows, j]


def _z_to_y(Z: np.ndarray) -> np.ndarray:
    return Z[:, :3, :4].reshape(len(Z), 12)


def _y_to_z(Y: np.ndarray) -> np.ndarray:
    n = len(Y)
    Z = np.zeros((n, 4, 4))
    Z[:, :3, :4] = Y.reshape(n, 3, 4)
    Z[:, 3, 3] = 1.0
    return Z


def _polar_derivative(M: np.ndarray, dM: np.ndarray) -> np.ndarray:
    """Derivative of the nearest rotation R(M) (polar factor, M = R S) for M (n, 3, 3) and
    its derivatives dM (n, 3, 3, k): dR = R [w]x with (tr(S) I - S) w = vee(R^T dM - dM^T R)."""
    R = project_to_so3(M)
    S = np.swapaxes(R, 1, 2) @ M
    S = 0.5 * (S + np.swapaxes(S, 1, 2))
    A = np.einsum("nba,nbck->nack", R, dM) - np.einsum("nbak,nbc->nack", dM, R)
    a = np.stack([A[:, 2, 1], A[:, 0, 2], A[:, 1, 0]], axis=1)  # (n, 3, k)
    G = np.trace(S, axis1=1, axis2=2)[:, None, None] * np.eye(3) - S
    w = np.linalg.solve(G, a)  # (n, 3, k)
    W = np.zeros(w.shape[:1] + (3, 3) + w.shape[2:])
    W[:, 0, 1], W[:, 0, 2] = -w[:, 2], w[:, 1]
    W[:, 1, 0], W[:, 1, 2] = w[:, 2], -w[:, 0]
    W[:, 2, 0], W[:, 2, 1] = -w[:, 1], w[:, 0]
    return np.einsum("nab,nbck->nack", R, W)


def _check_actions(actions, n_actions: int | None = None) -> np.ndarray:
    a = np.asarray(actions, float)
    if a.ndim == 1:
        a = a[None, :]
    if a.ndim != 2:
        raise ValueError(f"actions must be (n, n_actions), got shape {a.shape}")
    if n_actions is not None and a.shape[1] != n_actions:
        raise ValueError(f"actions must have {n_actions} columns, got {a.shape[1]}")
    if not np.all(np.isfinite(a)):
        raise ValueError("actions contain NaN or inf")
    return a


# ---------------------------------------------------------------------------- local models
class _ModelBase:
    """Shared interface of learned and engineered local models."""

    i: int
    j: int
    Q: tuple
    n_actions: int
    origin: str = "learned"

    @property
    def k(self) -> int:
        """Complexity: number of action signals the model depends on."""
        return len(self.Q)

    @property
    def key(self) -> tuple:
        return (self.i, self.j, self.Q)

    def nodes(self) -> frozenset:
        """Nodes of the Bayesian network this model touches (parts and actions)."""
        return frozenset([("x", self.i), ("x", self.j)] + [("q", a) for a in self.Q])

    def proximity(self, other) -> float:
        """Structural proximity d_DBN: ratio of shared nodes (Jaccard index)."""
        a, b = self.nodes(), other.nodes()
        return len(a & b) / len(a | b)

    def errors(self, actions, Z):
        """Translational (m) and rotational (rad) error of the prediction vs observed Z."""
        return pose_errors(self.predict(actions), np.asarray(Z, float))

    def __repr__(self):
        q = ",".join(f"q{a + 1}" for a in self.Q) or "-"
        return f"{type(self).__name__}(x{self.i + 1}-x{self.j + 1} | {q}, {self.origin})"


class LocalModel(_ModelBase):
    """GP local model ``z_ij = f(q_Q)``.

    Args:
        i, j: body-part indices (0-based).
        Q: action-signal indices (0-based) the model depends on.
        n_actions: length of the full action vector.
        kernel: "se" (the thesis' squared-exponential kernel) or "se+revolute" (plus the
            term sb2 prod_d (1 + cos(q_d - q'_d)) over the model's action signals, which
            spans the relative transform across revolute joints; actions in radians; see
            :mod:`mmlearn.models.common.gp` and ``SearchConfig.kernel``).
    """

    KERNELS = ("se", "se+revolute")

    def __init__(self, i: int, j: int, Q, n_actions: int, *, kernel: str = "se"):
        if i == j:
            raise ValueError(f"a local model needs two different parts, got i = j = {i}")
        Q = tuple(sorted(int(a) for a in Q))
        if any(a < 0 or a >= n_actions for a in Q) or len(set(Q)) != len(Q):
            raise ValueError(f"Q={Q} must be distinct indices in [0, {n_actions})")
        if kernel not in self.KERNELS:
            raise ValueError(f"LocalModel kernel must be one of {self.KERNELS}, got {kernel!r}")
        self.i, self.j, self.Q, self.n_actions = int(i), int(j), Q, int(n_actions)
        self.kernel = kernel
        self.gp: GaussianProcess | None = None
        self.origin = "learned"

    @property
    def n_train(self) -> int:
        return 0 if self.gp is None else self.gp.X.shape[0]

    def fit(self, actions, Z, *, optimize: bool = True, max_opt: int = 40,
            hyperparameters: dict | None = None, noise_min: float = 1e-8,
            n_restarts: int = 1, ftol: float = 1e-5, ell_starts=(),
            extra_starts=()) -> "LocalModel":
        """Train on commanded actions (n, m) and relative poses Z (n, 4, 4).

        With ``optimize``, hyper-parameters are fitted by marginal likelihood on at most
        ``max_opt`` evenly spaced samples (``n_restarts`` extra low-noise starts, best kept per
        output), then the GP conditions on all n samples. ``ell_starts`` and
        ``extra_starts``: further optimiser starts (GaussianProcess.fit).
        """
        actions = _check_actions(actions, self.n_actions)
        Z = np.asarray(Z, float)
        if Z.shape != (len(actions), 4, 4):
            raise ValueError(f"Z must be ({len(actions)}, 4, 4), got {Z.shape}")
        if len(actions) < 2:
            raise ValueError(f"local model x{self.i + 1}-x{self.j + 1} needs >= 2 samples, "
                             f"got {len(actions)}")
        if not np.all(np.isfinite(Z)):
            raise ValueError("Z contains NaN or inf")
        X = actions[:, list(self.Q)]
        Y = _z_to_y(Z)
        n = len(X)
        if optimize and n > max_opt:
            sub = np.unique(np.linspace(0, n - 1, max_opt).round().astype(int))
            g = self._new_gp().fit(X[sub], Y[sub], optimize=True,
                                              noise_min=noise_min, n_restarts=n_restarts,
                                              hyperparameters=hyperparameters, ftol=ftol,
                                              ell_starts=ell_starts,
                                              extra_starts=extra_starts)
            hyperparameters = g.hyperparameters()
            optimize = False
        self.gp = self._new_gp().fit(X, Y, optimize=optimize, noise_min=noise_min,
                                                hyperparameters=hyperparameters,
                                                n_restarts=n_restarts, ftol=ftol,
                                                ell_starts=ell_starts if optimize else (),
                                                extra_starts=extra_starts if optimize else ())
        return self

    def _new_gp(self) -> GaussianProcess:
        return GaussianProcess(ard=True, revolute=self.kernel == "se+revolute")

    def refit(self, actions, Z) -> "LocalModel":
        """Condition on new data keeping the current hyper-parameters (cheap)."""
        hp = self.gp.hyperparameters() if self.gp is not None else None
        return self.fit(actions, Z, optimize=hp is None, hyperparameters=hp)

    def _check(self, actions):
        if self.gp is None:
            raise ValueError(f"{self!r} is not trained")
        return _check_actions(actions, self.n_actions)

    def predict(self, actions, return_var: bool = False):
        """Predicted z_ij (n, 4, 4) (rotation orthonormalised) and optionally the GP
        predictive variance of the 12 raw entries (n, 12) (row-major 3x4 block)."""
        actions = self._check(actions)
        X = actions[:, list(self.Q)]
        if return_var:
            mean, var = self.gp.predict(X, return_var=True)
            return orthonormalize(_y_to_z(mean)), var
        return orthonormalize(_y_to_z(self.gp.predict(X)))

    def loo_predict(self) -> np.ndarray:
        """Leave-one-out predictions (n, 4, 4) at the training samples (each from the GP
        conditioned on all other training samples), rotation orthonormalised."""
        if self.gp is None:
            raise ValueError(f"{self!r} is not trained")
        return orthonormalize(_y_to_z(self.gp.loo_predict()[0]))

    def predict_jacobian(self, actions) -> np.ndarray:
        """d z_ij / d q (n, 4, 4, n_actions) of :meth:`predict` (zero outside Q): the GP mean
        derivative chained through the SVD orthonormalisation of the rotation block."""
        actions = self._check(actions)
        n = len(actions)
        J = np.zeros((n, 4, 4, self.n_actions))
        if self.k:
            X = actions[:, list(self.Q)]
            M = self.gp.predict(X).reshape(n, 3, 4)
            dM = self.gp.predict_jacobian(X).reshape(n, 3, 4, self.k)
            J[:, :3, 3, list(self.Q)] = dM[:, :, 3, :]
            J[:, :3, :3, list(self.Q)] = _polar_derivative(M[:, :, :3], dM[:, :, :3, :])
        return J

    def log_marginal_likelihood(self) -> float:
        return self.gp.log_marginal_likelihood()

    def to_dict(self) -> dict:
        return {"type": "LocalModel", "i": self.i, "j": self.j, "Q": list(self.Q),
                "n_actions": self.n_actions, "origin": self.origin, "kernel": self.kernel,
                "gp": None if self.gp is None else self.gp.to_dict()}

    @classmethod
    def from_dict(cls, d: dict) -> "LocalModel":
        m = cls(d["i"], d["j"], d["Q"], d["n_actions"], kernel=d.get("kernel", "se"))
        m.origin = d.get("origin", "learned")
        if d.get("gp") is not None:
            m.gp = GaussianProcess.from_dict(d["gp"])
        return m


class EngineeredModel(_ModelBase):
    """A known (hand-made) local model: ``function(q_Q (n, k)) -> z_ij (n, 4, 4)``.

    The Jacobian is taken by central finite differences (step ``eps``, units of the actions).
    """

    def __init__(self, i: int, j: int, Q, n_actions: int, function, *, eps: float = 1e-6):
        if i == j:
            raise ValueError(f"a local model needs two different parts, got i = j = {i}")
        self.i, self.j = int(i), int(j)
        self.Q = tuple(sorted(int(a) for a in Q))
        self.n_actions = int(n_actions)
        self.function = function
        self.eps = float(eps)
        self.origin = "engineered"

    def predict(self, actions, return_var: bool = False):
        actions = _check_actions(actions, self.n_actions)
        Z = np.asarray(self.function(actions[:, list(self.Q)]), float).reshape(-1, 4, 4)
        if return_var:
            return Z, np.zeros((len(Z), 12))
        return Z

    def predict_jacobian(self, actions) -> np.ndarray:
        actions = _check_actions(actions, self.n_actions)
        n = len(actions)
        J = np.zeros((n, 4, 4, self.n_actions))
        for a in self.Q:
            d = np.zeros(self.n_actions)
            d[a] = self.eps
            J[..., a] = (self.predict(actions + d) - self.predict(actions - d)) / (2 * self.eps)
        return J
