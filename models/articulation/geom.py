"""Track arrays and rotation helpers shared by the articulation link models (plain numpy /
scipy, vectorised over hypotheses and observations)."""

from __future__ import annotations

import math

import numpy as np

from mmlearn.models.articulation.kernels import (frame_with_z, log_rotations, nearest_rotation,
                                                 rotation_vectors,
                                                 rotvec_to_matrix, weighted_log_mean,
                                                 weighted_rotation_mean)
from mmlearn.models.common.se3 import as_pose_array, project_to_so3

# --------------------------------------------------------------------------- track data
class _Data:
    """Training/evaluation track as arrays: P (n, 3), R (n, 3, 3) or None."""

    def __init__(self, Z, what="track"):
        pa = as_pose_array(Z, what=what)
        self.P = np.ascontiguousarray(pa.positions, float)
        self.R = None if pa.rotations is None else pa.rotations.as_matrix()
        self.n = self.P.shape[0]
        self._obs_fit = None

    @property
    def has_orientation(self):
        return self.R is not None

    def observation_model(self, obs):
        """``obs.with_volume_from(P)``, kept for the next model fitted to the same track
        with the same ``obs`` (the candidates of one selection share it; it is never
        modified)."""
        if self._obs_fit is None or self._obs_fit[0] is not obs:
            self._obs_fit = (obs, obs.with_volume_from(self.P))
        return self._obs_fit[1]


def _rot_err(M: np.ndarray) -> np.ndarray:
    """Angle (rad) of rotation matrices M (..., 3, 3), precise near 0."""
    tr = M[..., 0, 0] + M[..., 1, 1] + M[..., 2, 2]
    vx = M[..., 2, 1] - M[..., 1, 2]
    vy = M[..., 0, 2] - M[..., 2, 0]
    vz = M[..., 1, 0] - M[..., 0, 1]
    s = 0.5 * np.sqrt(vx * vx + vy * vy + vz * vz)
    return np.arctan2(s, 0.5 * (tr - 1.0))


def _pair_mul(A: np.ndarray, B: np.ndarray, C: np.ndarray | None = None) -> np.ndarray:
    """All products A[h] @ B[n] (@ C[h]): A (H, 3, 3), B (n, 3, 3), C (H, 3, 3) ->
    (H, n, 3, 3), with one BLAS call per factor (much faster than stacked 3x3 matmuls)."""
    H, n = A.shape[0], B.shape[0]
    T = np.tensordot(A, B, axes=([2], [1]))  # (H, 3, n, 3)
    T = T.transpose(0, 2, 1, 3)
    if C is None:
        return T
    return (T.reshape(H, n * 3, 3) @ C).reshape(H, n, 3, 3)


def _rotz(q: np.ndarray) -> np.ndarray:
    c, s = np.cos(q), np.sin(q)
    R = np.zeros(q.shape + (3, 3))
    R[..., 0, 0] = c
    R[..., 0, 1] = -s
    R[..., 1, 0] = s
    R[..., 1, 1] = c
    R[..., 2, 2] = 1.0
    return R


def _rv2m(rv: np.ndarray) -> np.ndarray:
    """Rotation vectors (..., 3) -> rotation matrices (..., 3, 3): the Rodrigues formula in
    numpy (the link models convert one to a few hundred at a time, where scipy's
    ``Rotation`` spends ~0.1 ms per call on its array-API checks; same values to ~1e-16,
    ``models/common/se3.rotvec_to_matrix``)."""
    rv = np.asarray(rv, float)
    if rv.shape == (3,):
        return _rv2m_one(*rv.tolist())
    if rv.ndim == 2 and rv.shape[1] == 3:  # a batch: the compiled loop
        return rotvec_to_matrix(np.ascontiguousarray(rv))
    x, y, z = rv[..., 0], rv[..., 1], rv[..., 2]
    t2 = x * x + y * y + z * z
    t = np.sqrt(t2)
    small = t2 < 1e-8
    ts = np.where(small, 1.0, t)
    a = np.where(small, 1.0 - t2 / 6.0, np.sin(ts) / ts)  # sin t / t
    b = np.where(small, 0.5 - t2 / 24.0, (1.0 - np.cos(ts)) / (ts * ts))  # (1 - cos t) / t^2
    R = np.empty(rv.shape[:-1] + (3, 3))
    R[..., 0, 0] = 1.0 - b * (y * y + z * z)
    R[..., 1, 1] = 1.0 - b * (x * x + z * z)
    R[..., 2, 2] = 1.0 - b * (x * x + y * y)
    bxy, bxz, byz = b * x * y, b * x * z, b * y * z
    R[..., 0, 1] = bxy - a * z
    R[..., 1, 0] = bxy + a * z
    R[..., 0, 2] = bxz + a * y
    R[..., 2, 0] = bxz - a * y
    R[..., 1, 2] = byz - a * x
    R[..., 2, 1] = byz + a * x
    return R


def _log_rot(M: np.ndarray) -> np.ndarray:
    """Rotation vectors (..., 3) of rotation matrices M (..., 3, 3) from the skew part and
    the trace: cheap and exact for angles below ~pi - 1e-6 (direction ill-conditioned at pi,
    where the value is only used with a negligible weight)."""
    vx = M[..., 2, 1] - M[..., 1, 2]
    vy = M[..., 0, 2] - M[..., 2, 0]
    vz = M[..., 1, 0] - M[..., 0, 1]
    s2 = np.sqrt(vx * vx + vy * vy + vz * vz)  # 2 sin(angle)
    ang = np.arctan2(0.5 * s2, 0.5 * (M[..., 0, 0] + M[..., 1, 1] + M[..., 2, 2] - 1.0))
    f = np.where(s2 > 1e-12, ang / np.maximum(s2, 1e-12), 0.5)
    return np.stack([vx * f, vy * f, vz * f], axis=-1)


def _rv2m_one(x: float, y: float, z: float) -> np.ndarray:
    """:func:`_rv2m` of one rotation vector (scalar arithmetic: no array overhead)."""
    t2 = x * x + y * y + z * z
    if t2 < 1e-8:
        a, b = 1.0 - t2 / 6.0, 0.5 - t2 / 24.0
    else:
        t = math.sqrt(t2)
        a, b = math.sin(t) / t, (1.0 - math.cos(t)) / t2
    bxy, bxz, byz = b * x * y, b * x * z, b * y * z
    return np.array([[1.0 - b * (y * y + z * z), bxy - a * z, bxz + a * y],
                     [bxy + a * z, 1.0 - b * (x * x + z * z), byz - a * x],
                     [bxz - a * y, byz + a * x, 1.0 - b * (x * x + y * y)]])


def _m2rv(M: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) -> rotation vectors (..., 3), angle in [0, pi], in
    numpy (see :func:`_rv2m`; same values as ``models/common/se3.matrix_to_rotvec`` to
    ~1e-15, exact near pi as well: there the axis comes from the symmetric part)."""
    M = np.asarray(M, float)
    if M.shape == (3, 3):
        return rotation_vectors(np.ascontiguousarray(M[None]))[0]
    if M.ndim == 3:  # a batch: the compiled loop (near pi as well)
        return rotation_vectors(np.ascontiguousarray(M))
    return _m2rv_numpy(M)


def _m2rv_numpy(M: np.ndarray) -> np.ndarray:
    """:func:`_m2rv` in numpy for any stack shape (..., 3, 3) (the tests' reference)."""
    M = np.asarray(M, float)
    if M.ndim == 2:
        return _m2rv_numpy(M[None])[0]
    if M.ndim == 3:
        v, c = log_rotations(np.ascontiguousarray(M))
    else:
        v = _log_rot(M)
        c = 0.5 * (M[..., 0, 0] + M[..., 1, 1] + M[..., 2, 2] - 1.0)
    near_pi = c < -0.99
    if np.any(near_pi):
        Mp = M[near_pi]
        cp = c[near_pi]
        skew = np.stack([Mp[:, 2, 1] - Mp[:, 1, 2], Mp[:, 0, 2] - Mp[:, 2, 0],
                         Mp[:, 1, 0] - Mp[:, 0, 1]], axis=-1)  # 2 sin(angle) axis
        ang = np.arctan2(0.5 * np.linalg.norm(skew, axis=-1), cp)
        # (M + M^T) / 2 - cos(angle) I = (1 - cos(angle)) n n^T: its largest column
        B = 0.5 * (Mp + np.swapaxes(Mp, -1, -2)) - cp[:, None, None] * np.eye(3)
        j = np.argmax(np.diagonal(B, axis1=1, axis2=2), axis=1)
        col = B[np.arange(B.shape[0]), :, j]
        n = col / np.linalg.norm(col, axis=-1, keepdims=True)
        n = np.where(np.sum(n * skew, axis=-1, keepdims=True) < 0, -n, n)
        v[near_pi] = ang[:, None] * n
    return v


def _chordal_mean(R: np.ndarray) -> np.ndarray:
    """Chordal L2 mean of rotation matrices (n, 3, 3): the rotation nearest (Frobenius) to
    their sum, which is what scipy's ``Rotation.mean`` computes through quaternions (the
    largest eigenvector of sum q q^T maximises tr(sum_t R_t^T M)); the same values to
    ~1e-15, without scipy's conversions; the projection compiled:
    kernels.nearest_rotation)."""
    return nearest_rotation(np.ascontiguousarray(np.asarray(R, float).sum(axis=0)))


def _weighted_rotation_mean(R: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Weighted geodesic (Karcher) mean of rotations R (n, 3, 3) with weights w (n,): the
    minimiser of sum_t w_t angle(R^T R_t)^2, i.e. the exact M-step of the orientation noise
    model. Start from the weighted chordal mean (closed form), then one Gauss-Newton step on
    the manifold (the two agree to second order in the spread). Compiled
    (kernels.weighted_rotation_mean); :func:`_weighted_rotation_mean_numpy` is the
    reference."""
    return weighted_rotation_mean(np.ascontiguousarray(R, dtype=float),
                                  np.ascontiguousarray(w, dtype=float))


def _weighted_rotation_mean_numpy(R: np.ndarray, w: np.ndarray) -> np.ndarray:
    """:func:`_weighted_rotation_mean` in numpy (the tests' reference)."""
    R0 = project_to_so3(np.einsum("n,nij->ij", w, R))
    # sum_t w_t log(R0^T R_t) / sum_t w_t, compiled (kernels.weighted_log_mean)
    return R0 @ _rv2m(weighted_log_mean(np.ascontiguousarray(R0), R,
                                        np.ascontiguousarray(w, dtype=float)))


def _frame_with_z(axis: np.ndarray, xhint: np.ndarray) -> np.ndarray:
    """(H, 3, 3) rotation matrices whose z column is ``axis`` and x column lies along the
    component of ``xhint`` perpendicular to it (compiled for (H, 3) stacks:
    kernels.frame_with_z)."""
    if np.ndim(axis) == 2 and np.shape(axis) == np.shape(xhint):
        return frame_with_z(np.ascontiguousarray(axis, dtype=float),
                            np.ascontiguousarray(xhint, dtype=float))
    return _frame_with_z_numpy(axis, xhint)


def _frame_with_z_numpy(axis: np.ndarray, xhint: np.ndarray) -> np.ndarray:
    """:func:`_frame_with_z` in numpy (any broadcastable shapes; the tests' reference)."""
    z = axis / np.linalg.norm(axis, axis=-1, keepdims=True)
    x = xhint - np.sum(xhint * z, axis=-1, keepdims=True) * z
    nx = np.linalg.norm(x, axis=-1, keepdims=True)
    alt = np.where(np.abs(z[..., :1]) < 0.9, np.array([1.0, 0, 0]), np.array([0, 1.0, 0]))
    alt = alt - np.sum(alt * z, axis=-1, keepdims=True) * z
    x = np.where(nx > 1e-12, x / np.maximum(nx, 1e-300), alt / np.linalg.norm(alt, axis=-1,
                                                                             keepdims=True))
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=-1)





def _slot_rotations(thetas: np.ndarray, s: int, rots: dict | None = None) -> np.ndarray:
    """Rotation matrices (H, 3, 3) of the rotation-vector slot of ``thetas`` (H, p) starting
    at index s, or ``rots[s]`` where the caller passes them: the refinement evaluates
    rotations as R_base exp(u) (articulation_refine.LocalParametrisation), which the
    additive rotation-vector entries of theta do not represent."""
    if rots is not None:
        return rots[s]
    return _rv2m(thetas[:, s:s + 3])
