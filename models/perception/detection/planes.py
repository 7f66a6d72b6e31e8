"""Stage ``planes``: sequential RANSAC plane segmentation (thesis 5.1.1, Eq. 5.1).

Hypotheses are drawn locally on a subsampled pixel grid and scored all at once against the
sampled points; the inlier distance grows with the depth like the camera's noise. A plane is
the largest 8-connected region of its inliers, refined by least squares; its points leave the
pool of sampling points and the search repeats. Each plane is then refitted on the
full-resolution pixels near it (:func:`refine_plane_fullres`)."""

import math
from dataclasses import dataclass

import numba
import numpy as np
from llvmlite import ir as llvm_ir
from numba import types
from numba.extending import intrinsic

from mmlearn.models.perception.detection.config import FrontDetectorConfig


@dataclass
class Plane:
    """A plane found by RANSAC, camera frame: ``n . p + d = 0``, ``n`` unit towards the camera
    (``d > 0``); ``support`` = inliers among the sampled pixels (its largest connected region);
    ``bbox`` = (row0, row1, col0, col1) of that region on the sample grid; ``parent`` = the
    index of the plane an offset layer was split from (:func:`_offset_layers`), -1 for
    RANSAC's own planes; ``region`` = (row0, row1, col0, col1), image pixels: where an offset
    layer and its parent share pixels by the nearer-plane rule (None: everywhere)."""

    n: np.ndarray
    d: float
    support: int
    bbox: tuple = (0, 0, 0, 0)
    parent: int = -1
    region: tuple | None = None


@numba.njit(cache=True, nogil=True)
def _least_eigenvector(S):
    """The eigenvector of the symmetric (3, 3) ``S`` of its least eigenvalue (LAPACK's
    ``syevd`` as ``np.linalg.eigh``: the same vector, without numpy's ~20 us of call
    overhead)."""
    _, V = np.linalg.eigh(S)
    return V[:, 0].copy()


def _plane_from_scatter(c: np.ndarray, scatter: np.ndarray):
    """The plane through the centroid ``c`` (3,) whose normal is the least eigenvector of the
    (3, 3) ``scatter`` matrix of the points about it (fast at 3 x 3): unit normal towards
    the camera at the origin, and offset."""
    n = _least_eigenvector(np.ascontiguousarray(scatter, np.float64))
    if n @ c > 0:  # towards the camera at the origin
        n = -n
    return n, float(-n @ c)


def _fit_plane(P: np.ndarray, idx: np.ndarray | None = None):
    """Least-squares plane through points (k, 3) (with ``idx``: through ``P[idx]``, gathered
    in the compiled pass): unit normal towards the camera and offset."""
    if idx is None:
        idx = np.arange(len(P))
    c, scatter = np.empty(3), np.empty((3, 3))
    _index_scatter(np.ascontiguousarray(P, np.float64), idx, c, scatter)
    return _plane_from_scatter(c, scatter)


@numba.njit(cache=True, nogil=True, inline="always")
def _add_outer3(S, a, b, e):
    """Add the upper triangle of the outer product of (a, b, e) to the 3x3 ``S``."""
    S[0, 0] += a * a
    S[0, 1] += a * b
    S[0, 2] += a * e
    S[1, 1] += b * b
    S[1, 2] += b * e
    S[2, 2] += e * e


@numba.njit(cache=True, nogil=True, inline="always")
def _mirror_upper3(S):
    """Copy the upper triangle of the 3x3 ``S`` into its lower one."""
    S[1, 0], S[2, 0], S[2, 1] = S[0, 1], S[0, 2], S[1, 2]


@numba.njit(cache=True, nogil=True)
def _index_scatter(P, idx, c, scatter):
    """The centroid ``c`` (3,) of the points ``P[idx]`` and their scatter about it (3, 3), in
    two passes (float64)."""
    k = len(idx)
    s0 = s1 = s2 = 0.0
    for i in idx:
        s0 += P[i, 0]
        s1 += P[i, 1]
        s2 += P[i, 2]
    c[0], c[1], c[2] = s0 / k, s1 / k, s2 / k
    scatter[:] = 0.0
    for i in idx:
        _add_outer3(scatter, P[i, 0] - c[0], P[i, 1] - c[1], P[i, 2] - c[2])
    _mirror_upper3(scatter)


def _fit_plane_many(P: np.ndarray):
    """:func:`_fit_plane` for many points (the full-resolution refits): the centroid as a
    matrix-vector product (numpy's column mean of a (k, 3) array is a strided reduction, 4x
    slower) and the centred points as a (3, k) array (subtracting a 3-vector from (k, 3) rows
    is 10x slower); the same plane up to rounding (~1e-16)."""
    c = (np.ones(len(P)) @ P) * (1.0 / len(P))
    Q = P.T - c[:, None]
    return _plane_from_scatter(c, _scatter3(Q))


def _scatter3(Q: np.ndarray) -> np.ndarray:
    """Q Q^T of centred points ``Q`` (3, k) from its six distinct row products (``Q @ Q.T``
    is a rank-k update on 3 rows, 5x slower at k = 16000; the same matrix to ~1e-16
    relative)."""
    q0, q1, q2 = Q
    s01, s02, s12 = q0 @ q1, q0 @ q2, q1 @ q2
    return np.array([[q0 @ q0, s01, s02], [s01, q1 @ q1, s12], [s02, s12, q2 @ q2]])


def _components(sel, grid_rc, grid_shape):
    """The 8-connected region (1, 2, ... in the raster order of their first cell) of each
    point of ``sel`` (indices) on the sample grid (each cell holds at most one point)."""
    return _grid_labels(grid_rc[:, 0], grid_rc[:, 1], np.asarray(sel, np.int64),
                        int(grid_shape[0]), int(grid_shape[1]))


@numba.njit(cache=True, nogil=True)
def _grid_labels(rows, cols, sel, H, W):
    """8-connected regions of the grid cells ``(rows[sel], cols[sel])``, numbered from 1 in
    the raster order of each region's first cell: the label of each point of ``sel``."""
    Hp, Wp = H + 2, W + 2
    pcell = (rows + 1) * Wp + (cols + 1)
    lab = np.empty(len(sel), np.int32)
    _label_cells(pcell, sel, Hp, Wp, np.full(Hp * Wp, -1, np.int32),
                 np.empty(Hp * Wp, np.int32), np.empty(len(sel) + 1, np.int32), lab)
    return lab.astype(np.int64)


@numba.njit(cache=True, nogil=True, inline="always")
def _root(parent, a):
    """The root of ``a`` in the union-find forest ``parent`` (halving the path)."""
    while parent[a] != a:
        parent[a] = parent[parent[a]]
        a = parent[a]
    return a


@numba.njit(cache=True, nogil=True, inline="always")
def _union(parent, a, b):
    """Join the sets of ``a`` and ``b``: the smaller root stays the root."""
    a, b = _root(parent, a), _root(parent, b)
    if a < b:
        parent[b] = a
    elif b < a:
        parent[a] = b


@numba.njit(cache=True, nogil=True)
def _label_cells(pcell, sel, Hp, Wp, img, prov, parent, lab):
    """The 8-connected regions of the points ``sel`` on a grid padded by one cell on every
    side (``Hp`` x ``Wp``; ``pcell`` each point's flat padded cell, at most one point per
    cell): ``lab[:len(sel)]`` their labels from 1 in the raster order of each region's first
    cell; returns the number of regions. Two passes: provisional labels from the four cells
    before each cell in raster order, joined in a union-find forest whose roots are the
    smallest labels (the labels of the regions' first cells), then numbered in order.
    Buffers: ``img`` (Hp Wp,) -1 everywhere on entry and again on return, ``prov`` (Hp Wp,),
    ``parent`` at least ``len(sel)`` long."""
    n = len(sel)
    for j in range(n):
        img[pcell[sel[j]]] = j
    nprov = 0
    for p in range(Wp + 1, (Hp - 1) * Wp - 1):
        if img[p] < 0:
            continue
        # the cell above touches the other three: its label already joins theirs
        if img[p - Wp] >= 0:
            q = prov[p - Wp]
        elif img[p - 1] >= 0:
            q = prov[p - 1]
            if img[p - Wp + 1] >= 0:
                _union(parent, q, prov[p - Wp + 1])
        elif img[p - Wp - 1] >= 0:
            q = prov[p - Wp - 1]
            if img[p - Wp + 1] >= 0:
                _union(parent, q, prov[p - Wp + 1])
        elif img[p - Wp + 1] >= 0:
            q = prov[p - Wp + 1]
        else:
            q = nprov
            parent[q] = q
            nprov += 1
        prov[p] = q
    nlab = 0
    for q in range(nprov):  # (parent[q] < q for every q not a root: numbered before q)
        if parent[q] == q:
            nlab += 1
            parent[q] = -nlab
        else:
            parent[q] = parent[parent[q]]
    for j in range(n):
        c = pcell[sel[j]]
        lab[j] = -parent[prov[c]]
        img[c] = -1
    return nlab


@numba.njit(cache=True, nogil=True)
def _largest_cells(sel, pcell, Hp, Wp, img, prov, parent, lab):
    """The points of ``sel`` in its largest 8-connected region (of equally large ones, the
    one whose first cell comes first in raster order), in the order of ``sel``
    (:func:`_label_cells` and its buffers)."""
    n = len(sel)
    if n == 0:
        return sel[:0].copy()
    nlab = _label_cells(pcell, sel, Hp, Wp, img, prov, parent, lab)
    size = np.zeros(nlab + 1, np.int64)
    for j in range(n):
        size[lab[j]] += 1
    best = 1
    for q in range(2, nlab + 1):
        if size[q] > size[best]:
            best = q
    out = np.empty(size[best], np.int64)
    k = 0
    for j in range(n):
        if lab[j] == best:
            out[k] = sel[j]
            k += 1
    return out


class _GridBuffers:
    """The labelling buffers of a sample grid of ``grid_shape`` with ``m`` points at
    ``grid_rc`` (:func:`_label_cells`), made once per frame."""

    def __init__(self, grid_rc, grid_shape, m):
        self.Hp, self.Wp = int(grid_shape[0]) + 2, int(grid_shape[1]) + 2
        self.pcell = np.ascontiguousarray((grid_rc[:, 0] + 1) * self.Wp + (grid_rc[:, 1] + 1),
                                          np.int64)
        self.img = np.full(self.Hp * self.Wp, -1, np.int32)
        self.prov = np.empty(self.Hp * self.Wp, np.int32)
        self.parent = np.empty(m + 1, np.int32)
        self.lab = np.empty(m, np.int32)

    def args(self):
        return self.pcell, self.Hp, self.Wp, self.img, self.prov, self.parent, self.lab


def _largest_region(sel, grid_rc, grid_shape):
    """The points of ``sel`` (indices) in the largest 8-connected region on the sample grid
    (of equally large ones, the one whose first cell comes first in raster order)."""
    sel = np.asarray(sel, np.int64)
    return _largest_cells(sel, *_GridBuffers(grid_rc, grid_shape, len(grid_rc)).args())


def _cross_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of (N, 3) arrays: the products and differences of
    ``np.cross`` (the same values), without its per-call overhead (3x faster at 200 rows)."""
    a0, a1, a2 = a[:, 0], a[:, 1], a[:, 2]
    b0, b1, b2 = b[:, 0], b[:, 1], b[:, 2]
    out = np.empty(a.shape)
    out[:, 0] = a1 * b2 - a2 * b1
    out[:, 1] = a2 * b0 - a0 * b2
    out[:, 2] = a0 * b1 - a1 * b0
    return out


def _hypotheses(pts, idx, lookup, flat_rc, r, Wp, N, rng):
    """``N`` plane hypotheses (unit normals (k, 3), offsets (k,)) through a random active
    point (indices ``idx``) and two more among the first of 12 random offsets within ``r``
    grid cells that land on active points (``lookup``: the active point at each padded grid
    cell, rows of ``Wp``; ``flat_rc`` each point's cell); global triples when no local one
    is found; None when there is no triple at all."""
    first, off = _local_draws(idx, r, N, rng)
    nrm = np.empty((N, 3))
    dd = np.empty(N)
    ok = np.empty(N, np.bool_)
    k = _local_hypotheses(pts, first, off, lookup, flat_rc, Wp, nrm, dd, ok)
    if k == 0:
        return _global_hypotheses(pts, idx, N, rng)
    return (nrm, dd) if k == N else (nrm[ok], dd[ok])


def _local_draws(idx, r, N, rng):
    """The random draws of ``N`` local hypotheses: a first active point (of ``idx``) each,
    and 12 (row, column) offsets within ``r`` grid cells each."""
    first = idx[rng.integers(0, len(idx), N)]
    return first, rng.integers(-r, r + 1, (N, 12, 2))


def _global_hypotheses(pts, idx, N, rng):
    """``N`` hypotheses through random triples of the active points ``idx`` (when no local
    triple was found): unit normals (k, 3) and offsets (k,) of the non-degenerate ones, or
    None."""
    tri = idx[rng.integers(0, len(idx), (N, 3))]
    p1, p2, p3 = pts[tri[:, 0]], pts[tri[:, 1]], pts[tri[:, 2]]
    nrm = _cross_rows(p2 - p1, p3 - p1)
    ln = np.linalg.norm(nrm, axis=1)
    ok = ln > 1e-9
    if not ok.any():
        return None
    nrm = nrm[ok] / ln[ok, None]
    return nrm, -np.einsum("ij,ij->i", nrm, p1[ok])


@numba.njit(cache=True, nogil=True)
def _local_hypotheses(pts, first, off, lookup, flat_rc, Wp, nrm, dd, ok):
    """The local triples of :func:`_hypotheses` in one compiled pass: per hypothesis h the
    first two of its offsets ``off[h]`` (rows, columns) that are not (0, 0) and land on an
    active point; the unit normal ``nrm[h]`` of the triple with ``first[h]`` and its offset
    ``dd[h]`` (the array code's float64 operations in its order), ``ok[h]`` when both exist
    and the normal is not degenerate (cross product's norm > 1e-9). Returns the number ok."""
    N, T = off.shape[0], off.shape[1]
    nok = 0
    for h in range(N):
        f = first[h]
        base = flat_rc[f]
        j1 = j2 = -1
        for t in range(T):
            o0, o1 = off[h, t, 0], off[h, t, 1]
            if o0 == 0 and o1 == 0:
                continue
            cnd = lookup[base + (o0 * Wp + o1)]
            if cnd < 0:
                continue
            if j1 < 0:
                j1 = cnd
            else:
                j2 = cnd
                break
        ok[h] = False
        if j2 < 0:
            continue
        a0, a1, a2 = pts[j1, 0] - pts[f, 0], pts[j1, 1] - pts[f, 1], pts[j1, 2] - pts[f, 2]
        b0, b1, b2 = pts[j2, 0] - pts[f, 0], pts[j2, 1] - pts[f, 1], pts[j2, 2] - pts[f, 2]
        c0 = a1 * b2 - a2 * b1
        c1 = a2 * b0 - a0 * b2
        c2 = a0 * b1 - a1 * b0
        ln = np.sqrt((c0 * c0 + c1 * c1) + c2 * c2)
        if not ln > 1e-9:
            continue
        c0, c1, c2 = c0 / ln, c1 / ln, c2 / ln
        nrm[h, 0], nrm[h, 1], nrm[h, 2] = c0, c1, c2
        dd[h] = -((c0 * pts[f, 0] + c1 * pts[f, 1]) + c2 * pts[f, 2])
        ok[h] = True
        nok += 1
    return nok


@intrinsic
def _fma32(typingctx, a, b, c):
    """a b + c in float32 with one rounding (LLVM's ``llvm.fma``)."""
    sig = types.float32(types.float32, types.float32, types.float32)

    def codegen(context, builder, signature, args):
        f32 = llvm_ir.FloatType()
        fn = builder.module.declare_intrinsic("llvm.fma", [f32],
                                              llvm_ir.FunctionType(f32, [f32] * 3))
        return builder.call(fn, args)
    return sig, codegen


@intrinsic
def _fma64(typingctx, a, b, c):
    """a b + c in float64 with one rounding (LLVM's ``llvm.fma``)."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        f64 = llvm_ir.DoubleType()
        fn = builder.module.declare_intrinsic("llvm.fma", [f64],
                                              llvm_ir.FunctionType(f64, [f64] * 3))
        return builder.call(fn, args)
    return sig, codegen


@numba.njit(cache=True, nogil=True, inline="always")
def _dist32(n0, n1, n2, a, x, y, z):
    """n . p + a (float32): n0 x, then two fused multiply-adds, then the sum: the operations
    of the float32 matrix product ``N @ P.T`` of OpenBLAS' FMA kernels, plus ``a``."""
    return _fma32(n2, z, _fma32(n1, y, n0 * x)) + a


@numba.njit(cache=True, nogil=True, inline="always")
def _dist64(P, i, n, d):
    """n . P[i] + d (float64) by the operations of numpy's matrix-vector product ``P @ n``
    here (OpenBLAS' FMA kernel for three columns: y n1, then x n0 and z n2 fused in), plus
    ``d``: the same values bit for bit wherever that kernel is the one numpy calls, to
    rounding elsewhere."""
    return _fma64(P[i, 2], n[2], _fma64(P[i, 0], n[0], P[i, 1] * n[1])) + d


@numba.njit(cache=True, nogil=True)
def _inlier_counts(N32, dd, X, Y, Z, L, out):
    """``out[h]`` = the number of points ``i`` with |n_h . p_i + dd[h]| <= L[i] (float32,
    :func:`_dist32`; the points' coordinates as three arrays ``X``, ``Y``, ``Z``, which the
    compiler turns into vector operations), the hypotheses' (N, m) products never stored.
    Returns the first hypothesis with the most."""
    best = 0
    for h in range(N32.shape[0]):
        n0, n1, n2, a = N32[h, 0], N32[h, 1], N32[h, 2], dd[h]
        k = 0
        for i in range(X.shape[0]):
            k += 1 if abs(_dist32(n0, n1, n2, a, X[i], Y[i], Z[i])) <= L[i] else 0
        out[h] = k
        if k > out[best]:
            best = h
    return best


@numba.njit(cache=True, nogil=True)
def _pick(idx, P, n, d, L, scale):
    """The points of ``idx`` with |n . P[i] + d| <= scale L[i] (float64, :func:`_dist64`)."""
    out = np.empty(len(idx), np.int64)
    k = 0
    for i in idx:
        if abs(_dist64(P, i, n, d)) <= scale * L[i]:
            out[k] = i
            k += 1
    return out[:k]


@numba.njit(cache=True, nogil=True)
def _ransac_round(pts, XYZ32, Lp, Lp32, Lr, idx, hn, hd, min_points, active, lookup, flat_rc,
                  mark, pcell, Hp, Wp, img, prov, parent, lab):
    """One round of :func:`find_planes` after its hypotheses ``hn`` (k, 3), ``hd`` (k,): the
    best hypothesis on the active points ``idx`` (counted in float32 on ``XYZ32`` (3, m),
    ``Lp32``), its inliers' largest region, three least-squares refinements (L, L / 2, L),
    and the pool's update: the regions of the points within the removal band ``Lr`` that
    touch the plane's region, and that region, leave ``active`` and ``lookup`` (at their
    cells ``flat_rc``). Returns (found, n, d, the region's points, their centroid, their
    bounding box (row0, row1, col0, col1) on the sample grid); found is False (and the
    pool untouched) when the best hypothesis has fewer than ``min_points`` inliers. ``mark``
    (m,) is all False (and again on return); ``pcell`` ... ``lab``: the grid and buffers of
    :func:`_label_cells` (:class:`_GridBuffers`)."""
    cen, box = np.zeros(3), np.zeros(4, np.int64)
    k = len(idx)
    X, Y, Z = np.empty(k, np.float32), np.empty(k, np.float32), np.empty(k, np.float32)
    Li = np.empty(k, np.float32)
    for j in range(k):
        i = idx[j]
        X[j], Y[j], Z[j], Li[j] = XYZ32[0, i], XYZ32[1, i], XYZ32[2, i], Lp32[i]
    N32 = hn.astype(np.float32)
    dd32 = hd.astype(np.float32)
    counts = np.empty(len(N32), np.int64)
    best = _inlier_counts(N32, dd32, X, Y, Z, Li, counts)
    n = hn[best].copy()
    if counts[best] < min_points:
        return False, n, 0.0, idx[:0].copy(), cen, box
    n0, n1, n2, a = N32[best, 0], N32[best, 1], N32[best, 2], dd32[best]
    sel = np.empty(k, np.int64)
    m = 0
    for j in range(k):
        if abs(_dist32(n0, n1, n2, a, X[j], Y[j], Z[j])) <= Li[j]:
            sel[m] = idx[j]
            m += 1
    inl = _largest_cells(sel[:m], pcell, Hp, Wp, img, prov, parent, lab)
    d = hd[best]
    c, S = np.empty(3), np.empty((3, 3))
    for it in range(3):
        # least squares on the region, then its points within L (L / 2 in the second round)
        if len(inl) < 3:
            break
        _index_scatter(pts, inl, c, S)
        n = _least_eigenvector(S)
        if (n[0] * c[0] + n[1] * c[1]) + n[2] * c[2] > 0:  # towards the camera at the origin
            n = -n
        d = -((n[0] * c[0] + n[1] * c[1]) + n[2] * c[2])
        inl = _largest_cells(_pick(idx, pts, n, d, Lp, 0.5 if it == 1 else 1.0), pcell, Hp,
                             Wp, img, prov, parent, lab)
    # the pool's update: the removal band's regions that touch the plane's region
    loose = _pick(idx, pts, n, d, Lr, 1.0)
    nl = _label_cells(pcell, loose, Hp, Wp, img, prov, parent, lab)
    keep = np.zeros(nl + 1, np.bool_)
    for i in inl:
        mark[i] = True
    for j in range(len(loose)):
        if mark[loose[j]]:
            keep[lab[j]] = True
    for i in inl:
        mark[i] = False
        active[i] = False
        lookup[flat_rc[i]] = -1
    for j in range(len(loose)):
        if keep[lab[j]]:
            active[loose[j]] = False
            lookup[flat_rc[loose[j]]] = -1
    if len(inl) > 0:  # the region's centroid (the sums in order) and bounding box
        box[0], box[2] = (pcell[inl[0]] // Wp) - 1, Wp
        box[1], box[3] = box[0] + 1, 0
        for i in inl:
            cen[0] += pts[i, 0]
            cen[1] += pts[i, 1]
            cen[2] += pts[i, 2]
            rr, cc = pcell[i] // Wp - 1, pcell[i] % Wp - 1
            box[0], box[1] = min(box[0], rr), max(box[1], rr + 1)
            box[2], box[3] = min(box[2], cc), max(box[3], cc + 1)
        cen /= len(inl)
    return True, n, d, inl, cen, box


def find_planes(pts: np.ndarray, grid_rc: np.ndarray, grid_shape, cfg: FrontDetectorConfig,
                rng: np.random.Generator) -> list[Plane]:
    """Sequential RANSAC (5.1.1) on sampled points ``pts`` (m, 3) whose sample-grid positions
    are ``grid_rc`` (m, 2) in a grid of ``grid_shape``; returns up to ``cfg.max_planes``
    planes.

    Each round draws its hypotheses (:func:`_hypotheses`), then scores them, selects,
    refines and removes in one compiled pass (:func:`_ransac_round`)."""
    pts = np.ascontiguousarray(pts, np.float64)
    Lp = np.maximum(cfg.inlier_distance, cfg.inlier_distance_per_m2 * pts[:, 2] ** 2)
    # removal band: L plus (removal_factor - 1) times the noise part of L (a fixed multiple
    # of L would also take a front standing 2 cm proud of its carcass, L = 0.01-0.015 m)
    Lr = Lp + (cfg.removal_factor - 1.0) * cfg.inlier_distance_per_m2 * pts[:, 2] ** 2
    m = len(pts)
    planes: list[Plane] = []
    if m < max(3, cfg.min_plane_points):
        return planes
    active = np.ones(m, bool)
    r = max(1, int(round(cfg.ransac_local_radius_px / cfg.ransac_stride_px)))
    # index of the active point at each grid cell (-1: none), padded by r on every side so
    # that every local offset is a valid (flat) index
    Wp = grid_shape[1] + 2 * r
    lookup = np.full((grid_shape[0] + 2 * r) * Wp, -1, np.int64)
    flat_rc = (grid_rc[:, 0] + r) * Wp + (grid_rc[:, 1] + r)
    lookup[flat_rc] = np.arange(m)
    N = int(cfg.ransac_hypotheses)
    XYZ32 = np.ascontiguousarray(pts.T, np.float32)  # (3, m): the counts' vector operations
    Lp32 = Lp.astype(np.float32)
    grid = _GridBuffers(grid_rc, grid_shape, m).args()
    mark = np.zeros(m, bool)
    min_points = int(cfg.min_plane_points)
    cos5 = math.cos(math.radians(5.0))
    # max_planes counts the planes kept; rounds that only clear the pool (a copy of an earlier
    # plane, a region below min_plane_points) do not take a kept plane's turn, up to
    # 2 x max_planes rounds in all
    for _ in range(2 * int(cfg.max_planes)):
        if len(planes) >= int(cfg.max_planes):
            break
        idx = np.flatnonzero(active)
        if len(idx) < max(3, cfg.min_plane_points):
            break
        hyp = _hypotheses(pts, idx, lookup, flat_rc, r, Wp, N, rng)
        if hyp is None:
            break
        # the best hypothesis' largest connected region of inliers (on the sample grid: other
        # surfaces crossing the infinite plane stay in the pool), refined by least squares,
        # then again on those within L / 2 (a drawer's sides, seen from above, span the few
        # cm between its front and the cabinet face: with them the face's plane tilts towards
        # the front and then takes the front's points out of the pool), then within L. The
        # region's points within the removal band Lr (so that the noise tails of a far plane
        # do not come back as a second copy of it) leave the pool of sampling points.
        found, n, d, inl, cen, box = _ransac_round(pts, XYZ32, Lp, Lp32, Lr, idx, hyp[0], hyp[1],
                                                   min_points, active, lookup, flat_rc, mark,
                                                   *grid)
        if not found:
            break
        if len(inl) < cfg.min_plane_points:
            continue
        Lq = max(cfg.inlier_distance, cfg.inlier_distance_per_m2 * d * d)
        # a copy: (nearly) the same normal and its inliers' centroid within L of an earlier
        # plane (a front standing 2 cm proud of its carcass, L = 0.01 m, is not a copy)
        if any(abs(q.n @ n) > cos5 and abs(q.n @ cen + q.d) < Lq for q in planes):
            continue  # masks cover every pixel of a plane: a second copy adds nothing
        planes.append(Plane(n=n, d=float(d), support=len(inl), bbox=tuple(box.tolist())))
    return planes


@numba.njit(cache=True, nogil=True, inline="always")
def _band_point(Pc, L, r, q, n, d, shrink):
    """Whether pixel (r, q) of ``Pc`` is measured and within ``shrink`` L of the plane
    ``n . p + d = 0``, and its point (float64)."""
    x, y, z = np.float64(Pc[r, q, 0]), np.float64(Pc[r, q, 1]), np.float64(Pc[r, q, 2])
    if not np.isfinite(z):
        return False, x, y, z
    return abs(x * n[0] + y * n[1] + z * n[2] + d) <= shrink * np.float64(L[r, q]), x, y, z


@numba.njit(cache=True, nogil=True, fastmath={"reassoc", "nsz"})
def _band_scatter(Pc, L, R0, R1, C0, C1, step, n, d, shrink, c, scatter):
    """The centroid ``c`` (3,) and the scatter about it ``scatter`` (3, 3) of the measured
    points ``Pc`` (H, W, 3) in rows ``R0:R1`` and columns ``C0:C1`` (every ``step``-th) within
    ``shrink`` L of the plane ``n . p + d = 0`` (float64); returns their number. One pass over
    the crop, nothing gathered: the sums and products of the points relative to the first
    point taken (near the others: no cancellation beyond ~1e-15 relative), centred at the
    end. Every pixel adds its terms, zero when it is not taken, and the sums may be
    reassociated (the compiler's vector operations): the sums of the points in raster order
    to rounding (~1e-16 relative), also the distance of a point within rounding of the band's
    edge."""
    H, W = Pc.shape[0], Pc.shape[1]
    R1, C1 = min(R1, H), min(C1, W)
    nq = max(0, (C1 - C0 + step - 1) // step)
    scatter[:] = 0.0
    r0 = -1  # the row of the first point taken
    x0 = y0 = z0 = 0.0
    for r in range(R0, R1, step):
        for t in range(nq):
            inside, x, y, z = _band_point(Pc, L, r, C0 + t * step, n, d, shrink)
            if inside:
                r0, x0, y0, z0 = r, x, y, z
                break
        if r0 >= 0:
            break
    if r0 < 0:
        return 0
    s0 = s1 = s2 = 0.0
    S00 = S01 = S02 = S11 = S12 = S22 = 0.0
    k = 0
    n0, n1, n2 = n[0], n[1], n[2]
    for r in range(r0, R1, step):
        for t in range(nq):
            q = C0 + t * step
            x, y, z = np.float64(Pc[r, q, 0]), np.float64(Pc[r, q, 1]), np.float64(Pc[r, q, 2])
            # (an unmeasured pixel's NaN fails the test)
            inside = abs(x * n0 + y * n1 + z * n2 + d) <= shrink * np.float64(L[r, q])
            a = x - x0 if inside else 0.0
            b = y - y0 if inside else 0.0
            e = z - z0 if inside else 0.0
            s0 += a
            s1 += b
            s2 += e
            S00 += a * a
            S01 += a * b
            S02 += a * e
            S11 += b * b
            S12 += b * e
            S22 += e * e
            k += 1 if inside else 0
    m0, m1, m2 = s0 / k, s1 / k, s2 / k
    c[0], c[1], c[2] = x0 + m0, y0 + m1, z0 + m2
    scatter[0, 0] = S00 - s0 * m0
    scatter[0, 1] = S01 - s0 * m1
    scatter[0, 2] = S02 - s0 * m2
    scatter[1, 1] = S11 - s1 * m1
    scatter[1, 2] = S12 - s1 * m2
    scatter[2, 2] = S22 - s2 * m2
    _mirror_upper3(scatter)
    return k


def refine_plane_fullres(pl: Plane, Pc, Lmap, stride, off, max_points=20000) -> Plane:
    """Least-squares refit of a plane on the full-resolution pixels within L of it inside the
    bounding box of its sampled region (every pixel for small planes, a regular subset of at
    most ``max_points`` for large ones); two rounds, the second on the pixels within L / 2 of
    the first fit (keeps a handle or an edge strip from tilting a small front's plane). The
    centroid and scatter of the selected pixels are summed in one compiled pass per round
    (:func:`_band_scatter`). The plane itself when a round keeps fewer than 10 pixels or
    turns the normal by more than 10 deg. One plane of :func:`refine_planes_fullres`."""
    return refine_planes_fullres([pl], Pc, Lmap, stride, off, max_points)[0]


def refine_planes_fullres(planes, Pc, Lmap, stride, off, max_points=20000) -> list[Plane]:
    """:func:`refine_plane_fullres` of every plane of ``planes``, all in one compiled call
    (:func:`_refine_kernel`)."""
    k = len(planes)
    if k == 0:
        return []
    N0 = np.array([pl.n for pl in planes], np.float64).reshape(k, 3)
    D0 = np.array([pl.d for pl in planes], np.float64)
    boxes = np.array([pl.bbox for pl in planes], np.int64).reshape(k, 4)
    N, D = np.empty((k, 3)), np.empty(k)
    moved = _refine_kernel(Pc, Lmap, boxes, int(stride), int(off), float(max_points), N0, D0,
                           math.cos(math.radians(10.0)), N, D)
    return [Plane(n=N[i].copy(), d=float(D[i]), support=pl.support, bbox=pl.bbox)
            if moved[i] else pl for i, pl in enumerate(planes)]


@numba.njit(cache=True, nogil=True)
def _refine_kernel(Pc, L, boxes, stride, off, max_points, N0, D0, cos_lim, N, D):
    """The two refit rounds of :func:`refine_plane_fullres` for each plane (normals ``N0``,
    offsets ``D0``, sample-grid boxes ``boxes``): the refitted planes into ``N``, ``D``;
    returns per plane whether it was refitted (else it stays as it was). The crop, its step
    and the tests of the array code, the same float operations."""
    H, W = Pc.shape[0], Pc.shape[1]
    k = len(D0)
    moved = np.zeros(k, np.bool_)
    c, S = np.empty(3), np.empty((3, 3))
    for p in range(k):
        r0, r1, c0, c1 = boxes[p, 0], boxes[p, 1], boxes[p, 2], boxes[p, 3]
        R0, R1 = max(0, off + stride * r0 - stride), min(off + stride * r1 + stride, H)
        C0, C1 = max(0, off + stride * c0 - stride), min(off + stride * c1 + stride, W)
        area = max(0, R1 - R0) * max(0, C1 - C0)
        step = max(1, int(math.ceil(math.sqrt(area / max_points))))
        n0 = N0[p]
        n, d = n0.copy(), D0[p]
        ok = True
        for shrink in (1.0, 0.5):
            if _band_scatter(Pc, L, R0, R1, C0, C1, step, n, d, shrink, c, S) < 10:
                ok = False
                break
            v = _least_eigenvector(S)
            if (v[0] * c[0] + v[1] * c[1]) + v[2] * c[2] > 0:  # towards the camera
                v = -v
            d2 = -((v[0] * c[0] + v[1] * c[1]) + v[2] * c[2])
            if (v[0] * n0[0] + v[1] * n0[1]) + v[2] * n0[2] < cos_lim:
                ok = False
                break
            n, d = v, d2
        if ok:
            N[p, 0], N[p, 1], N[p, 2], D[p] = n[0], n[1], n[2], d
            moved[p] = True
    return moved
