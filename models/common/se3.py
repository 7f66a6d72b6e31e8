"""Small, vectorised SE(3) pose utilities for the articulation models.

Pose conventions (see ARCHITECTURE.md): a track of poses is either

- ``(n, 7)``: ``x y z qx qy qz qw`` (metres, unit quaternion in scalar-last order),
- ``(n, 4, 4)``: homogeneous matrices, or
- ``(n, 3)``: positions only (orientation unknown).

Internally the articulation code works on a :class:`PoseArray`: positions ``(n, 3)`` plus a
``scipy.spatial.transform.Rotation`` of length n, or ``None`` for position-only tracks.
All functions are vectorised over the n poses.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

__all__ = [
    "PoseArray",
    "as_pose_array",
    "relative_poses",
    "rotation_distance",
    "matrix_to_pose7",
    "quat_distance",
    "project_to_so3",
    "rotvec_to_matrix",
    "matrix_to_rotvec",
]


@dataclass
class PoseArray:
    """n poses: ``positions`` (n, 3) in metres and ``rotations`` (scipy Rotation, length n) or
    None when the orientation is unknown (position-only track)."""

    positions: np.ndarray
    rotations: Rotation | None = None

    def __len__(self) -> int:
        return int(self.positions.shape[0])

    @property
    def has_orientation(self) -> bool:
        return self.rotations is not None

    def __getitem__(self, idx) -> "PoseArray":
        idx = np.atleast_1d(np.arange(len(self))[idx])
        rot = None if self.rotations is None else self.rotations[idx]
        return PoseArray(self.positions[idx], rot)

    def quaternions(self) -> np.ndarray | None:
        """(n, 4) scalar-last quaternions or None."""
        return None if self.rotations is None else self.rotations.as_quat()

    def as_array(self) -> np.ndarray:
        """(n, 7) or (n, 3) array (position-only)."""
        if self.rotations is None:
            return self.positions.copy()
        return np.hstack([self.positions, self.rotations.as_quat()])

    def as_matrices(self) -> np.ndarray:
        """(n, 4, 4) homogeneous matrices (identity rotation for position-only tracks)."""
        n = len(self)
        T = np.tile(np.eye(4), (n, 1, 1))
        T[:, :3, 3] = self.positions
        if self.rotations is not None:
            T[:, :3, :3] = self.rotations.as_matrix()
        return T

    def inverse(self) -> "PoseArray":
        if self.rotations is None:
            return PoseArray(-self.positions, None)
        inv = self.rotations.inv()
        return PoseArray(-inv.apply(self.positions), inv)

    def compose(self, other: "PoseArray") -> "PoseArray":
        """self (+) other, i.e. matrix product self @ other (broadcast 1 vs n allowed)."""
        if self.rotations is None:
            return PoseArray(self.positions + other.positions, None)
        pos = self.positions + self.rotations.apply(other.positions)
        rot = None if other.rotations is None else self.rotations * other.rotations
        return PoseArray(pos, rot)


MAX_COORDINATE = 1e6
"""Largest accepted position coordinate, m: beyond it the squared errors of the fits
overflow, and such a track is not in metres."""


def _check_finite(a: np.ndarray, what: str) -> None:
    if not np.all(np.isfinite(a)):
        bad = np.argwhere(~np.isfinite(a.reshape(a.shape[0], -1)).all(axis=1)).ravel()
        raise ValueError(f"{what} contains NaN/inf values (rows {bad[:10].tolist()})")


def _check_scale(P: np.ndarray, what: str) -> None:
    big = np.abs(P) > MAX_COORDINATE
    if np.any(big):
        rows = np.flatnonzero(big.any(axis=-1))
        raise ValueError(f"{what}: position coordinates beyond {MAX_COORDINATE:g} m (rows "
                         f"{rows[:10].tolist()}); positions must be in metres")


def as_pose_array(data, *, what: str = "track", allow_nan: bool = False) -> PoseArray:
    """Convert ``(n, 3)``, ``(n, 7)``, ``(n, 4, 4)``, a single pose, or a PoseArray into a
    PoseArray. Quaternions are normalised. Raises ValueError on wrong shapes / NaN."""
    if isinstance(data, PoseArray):
        return data
    a = np.asarray(data, dtype=float)
    if a.ndim == 1 and a.shape[0] in (3, 7):
        a = a[None]
    if a.ndim == 2 and a.shape == (4, 4):
        a = a[None]
    if a.ndim == 3:
        if a.shape[1:] != (4, 4):
            raise ValueError(f"{what}: expected (n, 4, 4) matrices, got shape {a.shape}")
        if not allow_nan:
            _check_finite(a, what)
        with np.errstate(invalid="ignore"):
            _check_scale(a[:, :3, 3], what)
        return PoseArray(a[:, :3, 3].copy(), Rotation.from_matrix(a[:, :3, :3]))
    if a.ndim != 2 or a.shape[1] not in (3, 7):
        raise ValueError(
            f"{what}: expected an (n, 3) position, (n, 7) x y z qx qy qz qw or (n, 4, 4) "
            f"array, got shape {a.shape}"
        )
    if not allow_nan:
        _check_finite(a, what)
    with np.errstate(invalid="ignore"):
        _check_scale(a[:, :3], what)
    if a.shape[1] == 3:
        return PoseArray(a.copy(), None)
    q = a[:, 3:]
    with np.errstate(over="ignore"):
        norm = np.linalg.norm(q, axis=1)
    if not allow_nan and not np.all(np.isfinite(norm)):
        raise ValueError(f"{what}: quaternion too large to normalise in rows "
                         f"{np.flatnonzero(~np.isfinite(norm))[:10].tolist()}")
    if np.any(norm < 1e-9):
        raise ValueError(f"{what}: zero quaternion in rows {np.flatnonzero(norm < 1e-9)[:10].tolist()}")
    return PoseArray(a[:, :3].copy(), Rotation.from_quat(q / norm[:, None]))


def matrix_to_pose7(T) -> np.ndarray:
    """(n, 4, 4) -> (n, 7)."""
    return as_pose_array(T).as_array()


def relative_poses(y_i, y_j) -> PoseArray:
    """Relative transformation z = y_i^-1 y_j (pose of part j in the frame of part i),
    vectorised over n time steps. If either track is position-only the result is
    position-only: z = p_j - p_i when y_i has no orientation, or R_i^T (p_j - p_i)."""
    a = as_pose_array(y_i, what="y_i")
    b = as_pose_array(y_j, what="y_j")
    if len(a) != len(b):
        raise ValueError(f"relative_poses: tracks differ in length ({len(a)} vs {len(b)})")
    if a.rotations is None:
        return PoseArray(b.positions - a.positions, None)
    inv = a.rotations.inv()
    pos = inv.apply(b.positions - a.positions)
    rot = None if b.rotations is None else inv * b.rotations
    return PoseArray(pos, rot)


def rotation_distance(Ra: Rotation, Rb: Rotation) -> np.ndarray:
    """Geodesic angle between rotations (radians), vectorised (broadcast 1 vs n allowed)."""
    return quat_distance(np.atleast_2d(Ra.as_quat()), np.atleast_2d(Rb.as_quat()))


def quat_distance(qa: np.ndarray, qb: np.ndarray) -> np.ndarray:
    """Geodesic angle between unit quaternion arrays (..., 4), radians (broadcasting)."""
    d = np.abs(np.sum(qa * qb, axis=-1))
    return 2.0 * np.arccos(np.clip(d, 0.0, 1.0))


def rotvec_to_matrix(rv: np.ndarray) -> np.ndarray:
    """Rotation vectors (..., 3) (radians) -> rotation matrices (..., 3, 3) (scipy)."""
    rv = np.asarray(rv, float)
    shape = rv.shape[:-1]
    flat = rv.reshape(-1, 3)
    if flat.shape[0] == 0:
        return np.zeros(shape + (3, 3))
    return Rotation.from_rotvec(flat).as_matrix().reshape(shape + (3, 3))


def matrix_to_rotvec(M: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) -> rotation vectors (..., 3), angle in [0, pi] (scipy;
    exact near pi as well)."""
    M = np.asarray(M, float)
    shape = M.shape[:-2]
    flat = M.reshape(-1, 3, 3)
    if flat.shape[0] == 0:
        return np.zeros(shape + (3,))
    return Rotation.from_matrix(flat).as_rotvec().reshape(shape + (3,))


def project_to_so3(M: np.ndarray) -> np.ndarray:
    """The nearest rotation matrices (Frobenius norm) to (..., 3, 3) matrices M: SVD with the
    determinant fixed to +1. The one SO(3) projection of the project.

    Stacks of at least ``_NEWTON_MIN`` matrices are computed by the scaled Newton iteration
    for the orthogonal polar factor instead (the same result to rounding; faster
    than numpy's batched 3 x 3 SVDs, which the structure search's screening projects
    thousands of at a time); matrices with det <= 0 (their nearest rotation is not the
    polar factor), nearly singular ones and any that do not converge go through the SVD."""
    M = np.asarray(M, float)
    if M.ndim >= 3 and M.size >= 9 * _NEWTON_MIN:
        return _project_newton(M)
    return _project_svd(M)


def _project_svd(M: np.ndarray) -> np.ndarray:
    U, _, Vt = np.linalg.svd(M)
    det = np.linalg.det(U @ Vt)
    D = np.ones(M.shape[:-1])
    D[..., 2] = det
    return (U * D[..., None, :]) @ Vt


#: fewest matrices for which :func:`project_to_so3` uses the Newton iteration (below it,
#: numpy's per-call overhead makes the SVD faster; measured crossover ~150 on this machine)
_NEWTON_MIN = 128


def _cofactors(X: np.ndarray) -> np.ndarray:
    """Cofactor matrices of 3 x 3 matrices stored as (9, N) entry rows (row-major)."""
    a0, a1, a2, a3, a4, a5, a6, a7, a8 = X
    return np.stack([a4 * a8 - a5 * a7, a5 * a6 - a3 * a8, a3 * a7 - a4 * a6,
                     a2 * a7 - a1 * a8, a0 * a8 - a2 * a6, a1 * a6 - a0 * a7,
                     a1 * a5 - a2 * a4, a2 * a3 - a0 * a5, a0 * a4 - a1 * a3])


def _project_newton(M: np.ndarray, tol: float = 1e-9, max_iter: int = 30) -> np.ndarray:
    """Orthogonal polar factor by the Frobenius-scaled Newton iteration
    X <- (g X + X^-T / g) / 2, g = (|X^-1|_F / |X|_F)^(1/2) (Higham, Functions of Matrices,
    ch. 8), on entry rows (9, N); X^-T = cofactors / det. Converges quadratically: once an
    update changes no entry by more than ``tol``, the iterate is within ~tol^2 of the
    limit. Matrices with det <= 1e-9 |M|_F^3 (including non-finite ones) or not converged
    after ``max_iter`` updates are projected by the SVD."""
    shape = M.shape
    F = M.reshape(-1, 9)
    X = F.T.copy()
    nrm2 = np.einsum("ij,ij->j", X, X)
    C = _cofactors(X)
    det = np.einsum("ij,ij->j", X[:3], C[:3])
    newton = det > 1e-9 * nrm2 ** 1.5  # False for NaN
    idx = np.flatnonzero(newton)
    X = X[:, idx]
    done = np.zeros(idx.size, bool)
    out = np.empty_like(F)
    for _ in range(max_iter):
        C = _cofactors(X)
        C /= np.einsum("ij,ij->j", X[:3], C[:3])
        g = np.sqrt(np.sqrt(np.einsum("ij,ij->j", C, C) / np.einsum("ij,ij->j", X, X)))
        Xn = 0.5 * (g * X + C / g)
        conv = np.max(np.abs(Xn - X), axis=0) <= tol
        X = Xn
        if conv.all():
            done[:] = True
            break
        done = conv
    out[idx[done]] = X[:, done].T
    rest = np.ones(len(F), bool)
    rest[idx[done]] = False
    if rest.any():
        out[rest] = _project_svd(F[rest].reshape(-1, 3, 3)).reshape(-1, 9)
    return out.reshape(shape)