"""Compiled (numba) inner loops of link-model fitting: the revolute model's errors for a batch
of parameter vectors against every observation (:func:`revolute_errors`), the rigid and
prismatic models' orientation errors (:func:`rotation_errors`), the weighted geodesic mean's
tangent step (:func:`weighted_log_mean`), the outlier-ratio EM (:func:`em_gamma_full`) and
batched rotation-vector / matrix conversions (:func:`rotvec_to_matrix`,
:func:`log_rotations`).

Each kernel does, per hypothesis and observation, the arithmetic of the numpy expressions it
replaces (which did it on whole (H, n) arrays), so the results agree with them to rounding
(~1e-15 relative; the tests compare both). The revolute kernel takes the sine and cosine of
an angle from the vector whose angle it is (x / r, y / r) instead of atan2 then sin and cos:
the same values to rounding, with two transcendental calls per observation instead of
eight. At the sizes selection works on (100 hypotheses x 30-200 observations, a few dozen
calls per fit) the numpy forms spend most of their time creating the dozens of (H, n)
temporaries; the loops here create none. Compiled on first use and cached on disk
(``cache=True``; ~10 s of CPU once for all of them and the GP's, ~0.3 s per process to load).
"""

from __future__ import annotations

import math

import numba
import numpy as np

_LOG2 = math.log(2.0)


@numba.njit(cache=True, nogil=True, inline="always")
def _pymod(x, y):
    """numpy's / Python's float modulo (result has the sign of y)."""
    r = np.fmod(x, y)
    if r != 0.0:
        if (y < 0.0) != (r < 0.0):
            r += y
    else:
        r = math.copysign(0.0, y)
    return r


@numba.njit(cache=True, nogil=True)
def revolute_errors(cp, Rc, rp, Rr, P, R, sigma_pos, sigma_orient, q_center, vectors,
                    sp_out, so_out, want_q=True):
    """Errors of the revolute model (links.RevoluteModel._errors) for H parameter sets.

    Args:
        cp (H, 3), Rc (H, 3, 3), rp (H, 3): centre frame and the part's offset in it;
        Rr (H, 3, 3): the part's rotation in the rotated frame (ignored when R is empty);
        P (n, 3), R (n, 3, 3) or (0, 3, 3): the observations (R empty: position-only);
        sigma_pos, sigma_orient: the weights of f^-1 (position weight r^2 / sigma_pos^2,
        orientation weight 1 / sigma_orient^2); q_center: centre of the angle wrap;
        vectors: return residual vectors instead of squared errors;
        sp_out, so_out: noise units of the residual vectors.
    Returns:
        q (H, n); ep2 (H, n) squared position errors; eo (H, n) orientation errors (rad;
        zeros when position-only); res (H, n, 3 | 6) residual vectors in noise units when
        ``vectors`` (else (0, 0, 0)). q is (0, 0) unless ``want_q`` (the errors need only
        its sine and cosine).
    """
    H = cp.shape[0]
    n = P.shape[0]
    has_o = R.shape[0] > 0
    m = 6 if has_o else 3
    q_out = np.empty((H, n)) if want_q else np.empty((0, 0))
    ep2 = np.empty((H, n))
    eo = np.zeros((H, n))
    res = np.empty((H, n, m)) if vectors else np.empty((0, 0, 0))
    twopi = 2.0 * np.pi
    wr = 1.0 / (sigma_orient * sigma_orient)
    T = np.empty((3, 3))
    for h in range(H):
        rp0, rp1, rp2 = rp[h, 0], rp[h, 1], rp[h, 2]
        rho2 = rp0 * rp0 + rp1 * rp1
        # direction of r's projection: (cos, sin) of phi_r = atan2(rp1, rp0)
        rho = math.sqrt(rho2)
        cr, sr = (rp0 / rho, rp1 / rho) if rho > 0.0 else (1.0, 0.0)
        wp = rho2 / (sigma_pos * sigma_pos)
        for t in range(n):
            d0 = P[t, 0] - cp[h, 0]
            d1 = P[t, 1] - cp[h, 1]
            d2 = P[t, 2] - cp[h, 2]
            pl0 = d0 * Rc[h, 0, 0] + d1 * Rc[h, 1, 0] + d2 * Rc[h, 2, 0]
            pl1 = d0 * Rc[h, 0, 1] + d1 * Rc[h, 1, 1] + d2 * Rc[h, 2, 1]
            pl2 = d0 * Rc[h, 0, 2] + d1 * Rc[h, 1, 2] + d2 * Rc[h, 2, 2]
            # q_pos = atan2(pl1, pl0) - phi_r; its sine and cosine without the angle
            rl = math.sqrt(pl0 * pl0 + pl1 * pl1)
            cl, sl = (pl0 / rl, pl1 / rl) if rl > 0.0 else (1.0, 0.0)
            s = wp * (sl * cr - cl * sr)
            c = wp * (cl * cr + sl * sr)
            if has_o:
                # Ml = Rc^T R_t Rr^T: first T = Rc^T R_t, then T Rr^T
                for a in range(3):
                    for j in range(3):
                        T[a, j] = (Rc[h, 0, a] * R[t, 0, j] + Rc[h, 1, a] * R[t, 1, j]
                                   + Rc[h, 2, a] * R[t, 2, j])
                m00 = T[0, 0] * Rr[h, 0, 0] + T[0, 1] * Rr[h, 0, 1] + T[0, 2] * Rr[h, 0, 2]
                m01 = T[0, 0] * Rr[h, 1, 0] + T[0, 1] * Rr[h, 1, 1] + T[0, 2] * Rr[h, 1, 2]
                m02 = T[0, 0] * Rr[h, 2, 0] + T[0, 1] * Rr[h, 2, 1] + T[0, 2] * Rr[h, 2, 2]
                m10 = T[1, 0] * Rr[h, 0, 0] + T[1, 1] * Rr[h, 0, 1] + T[1, 2] * Rr[h, 0, 2]
                m11 = T[1, 0] * Rr[h, 1, 0] + T[1, 1] * Rr[h, 1, 1] + T[1, 2] * Rr[h, 1, 2]
                m12 = T[1, 0] * Rr[h, 2, 0] + T[1, 1] * Rr[h, 2, 1] + T[1, 2] * Rr[h, 2, 2]
                m20 = T[2, 0] * Rr[h, 0, 0] + T[2, 1] * Rr[h, 0, 1] + T[2, 2] * Rr[h, 0, 2]
                m21 = T[2, 0] * Rr[h, 1, 0] + T[2, 1] * Rr[h, 1, 1] + T[2, 2] * Rr[h, 1, 2]
                m22 = T[2, 0] * Rr[h, 2, 0] + T[2, 1] * Rr[h, 2, 1] + T[2, 2] * Rr[h, 2, 2]
                # q_rot = atan2(m10 - m01, m00 + m11): its sine and cosine
                yr = m10 - m01
                xr = m00 + m11
                rr = math.sqrt(xr * xr + yr * yr)
                if rr > 0.0:
                    s = s + wr * (yr / rr)
                    c = c + wr * (xr / rr)
                else:
                    c = c + wr
            if want_q:
                q = math.atan2(s, c)
                q_out[h, t] = _pymod(q - q_center + np.pi, twopi) - np.pi + q_center
            # sine and cosine of q (the wrap above moves q by whole turns only)
            rq = math.sqrt(s * s + c * c)
            cq, sq = (c / rq, s / rq) if rq > 0.0 else (1.0, 0.0)
            ex = pl0 - (cq * rp0 - sq * rp1)
            ey = pl1 - (sq * rp0 + cq * rp1)
            ez = pl2 - rp2
            ep2[h, t] = ex * ex + ey * ey + ez * ez
            if vectors:
                res[h, t, 0] = ex / sp_out
                res[h, t, 1] = ey / sp_out
                res[h, t, 2] = ez / sp_out
            if has_o:
                # angle of RotZ(-q) Ml (rows 0, 1 rotated, row 2 unchanged)
                M00 = cq * m00 + sq * m10
                M01 = cq * m01 + sq * m11
                M02 = cq * m02 + sq * m12
                M10 = -sq * m00 + cq * m10
                M11 = -sq * m01 + cq * m11
                M12 = -sq * m02 + cq * m12
                tr = M00 + M11 + m22
                vx = m21 - M12
                vy = M02 - m20
                vz = M10 - M01
                s2 = math.sqrt(vx * vx + vy * vy + vz * vz)  # 2 sin(angle)
                ang = math.atan2(0.5 * s2, 0.5 * (tr - 1.0))
                eo[h, t] = ang
                if vectors:
                    f = (ang / max(s2, 1e-12) if s2 > 1e-12 else 0.5) / so_out
                    res[h, t, 3] = vx * f
                    res[h, t, 4] = vy * f
                    res[h, t, 5] = vz * f
    return q_out, ep2, eo, res


@numba.njit(cache=True, nogil=True)
def em_gamma_loop(L, g, w, iters, tol):
    """The fixed-point iterations of obs.em_gamma: L (H, n) inlier / outlier likelihood
    ratios, g (H,) start (overwritten); returns the outlier ratios (H,)."""
    H, n = L.shape
    A = np.empty(H)
    g_new = np.empty(H)
    for _ in range(iters):
        for h in range(H):
            gh = g[h]
            s = 0.0
            for t in range(n):
                s += gh / ((1.0 - gh) * L[h, t] + gh)
            A[h] = s
        done = True
        for h in range(H):
            if w > 0:
                sw = n + w
                v = (sw - math.sqrt(max(sw * sw - 4 * w * A[h], 0.0))) / (2 * w)
            else:
                v = A[h] / n
            v = min(max(v, 1e-6), 1 - 1e-6)
            if not abs(v - g[h]) < tol:
                done = False
            g_new[h] = v
        g[:] = g_new
        if done:
            break
    return g


@numba.njit(cache=True, nogil=True)
def rotation_errors(Ra, R):
    """Angles (H, n) of Ra[h]^T R[t] (geom._rot_err of geom._pair_mul(Ra^T, R)): the
    orientation errors of the rigid and prismatic models. Ra (H, 3, 3), R (n, 3, 3)."""
    H = Ra.shape[0]
    n = R.shape[0]
    out = np.empty((H, n))
    for h in range(H):
        for t in range(n):
            # M = Ra^T R_t, the entries the angle needs
            m00 = Ra[h, 0, 0] * R[t, 0, 0] + Ra[h, 1, 0] * R[t, 1, 0] + Ra[h, 2, 0] * R[t, 2, 0]
            m11 = Ra[h, 0, 1] * R[t, 0, 1] + Ra[h, 1, 1] * R[t, 1, 1] + Ra[h, 2, 1] * R[t, 2, 1]
            m22 = Ra[h, 0, 2] * R[t, 0, 2] + Ra[h, 1, 2] * R[t, 1, 2] + Ra[h, 2, 2] * R[t, 2, 2]
            m21 = Ra[h, 0, 2] * R[t, 0, 1] + Ra[h, 1, 2] * R[t, 1, 1] + Ra[h, 2, 2] * R[t, 2, 1]
            m12 = Ra[h, 0, 1] * R[t, 0, 2] + Ra[h, 1, 1] * R[t, 1, 2] + Ra[h, 2, 1] * R[t, 2, 2]
            m02 = Ra[h, 0, 0] * R[t, 0, 2] + Ra[h, 1, 0] * R[t, 1, 2] + Ra[h, 2, 0] * R[t, 2, 2]
            m20 = Ra[h, 0, 2] * R[t, 0, 0] + Ra[h, 1, 2] * R[t, 1, 0] + Ra[h, 2, 2] * R[t, 2, 0]
            m10 = Ra[h, 0, 1] * R[t, 0, 0] + Ra[h, 1, 1] * R[t, 1, 0] + Ra[h, 2, 1] * R[t, 2, 0]
            m01 = Ra[h, 0, 0] * R[t, 0, 1] + Ra[h, 1, 0] * R[t, 1, 1] + Ra[h, 2, 0] * R[t, 2, 1]
            tr = m00 + m11 + m22
            vx = m21 - m12
            vy = m02 - m20
            vz = m10 - m01
            s = 0.5 * math.sqrt(vx * vx + vy * vy + vz * vz)
            out[h, t] = math.atan2(s, 0.5 * (tr - 1.0))
    return out


@numba.njit(cache=True, nogil=True)
def weighted_log_mean(R0, R, w):
    """sum_t w_t log(R0^T R_t) / sum_t w_t (rotation vectors; geom._log_rot): the tangent
    step of the weighted geodesic mean. R0 (3, 3), R (n, 3, 3), w (n,)."""
    n = R.shape[0]
    acc0 = 0.0
    acc1 = 0.0
    acc2 = 0.0
    sw = 0.0
    for t in range(n):
        m00 = R0[0, 0] * R[t, 0, 0] + R0[1, 0] * R[t, 1, 0] + R0[2, 0] * R[t, 2, 0]
        m11 = R0[0, 1] * R[t, 0, 1] + R0[1, 1] * R[t, 1, 1] + R0[2, 1] * R[t, 2, 1]
        m22 = R0[0, 2] * R[t, 0, 2] + R0[1, 2] * R[t, 1, 2] + R0[2, 2] * R[t, 2, 2]
        m21 = R0[0, 2] * R[t, 0, 1] + R0[1, 2] * R[t, 1, 1] + R0[2, 2] * R[t, 2, 1]
        m12 = R0[0, 1] * R[t, 0, 2] + R0[1, 1] * R[t, 1, 2] + R0[2, 1] * R[t, 2, 2]
        m02 = R0[0, 0] * R[t, 0, 2] + R0[1, 0] * R[t, 1, 2] + R0[2, 0] * R[t, 2, 2]
        m20 = R0[0, 2] * R[t, 0, 0] + R0[1, 2] * R[t, 1, 0] + R0[2, 2] * R[t, 2, 0]
        m10 = R0[0, 1] * R[t, 0, 0] + R0[1, 1] * R[t, 1, 0] + R0[2, 1] * R[t, 2, 0]
        m01 = R0[0, 0] * R[t, 0, 1] + R0[1, 0] * R[t, 1, 1] + R0[2, 0] * R[t, 2, 1]
        vx = m21 - m12
        vy = m02 - m20
        vz = m10 - m01
        s2 = math.sqrt(vx * vx + vy * vy + vz * vz)  # 2 sin(angle)
        ang = math.atan2(0.5 * s2, 0.5 * (m00 + m11 + m22 - 1.0))
        f = ang / max(s2, 1e-12) if s2 > 1e-12 else 0.5
        acc0 += w[t] * (vx * f)
        acc1 += w[t] * (vy * f)
        acc2 += w[t] * (vz * f)
        sw += w[t]
    out = np.empty(3)
    out[0] = acc0 / sw
    out[1] = acc1 / sw
    out[2] = acc2 / sw
    return out


@numba.njit(cache=True, nogil=True)
def rotvec_to_matrix(rv):
    """Rotation matrices (k, 3, 3) of rotation vectors rv (k, 3): geom._rv2m's Rodrigues
    formula (the same series below an angle of 1e-4), one vector at a time."""
    k = rv.shape[0]
    R = np.empty((k, 3, 3))
    for i in range(k):
        x, y, z = rv[i, 0], rv[i, 1], rv[i, 2]
        t2 = x * x + y * y + z * z
        if t2 < 1e-8:
            a = 1.0 - t2 / 6.0
            b = 0.5 - t2 / 24.0
        else:
            t = math.sqrt(t2)
            a = math.sin(t) / t
            b = (1.0 - math.cos(t)) / (t * t)
        R[i, 0, 0] = 1.0 - b * (y * y + z * z)
        R[i, 1, 1] = 1.0 - b * (x * x + z * z)
        R[i, 2, 2] = 1.0 - b * (x * x + y * y)
        bxy, bxz, byz = b * x * y, b * x * z, b * y * z
        R[i, 0, 1] = bxy - a * z
        R[i, 1, 0] = bxy + a * z
        R[i, 0, 2] = bxz + a * y
        R[i, 2, 0] = bxz - a * y
        R[i, 1, 2] = byz - a * x
        R[i, 2, 1] = byz + a * x
    return R


@numba.njit(cache=True, nogil=True)
def log_rotations(M):
    """Rotation vectors (k, 3) of rotation matrices M (k, 3, 3) from the skew part and the
    trace (geom._log_rot, one matrix at a time), and the cosines of their angles (k,)."""
    k = M.shape[0]
    v = np.empty((k, 3))
    c = np.empty(k)
    for i in range(k):
        vx = M[i, 2, 1] - M[i, 1, 2]
        vy = M[i, 0, 2] - M[i, 2, 0]
        vz = M[i, 1, 0] - M[i, 0, 1]
        s2 = math.sqrt(vx * vx + vy * vy + vz * vz)  # 2 sin(angle)
        ci = 0.5 * (M[i, 0, 0] + M[i, 1, 1] + M[i, 2, 2] - 1.0)
        ang = math.atan2(0.5 * s2, ci)
        f = ang / max(s2, 1e-12) if s2 > 1e-12 else 0.5
        v[i, 0] = vx * f
        v[i, 1] = vy * f
        v[i, 2] = vz * f
        c[i] = ci
    return v, c


@numba.njit(cache=True, nogil=True, inline="always")
def _logaddexp(x, y):
    """numpy's logaddexp for two floats."""
    if x == y:
        return x + _LOG2
    d = x - y
    if d > 0:
        return x + math.log1p(math.exp(-d))
    if d <= 0:
        return y + math.log1p(math.exp(d))
    return d  # nan


@numba.njit(cache=True, nogil=True)
def em_gamma_full(log_in, log_out, gamma0, w, iters, tol, want_resp):
    """obs.em_gamma: outlier ratios (H,), mixture log-likelihood sums (H,) and, with
    ``want_resp``, inlier responsibilities (H, n) (else (0, 0)), for inlier log densities
    log_in (H, n) and the outlier log density log_out."""
    H, n = log_in.shape
    L = np.empty((H, n))
    for h in range(H):
        for t in range(n):
            L[h, t] = math.exp(min(max(log_in[h, t] - log_out, -700.0), 700.0))
    g = em_gamma_loop(L, np.full(H, gamma0), w, iters, tol)
    ll = np.empty(H)
    resp = np.empty((H, n)) if want_resp else np.empty((0, 0))
    for h in range(H):
        lg1 = math.log1p(-g[h])
        b = math.log(g[h]) + log_out
        s = 0.0
        for t in range(n):
            a = lg1 + log_in[h, t]
            lse = _logaddexp(a, b)
            s += lse
            if want_resp:
                resp[h, t] = math.exp(a - lse)
        ll[h] = s
    return g, ll, resp


@numba.njit(cache=True, nogil=True)
def frame_with_z(axis, xhint):
    """geom._frame_with_z one frame at a time: (H, 3, 3) rotations whose z column is
    ``axis`` (H, 3) normalised and whose x column lies along the part of ``xhint`` (H, 3)
    perpendicular to it (along e_x or e_y made perpendicular where that part vanishes)."""
    H = axis.shape[0]
    out = np.empty((H, 3, 3))
    for h in range(H):
        nz = math.sqrt(axis[h, 0] * axis[h, 0] + axis[h, 1] * axis[h, 1]
                       + axis[h, 2] * axis[h, 2])
        z0, z1, z2 = axis[h, 0] / nz, axis[h, 1] / nz, axis[h, 2] / nz
        dz = xhint[h, 0] * z0 + xhint[h, 1] * z1 + xhint[h, 2] * z2
        x0, x1, x2 = xhint[h, 0] - dz * z0, xhint[h, 1] - dz * z1, xhint[h, 2] - dz * z2
        nx = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
        if nx > 1e-12:
            x0, x1, x2 = x0 / nx, x1 / nx, x2 / nx
        else:
            a0, a1 = (1.0, 0.0) if abs(z0) < 0.9 else (0.0, 1.0)
            da = a0 * z0 + a1 * z1
            x0, x1, x2 = a0 - da * z0, a1 - da * z1, -da * z2
            na = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
            x0, x1, x2 = x0 / na, x1 / na, x2 / na
        out[h, 0, 0], out[h, 1, 0], out[h, 2, 0] = x0, x1, x2
        out[h, 0, 1] = z1 * x2 - z2 * x1
        out[h, 1, 1] = z2 * x0 - z0 * x2
        out[h, 2, 1] = z0 * x1 - z1 * x0
        out[h, 0, 2], out[h, 1, 2], out[h, 2, 2] = z0, z1, z2
    return out


@numba.njit(cache=True, nogil=True)
def circle_hypotheses(P, R, idx, minsep):
    """The revolute model's 3-point hypotheses (links.RevoluteModel._point_hypotheses) for
    the index triples idx (H, 3) into the positions P (n, 3): which triples give a circle
    (the three points pairwise farther apart than ``minsep``, not collinear), and for
    those, in order, the centre (k, 3), the centre frame Rc (k, 3, 3) (z along the
    circle's normal, x towards the first point), the first point in that frame (k, 3) and,
    when R (n, 3, 3) is not empty, the first orientation in it, Rc^T R (k, 3, 3)."""
    H = idx.shape[0]
    ok = np.zeros(H, np.bool_)
    center = np.empty((H, 3))
    axb = np.empty((H, 3))
    rel = np.empty((H, 3))
    k = 0
    for h in range(H):
        i1, i2, i3 = idx[h, 0], idx[h, 1], idx[h, 2]
        a0, a1, a2 = P[i1, 0] - P[i3, 0], P[i1, 1] - P[i3, 1], P[i1, 2] - P[i3, 2]
        b0, b1, b2 = P[i2, 0] - P[i3, 0], P[i2, 1] - P[i3, 1], P[i2, 2] - P[i3, 2]
        c0, c1, c2 = a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0
        nn = c0 * c0 + c1 * c1 + c2 * c2
        aa = a0 * a0 + a1 * a1 + a2 * a2
        bb = b0 * b0 + b1 * b1 + b2 * b2
        la, lb = math.sqrt(aa), math.sqrt(bb)
        e0, e1, e2 = P[i1, 0] - P[i2, 0], P[i1, 1] - P[i2, 1], P[i1, 2] - P[i2, 2]
        l12 = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
        if not (nn > 1e-18 and la > minsep and lb > minsep and l12 > minsep
                and math.sqrt(nn) > 1e-6 * la * lb):
            continue
        ok[h] = True
        v0, v1, v2 = aa * b0 - bb * a0, aa * b1 - bb * a1, aa * b2 - bb * a2
        n0, n1, n2 = v1 * c2 - v2 * c1, v2 * c0 - v0 * c2, v0 * c1 - v1 * c0
        center[k, 0] = P[i3, 0] + n0 / (2 * nn)
        center[k, 1] = P[i3, 1] + n1 / (2 * nn)
        center[k, 2] = P[i3, 2] + n2 / (2 * nn)
        axb[k, 0], axb[k, 1], axb[k, 2] = c0, c1, c2
        for j in range(3):
            rel[k, j] = P[i1, j] - center[k, j]
        k += 1
    Rc = frame_with_z(axb[:k], rel[:k])
    r_p = np.empty((k, 3))
    has_o = R.shape[0] > 0
    Rr = np.empty((k if has_o else 0, 3, 3))
    j = 0
    for h in range(H):
        if not ok[h]:
            continue
        for a in range(3):
            r_p[j, a] = Rc[j, 0, a] * rel[j, 0] + Rc[j, 1, a] * rel[j, 1] + Rc[j, 2, a] * rel[j, 2]
        if has_o:
            i1 = idx[h, 0]
            for a in range(3):
                for c in range(3):
                    Rr[j, a, c] = (Rc[j, 0, a] * R[i1, 0, c] + Rc[j, 1, a] * R[i1, 1, c]
                                   + Rc[j, 2, a] * R[i1, 2, c])
        j += 1
    return ok, center[:k], Rc, r_p, Rr


@numba.njit(cache=True, nogil=True)
def prismatic_errors(a, e, P, Ra, R):
    """Errors of the prismatic model (links.PrismaticModel._residuals_batch) for H
    parameter sets: origins a (H, 3), axes e (H, 3) (normalised here), origin rotations
    Ra (H, 3, 3) (ignored when R is empty), observations P (n, 3), R (n, 3, 3) or
    (0, 3, 3). Returns the squared distances to the line (H, n), the orientation errors
    (H, n) (zeros without R) and the configurations q (H, n)."""
    H = a.shape[0]
    n = P.shape[0]
    ep2 = np.empty((H, n))
    q = np.empty((H, n))
    for h in range(H):
        ne = math.sqrt(e[h, 0] * e[h, 0] + e[h, 1] * e[h, 1] + e[h, 2] * e[h, 2])
        e0, e1, e2 = e[h, 0] / ne, e[h, 1] / ne, e[h, 2] / ne
        for t in range(n):
            d0, d1, d2 = P[t, 0] - a[h, 0], P[t, 1] - a[h, 1], P[t, 2] - a[h, 2]
            qt = d0 * e0 + d1 * e1 + d2 * e2
            p0, p1, p2 = d0 - qt * e0, d1 - qt * e1, d2 - qt * e2
            q[h, t] = qt
            ep2[h, t] = p0 * p0 + p1 * p1 + p2 * p2
    eo = rotation_errors(Ra, R) if R.shape[0] > 0 else np.zeros((H, n))
    return ep2, eo, q


@numba.njit(cache=True, nogil=True)
def nearest_rotation(M):
    """The rotation nearest (Frobenius) to the 3 x 3 matrix M: se3._project_svd (SVD, the
    determinant fixed to +1)."""
    U, _, Vt = np.linalg.svd(M)
    det = np.linalg.det(U @ Vt)
    for i in range(3):
        U[i, 2] *= det
    return U @ Vt


@numba.njit(cache=True, nogil=True)
def weighted_rotation_mean(R, w):
    """geom._weighted_rotation_mean in one call: the nearest rotation R0 to the weighted sum
    sum_t w_t R_t (SVD, determinant fixed to +1), then R0 exp(weighted_log_mean(R0, R, w))
    (Rodrigues). R (n, 3, 3), w (n,)."""
    M = np.zeros((3, 3))
    for t in range(R.shape[0]):
        for i in range(3):
            for j in range(3):
                M[i, j] += w[t] * R[t, i, j]
    R0 = nearest_rotation(M)
    v = weighted_log_mean(R0, R, w)
    return R0 @ rotvec_to_matrix(v.reshape(1, 3))[0]


@numba.njit(cache=True, nogil=True)
def rotation_vectors(M):
    """Rotation vectors (k, 3) (angle in [0, pi]) of rotation matrices M (k, 3, 3): geom._m2rv
    one matrix at a time. :func:`log_rotations` where the angle's cosine is at least -0.99;
    beyond it (near pi, where the skew part vanishes) the axis is the largest column of the
    symmetric part minus cos(angle) I, signed like the skew part."""
    v, c = log_rotations(M)
    for i in range(M.shape[0]):
        ci = c[i]
        if not ci < -0.99:
            continue
        sx = M[i, 2, 1] - M[i, 1, 2]
        sy = M[i, 0, 2] - M[i, 2, 0]
        sz = M[i, 1, 0] - M[i, 0, 1]
        ang = math.atan2(0.5 * math.sqrt(sx * sx + sy * sy + sz * sz), ci)
        j = 0
        best = M[i, 0, 0] - ci
        for a in range(1, 3):
            if M[i, a, a] - ci > best:  # (argmax: the first of equal ones)
                best = M[i, a, a] - ci
                j = a
        col = np.empty(3)
        for a in range(3):
            col[a] = 0.5 * (M[i, a, j] + M[i, j, a]) - (ci if a == j else 0.0)
        nc = math.sqrt(col[0] * col[0] + col[1] * col[1] + col[2] * col[2])
        n0, n1, n2 = col[0] / nc, col[1] / nc, col[2] / nc
        if n0 * sx + n1 * sy + n2 * sz < 0:
            n0, n1, n2 = -n0, -n1, -n2
        v[i, 0] = ang * n0
        v[i, 1] = ang * n1
        v[i, 2] = ang * n2
    return v
