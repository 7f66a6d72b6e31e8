"""The parametric link models of thesis Sec. 4.1 (Table 4.1), a section each: rigid
(Eq. 4.18), prismatic (Eq. 4.19-4.20), revolute (Eq. 4.21-4.22). The GP model is in
models/articulation/gp_link.py; the shared fitting and evaluation in models/articulation/base.py;
the public names in models/articulation/link.py (module docstring: the whole model)."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from mmlearn.models.articulation.base import LinkModel
from mmlearn.models.articulation.geom import (_chordal_mean, _frame_with_z, _m2rv, _pair_mul,
                                              _rotz, _rv2m, _slot_rotations, _weighted_rotation_mean)
from mmlearn.models.articulation.kernels import (circle_hypotheses, prismatic_errors,
                                                 revolute_errors, rotation_errors)

__all__ = ["RigidModel", "PrismaticModel", "RevoluteModel"]

_NO_ROT = np.zeros((0, 3, 3))  # the kernels' "no orientation"


def _cross(a, b):
    """np.cross(a, b) of a vector (3,) and vectors (3,) or (k, 3): the same products and
    differences, without np.cross's broadcasting machinery."""
    a0, a1, a2 = (float(x) for x in a)
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


# --------------------------------------------------------------------------- rigid
class RigidModel(LinkModel):
    """Fixed relative transform (Eq. 4.18). theta = [p (3), rotvec (3)] ([p] position-only)."""

    name = "rigid"
    dof = 0
    min_samples = 1
    #: EM: the weighted ML fit is closed-form (weighted mean position, weighted geodesic
    #: mean orientation), so each iteration is one residual evaluation.
    refinement = "em"

    def num_params(self, n=None):
        return 6 if self.has_orientation else 3

    def _rot_slots(self):
        return [3] if self.has_orientation else []

    def _hypotheses(self, d, rng, H):
        idx = np.arange(d.n) if d.n <= H else rng.choice(d.n, H, replace=False)
        if d.has_orientation:
            return np.hstack([d.P[idx], _m2rv(d.R[idx])])
        return d.P[idx].copy()

    def _consensus_fit(self, d, inl, theta):
        return self._weighted_fit(d, inl.astype(float), theta)

    def _weighted_fit(self, d, w, theta):
        out = theta.copy()
        out[:3] = w @ d.P / w.sum()
        if d.has_orientation:
            out[3:6] = _m2rv(_weighted_rotation_mean(d.R, w))
        return out

    def _residuals_batch(self, thetas, d, rots=None):
        p = thetas[:, :3]
        diff = d.P[None] - p[:, None]
        ep2 = np.einsum("hni,hni->hn", diff, diff)
        eo = None
        if d.has_orientation:
            Rh = _slot_rotations(thetas, 3, rots)
            eo = rotation_errors(np.ascontiguousarray(Rh), d.R)
        return ep2, eo, np.zeros((thetas.shape[0], d.n, 0))

    def forward(self, q=None):
        self._check_fitted()
        m = 1 if q is None else self._check_q(q).shape[0]
        P = np.tile(self.theta[:3], (m, 1))
        if not self.has_orientation:
            return P
        return np.hstack([P, np.tile(Rotation.from_rotvec(self.theta[3:6]).as_quat(), (m, 1))])

    def jacobian(self, q=None):
        m = 1 if q is None else self._check_q(q).shape[0]
        return np.zeros((m, 6 if self.has_orientation else 3, 0))

    def params(self):
        out = {"position_m": self.theta[:3].tolist()}
        if self.has_orientation:
            out["quaternion_xyzw"] = Rotation.from_rotvec(self.theta[3:6]).as_quat().tolist()
        return out


# --------------------------------------------------------------------------- prismatic
class PrismaticModel(LinkModel):
    """Translation along a unit axis e from an origin a (Eq. 4.19-4.20): f(q) = (a_p + q e,
    R_a), f^-1(z) = e . (p_z - a_p). theta = [a_p (3), a_rotvec (3), e (3)] ([a_p, e]
    position-only). e is expressed in the parent frame; q in metres."""

    name = "prismatic"
    dof = 1
    min_samples = 2
    #: EM: the weighted ML fit is closed-form (weighted mean and principal axis of the
    #: weighted scatter, weighted geodesic mean orientation).
    refinement = "em"

    def num_params(self, n=None):
        return 9 if self.has_orientation else 6

    def _rot_slots(self):
        return [3] if self.has_orientation else []

    def _eidx(self):
        return slice(6, 9) if self.has_orientation else slice(3, 6)

    def _hypotheses(self, d, rng, H):
        i = rng.integers(0, d.n, H)
        j = rng.integers(0, d.n, H)
        v = d.P[j] - d.P[i]
        nv = np.linalg.norm(v, axis=1)
        ok = nv > max(2.0 * self.obs.sigma_pos, 1e-9)
        if not ok.any():  # fall back to the two most distant points
            j0 = np.argmax(np.linalg.norm(d.P - d.P[0], axis=1))
            i0 = np.argmax(np.linalg.norm(d.P - d.P[j0], axis=1))
            i, j = np.array([i0]), np.array([j0])
            v = d.P[j] - d.P[i]
            nv = np.linalg.norm(v, axis=1)
            ok = nv > 1e-12
        i, v, nv = i[ok], v[ok], nv[ok]
        e = v / nv[:, None]
        if d.has_orientation:
            return np.hstack([d.P[i], _m2rv(d.R[i]), e])
        return np.hstack([d.P[i], e])

    def _consensus_fit(self, d, inl, theta):
        return self._weighted_fit(d, inl.astype(float), theta)

    def _weighted_fit(self, d, w, theta):
        # weighted total least squares: the line through the weighted mean along the
        # principal axis of the weighted scatter minimises sum_t w_t |perpendicular error|^2
        sw = w.sum()
        mu = w @ d.P / sw
        X = d.P - mu
        _, V = np.linalg.eigh((X * w[:, None]).T @ X)
        e = V[:, -1]
        e_old = theta[self._eidx()]
        if np.dot(e, e_old) < 0:
            e = -e
        out = theta.copy()
        out[:3] = mu
        out[self._eidx()] = e
        if d.has_orientation:
            out[3:6] = _m2rv(_weighted_rotation_mean(d.R, w))
        return out

    def _residuals_batch(self, thetas, d, rots=None):
        # compiled (kernels.prismatic_errors); _residuals_batch_numpy is the reference
        has_o = thetas.shape[1] == 9 and d.has_orientation
        e = thetas[:, 6:9] if thetas.shape[1] == 9 else thetas[:, 3:6]
        Ra = np.ascontiguousarray(_slot_rotations(thetas, 3, rots)) if has_o else _NO_ROT
        ep2, eo, q = prismatic_errors(np.ascontiguousarray(thetas[:, :3]),
                                      np.ascontiguousarray(e), d.P, Ra,
                                      d.R if has_o else _NO_ROT)
        return ep2, (eo if has_o else None), q[..., None]

    def _residuals_batch_numpy(self, thetas, d, rots=None):
        """:meth:`_residuals_batch` in numpy (the tests' reference)."""
        has_o = thetas.shape[1] == 9
        a = thetas[:, :3]
        e = thetas[:, 6:9] if has_o else thetas[:, 3:6]
        e = e / np.linalg.norm(e, axis=1, keepdims=True)
        diff = d.P[None] - a[:, None]
        q = np.einsum("hni,hi->hn", diff, e)
        perp = diff - q[..., None] * e[:, None]
        ep2 = np.einsum("hni,hni->hn", perp, perp)
        eo = None
        if has_o and d.has_orientation:
            Ra = _slot_rotations(thetas, 3, rots)
            eo = rotation_errors(np.ascontiguousarray(Ra), d.R)
        return ep2, eo, q[..., None]

    def _canonicalize(self, d, inl):
        e = self.axis
        q = (d.P - self.theta[:3]) @ e
        inl_idx = np.flatnonzero(inl)
        first, last = inl_idx[0], inl_idx[-1]
        if q[last] < q[first]:
            e = -e
        self.theta[self._eidx()] = e
        q = (d.P - self.theta[:3]) @ e
        self.theta[:3] = self.theta[:3] + q[first] * e

    @property
    def axis(self) -> np.ndarray:
        e = self.theta[self._eidx()]
        return e / np.linalg.norm(e)

    def forward(self, q):
        q = self._check_q(q)
        P = self.theta[:3] + q[:, :1] * self.axis
        if not self.has_orientation:
            return P
        quat = Rotation.from_rotvec(self.theta[3:6]).as_quat()
        return np.hstack([P, np.tile(quat, (P.shape[0], 1))])

    def jacobian(self, q):
        q = self._check_q(q)
        J = np.zeros((q.shape[0], 6 if self.has_orientation else 3, 1))
        J[:, :3, 0] = self.axis
        return J

    def params(self):
        out = {"origin_m": self.theta[:3].tolist(), "axis": self.axis.tolist(),
               "q_min_m": float(self.q_min[0]), "q_max_m": float(self.q_max[0])}
        if self.has_orientation:
            out["quaternion_xyzw"] = Rotation.from_rotvec(self.theta[3:6]).as_quat().tolist()
        return out


# --------------------------------------------------------------------------- revolute
class RevoluteModel(LinkModel):
    """Rotation about an axis (Eq. 4.21-4.22): f(q) = c (+) RotZ(q) (+) r.

    theta = [c_p (3), c_rotvec (3), r_p (3), r_rotvec (3)] ([c_p, c_rotvec, r_p]
    position-only). The z column of c's rotation is the rotation axis (parent frame), q the
    angle in radians. f^-1 combines the angle from the position (weight r^2/sigma_pos^2) and,
    for full poses, the angle from the orientation (weight 1/sigma_orient^2) by a weighted
    circular mean; the thesis uses the orientation alone (Eq. 4.22).
    """

    name = "revolute"
    dof = 1
    min_samples = 3
    #: Levenberg-Marquardt: the weighted fit of a circle and its axis has no closed form,
    #: but the residual vectors (_residual_vectors) give Gauss-Newton steps, with fewer
    #: batched residual evaluations than L-BFGS for the same or a better optimum. The
    #: hand-written LM (articulation_refine._lm_fixed_gamma) is kept over
    #: scipy.optimize.least_squares; see the measurement there.
    refinement = "lm"

    def __init__(self, **kw):
        super().__init__(**kw)
        self.q_center = 0.0

    def num_params(self, n=None):
        return 12 if self.has_orientation else 9

    def _rot_slots(self):
        return [3, 9] if self.has_orientation else [3]

    def _frozen(self):
        # gauge: rotation of c about its own z axis (= shift of q), r_p's y and z components
        # (hypotheses and refinement keep r_p = (radius, 0, 0))
        return [5, 7, 8]

    def _hypotheses(self, d, rng, H):
        th = self._point_hypotheses(d, rng, H)
        if d.has_orientation and th.shape[0] == 0:
            # full poses whose positions are too close together for 3 points 2 sigma_pos
            # apart (a door seen near its hinge, a short arc at a large assumed sigma; no
            # 3-point hypothesis exists there): hypotheses from pairs of poses, whose relative
            # rotation gives the axis. Only then, and from a generator of its own (seeded
            # by the track's size, not drawn from ``rng``), so every fit that had 3-point
            # hypotheses, and every later fit on the same ``rng``, is unchanged.
            th = self._pose_pair_hypotheses(d, np.random.default_rng([d.n, H]), H)
        return th

    def _pose_pair_hypotheses(self, d, rng, H):
        """Hypotheses from 2 full poses (minimal sample with orientation): the relative
        rotation R_j R_i^T (rotation angle above 3 sigma_orient) is a rotation about the
        axis, whose line holds the centre c solving (I - R_rel) c = p_j - R_rel p_i (least
        norm; then moved along the axis to the height of p_i). Returns (h, 12)."""
        n = d.n
        i, j = rng.integers(0, n, H), rng.integers(0, n, H)
        Rrel = d.R[j] @ np.swapaxes(d.R[i], 1, 2)
        rv = _m2rv(Rrel)
        ang = np.linalg.norm(rv, axis=1)
        ok = (ang > 3.0 * self.obs.sigma_orient) & (ang < np.pi - 1e-3)
        if not ok.any():
            return np.zeros((0, 12))
        i, j, Rrel, rv, ang = i[ok], j[ok], Rrel[ok], rv[ok], ang[ok]
        a = rv / ang[:, None]
        A = np.eye(3)[None] - Rrel
        b = d.P[j] - np.einsum("hab,hb->ha", Rrel, d.P[i])
        c = np.einsum("hab,hb->ha", np.linalg.pinv(A, rcond=1e-6), b)
        c = c + a * np.einsum("ha,ha->h", d.P[i] - c, a)[:, None]
        Rc = _frame_with_z(a, d.P[i] - c)
        r_p = np.einsum("hba,hb->ha", Rc, d.P[i] - c)
        Rr = np.einsum("hba,hbc->hac", Rc, d.R[i])
        return np.hstack([c, _m2rv(Rc), r_p, _m2rv(Rr)])

    def _point_hypotheses(self, d, rng, H):
        """Circles through 3 observed positions (compiled: kernels.circle_hypotheses;
        :meth:`_point_hypotheses_numpy` is the reference). Returns (h, 12 | 9)."""
        n = d.n
        idx = np.stack([rng.integers(0, n, H) for _ in range(3)], axis=1)
        minsep = max(2.0 * self.obs.sigma_pos, 1e-9)
        ok, center, Rc, r_p, Rr = circle_hypotheses(
            d.P, d.R if d.has_orientation else _NO_ROT, idx, minsep)
        if not ok.any():
            return np.zeros((0, 12 if d.has_orientation else 9))
        out = [center, _m2rv(Rc), r_p]
        if d.has_orientation:
            out.append(_m2rv(Rr))
        return np.hstack(out)

    def _point_hypotheses_numpy(self, d, rng, H):
        """:meth:`_point_hypotheses` in numpy (the tests' reference)."""
        n = d.n
        idx = np.stack([rng.integers(0, n, H) for _ in range(3)], axis=1)
        p1, p2, p3 = d.P[idx[:, 0]], d.P[idx[:, 1]], d.P[idx[:, 2]]
        a = p1 - p3
        b = p2 - p3
        axb = np.cross(a, b)
        nn = np.einsum("hi,hi->h", axb, axb)
        la, lb = np.linalg.norm(a, axis=1), np.linalg.norm(b, axis=1)
        minsep = max(2.0 * self.obs.sigma_pos, 1e-9)
        ok = (nn > 1e-18) & (la > minsep) & (lb > minsep) & (np.linalg.norm(p1 - p2, axis=1)
                                                             > minsep)
        # circle radius must be finite: sin of the angle between a and b not ~0
        ok &= np.sqrt(nn) > 1e-6 * la * lb
        if not ok.any():
            return np.zeros((0, 12 if d.has_orientation else 9))
        idx, a, b, axb, nn = idx[ok], a[ok], b[ok], axb[ok], nn[ok]
        p1, p3 = p1[ok], p3[ok]
        num = np.cross(np.einsum("hi,hi->h", a, a)[:, None] * b
                       - np.einsum("hi,hi->h", b, b)[:, None] * a, axb)
        center = p3 + num / (2 * nn[:, None])
        Rc = _frame_with_z(axb, p1 - center)
        r_p = np.einsum("hba,hb->ha", Rc, p1 - center)
        out = [center, _m2rv(Rc), r_p]
        if d.has_orientation:
            Rr = np.einsum("hba,hbc->hac", Rc, d.R[idx[:, 0]])
            out.append(_m2rv(Rr))
        return np.hstack(out)

    def _consensus_fit(self, d, inl, theta):
        X = d.P[inl]
        m = X.shape[0]
        mu = X.mean(axis=0)
        _, S, Vt = np.linalg.svd(X - mu, full_matrices=False)
        if S.shape[0] < 2 or S[1] < 3.0 * self.obs.sigma_pos * np.sqrt(m):
            return None  # nearly collinear: plane undetermined, keep the sample estimate
        Rc_old = _rv2m(theta[3:6])
        nrm = Vt[2] if np.dot(Vt[2], Rc_old[:, 2]) >= 0 else -Vt[2]
        # Kasa circle fit in the plane
        u, v = Vt[0], _cross(nrm, Vt[0])
        x = (X - mu) @ u
        y = (X - mu) @ v
        A = np.stack([2 * x, 2 * y, np.ones(m)], axis=1)
        sol, *_ = np.linalg.lstsq(A, x * x + y * y, rcond=None)
        rho2 = sol[2] + sol[0] ** 2 + sol[1] ** 2
        if not rho2 > 0:
            return None
        center = mu + sol[0] * u + sol[1] * v
        first = X[0]
        Rc = _frame_with_z(nrm[None], (first - center)[None])[0]
        out = theta.copy()
        out[:3] = center
        out[3:6] = _m2rv(Rc)
        out[6:9] = [np.sqrt(rho2), 0.0, 0.0]
        if d.has_orientation and theta.shape[0] == 12:
            pl = (X - center) @ Rc
            q = np.arctan2(pl[:, 1], pl[:, 0])
            Rl = np.swapaxes(_rotz(q), 1, 2) @ (Rc.T[None] @ d.R[inl])  # Rz(-q) Rc^T R
            out[9:12] = _m2rv(_chordal_mean(Rl))
        return out

    def _angles(self, thetas, d, rots=None):
        """Configurations (H, n) and helper terms."""
        has_o = thetas.shape[1] == 12
        cp = thetas[:, :3]
        Rc = _slot_rotations(thetas, 3, rots)
        rp = thetas[:, 6:9]
        pl = (d.P[None] - cp[:, None]) @ Rc  # local positions (H, n, 3)
        rho2 = rp[:, 0] ** 2 + rp[:, 1] ** 2
        phi_r = np.arctan2(rp[:, 1], rp[:, 0])
        q_pos = np.arctan2(pl[..., 1], pl[..., 0]) - phi_r[:, None]
        sp = self.obs.sigma_pos
        wp = (rho2 / sp**2)[:, None]
        s = wp * np.sin(q_pos)
        c = wp * np.cos(q_pos)
        Ml = None
        if has_o and d.has_orientation:
            Rr = _slot_rotations(thetas, 9, rots)
            # Ml = Rc^T R_z Rr^T  (= RotZ(q) for a noise-free observation)
            Ml = _pair_mul(np.swapaxes(Rc, 1, 2), d.R, np.swapaxes(Rr, 1, 2))
            q_rot = np.arctan2(Ml[..., 1, 0] - Ml[..., 0, 1], Ml[..., 0, 0] + Ml[..., 1, 1])
            wr = 1.0 / self.obs.sigma_orient**2
            s = s + wr * np.sin(q_rot)
            c = c + wr * np.cos(q_rot)
        q = np.arctan2(s, c)
        return q, pl, rp, Ml

    def _kernel_errors(self, thetas, d, rots, vectors, want_q=True):
        """The compiled form of :meth:`_errors` (models/articulation/kernels.py): q ((0, 0)
        unless ``want_q``), ep2, eo (None position-only) and, with ``vectors``, the residual
        vectors."""
        has_o = thetas.shape[1] == 12 and d.has_orientation
        Rc = np.ascontiguousarray(_slot_rotations(thetas, 3, rots))
        Rr = np.ascontiguousarray(_slot_rotations(thetas, 9, rots)) if has_o else _NO_ROT
        obs_fit = getattr(self, "obs_fit", self.obs)
        q, ep2, eo, res = revolute_errors(
            np.ascontiguousarray(thetas[:, :3]), Rc, np.ascontiguousarray(thetas[:, 6:9]), Rr,
            d.P, d.R if has_o else _NO_ROT, self.obs.sigma_pos, self.obs.sigma_orient,
            float(getattr(self, "q_center", 0.0)), vectors, obs_fit.sigma_pos,
            obs_fit.sigma_orient, want_q)
        return q, ep2, (eo if has_o else None), res

    def _residuals_batch(self, thetas, d, rots=None):
        q, ep2, eo, _ = self._kernel_errors(thetas, d, rots, False)
        return ep2, eo, q[..., None]

    def _scores_batch(self, thetas, d):
        return self._kernel_errors(thetas, d, None, False, want_q=False)[1:3]

    def _residual_vectors(self, thetas, d, rots=None):
        return self._kernel_errors(thetas, d, rots, True, want_q=False)[3]

    def _residuals_batch_numpy(self, thetas, d, rots=None):
        """:meth:`_residuals_batch` from the numpy :meth:`_errors` (the reference the tests
        compare the compiled kernel with)."""
        q, ex, ey, ez, ov = self._errors(thetas, d, rots)
        ep2 = ex * ex + ey * ey + ez * ez
        eo = None
        if ov is not None:
            vx, vy, vz, tr = ov
            eo = np.arctan2(0.5 * np.sqrt(vx * vx + vy * vy + vz * vz), 0.5 * (tr - 1.0))
        return ep2, eo, q[..., None]

    def _residual_vectors_numpy(self, thetas, d, rots=None):
        """:meth:`_residual_vectors` from the numpy :meth:`_errors` (test reference)."""
        _, ex, ey, ez, ov = self._errors(thetas, d, rots)
        sp = self.obs_fit.sigma_pos
        parts = [ex / sp, ey / sp, ez / sp]
        if ov is not None:
            vx, vy, vz, tr = ov
            s2 = np.sqrt(vx * vx + vy * vy + vz * vz)  # 2 sin(angle)
            ang = np.arctan2(0.5 * s2, 0.5 * (tr - 1.0))
            # rotation vector = angle * axis, axis = v / |v| (|v| = 2 sin(angle))
            f = np.where(s2 > 1e-12, ang / np.maximum(s2, 1e-12), 0.5) / self.obs_fit.sigma_orient
            parts += [vx * f, vy * f, vz * f]
        return np.stack(parts, axis=-1)

    def _errors(self, thetas, d, rots=None):
        """Configurations (H, n), local position errors ex, ey, ez (H, n) and, for full
        poses, (vx, vy, vz, trace) of the orientation error matrix (else None)."""
        q, pl, rp, Ml = self._angles(thetas, d, rots)
        qc = getattr(self, "q_center", 0.0)
        q = np.mod(q - qc + np.pi, 2 * np.pi) - np.pi + qc
        cq, sq = np.cos(q), np.sin(q)
        px = cq * rp[:, None, 0] - sq * rp[:, None, 1]
        py = sq * rp[:, None, 0] + cq * rp[:, None, 1]
        ex = pl[..., 0] - px
        ey = pl[..., 1] - py
        ez = pl[..., 2] - rp[:, None, 2]
        ov = None
        if Ml is not None:
            # angle of M = RotZ(-q) Ml, element-wise (rows 0, 1 rotated, row 2 unchanged)
            m00, m01, m02 = Ml[..., 0, 0], Ml[..., 0, 1], Ml[..., 0, 2]
            m10, m11, m12 = Ml[..., 1, 0], Ml[..., 1, 1], Ml[..., 1, 2]
            M00 = cq * m00 + sq * m10
            M01 = cq * m01 + sq * m11
            M02 = cq * m02 + sq * m12
            M10 = -sq * m00 + cq * m10
            M11 = -sq * m01 + cq * m11
            M12 = -sq * m02 + cq * m12
            tr = M00 + M11 + Ml[..., 2, 2]
            vx = Ml[..., 2, 1] - M12
            vy = M02 - Ml[..., 2, 0]
            vz = M10 - M01
            ov = (vx, vy, vz, tr)
        return q, ex, ey, ez, ov

    def _angles_compiled(self, th, d):
        """Configurations (n,) of the parameter vector th in [-pi, pi) (the first output of
        :meth:`_angles`, by the compiled kernel; ``q_center`` must be 0)."""
        return self._kernel_errors(th[None], d, None, False)[0][0]

    def _canonicalize(self, d, inl):
        th = self.theta
        Rc = _rv2m(th[3:6])
        # move c along the axis so that r_p has no axial component
        h = th[8]
        th[:3] = th[:3] + h * Rc[:, 2]
        th[8] = 0.0
        self.q_center = 0.0
        q = self._angles_compiled(th, d)
        inl_idx = np.flatnonzero(inl)
        first = inl_idx[0]
        # make q increase in the direction of motion: unwrap around the circular mean
        mu = np.arctan2(np.sin(q[inl]).mean(), np.cos(q[inl]).mean())
        qu = np.mod(q - mu + np.pi, 2 * np.pi) - np.pi + mu
        if qu[inl_idx[-1]] < qu[first]:
            # flip the axis: rotate c by pi about its x axis; r's orientation follows
            F = np.diag([1.0, -1.0, -1.0])
            Rc = Rc @ F
            th[3:6] = _m2rv(Rc)
            th[6:9] = F @ th[6:9]
            if self.has_orientation:
                th[9:12] = _m2rv(F @ _rv2m(th[9:12]))
            q = self._angles_compiled(th, d)
        # rotate c about z so that q = 0 at the first inlier observation
        q0 = q[first]
        Rc = _rv2m(th[3:6]) @ _rotz(np.array(q0))
        th[3:6] = _m2rv(Rc)
        q = self._angles_compiled(th, d)
        mu = np.arctan2(np.sin(q[inl]).mean(), np.cos(q[inl]).mean())
        self.q_center = float(mu)
        self.theta = th

    def _extra_to_dict(self):
        return {"q_center": float(self.q_center)}

    def _extra_from_dict(self, e):
        self.q_center = float(e.get("q_center", 0.0))

    @property
    def axis(self) -> np.ndarray:
        return _rv2m(self.theta[3:6])[:, 2]

    @property
    def radius(self) -> float:
        return float(np.hypot(self.theta[6], self.theta[7]))

    @property
    def center(self) -> np.ndarray:
        """Centre of the circle of the part's origin (parent frame, metres)."""
        Rc = _rv2m(self.theta[3:6])
        return self.theta[:3] + Rc[:, 2] * self.theta[8]

    def forward(self, q):
        q = self._check_q(q)[:, 0]
        Rc, Rq, P = self._forward_positions(q)
        if not self.has_orientation:
            return P
        R = np.einsum("ab,mbc,cd->mad", Rc, Rq, _rv2m(self.theta[9:12]))
        return np.hstack([P, Rotation.from_matrix(R).as_quat()])

    def _forward_positions(self, q):
        """(Rc, RotZ(q) (m, 3, 3), positions (m, 3)) of f(q) for angles q (m,)."""
        Rc = _rv2m(self.theta[3:6])
        Rq = _rotz(q)
        return Rc, Rq, self.theta[:3] + np.einsum("ab,mbc,c->ma", Rc, Rq, self.theta[6:9])

    def jacobian(self, q):
        qq = self._check_q(q)
        P = self._forward_positions(qq[:, 0])[2]
        ax = self.axis
        J = np.zeros((qq.shape[0], 6 if self.has_orientation else 3, 1))
        J[:, :3, 0] = _cross(ax, P - self.theta[:3])
        if self.has_orientation:
            J[:, 3:, 0] = ax
        return J

    def params(self):
        out = {"radius_m": self.radius, "axis": self.axis.tolist(),
               "center": self.center.tolist(),
               "q_min_rad": float(self.q_min[0]), "q_max_rad": float(self.q_max[0])}
        return out

