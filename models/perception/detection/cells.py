"""Stage ``planes`` on the organised image (``FrontDetectorConfig.plane_method = "cells"``).

The image is cut into square cells aligned with the RANSAC sample grid (one
``ransac_stride_px`` cell per sample, centred on it). One pass sums, per cell, the number of
measured pixels, their x, y, z and the six products (:func:`_cell_sums`, every
``cell_pixel_step``-th pixel), so that the plane of any set of cells is a sum of cells. A
cell is planar when one of the 2 x 2 blocks of cells that contain it holds at least half
its pixels and their RMS distance to the block's plane is at most ``cell_planarity`` L; its
normal is that block's (:func:`_cell_fits`). Regions are grown over the 8-neighbours of
planar cells whose normals agree with the region's plane within ``cell_normal_deg`` and
whose centroids lie within ``cell_distance`` L of it, the region's plane refitted from its
blocks' sums as it grows (:func:`_grow_regions`). The regions, largest first, replace
RANSAC's best hypotheses (:func:`_cell_round`): twice the largest 8-connected region of the
active cells whose centroid lies within ``cell_distance`` L and the least-squares plane from
the sums of those of its cells that lie near the plane as a whole, then the removal band
(times ``cell_distance``) and the copy test of
:func:`~mmlearn.models.perception.detection.planes.find_planes`.

Each :class:`~mmlearn.models.perception.detection.planes.Plane` keeps ``support`` (inlier
cells: the sample grid's points) and ``bbox`` (on the sample grid), so that the later stages
rank and gate these planes as RANSAC's (CAPE, Proença and Gao, 2018; PEAC, Feng et al.,
2014)."""

import math

import numba
import numpy as np

from mmlearn.models.perception.detection.config import FrontDetectorConfig
from mmlearn.models.perception.detection.planes import (
    Plane, _grid_labels, _least_eigenvector, _plane_from_scatter)


@numba.njit(cache=True, nogil=True)
def _cell_sums(Pc, max_depth, st, Hc, Wc, step):
    """(Hc, Wc, 10) float64 per cell ``[st i, st i + st) x [st j, st j + st)`` of the
    measured points ``Pc`` (H, W, 3) nearer than ``max_depth`` in every ``step``-th row and
    column: count, x, y, z, xx, xy, xz, yy, yz, zz summed (one pass, a row of a cell summed
    in locals)."""
    S = np.zeros((Hc, Wc, 10))
    H, W = Pc.shape[0], Pc.shape[1]
    for r in range(0, min(H, Hc * st), step):
        i = r // st
        for j in range(Wc):
            n = sx = sy = sz = sxx = sxy = sxz = syy = syz = szz = 0.0
            for q in range(j * st, min(W, j * st + st), step):
                z = np.float64(Pc[r, q, 2])
                if not (z <= max_depth):  # NaN (not measured) fails too
                    continue
                x, y = np.float64(Pc[r, q, 0]), np.float64(Pc[r, q, 1])
                n += 1.0
                sx += x
                sy += y
                sz += z
                sxx += x * x
                sxy += x * y
                sxz += x * z
                syy += y * y
                syz += y * z
                szz += z * z
            s = S[i, j]
            s[0] += n
            s[1] += sx
            s[2] += sy
            s[3] += sz
            s[4] += sxx
            s[5] += sxy
            s[6] += sxz
            s[7] += syy
            s[8] += syz
            s[9] += szz
    return S


def _block_sums(S):
    """The sums of the 2 x 2 blocks of cells (Hc - 1, Wc - 1, 10): block (i, j) holds cells
    i..i+1 x j..j+1."""
    return S[:-1, :-1] + S[1:, :-1] + S[:-1, 1:] + S[1:, 1:]


@numba.njit(cache=True, nogil=True)
def _sym_least_eig(a00, a01, a02, a11, a12, a22):
    """The least eigenvalue of a symmetric 3 x 3 matrix and a unit eigenvector of it (closed
    form: the trigonometric solution of the characteristic cubic, the vector as the largest
    cross product of two rows of A - lambda I)."""
    p1 = a01 * a01 + a02 * a02 + a12 * a12
    q = (a00 + a11 + a22) / 3.0
    b00, b11, b22 = a00 - q, a11 - q, a22 - q
    p2 = b00 * b00 + b11 * b11 + b22 * b22 + 2.0 * p1
    p = math.sqrt(p2 / 6.0)
    if p < 1e-300:
        return q, 0.0, 0.0, 1.0
    detb = (b00 * (b11 * b22 - a12 * a12) - a01 * (a01 * b22 - a12 * a02)
            + a02 * (a01 * a12 - b11 * a02))
    rr = detb / (2.0 * p * p * p)
    rr = min(1.0, max(-1.0, rr))
    phi = math.acos(rr) / 3.0
    lam = q + 2.0 * p * math.cos(phi + 2.0 * math.pi / 3.0)
    r0 = (a00 - lam, a01, a02)
    r1 = (a01, a11 - lam, a12)
    r2 = (a02, a12, a22 - lam)
    best = -1.0
    vx = vy = 0.0
    vz = 1.0
    for u, v in ((r0, r1), (r0, r2), (r1, r2)):
        cx = u[1] * v[2] - u[2] * v[1]
        cy = u[2] * v[0] - u[0] * v[2]
        cz = u[0] * v[1] - u[1] * v[0]
        nn = cx * cx + cy * cy + cz * cz
        if nn > best:
            best, vx, vy, vz = nn, cx, cy, cz
    if best <= 0.0:
        return lam, 0.0, 0.0, 1.0
    ln = math.sqrt(best)
    return lam, vx / ln, vy / ln, vz / ln


@numba.njit(cache=True, nogil=True, inline="always")
def _fit_sums(s):
    """The plane of summed points ``s`` (10,): centroid (3), unit normal (3, towards the
    camera at the origin), offset and mean squared distance to it."""
    k = s[0]
    cx, cy, cz = s[1] / k, s[2] / k, s[3] / k
    lam, nx, ny, nz = _sym_least_eig(s[4] - s[1] * cx, s[5] - s[1] * cy, s[6] - s[1] * cz,
                                     s[7] - s[2] * cy, s[8] - s[2] * cz, s[9] - s[3] * cz)
    if nx * cx + ny * cy + nz * cz > 0:
        nx, ny, nz = -nx, -ny, -nz
    return cx, cy, cz, nx, ny, nz, -(nx * cx + ny * cy + nz * cz), max(lam, 0.0) / k


@numba.njit(cache=True, nogil=True)
def _cell_fits(S, B, min_count, base, per_m2, planarity):
    """Per cell: centroid (Hc, Wc, 3; NaN when empty) and L at its depth; of the 2 x 2
    blocks ``B`` (:func:`_block_sums`) that contain it, the planar one (at least
    ``min_count`` points, RMS distance to its plane <= ``planarity`` L) with the least mean
    squared distance: its unit normal (Hc, Wc, 3), sums (Hc, Wc, 10) and mean squared
    distance; whether there is one (the cell is planar). An 8 px cell spans 4 cm at 3 m,
    where the noise is ~13 mm: its own fit's normal is noise; a cell at a front's edge is
    planar by the block on the front's side."""
    Hc, Wc = S.shape[0], S.shape[1]
    cen = np.full((Hc, Wc, 3), np.nan)
    Lc = np.zeros((Hc, Wc))
    for i in range(Hc):
        for j in range(Wc):
            s = S[i, j]
            if s[0] < 1:
                continue
            cz = s[3] / s[0]
            cen[i, j, 0], cen[i, j, 1], cen[i, j, 2] = s[1] / s[0], s[2] / s[0], cz
            Lc[i, j] = max(base, per_m2 * cz * cz)
    nrm = np.zeros((Hc, Wc, 3))
    G = np.zeros((Hc, Wc, 10))
    planar = np.zeros((Hc, Wc), np.bool_)
    mse = np.full((Hc, Wc), np.inf)
    for i in range(Hc - 1):
        for j in range(Wc - 1):
            s = B[i, j]
            if s[0] < min_count:
                continue
            _, _, cz, nx, ny, nz, _, e = _fit_sums(s)
            L = max(base, per_m2 * cz * cz)
            if e > (planarity * L) ** 2:
                continue
            for i2 in range(i, i + 2):
                for j2 in range(j, j + 2):
                    if e < mse[i2, j2] and S[i2, j2, 0] >= 1:
                        mse[i2, j2] = e
                        planar[i2, j2] = True
                        nrm[i2, j2, 0], nrm[i2, j2, 1], nrm[i2, j2, 2] = nx, ny, nz
                        G[i2, j2] = s
    return cen, nrm, G, Lc, planar, mse


@numba.njit(cache=True, nogil=True)
def _grow_regions(B, cen, nrm, Lc, planar, order, cos_max):
    """Region labels (Hc, Wc; 0 = none, regions 1, 2, ... in the order of their seeds) grown
    from the planar cells in ``order`` (flat indices) over 8-neighbours: a planar, unlabelled
    cell joins when its normal is within ``acos(cos_max)`` of the region's plane and its
    centroid within its L of it; the plane is refitted as the region grows (at 2, 4, 8, ...
    cells, then every 32), from the sums
    of the region's cells' blocks ``B`` (a few far cells' own sums leave the normal to the
    noise)."""
    Hc, Wc = planar.shape
    lab = np.zeros((Hc, Wc), np.int64)
    stack = np.empty(Hc * Wc, np.int64)
    acc = np.zeros(10)
    nlab = 0
    for f in order:
        i0, j0 = f // Wc, f % Wc
        if lab[i0, j0] != 0:
            continue
        nlab += 1
        lab[i0, j0] = nlab
        acc[:] = B[i0, j0]
        size = 1
        nx, ny, nz = nrm[i0, j0, 0], nrm[i0, j0, 1], nrm[i0, j0, 2]
        d = -(nx * cen[i0, j0, 0] + ny * cen[i0, j0, 1] + nz * cen[i0, j0, 2])
        stack[0] = f
        top = 1
        while top > 0:
            top -= 1
            g = stack[top]
            i, j = g // Wc, g % Wc
            for i2 in range(max(0, i - 1), min(Hc, i + 2)):
                for j2 in range(max(0, j - 1), min(Wc, j + 2)):
                    if lab[i2, j2] != 0 or not planar[i2, j2]:
                        continue
                    if abs(nx * nrm[i2, j2, 0] + ny * nrm[i2, j2, 1]
                           + nz * nrm[i2, j2, 2]) < cos_max:
                        continue
                    if abs(nx * cen[i2, j2, 0] + ny * cen[i2, j2, 1] + nz * cen[i2, j2, 2]
                           + d) > Lc[i2, j2]:
                        continue
                    lab[i2, j2] = nlab
                    acc += B[i2, j2]
                    size += 1
                    if size & (size - 1) == 0 or size % 32 == 0:  # 2, 4, 8, ..., every 32
                        _, _, _, nx, ny, nz, d, _ = _fit_sums(acc)
                    stack[top] = i2 * Wc + j2
                    top += 1
    return lab


def _sums_plane(S):
    """The least-squares plane (unit normal towards the camera, offset) of the points summed
    in the rows of ``S`` (k, 10)."""
    s = S.sum(axis=0)
    k = s[0]
    c = s[1:4] / k
    M = np.array([[s[4], s[5], s[6]], [s[5], s[7], s[8]], [s[6], s[8], s[9]]])
    return _plane_from_scatter(c, M - np.outer(s[1:4], c))


@numba.njit(cache=True, nogil=True)
def _regions_of(mask, img, rows, cols):
    """8-connected regions of the points ``mask`` (bool, m) on the grid ``img`` (the point
    at each cell, -1: none) in the raster order of their first cell
    (:func:`~mmlearn.models.perception.detection.planes._grid_labels`): labels (m, 0 = not in
    ``mask``) and their number."""
    Hc, Wc = img.shape
    sel = np.flatnonzero(mask).astype(np.int64)
    lab = np.zeros(len(mask), np.int64)
    if len(sel) == 0:
        return lab, 0
    lab[sel] = _grid_labels(rows, cols, sel, Hc, Wc)
    return lab, int(lab.max())


@numba.njit(cache=True, nogil=True)
def _largest(mask, img, rows, cols):
    """The largest 8-connected region of ``mask`` (of equally large ones the first in
    raster order), as a mask."""
    lab, nlab = _regions_of(mask, img, rows, cols)
    cnt = np.zeros(nlab + 1, np.int64)
    for j in range(len(lab)):
        cnt[lab[j]] += 1
    best = 0
    for q in range(1, nlab + 1):
        if best == 0 or cnt[q] > cnt[best]:
            best = q
    return lab == best if best > 0 else np.zeros(len(mask), np.bool_)


@numba.njit(cache=True, nogil=True)
def _near_sums_plane(S, inl, n, d, thr2):
    """The summed points (10,) of the cells of ``inl`` whose pixels' mean squared distance
    to ``n . p + d = 0`` is at most ``thr2``, and how many cells."""
    acc = np.zeros(10)
    k = 0
    a, b, c = n[0], n[1], n[2]
    for j in range(len(inl)):
        if not inl[j]:
            continue
        s = S[j]
        q = (a * a * s[4] + b * b * s[7] + c * c * s[9]
             + 2.0 * (a * b * s[5] + a * c * s[6] + b * c * s[8])
             + 2.0 * d * (a * s[1] + b * s[2] + c * s[3]) + d * d * s[0])
        if q <= thr2[j] * s[0]:
            acc += s
            k += 1
    return acc, k


@numba.njit(cache=True, nogil=True)
def _cell_round(pts, S, Lp, Lr, thr2, active, img, rows, cols, n, d):
    """One round of :func:`find_cell_planes` from the plane ``n . p + d = 0``: twice the
    largest 8-connected region of the active cells whose centroid ``pts`` is within ``Lp``
    and the least-squares plane of those of its cells that lie near the plane as a whole
    (``thr2``: the largest mean squared distance; the centroids' plane when fewer than 3);
    then the active cells within ``Lr`` in regions touching it leave ``active``. Returns
    the plane and its region (mask)."""
    m = len(pts)
    sel = np.zeros(m, np.bool_)
    inl = np.zeros(m, np.bool_)
    c = np.empty(3)
    M = np.empty((3, 3))
    for _ in range(2):
        for j in range(m):
            sel[j] = active[j] and abs(pts[j, 0] * n[0] + pts[j, 1] * n[1]
                                       + pts[j, 2] * n[2] + d) <= Lp[j]
        inl = _largest(sel, img, rows, cols)
        acc, k = _near_sums_plane(S, inl, n, d, thr2)
        if k < 3:
            acc[:] = 0.0
            for j in range(m):
                if inl[j]:
                    x, y, z = pts[j, 0], pts[j, 1], pts[j, 2]
                    acc[0] += 1.0
                    acc[1] += x
                    acc[2] += y
                    acc[3] += z
                    acc[4] += x * x
                    acc[5] += x * y
                    acc[6] += x * z
                    acc[7] += y * y
                    acc[8] += y * z
                    acc[9] += z * z
            if acc[0] < 3:
                break
        k = acc[0]
        for t in range(3):
            c[t] = acc[1 + t] / k
        M[0, 0] = acc[4] - acc[1] * c[0]
        M[0, 1] = M[1, 0] = acc[5] - acc[1] * c[1]
        M[0, 2] = M[2, 0] = acc[6] - acc[1] * c[2]
        M[1, 1] = acc[7] - acc[2] * c[1]
        M[1, 2] = M[2, 1] = acc[8] - acc[2] * c[2]
        M[2, 2] = acc[9] - acc[3] * c[2]
        v = _least_eigenvector(M)
        if v[0] * c[0] + v[1] * c[1] + v[2] * c[2] > 0:
            v = -v
        n = v
        d = -(n[0] * c[0] + n[1] * c[1] + n[2] * c[2])
    for j in range(m):
        sel[j] = active[j] and abs(pts[j, 0] * n[0] + pts[j, 1] * n[1]
                                   + pts[j, 2] * n[2] + d) <= Lr[j]
    lab, nlab = _regions_of(sel, img, rows, cols)
    touch = np.zeros(nlab + 1, np.bool_)
    for j in range(m):
        if inl[j]:
            touch[lab[j]] = True
    for j in range(m):
        if inl[j] or (lab[j] > 0 and touch[lab[j]]):
            active[j] = False
    return n, d, inl


def find_cell_planes(Pc: np.ndarray, st: int, cfg: FrontDetectorConfig) -> tuple[list[Plane], int]:
    """Up to ``cfg.max_planes`` planes of the camera-frame points ``Pc`` (H, W, 3; NaN where
    not measured) on the cell grid of stride ``st`` (module docstring); also returns the
    number of planar cells."""
    H, W = Pc.shape[:2]
    off = st // 2
    Hc, Wc = len(range(off, H, st)), len(range(off, W, st))
    step = int(cfg.cell_pixel_step)
    S = _cell_sums(Pc, float(cfg.max_depth), st, Hc, Wc, step)
    B = _block_sums(S)
    base, per_m2 = float(cfg.inlier_distance), float(cfg.inlier_distance_per_m2)
    cen, nrm, G, Lc, planar, mse = _cell_fits(S, B, 2.0 * len(range(0, st, step)) ** 2, base, per_m2,
                                           float(cfg.cell_planarity))
    order = np.flatnonzero(planar.ravel())
    order = order[np.argsort(mse.ravel()[order], kind="stable")]
    fd = float(cfg.cell_distance)
    lab = _grow_regions(G, cen, nrm, fd * Lc, planar, order,
                        math.cos(math.radians(cfg.cell_normal_deg)))
    planes: list[Plane] = []
    S_flat = S.reshape(-1, 10)
    ok = np.isfinite(cen[..., 2]).ravel()
    cells = np.flatnonzero(ok)  # the "points": one per measured cell
    if len(cells) < max(3, cfg.min_plane_points):
        return planes, int(planar.sum())
    pts = cen.reshape(-1, 3)[cells]
    grid_rc = np.column_stack([cells // Wc, cells % Wc])
    z2 = pts[:, 2] ** 2
    Lp = fd * np.maximum(base, per_m2 * z2)
    Lr = Lp + fd * (cfg.removal_factor - 1.0) * per_m2 * z2
    lab_p = lab.ravel()[cells]
    sizes = np.bincount(lab_p)
    sizes[0] = 0
    active = np.ones(len(cells), bool)
    # regions largest first, each one round of RANSAC's (its best hypothesis: the region's
    # plane); a region down to half min_plane_points planar cells may still gather enough
    # inliers
    rounds = 0
    least = max(3, int(cfg.min_plane_points) // 2)
    img = np.full((Hc, Wc), -1, np.int64)
    img[grid_rc[:, 0], grid_rc[:, 1]] = np.arange(len(cells))
    S_p = np.ascontiguousarray(S_flat[cells])
    thr2 = (float(cfg.cell_planarity) * Lc.ravel()[cells]) ** 2
    rows, cols = grid_rc[:, 0].copy(), grid_rc[:, 1].copy()
    for region in np.argsort(-sizes, kind="stable"):
        if (len(planes) >= int(cfg.max_planes) or rounds >= 2 * int(cfg.max_planes)
                or sizes[region] < least):
            break
        seed = np.flatnonzero((lab_p == region) & active)
        if len(seed) < least:
            continue
        rounds += 1
        n, d = _sums_plane(S_p[seed])
        n, d, inl_m = _cell_round(pts, S_p, Lp, Lr, thr2, active, img, rows, cols,
                                  np.asarray(n, np.float64), float(d))
        active[seed] = False
        inl = np.flatnonzero(inl_m)
        if len(inl) < cfg.min_plane_points:
            continue
        Lq = max(base, per_m2 * d * d)
        cen_p = pts[inl].mean(axis=0)
        if any(abs(q.n @ n) > math.cos(math.radians(5.0)) and abs(q.n @ cen_p + q.d) < Lq
               for q in planes):
            continue
        rc = grid_rc[inl]
        planes.append(Plane(n=n, d=float(d), support=len(inl),
                            bbox=(int(rc[:, 0].min()), int(rc[:, 0].max()) + 1,
                                  int(rc[:, 1].min()), int(rc[:, 1].max()) + 1)))
    return planes, int(planar.sum())
