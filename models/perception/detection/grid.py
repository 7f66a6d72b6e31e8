"""Stage ``masks``, rectified grids: a plane's label image resampled onto a metric grid in the
plane (one nearest-neighbour perspective warp), its axes along the dominant edge direction and
gravity, with the summed-area tables of the costs and of the in-plane cells (Eq. 5.3-5.5 as four
look-ups per rectangle)."""

import math
from dataclasses import dataclass

import cv2
import numba
import numpy as np

from mmlearn.models.common.camera import PinholeIntrinsics
from mmlearn.models.perception.detection.labels import GAP, IN_PLANE, OUTSIDE, UNKNOWN
from mmlearn.models.perception.detection.planes import Plane


@dataclass
class _Grid:
    """A plane's rectified label grid: cell (row i, col j) is the plane point
    ``o + (u0 + (j + 0.5) c) e1 + (v0 + (i + 0.5) c) e2`` (camera frame)."""

    plane_index: int
    n: np.ndarray
    d: float
    o: np.ndarray
    e1: np.ndarray
    e2: np.ndarray
    u0: float
    v0: float
    c: float
    labels: np.ndarray
    sat_cost: np.ndarray
    sat_in: np.ndarray
    sat_gap: tuple | None = None  # (GAP, UNKNOWN) summed-area tables: gap_sats()

    @property
    def shape(self):
        return self.labels.shape

    def gap_sats(self) -> tuple:
        """The summed-area tables (int32) of the ``GAP`` and the ``UNKNOWN`` cells of
        ``labels``, made on first use (:func:`_gap_bounded`)."""
        if self.sat_gap is None:
            self.sat_gap = _sats_gap(self.labels)
        return self.sat_gap


def _plane_axes(n: np.ndarray, down_C: np.ndarray | None):
    """In-plane axes (e1, e2) with e1 x e2 = n: e2 along gravity ("down") projected onto the
    plane, or, for a (near) horizontal plane or unknown gravity, e1 along the camera x axis."""
    # (norms as the square root of the dot product and cross products written out: what
    # np.linalg.norm and np.cross compute, the same float operations, without their ~30 us
    # of call overhead)
    if down_C is not None:
        g = down_C - (down_C @ n) * n
        ng = math.sqrt(g @ g)
        if ng > 0.5:  # plane tilted less than 60 deg from vertical
            e2 = g / ng
            return _cross3(e2, n), e2
    x = np.array([1.0, 0.0, 0.0]) - n[0] * n
    nx = math.sqrt(x @ x)
    if nx < 1e-6:
        x = np.array([0.0, 1.0, 0.0]) - n[1] * n
        nx = math.sqrt(x @ x)
    e1 = x / nx
    return e1, _cross3(n, e1)


def _cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b of two 3-vectors (float64): the products and differences of np.cross, in the
    same order, on Python floats."""
    a0, a1, a2 = a.tolist()
    b0, b1, b2 = b.tolist()
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def _rotate_axes(e1, e2, theta):
    c, s = math.cos(theta), math.sin(theta)
    return c * e1 + s * e2, -s * e1 + c * e2


def _grid_homography(K: PinholeIntrinsics, o, e1, e2, u0, v0, c, cb):
    """(M, A, H) of a plane grid (see :func:`_warp_labels`): M = [e1 e2 o] (3 x 3), A the
    grid cell -> plane coordinates (cells ``c`` x ``cb``, m, from (u0, v0)), H = K M A the
    cell -> pixel homography (the same products as before, with the intrinsics' matrix made
    once per camera and M filled in place: ~10 us less per warp, ~100 warps per frame)."""
    Km = _K_MATRICES.get(K)
    if Km is None:
        if len(_K_MATRICES) > 64:
            _K_MATRICES.clear()
        Km = _K_MATRICES[K] = np.array([[K.fx, 0, K.cx], [0, K.fy, K.cy], [0, 0, 1.0]])
    A = np.array([[c, 0, u0 + 0.5 * c], [0, cb, v0 + 0.5 * cb], [0, 0, 1.0]])
    M = np.empty((3, 3))
    M[:, 0], M[:, 1], M[:, 2] = e1, e2, o
    return M, A, Km @ M @ A


_K_MATRICES: dict = {}  # intrinsics -> their 3 x 3 matrix (read-only; K is hashable, frozen)


def _warp_labels(labels_img, K: PinholeIntrinsics, o, e1, e2, u0, v0, c, shape, cb=None,
                 outside=OUTSIDE):
    """Nearest-neighbour resampling of the image label mask onto a plane grid (cells ``c``
    along e1 and ``cb`` (default ``c``) along e2, m); cells that do not project into the
    image (or lie behind the camera) are OUTSIDE. Any uint8 image of per-pixel values works
    (a cost image ``lut[labels]``: then ``outside`` = ``lut[OUTSIDE]``, and the result is
    ``lut`` of the label grid: nearest neighbour only selects pixels)."""
    Hg, Wg = shape
    M, A, H = _grid_homography(K, o, e1, e2, u0, v0, c, c if cb is None else cb)
    out = cv2.warpPerspective(labels_img, H, (int(Wg), int(Hg)),
                              flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP,
                              borderMode=cv2.BORDER_CONSTANT, borderValue=int(outside))
    # depth of each cell is affine in (i, j): mask cells behind (or too close to) the camera
    zc = (M @ A)[2]  # z = zc[0] j + zc[1] i + zc[2]
    # affine: its least value over the grid is at a corner (most grids need no mask)
    if zc[2] + min(0.0, zc[0] * (Wg - 1)) + min(0.0, zc[1] * (Hg - 1)) < 0.05:
        jj = np.arange(Wg, dtype=np.float64)
        ii = np.arange(Hg, dtype=np.float64)
        z = zc[0] * jj[None, :] + zc[1] * ii[:, None] + zc[2]
        out[z < 0.05] = outside
    return out


def _warp_float(img, K, o, e1, e2, u0, v0, c, shape, cb=None, outside=float("nan")):
    """Like :func:`_warp_labels` for a float32 image (nearest neighbour; ``outside`` (NaN by
    default) where the cells leave the image; cells behind the camera are not masked)."""
    Hg, Wg = shape
    H = _grid_homography(K, o, e1, e2, u0, v0, c, c if cb is None else cb)[2]
    return cv2.warpPerspective(img, H, (int(Wg), int(Hg)),
                               flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP,
                               borderMode=cv2.BORDER_CONSTANT, borderValue=float(outside))


def _edge_tables():
    """Per Sobel gradient (gx, gy) of a 0 / 1 image (integers in -4..4; index (gx + 4) 9 +
    (gy + 4)): its magnitude (float32) and magnitude x exp(4 i phi) (complex64), by the
    numpy operations of the edge angle on arrays (the same values element by element)."""
    g = np.arange(-4, 5, dtype=np.float32)
    gx, gy = (a.ravel() for a in np.meshgrid(g, g, indexing="ij"))
    mag = np.hypot(gx, gy)
    return mag, mag * np.exp(4j * np.arctan2(gy, gx))


_EDGE_MAG, _EDGE_ROT4 = _edge_tables()


@numba.njit(cache=True, nogil=True)
def _edge_codes(u8, code):
    """The edge cells of a 0 / 1 grid ``u8`` (uint8) in raster order: their codes
    (gx + 4) 9 + (gy + 4) into ``code`` (int64, at least the grid's size) from OpenCV's 3 x 3
    Sobel gradients (``cv2.Sobel(u8, cv2.CV_16S, 1, 0)`` and ``(0, 1)``, its default border
    reflected about the edge cell, exact integers) of the cells where they are not both 0.
    Returns their number."""
    H, W = u8.shape
    n = 0
    for r in range(H):
        ru = r - 1 if r > 0 else (1 if H > 1 else 0)
        rd = r + 1 if r < H - 1 else (H - 2 if H > 1 else 0)
        a, b, e = u8[ru], u8[r], u8[rd]
        for c in range(W):
            cl = c - 1 if c > 0 else (1 if W > 1 else 0)
            cr = c + 1 if c < W - 1 else (W - 2 if W > 1 else 0)
            gx = (np.int64(a[cr]) + 2 * np.int64(b[cr]) + np.int64(e[cr])) - (
                np.int64(a[cl]) + 2 * np.int64(b[cl]) + np.int64(e[cl]))
            gy = (np.int64(e[cl]) + 2 * np.int64(e[c]) + np.int64(e[cr])) - (
                np.int64(a[cl]) + 2 * np.int64(a[c]) + np.int64(a[cr]))
            if gx != 0 or gy != 0:
                code[n] = gx * 9 + gy + 40
                n += 1
    return n


def _edge_angle(inplane: np.ndarray) -> float:
    """Dominant direction (mod 90 deg) of the edges of a binary in-plane grid, radians in
    (-pi/4, pi/4]: the argument of the magnitude-weighted mean of exp(4 i phi) / 4. The
    Sobel gradients of a 0 / 1 grid are small integers: each edge cell's magnitude and
    weighted exp(4 i phi) are looked up (:func:`_edge_tables`), then summed as before."""
    u8 = inplane.view(np.uint8) if inplane.dtype == bool else inplane.astype(np.uint8)
    # on the edge cells only (gradient not 0: the magnitude is > 0 exactly there), in
    # raster order (one compiled pass: :func:`_edge_codes`)
    code = np.empty(u8.size, np.int64)
    n = _edge_codes(np.ascontiguousarray(u8), code)
    if n < 8:
        return 0.0
    code = code[:n]
    mag = _EDGE_MAG[code]
    z = np.sum(_EDGE_ROT4[code])
    if abs(z) < 1e-6 * mag.sum():
        return 0.0
    return float(np.angle(z) / 4.0)


def _sats(labels: np.ndarray, lut: np.ndarray):
    """The summed-area tables (int32) of a label grid's cost x 255 (``lut``: label -> cost x
    255, uint8; costs are quantised to 1/255 as in the original code) and of its in-plane
    indicator, both in one compiled pass (:func:`_sats_kernel`: OpenCV's integrals' values)."""
    H, W = labels.shape
    sc = np.empty((H + 1, W + 1), np.int32)
    si = np.empty((H + 1, W + 1), np.int32)
    _sats_kernel(np.ascontiguousarray(labels, np.uint8), np.ascontiguousarray(lut, np.uint8),
                 sc, si)
    return sc, si


@numba.njit(cache=True, nogil=True)
def _sats_kernel(labels, lut, sc, si):
    """The summed-area tables (int32, a zero first row and column, as ``cv2.integral``) of
    ``lut[labels]`` into ``sc`` and of the IN_PLANE indicator into ``si``: each row's running
    sums added to the row above (exact integers)."""
    H, W = labels.shape
    for c in range(W + 1):
        sc[0, c] = 0
        si[0, c] = 0
    for r in range(H):
        lr, up_c, up_i, oc, oi = labels[r], sc[r], si[r], sc[r + 1], si[r + 1]
        oc[0] = 0
        oi[0] = 0
        a = np.int32(0)
        b = np.int32(0)
        for c in range(W):
            v = lr[c]
            a += np.int32(lut[v])
            b += np.int32(v == IN_PLANE)
            oc[c + 1] = up_c[c + 1] + a
            oi[c + 1] = up_i[c + 1] + b


def _sats_gap(labels):
    """Summed-area tables (int32) of the GAP and the UNKNOWN cells of a label grid."""
    return (cv2.integral((labels == GAP).view(np.uint8), sdepth=cv2.CV_32S),
            cv2.integral((labels == UNKNOWN).view(np.uint8), sdepth=cv2.CV_32S))


def _median(a: np.ndarray) -> float:
    """``np.median`` of a finite 1-D float64 or float32 array (the same value: the middle
    element, or the mean of the two middle ones in the array's type), by one partition
    without np.median's overhead (~35 us a call, ~20 calls a frame in the grids, a few in
    the offset layers)."""
    n = len(a)
    h = n // 2
    if n % 2:
        return np.partition(a, h)[h]
    p = np.partition(a, (h - 1, h))
    return (p[h - 1] + p[h]) / 2.0


@numba.njit(cache=True, nogil=True)
def _column_means(a):
    """``a.mean(axis=0)`` of a (n, 3) float64 array (the same values: numpy sums the rows one
    after another along that axis, then divides by n) without its overhead (~40 us)."""
    n, m = a.shape
    s = np.zeros(m)
    for i in range(n):
        for j in range(m):
            s[j] += a[i, j]
    return s / n


def _make_grid(k, plane: Plane, lab_img, sample_pts, K, down_C, cfg, lut) -> _Grid | None:
    n, d = plane.n, plane.d
    Lp = np.maximum(cfg.inlier_distance, cfg.inlier_distance_per_m2 * sample_pts[:, 2] ** 2)
    inl = np.compress(np.abs(sample_pts @ n + d) <= Lp, sample_pts, axis=0)  # (5x P[mask])
    if len(inl) < 3:
        return None
    o = _column_means(inl)
    o = o - (o @ n + d) * n
    e1, e2 = _plane_axes(n, down_C)
    rel = inl - o  # (the same for both extents)

    def extent(e1, e2):
        a = rel @ e1
        b = rel @ e2
        pad = 0.1
        half = 0.5 * cfg.max_plane_extent
        am, bm = _median(a), _median(b)
        lo_a, hi_a = max(a.min(), am - half) - pad, min(a.max(), am + half) + pad
        lo_b, hi_b = max(b.min(), bm - half) - pad, min(b.max(), bm + half) + pad
        return lo_a, hi_a, lo_b, hi_b

    def shape_of(lo_a, hi_a, lo_b, hi_b, c):
        return (max(1, int(math.ceil((hi_b - lo_b) / c))),
                max(1, int(math.ceil((hi_a - lo_a) / c))))

    # dominant edge direction on a grid of twice the cell size (a quarter of the cells)
    lo_a, hi_a, lo_b, hi_b = extent(e1, e2)
    c = max(cfg.cell_size, max(hi_a - lo_a, hi_b - lo_b) / cfg.max_grid_cells)
    coarse = _warp_labels(lab_img, K, o, e1, e2, lo_a, lo_b, 2 * c,
                          shape_of(lo_a, hi_a, lo_b, hi_b, 2 * c))
    theta = _edge_angle(coarse == IN_PLANE)
    if theta != 0.0:
        e1, e2 = _rotate_axes(e1, e2, theta)
        lo_a, hi_a, lo_b, hi_b = extent(e1, e2)
        c = max(cfg.cell_size, max(hi_a - lo_a, hi_b - lo_b) / cfg.max_grid_cells)
    lab0 = _warp_labels(lab_img, K, o, e1, e2, lo_a, lo_b, c, shape_of(lo_a, hi_a, lo_b, hi_b, c))
    sat_cost, sat_in = _sats(lab0, lut)
    return _Grid(k, n, d, o, e1, e2, lo_a, lo_b, c, lab0, sat_cost, sat_in)


def _rect_camera(g: _Grid, R, e1=None, e2=None, u0=None, v0=None, c=None):
    """Centre (camera frame), axes and size of a grid rectangle."""
    e1 = g.e1 if e1 is None else e1
    e2 = g.e2 if e2 is None else e2
    u0 = g.u0 if u0 is None else u0
    v0 = g.v0 if v0 is None else v0
    c = g.c if c is None else c
    x0, x1, y0, y1 = (float(v) for v in R)
    a = u0 + 0.5 * (x0 + x1) * c
    b = v0 + 0.5 * (y0 + y1) * c
    return g.o + a * e1 + b * e2, e1, e2, (x1 - x0) * c, (y1 - y0) * c
