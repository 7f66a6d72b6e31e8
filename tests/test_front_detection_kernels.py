"""The detector's compiled passes against the array code they replace: the same regions,
planes, ramps, refits, bent-window tests, window means and reveal lines (to rounding, or bit
for bit) on random inputs."""

import math

import cv2
import numpy as np
import pytest
from plane_reference import svd_plane

from mmlearn.models.perception.detection import Plane
from mmlearn.models.perception.detection.check import _refit_plane
from mmlearn.models.perception.detection.gaps import (_bent_windows, _box_rows, _line_blocks,
                                                      _line_hits_kernel,
                                                      _long_runs, _stretch_at, _window_means)
from mmlearn.models.perception.detection.labels import (IN_PLANE, OCCLUDED, OFF_SURFACE,
                                                        _affine_lstsq, _broadcast_rows,
                                                        _mark_off_surface, _plane_label_kernel,
                                                        _ramp_fit, _ramp_fit_lstsq,
                                                        _refit_on_own_pixels,
                                                        _shared_in_plane, _surface_deviation)
from mmlearn.models.perception.detection.planes import (_components, _fit_plane, _inlier_counts,
                                                        _fit_plane_many,
                                                        _largest_region, refine_plane_fullres)
from mmlearn.models.common.camera import PinholeIntrinsics

K = PinholeIntrinsics.from_fov(640, 480, 58.0)



@pytest.mark.parametrize("seed", [0, 1, 2])
def test_grid_regions_are_opencv_s_8_connected_components(seed):
    """The same partition as OpenCV's (numbered from 1 in the raster order of each region's
    first cell); the largest region is the largest."""
    rng = np.random.default_rng(seed)
    H, W = 30, 40
    rc = np.column_stack([a.ravel() for a in np.mgrid[0:H, 0:W]])
    sel = np.flatnonzero(rng.random(len(rc)) < 0.45)
    img = np.zeros((H, W), np.uint8)
    img[rc[sel, 0], rc[sel, 1]] = 1
    _, ref = cv2.connectedComponents(img, connectivity=8)
    lab = _components(sel, rc, (H, W))
    ref = ref[rc[sel, 0], rc[sel, 1]]
    pairs = set(zip(lab.tolist(), ref.tolist()))
    assert len(pairs) == len(set(lab.tolist())) == len(set(ref.tolist()))  # a bijection
    first = [int(np.flatnonzero(lab == k)[0]) for k in range(1, lab.max() + 1)]
    assert first == sorted(first)  # (sel is in raster order)
    big = _largest_region(sel, rc, (H, W))
    sizes = np.bincount(ref)
    assert len(big) == sizes.max()


def test_least_squares_planes_match_the_svd():
    rng = np.random.default_rng(3)
    n0 = np.array([0.1, -0.3, -1.0])
    n0 /= np.linalg.norm(n0)
    xy = rng.uniform(-0.5, 0.5, (500, 2))
    z = (1.5 - n0[0] * xy[:, 0] - n0[1] * xy[:, 1]) / n0[2] * -1.0
    P = np.column_stack([xy, z]) + rng.normal(0, 0.002, (500, 3))
    idx = np.flatnonzero(rng.random(500) < 0.5)
    n, d = _fit_plane(P, idx)
    n_ref, d_ref = svd_plane(P[idx])
    assert np.allclose(n, n_ref, atol=1e-10) and abs(d - d_ref) < 1e-10


def test_full_resolution_refit_matches_the_gathered_pixels():
    """A tilted wall 2 m away with a box 10 cm in front of part of it: the refit uses the
    pixels within L, then L / 2, of the fits, as the gathered-array version does."""
    rng = np.random.default_rng(4)
    v, u = np.mgrid[0:480, 0:640].astype(np.float64)
    x, y = (u - K.cx) / K.fx, (v - K.cy) / K.fy
    n_true = np.array([0.2, 0.05, -1.0]) / np.linalg.norm([0.2, 0.05, -1.0])
    z = 2.0 / -(n_true[0] * x + n_true[1] * y + n_true[2])  # n . p + 2 = 0
    z += rng.normal(0, 0.004, z.shape)
    z[100:200, 300:420] -= 0.1
    z[rng.random(z.shape) < 0.02] = np.nan
    Pc = np.dstack([x * z, y * z, z]).astype(np.float32)
    L = np.maximum(0.02, 0.004 * np.nan_to_num(z) ** 2).astype(np.float32)
    start = Plane(n=n_true + np.array([0.01, 0.0, 0.0]), d=2.0, support=4000,
                  bbox=(0, 60, 0, 80))
    start.n = start.n / np.linalg.norm(start.n)
    got = refine_plane_fullres(start, Pc, L, 8, 4, max_points=20000)
    # the reference: the gathered pixels of the same regular subset
    step = int(math.ceil(math.sqrt(480 * 640 / 20000)))
    P = Pc[::step, ::step].reshape(-1, 3).astype(np.float64)
    Ls = L[::step, ::step].reshape(-1).astype(np.float64)
    ok = np.isfinite(P[:, 2])
    P, Ls = P[ok], Ls[ok]
    n, d = start.n, start.d
    for shrink in (1.0, 0.5):
        sel = np.abs(P @ n + d) <= shrink * Ls
        n, d = svd_plane(P[sel])
    assert np.allclose(got.n, n, atol=1e-9) and abs(got.d - d) < 1e-9
    assert math.degrees(math.acos(min(1.0, got.n @ n_true))) < 0.2


@pytest.mark.parametrize("seed", [0, 1])
def test_surface_ramp_fit_matches_the_array_fit(seed):
    """The trimmed ramp of the surface check: the compiled fit equals the array code's on a
    noisy ramp with a strip of outliers and holes; points on one line defer to lstsq."""
    rng = np.random.default_rng(seed)
    H, W = 90, 130
    yy, xx = np.mgrid[0:H, 0:W]
    S = (1e-4 * xx - 2e-4 * yy + 0.003 + rng.normal(0, 0.001, (H, W))).astype(np.float32)
    S[:, 60:66] += 0.02
    m8 = np.where(rng.random((H, W)) < 0.8, 255, 0).astype(np.uint8)
    Lm = np.full((H, W), 0.003, np.float32)
    coef = np.empty(3)
    assert _ramp_fit(S, m8, Lm, coef) == 1
    ref = _ramp_fit_lstsq(S, m8 > 0, Lm)
    assert np.allclose(coef, ref, rtol=1e-9, atol=1e-13)
    line = np.zeros((H, W), np.uint8)
    line[8, :] = 255  # one row of samples: the 2 x 2 system is singular
    assert _ramp_fit(S, line, Lm, coef) == -1
    empty = np.zeros((H, W), np.uint8)
    assert _ramp_fit(S, empty, Lm, coef) == 0


@pytest.mark.parametrize("with_ramp", [True, False])
def test_surface_deviation_and_marks_match_the_array_expressions(with_ramp):
    """The surface check's deviation from the ramp and its OFF_SURFACE marks, on a box of
    the images at an offset: bit for bit the float32 array expressions (and nothing written
    outside the box)."""
    rng = np.random.default_rng(3)
    H, W, y0, x0, h, w = 70, 90, 5, 7, 50, 61
    S = rng.normal(0, 0.01, (H, W)).astype(np.float32)
    m8 = np.where(rng.random((H, W)) < 0.7, 255, 0).astype(np.uint8)
    a, b, c = np.float32(3e-4), np.float32(-2e-4), np.float32(0.002)
    dev = np.empty((h, w), np.float32)
    _surface_deviation(S, m8, y0, x0, a, b, c, with_ramp, dev)
    Sb, mb = S[y0:y0 + h, x0:x0 + w], m8[y0:y0 + h, x0:x0 + w] > 0
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    ramp = (a * xx + b * yy) + c if with_ramp else np.float32(0.0)
    ref = (Sb - ramp) * mb.astype(np.float32)
    assert np.array_equal(dev, ref)
    num = cv2.boxFilter(dev, -1, (5, 5), normalize=False)
    den = cv2.boxFilter(mb.view(np.uint8), cv2.CV_32F, (5, 5), normalize=False)
    Lm = rng.uniform(0.002, 0.02, (H, W)).astype(np.float32)
    lab = rng.integers(0, 4, (H, W)).astype(np.uint8)
    want = lab.copy()
    hit = mb & (np.abs(num) > den * Lm[y0:y0 + h, x0:x0 + w])
    assert hit.any() and not hit.all()
    want[y0:y0 + h, x0:x0 + w][hit] |= np.uint8(OFF_SURFACE)
    _mark_off_surface(num, den, Lm, m8, y0, x0, lab)
    assert np.array_equal(lab, want)


@pytest.mark.parametrize("full_rows", [False, True])
def test_plane_labels_match_the_array_expression(full_rows):
    """A plane's signed distances (n . ray) d + dpl and Eq. 5.2 labels: bit for bit the
    float32 array expressions, with n1 y given per row or per pixel."""
    from mmlearn.models.perception.detection.labels import FREE, UNKNOWN
    rng = np.random.default_rng(4)
    H, W = 37, 53
    valid = rng.random((H, W)) < 0.9
    d = np.where(valid, rng.uniform(0.5, 3.0, (H, W)), 0.0).astype(np.float32)
    L = rng.uniform(0.005, 0.03, (H, W)).astype(np.float32)
    xs = np.linspace(-0.5, 0.5, W, dtype=np.float32)[None, :]
    ys = np.linspace(-0.4, 0.4, H, dtype=np.float32)[:, None]
    n, dpl = np.array([0.1, -0.2, -0.97], np.float32), np.float32(1.6)
    ax = _broadcast_rows(n[0] * xs + n[2], d.shape)
    by = _broadcast_rows((n[1] * ys).T, d.shape[::-1]).T
    if full_rows:
        by = np.ascontiguousarray(np.broadcast_to(by, (H, W)))
    S = np.empty((H, W), np.float32)
    lab = np.empty((H, W), np.uint8)
    _plane_label_kernel(ax, by, d, valid, L, dpl, S, lab)
    ref = (ax + by) * d + dpl
    assert np.array_equal(S, ref)
    want = np.where(ref < -L, FREE, np.where(ref > L, OCCLUDED, IN_PLANE))
    want = np.where(valid, want, UNKNOWN).astype(np.uint8)
    assert len(np.unique(want)) == 4 and np.array_equal(lab, want)


@pytest.mark.parametrize("horizontal", [True, False])
def test_line_blocks_are_opencv_s_area_resize(horizontal):
    """The reveals' block means of 4 pixels along the lines (rows or columns; a number of
    blocks that is no multiple of the column tiles): bit for bit OpenCV's INTER_AREA resize
    by 4 of the depth and of the measured share, rows across the lines."""
    rng = np.random.default_rng(5)
    H, W = 150, 93
    valid = rng.random((H, W)) < 0.8
    z = np.where(valid, rng.uniform(0.5, 3.0, (H, W)), 0.0).astype(np.float32)
    Hc, Wc = H - H % 4, W - W % 4
    A, N, V = _line_blocks(z, valid, None, horizontal, Hc, Wc)
    assert V is None
    vf = valid.astype(np.float32)
    if horizontal:
        ref = [cv2.resize(x[:, :Wc], (Wc // 4, H), interpolation=cv2.INTER_AREA) for x in (z, vf)]
    else:
        ref = [cv2.resize(x[:Hc], (W, Hc // 4), interpolation=cv2.INTER_AREA).T for x in (z, vf)]
    assert A.shape == ref[0].shape and np.array_equal(A, ref[0])
    assert np.array_equal(N, ref[1])


@pytest.mark.parametrize("P", [3, 20])
def test_shared_in_plane_pixels_match_the_array_code(P):
    """The pixels in-plane for several planes and each plane's in-plane flags there: the
    flat indices of the in-plane counts above 1 and the images gathered at them (bits of
    16 and of 64 bits)."""
    rng = np.random.default_rng(P)
    stack = rng.choice(np.uint8([IN_PLANE, 1, OCCLUDED, 3]), (P, 31, 47),
                       p=[1.5 / P, 0.5, 0.5 - 1.5 / P, 0.0])
    bits = np.empty(31 * 47, np.uint16 if P <= 16 else np.uint64)
    pows = (np.uint64(1) << np.arange(P, dtype=np.uint64)).astype(bits.dtype)
    shared, near = _shared_in_plane(stack.reshape(P, -1), pows, bits)
    count = (stack == IN_PLANE).sum(axis=0).reshape(-1)
    want = np.flatnonzero(count > 1)
    assert len(want) > 5 and np.array_equal(shared, want)
    assert np.array_equal(near, stack.reshape(P, -1)[:, want] == IN_PLANE)


def test_median_is_numpy_s_median():
    """The one-partition median of the grids and offset layers: np.median's value for float32
    and float64 arrays of odd and even length, strided columns too."""
    from mmlearn.models.perception.detection.grid import _median
    rng = np.random.default_rng(6)
    for dtype in (np.float32, np.float64):
        for n in (1, 2, 5, 6, 999, 1000):
            a = rng.uniform(0.5, 3.0, (n, 3)).astype(dtype)
            for x in (a[:, 0], np.ascontiguousarray(a[:, 2])):
                got, want = _median(x), np.median(x)
                assert got == want and np.asarray(got).dtype == np.asarray(want).dtype


def test_grid_origin_mean_is_numpy_s_mean():
    """The grids' origin: the inlier points' column means, bit for bit ``mean(axis=0)``."""
    from mmlearn.models.perception.detection.grid import _column_means
    rng = np.random.default_rng(7)
    for n in (1, 3, 1000, 4097):
        a = rng.normal(0.0, 2.0, (n, 3)) + rng.normal(0.0, 3.0, 3)
        assert np.array_equal(_column_means(a), a.mean(axis=0))


def test_affine_lstsq_matches_numpy():
    rng = np.random.default_rng(5)
    A = np.column_stack([rng.uniform(0, 50, 40), rng.uniform(0, 50, 40), np.ones(40)])
    b = A @ np.array([0.1, -0.2, 3.0]) + rng.normal(0, 0.01, 40)
    assert np.allclose(_affine_lstsq(A, b), np.linalg.lstsq(A, b, rcond=None)[0], atol=1e-10)


def test_rectangle_refit_uses_the_in_plane_pixels_inside_the_shrunk_rectangle():
    """A front 1.2 m away, tilted 10 deg about the vertical, with a hole and a strip of
    another label: the refit equals the SVD plane of the in-plane pixels whose offset to the
    centre lies within 45 % of the width and height."""
    rng = np.random.default_rng(6)
    a = math.radians(10.0)
    n_true = np.array([math.sin(a), 0.0, -math.cos(a)])
    v, u = np.mgrid[0:480, 0:640].astype(np.float64)
    x, y = (u - K.cx) / K.fx, (v - K.cy) / K.fy
    z = 1.2 / -(n_true[0] * x + n_true[2])
    z += rng.normal(0, 0.002, z.shape)
    Pc = np.dstack([x * z, y * z, z]).astype(np.float32)
    lab = np.zeros((480, 640), np.uint8)
    lab[200:260, 280:300] = 3
    center = -1.2 * n_true
    e1 = np.cross([0.0, 1.0, 0.0], n_true)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n_true, e1)
    w, h = 0.4, 0.3
    got = _refit_plane(Pc, lab, center, e1, e2, w, h, K, n_true, 0.02)
    P = Pc.reshape(-1, 3).astype(np.float64)[lab.reshape(-1) == 0]
    q = P - center
    P = P[(np.abs(q @ e1) <= 0.45 * w) & (np.abs(q @ e2) <= 0.45 * h)]
    n, d = svd_plane(P)
    assert np.allclose(got[0], n, atol=1e-9) and abs(got[1] - d) < 1e-9
    assert _refit_plane(Pc, np.full_like(lab, 3), center, e1, e2, w, h, K, n_true, 0.02) is None


class _Cfg:
    gap_side_tolerance_per_m2 = 0.004


def _bent_reference(A, N, nb, tol_m2):
    with np.errstate(invalid="ignore", divide="ignore"):
        B = A / N
        h0, h1 = nb // 2, nb - 1 - nb // 2
        bent = np.zeros(B.shape, bool)
        if B.shape[1] > nb:
            chord = (B[:, : B.shape[1] - nb + 1] + B[:, nb - 1:]) * np.float32(0.5)
            zc = B[:, h0: B.shape[1] - h1]
            tol = np.maximum(np.float32(0.01), np.float32(tol_m2) * zc * zc)
            bent[:, h0: B.shape[1] - h1] = np.abs(zc - chord) > tol
    return bent


@pytest.mark.parametrize("nb", [8, 32])
def test_bent_windows_match_the_array_expression(nb):
    """Lines with steps, unmeasured blocks (0 / 0) and steady ramps: the same bent windows."""
    rng = np.random.default_rng(nb)
    N = rng.integers(0, 5, (60, 160)).astype(np.float32)
    z = np.linspace(1.0, 2.5, 160, dtype=np.float32)[None, :] + np.zeros((60, 1), np.float32)
    z[:, 70:] += np.float32(0.05)  # a step
    A = (z * N).astype(np.float32)
    got = _bent_windows(A, N, nb, _Cfg)
    assert np.array_equal(got, _bent_reference(A, N, nb, _Cfg.gap_side_tolerance_per_m2))
    assert got[:, 70 - nb // 2:70 + nb // 2].any() and not got[:, :45].any()


def _long_runs_reference(g, zg, min_len_fx, floor):
    """The array code of the reveal runs: OpenCV's 8-connected components with stats."""
    n_lab, lab, stats, cent = cv2.connectedComponentsWithStats(g.view(np.uint8),
                                                               connectivity=8, ltype=cv2.CV_32S)
    if n_lab <= 1:
        return None
    length = 4 * stats[1:, cv2.CC_STAT_WIDTH].astype(np.float64)
    cr = np.clip(np.round(cent[1:, 1]).astype(np.int64), 0, lab.shape[0] - 1)
    cc = np.clip(np.round(cent[1:, 0]).astype(np.int64), 0, lab.shape[1] - 1)
    zrun = zg[cr, cc].astype(np.float64)
    off = np.flatnonzero(lab[cr, cc] != np.arange(1, n_lab))
    if len(off):
        on = np.flatnonzero(g)
        zsum = np.bincount(lab.reshape(-1)[on], weights=zg.reshape(-1)[on],
                           minlength=n_lab)[1:]
        zrun[off] = zsum[off] / np.maximum(stats[1 + off, cv2.CC_STAT_AREA], 1)
    min_px = min_len_fx / np.maximum(zrun, 1e-6)
    if floor is not None:
        min_px = np.maximum(min_px, np.float64(floor))
    keep = np.concatenate([[False], length >= min_px])
    if not keep.any():
        return None
    return keep[lab]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_reveal_runs_match_opencv_s_components(seed):
    """Random hits with long lines, bent runs (centroid off the run) and specks: the same kept
    runs as with OpenCV's components and stats."""
    rng = np.random.default_rng(seed)
    g = rng.random((90, 160)) < 0.04
    g[20, 10:120] = True
    g[40, 5:60] = True
    g[41:60, 59] = True  # an L: its centroid is off the run
    zg = np.where(g, rng.uniform(0.8, 3.0, g.shape), 0.0).astype(np.float32)

    class C:
        gap_min_length = 0.2

    for fx, floor in ((120.0, None), (120.0, 40.0), (30.0, None)):
        got = _long_runs(g, zg, fx, C, floor)
        ref = _long_runs_reference(g, zg, C.gap_min_length * fx, floor)
        assert (got is None) == (ref is None)
        if ref is not None:
            assert np.array_equal(got, ref)
    assert _long_runs(np.zeros((5, 5), bool), np.zeros((5, 5), np.float32), 1.0, C) is None


def test_hypothesis_counts_match_the_matrix_product():
    """RANSAC's counts without the (hypotheses, points) matrix: each point's distance within
    a float32 rounding of the matrix product's, the same counts wherever no point lies within
    that rounding of its bound, and the first hypothesis with the most."""
    rng = np.random.default_rng(7)
    N = rng.normal(size=(200, 3))
    N32 = (N / np.linalg.norm(N, axis=1)[:, None]).astype(np.float32)
    P32 = (rng.normal(size=(3000, 3)) * [1.0, 1.0, 0.5] + [0.0, 0.0, 2.0]).astype(np.float32)
    dd = rng.uniform(-2.5, -1.5, 200).astype(np.float32)
    L = rng.uniform(0.02, 0.05, 3000).astype(np.float32)
    D = np.abs(N32 @ P32.T + dd[:, None])  # float32 matrix product
    exact = np.abs(N32.astype(np.float64) @ P32.T.astype(np.float64) + dd[:, None])
    assert np.abs(D - exact).max() < 1e-6
    near = np.abs(exact - L[None, :]) < 1e-5  # within rounding of the bound: either way
    counts = np.empty(200, np.int64)
    X, Y, Z = (np.ascontiguousarray(P32[:, j]) for j in range(3))
    best = _inlier_counts(N32, dd, X, Y, Z, L, counts)
    lo = ((exact <= L) & ~near).sum(axis=1)
    assert np.all((lo <= counts) & (counts <= lo + near.sum(axis=1)))
    assert counts.max() > 0 and best == int(np.argmax(counts))
    assert np.array_equal(counts, (D <= L).sum(axis=1))  # the matrix product's, bit for bit


@pytest.mark.parametrize("seed", [0, 1])
def test_window_sums_are_opencv_s_box_filter(seed):
    """The window sums, four rows at a time, bit for bit those of ``cv2.boxFilter`` (zero
    border), also for values over many orders of magnitude and windows longer than a row."""
    rng = np.random.default_rng(seed)
    for nb in (1, 2, 3, 8, 32, 200):
        for shape in ((9, 160), (7, 5), (13, 1), (4, 33)):
            X = (rng.standard_normal(shape)
                 * 10.0 ** rng.uniform(-8, 8, (shape[0], 1))).astype(np.float32)
            X[rng.random(shape) < 0.2] = 0.0
            ref = cv2.boxFilter(X, -1, (nb, 1), normalize=False, borderType=cv2.BORDER_CONSTANT)
            got = np.empty_like(X)
            _box_rows(X, nb, got)
            assert np.array_equal(got.view(np.int32), ref.view(np.int32)), (nb, shape)


def _window_means_reference(A, N, V, nb):
    """The array code of the window means (OpenCV's box filter, then numpy)."""
    Lw = nb * 4
    bent = _bent_windows(A, N, nb, _Cfg)
    box = (lambda X: cv2.boxFilter(X, -1, (nb, 1), normalize=False,
                                   borderType=cv2.BORDER_CONSTANT) * np.float32(4))
    A, N = box(A), box(N)
    if V is not None:
        V = np.sqrt(np.minimum(box(V) / np.maximum(N, np.float32(1.0)), np.float32(1.0)))
    meas = N >= max(3.0, Lw / 3.0)
    m = A / np.maximum(N, np.float32(1.0))
    m[~meas] = np.nan
    return m, ~meas, (N >= 0.8 * Lw) & ~bent, V


@pytest.mark.parametrize("nb", [8, 32])
def test_window_means_match_the_array_code(nb):
    """Block means with unmeasured runs, a step and a noise factor: the same means, masks and
    noise factors, bit for bit."""
    rng = np.random.default_rng(nb)
    N = rng.choice(np.float32([0.0, 0.25, 0.5, 1.0]), (50, 150), p=[0.1, 0.1, 0.1, 0.7])
    N[:, 60:80] = 0.0
    z = rng.uniform(1.0, 2.5, (50, 150)).astype(np.float32)
    z[:, 100:] += np.float32(0.05)
    A = (z * N).astype(np.float32)
    V = (rng.uniform(0.2, 1.0, A.shape) * N).astype(np.float32)
    for v in (None, V):
        got = _window_means(A, N, v, nb, _Cfg)
        ref = _window_means_reference(A, N, v, nb)
        for g, r in zip(got, ref):
            assert (g is None) == (r is None)
            if r is not None:
                assert np.array_equal(g.view(np.uint8), r.view(np.uint8))
        assert got[1].any() and got[2].any()


class _GapCfg:
    gap_side_tolerance_per_m2 = 0.004
    gap_offsets_px = [2, 3, 4, 5, 7, 9]


def _line_hits_reference(m, unmeas, side_ok, V, gd, gdz, near_z, Hi):
    """Every test of the reveal lines on every line and offset, in float32 scalars (no
    prefilter)."""
    f = np.float32
    half, tol_m2 = f(0.5), f(_GapCfg.gap_side_tolerance_per_m2)
    g = np.zeros(m.shape, bool)
    zg = np.zeros(m.shape, np.float32)
    for o in _GapCfg.gap_offsets_px:
        for r in range(2 * o, m.shape[0] - 2 * o):
            for c in range(m.shape[1]):
                if not (side_ok[r - o, c] and side_ok[r + o, c]):
                    continue
                up, dn, cv, unm = m[r - o, c], m[r + o, c], m[r, c], bool(unmeas[r, c])
                ref = (up + dn) * half
                z2 = ref * ref
                t = f(gdz) * z2 * (V[r, c] if V is not None else f(1.0))
                thr = max(f(gd), t)
                if Hi is not None:
                    thr = thr * np.sqrt(_stretch_at.py_func(Hi, r, c, 4, True, False))
                if not (cv - ref > thr or unm) or not abs(up - dn) < max(f(0.01), tol_m2 * z2):
                    continue
                ext = (up + dn) - half * (m[r - 2 * o, c] + m[r + 2 * o, c])
                if not (cv - ext > half * thr or unm):
                    continue
                if Hi is not None and unm:
                    sv = _stretch_at.py_func(Hi, r, c, 4, True, True)
                    near = o <= float(f(5.0) * sv) or float(ref) * (o - 2.0 * float(sv)) < near_z
                else:
                    near = o <= 5 or ref * f(o - 2) < f(near_z)
                if near:
                    g[r, c], zg[r, c] = True, ref
    return g, zg


@pytest.mark.parametrize("seed", [0, 1])
def test_line_hits_match_every_test_on_every_line(seed):
    """Reveals (behind, unmeasured), creases and noise, with and without a noise factor and a
    view's homography: the compiled pass (whole-row tests first) hits the same lines at the
    same depths as the tests run one by one."""
    rng = np.random.default_rng(seed)
    # at 2.5 m the threshold's z^2 part (6 mm) is above its floor (2.5 mm): the reveal at row 30
    # is behind by more than the threshold where the noise factor lowers it, and not elsewhere
    m = (rng.uniform(2.5, 2.6, (1, 24)) + rng.normal(0, 0.0005, (70, 24))).astype(np.float32)
    m[30] += np.float32(0.004)       # a reveal behind its sides
    m[45] = np.nan                   # a line without return
    m[52:56] += np.float32(0.02)     # a band
    unmeas = np.isnan(m)
    side_ok = ~unmeas & (rng.random(m.shape) < 0.95)
    V = rng.uniform(0.3, 1.0, m.shape).astype(np.float32)
    Hi = np.array([[0.9, 0.05, 3.0], [0.02, 1.1, -2.0], [1e-4, 2e-4, 1.0]])
    for v, h in ((None, None), (V, None), (None, Hi), (V, Hi)):
        g = np.zeros(m.shape, bool)
        zg = np.zeros(m.shape, np.float32)
        _line_hits_kernel(m, unmeas.view(np.uint8), side_ok.view(np.uint8),
                          np.zeros((1, 1), np.float32) if v is None else v,
                          np.eye(3) if h is None else h, np.float32(0.0025), np.float32(0.001),
                          np.float32(_GapCfg.gap_side_tolerance_per_m2), np.float32(5.25),
                          np.asarray(_GapCfg.gap_offsets_px, np.int64), True, v is not None,
                          h is not None, True, g, zg)
        rg, rz = _line_hits_reference(m, unmeas, side_ok, v, 0.0025, 0.001, 5.25, h)
        assert np.array_equal(g, rg) and np.array_equal(zg.view(np.int32), rz.view(np.int32))
        assert g[45].any() and g[30].any() == (v is not None)


def _refit_reference(planes, labels, Pc, Lmap, min_change_deg, crossing_angle_deg, rounds=3,
                     max_points=40000, max_change_deg=5.0, min_support=100):
    """The own-pixel refit as array code: every sampled pixel's distance to every plane,
    the partners' nearest within L by masked minima."""
    N0 = np.array([pl.n for pl in planes])
    cosang = np.abs(N0 @ N0.T)
    partners = ((cosang < math.cos(math.radians(crossing_angle_deg)))
                & (cosang > math.cos(math.radians(30.0))))
    H, W = labels[0].shape
    step = max(1, int(math.ceil(math.sqrt(H * W / max_points))))
    P = Pc[::step, ::step].reshape(-1, 3).astype(np.float64)
    L = Lmap[::step, ::step].reshape(-1).astype(np.float64)
    own0 = np.array([lab[::step, ::step].reshape(-1) == IN_PLANE for lab in labels])
    ok = np.isfinite(P[:, 2]) & own0.any(axis=0)
    P, L, own0 = P[ok], L[ok], own0[:, ok]
    refit = [k for k, pl in enumerate(planes) if partners[k].any() and pl.support >= min_support]
    cur = list(planes)
    for _ in range(rounds):
        A = np.abs(P @ np.array([pl.n for pl in cur]).T + np.array([pl.d for pl in cur])).T
        Ain = np.where(A <= L, A, np.inf)
        nxt = list(cur)
        for k in refit:
            sel = own0[k] & (A[k] <= 0.5 * L) & (A[k] <= Ain[partners[k]].min(axis=0))
            if sel.sum() < 10:
                continue
            n, d = _fit_plane_many(P[sel])
            if n @ planes[k].n >= math.cos(math.radians(10.0)):
                nxt[k] = Plane(n=n, d=d, support=cur[k].support, bbox=cur[k].bbox)
        cur = nxt
    cmin, cmax = (math.cos(math.radians(a)) for a in (min_change_deg, max_change_deg))
    return [b if cmax <= float(a.n @ b.n) < cmin else a for a, b in zip(planes, cur)]


@pytest.mark.parametrize("seed", [0, 1])
def test_own_pixel_refit_matches_the_array_code(seed):
    """A wall and a door crossing it at 6 deg, the door's fit tilted towards the wall by 1.5
    deg, a few pixels without a measurement and a third plane far away: the compiled
    selection of each plane's own pixels gives the array code's refitted planes bit for bit,
    and the door turns back towards its own surface."""
    rng = np.random.default_rng(seed)
    H, W = 120, 160
    ys, xs = np.mgrid[0:H, 0:W].astype(np.float64)
    ray = np.stack([(xs - W / 2) / 150.0, (ys - H / 2) / 150.0, np.ones((H, W))], axis=-1)

    def plane(deg, d):
        a = math.radians(deg)
        return np.array([math.sin(a), 0.0, -math.cos(a)]), d

    n_wall, d_wall = plane(0.0, 2.0)
    n_door, d_door = plane(6.0, 1.9)
    # each pixel on the nearer surface (the door left of its crossing with the wall)
    z_wall = -d_wall / (ray @ n_wall)
    z_door = -d_door / (ray @ n_door)
    z = np.where(xs < W // 2, z_door, z_wall) + rng.normal(0, 0.002, (H, W))
    z[rng.random((H, W)) < 0.02] = np.nan
    Pc = (ray * z[..., None]).astype(np.float32)
    Lmap = np.full((H, W), 0.02, np.float32)
    tilt = plane(7.5, 1.9)
    planes = [Plane(n=n_wall, d=d_wall, support=900, bbox=(0, 15, 0, 20)),
              Plane(n=tilt[0], d=tilt[1], support=500, bbox=(0, 15, 0, 10)),
              Plane(n=np.array([0.0, -1.0, 0.0]), d=0.5, support=300, bbox=(0, 2, 0, 20))]
    labels = []
    for pl in planes:
        s = np.abs(Pc.astype(np.float64) @ pl.n + pl.d)
        labels.append(np.where(s <= 0.02, IN_PLANE, OCCLUDED).astype(np.uint8))
    labels[0][:, : W // 2 - 3] = OCCLUDED  # the crossing's strip stays with both
    for min_change in (0.0, 0.5):
        got = _refit_on_own_pixels(planes, labels, Pc, Lmap, min_change, 3.0)
        ref = _refit_reference(planes, labels, Pc, Lmap, min_change, 3.0)
        assert got is not None
        assert all(np.array_equal(a.n, b.n) and a.d == b.d for a, b in zip(got, ref))
    # the door's refit is nearer its true normal than the tilted fit it started from
    assert got[1].n @ n_door > tilt[0] @ n_door
