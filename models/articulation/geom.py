"""Track arrays and rotation helpers shared by the articulation link models (plain numpy /
scipy, vectorised over hypotheses and observations)."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from mmlearn.models.common.se3 import as_pose_array, matrix_to_rotvec, project_to_so3, rotvec_to_matrix

# --------------------------------------------------------------------------- track data
class _Data:
    """Training/evaluation track as arrays: P (n, 3), R (n, 3, 3) or None."""

    def __init__(self, Z, what="track"):
        pa = as_pose_array(Z, what=what)
        self.P = np.ascontiguousarray(pa.positions, float)
        self.R = None if pa.rotations is None else pa.rotations.as_matrix()
        self.n = self.P.shape[0]

    @property
    def has_orientation(self):
        return self.R is not None


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


_rv2m = rotvec_to_matrix  # scipy's compiled Rodrigues map (models/common/se3.py)


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


_m2rv = matrix_to_rotvec  # (models/common/se3.py)


def _chordal_mean(R: np.ndarray) -> np.ndarray:
    """Chordal L2 mean of rotation matrices (n, 3, 3) (scipy's Rotation.mean)."""
    return Rotation.from_matrix(R).mean().as_matrix()


def _weighted_rotation_mean(R: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Weighted geodesic (Karcher) mean of rotations R (n, 3, 3) with weights w (n,): the
    minimiser of sum_t w_t angle(R^T R_t)^2, i.e. the exact M-step of the orientation noise
    model. Start from the weighted chordal mean (closed form), then one Gauss-Newton step on
    the manifold (the two agree to second order in the spread)."""
    R0 = project_to_so3(np.einsum("n,nij->ij", w, R))
    v = _log_rot(np.einsum("ba,nbc->nac", R0, R))
    return R0 @ _rv2m(w @ v / w.sum())


def _frame_with_z(axis: np.ndarray, xhint: np.ndarray) -> np.ndarray:
    """(H, 3, 3) rotation matrices whose z column is ``axis`` and x column lies along the
    component of ``xhint`` perpendicular to it."""
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
