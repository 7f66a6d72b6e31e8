"""Compiled (numba) negative log marginal likelihood of the GP (models/common/gp.py) and its
gradient, for the hyper-parameter optimisation.

Per output c, the kernel K_c = Kse_c (+ sb2_c P) + sn2_c I, its Cholesky factor L, the
inverse factor X = L^-1 and K_c^-1 = X^T X (both by row updates over contiguous memory),
alpha = K_c^-1 y_c, and the gradient 0.5 tr((alpha alpha^T - K^-1) dK/dh) summed over the
lower triangle (reductions may be reassociated: ``fastmath`` reassoc and contract only, so
NaN and infinity keep their meaning). The same quantities as ``GaussianProcess._neg_lml_and_grad_numpy``
(equal to ~1e-15 relative; the tests compare both), without the per-output LAPACK calls and
array temporaries, which dominate at the link models' sizes (n = 30-50 inputs, 3-6 outputs,
~20 evaluations per fit). Compiled on first use and cached on disk.
"""

from __future__ import annotations

import math

import numba
import numpy as np

_LOG_2PI = math.log(2.0 * math.pi)


@numba.njit(cache=True, nogil=True, fastmath={"reassoc", "contract"})
def neg_lml_and_grad(theta, D2, P, Yc, d_ell, width, ard, has_rev):
    """(-log marginal likelihood summed over outputs, its gradient (m * width,), ok).

    Args:
        theta: (m * width,) per output: log ell (d_ell), log sf2, log sn2 [, log sb2].
        D2: (d, n, n) per-input squared differences; P: (n, n) the revolute term's product
            (used only with ``has_rev``); Yc: (n, m) centred targets.
    ``ok`` is False when a kernel matrix is not positive definite (the caller then falls
    back to the jittered numpy path)."""
    n, m = Yc.shape
    d = D2.shape[0]
    g = np.zeros(m * width)
    f = 0.0
    K = np.empty((n, n))
    Kse = np.empty((n, n))
    L = np.empty((n, n))
    W = np.empty((n, n))
    inv = np.empty(max(d, 1))
    alpha = np.empty(n)
    z = np.empty(max(d_ell, 1))
    for c in range(m):
        o = c * width
        for j in range(d):
            inv[j] = math.exp(-2.0 * theta[o + (j if ard else 0)])
        lsf2 = theta[o + d_ell]
        sn2 = math.exp(theta[o + d_ell + 1])
        sb2 = math.exp(theta[o + d_ell + 2]) if has_rev else 0.0
        for a in range(n):
            for b in range(a + 1):
                r = 0.0
                for j in range(d):
                    r += inv[j] * D2[j, a, b]
                v = math.exp(-0.5 * r + lsf2)
                Kse[a, b] = v
                Kse[b, a] = v
                k = v + sb2 * P[a, b] if has_rev else v
                K[a, b] = k
                K[b, a] = k
            K[a, a] += sn2
        # Cholesky factor (lower)
        for j in range(n):
            s = K[j, j]
            for k in range(j):
                s -= L[j, k] * L[j, k]
            if not s > 0.0:
                return np.nan, g, False
            ljj = math.sqrt(s)
            L[j, j] = ljj
            for i in range(j + 1, n):
                s = K[i, j]
                for k in range(j):
                    s -= L[i, k] * L[j, k]
                L[i, j] = s / ljj
        # X = L^-1 row by row (X[i] = (e_i - sum_k<i L[i, k] X[k]) / L[i, i]; row updates
        # over contiguous memory, K is no longer needed)
        X = K
        for i in range(n):
            for b in range(n):
                X[i, b] = 0.0
            X[i, i] = 1.0
            for k in range(i):
                lik = L[i, k]
                for b in range(k + 1):
                    X[i, b] -= lik * X[k, b]
            inv_ii = 1.0 / L[i, i]
            for b in range(i + 1):
                X[i, b] *= inv_ii
        # W = K^-1 = X^T X, lower triangle accumulated over the rows of X, then mirrored
        for a in range(n):
            for b in range(a + 1):
                W[a, b] = 0.0
        for k in range(n):
            for a in range(k + 1):
                xka = X[k, a]
                for b in range(a + 1):
                    W[a, b] += xka * X[k, b]
        for a in range(n):
            for b in range(a):
                W[b, a] = W[a, b]
        logdet_half = 0.0
        for j in range(n):
            logdet_half += math.log(L[j, j])
        quad = 0.0
        for a in range(n):
            s = 0.0
            for b in range(n):
                s += W[a, b] * Yc[b, c]
            alpha[a] = s
            quad += Yc[a, c] * s
        f += 0.5 * quad + logdet_half + 0.5 * n * _LOG_2PI
        # gradient: 0.5 sum_ab (alpha_a alpha_b - Kinv_ab) dK_ab / dh (lower triangle twice)
        gsf = 0.0
        gsn = 0.0
        gsb = 0.0
        for j in range(d_ell):
            z[j] = 0.0
        for a in range(n):
            for b in range(a + 1):
                w = alpha[a] * alpha[b] - W[a, b]
                if a == b:
                    gsn += w
                else:
                    w = 2.0 * w
                wk = w * Kse[a, b]
                gsf += wk
                if has_rev:
                    gsb += w * P[a, b]
                if ard:
                    for j in range(d):
                        z[j] += wk * D2[j, a, b]
                else:
                    for j in range(d):
                        z[0] += wk * D2[j, a, b] * inv[j]
        for j in range(d_ell):
            g[o + j] = -0.5 * z[j] * (inv[j] if ard else 1.0)
        g[o + d_ell] = -0.5 * gsf
        g[o + d_ell + 1] = -0.5 * sn2 * gsn
        if has_rev:
            g[o + d_ell + 2] = -0.5 * sb2 * gsb
    return f, g, True


@numba.njit(cache=True, nogil=True)
def factorise(K, Yc):
    """Per output c: the Cholesky factor L_c of K[c] (m, n, n) (lower, zeros above the
    diagonal), alpha_c = K_c^-1 y_c by forward and back substitution (Yc (n, m) the centred
    targets) and the log marginal likelihood. Returns (L (m, n, n), alpha (m, n), lml (m,),
    ok); ok is False when a K[c] is not positive definite (the caller then adds jitter)."""
    m, n, _ = K.shape
    L = np.zeros((m, n, n))
    alpha = np.empty((m, n))
    lml = np.empty(m)
    z = np.empty(n)
    for c in range(m):
        Lc = L[c]
        for j in range(n):
            s = K[c, j, j]
            for k in range(j):
                s -= Lc[j, k] * Lc[j, k]
            if not s > 0.0:
                return L, alpha, lml, False
            ljj = math.sqrt(s)
            Lc[j, j] = ljj
            for i in range(j + 1, n):
                s = K[c, i, j]
                for k in range(j):
                    s -= Lc[i, k] * Lc[j, k]
                Lc[i, j] = s / ljj
        quad = 0.0
        logdet_half = 0.0
        for i in range(n):  # z = L^-1 y
            s = Yc[i, c]
            for k in range(i):
                s -= Lc[i, k] * z[k]
            z[i] = s / Lc[i, i]
            quad += z[i] * z[i]
            logdet_half += math.log(Lc[i, i])
        for i in range(n - 1, -1, -1):  # alpha = L^-T z
            s = z[i]
            for k in range(i + 1, n):
                s -= Lc[k, i] * alpha[c, k]
            alpha[c, i] = s / Lc[i, i]
        lml[c] = -0.5 * quad - logdet_half - 0.5 * n * _LOG_2PI
    return L, alpha, lml, True
