"""The masks stage's compiled passes against the OpenCV and numpy expressions they replace,
bit for bit on random inputs: the offset layers' candidate masks, the window sums."""

import cv2
import numpy as np
import pytest

from mmlearn.models.perception.detection.labels import (GAP, IN_PLANE, OCCLUDED, OFF_SURFACE,
                                                        UNKNOWN)
from mmlearn.models.perception.detection.layers import _band_candidates, _drop_unknown_gap


@pytest.mark.parametrize("seed", [0, 1])
def test_layer_candidates_match_opencv_s_compares(seed):
    """In front of the plane within the band, OCCLUDED or OFF_SURFACE (on a crop of the
    images), then UNKNOWN and GAP pixels dropped: OpenCV's compares and ands, and their count."""
    rng = np.random.default_rng(seed)
    H, W = 60, 80
    S = rng.normal(0.0, 0.02, (H, W)).astype(np.float32)
    S[rng.random((H, W)) < 0.05] = np.nan
    S[0, :5] = 0.0
    Lband = rng.uniform(0.0, 0.03, (H, W)).astype(np.float32)
    Lband[1, :5] = S[1, :5]  # (equal: in the band)
    lab = rng.choice(np.uint8([IN_PLANE, OCCLUDED, OFF_SURFACE, UNKNOWN, GAP, 1]), (H, W))
    R0, R1, C0, C1 = 7, 51, 3, 70
    Sk, lb = S[R0:R1, C0:C1], lab[R0:R1, C0:C1]
    ref = cv2.compare(Sk, Lband[R0:R1, C0:C1], cv2.CMP_LE)
    ref &= cv2.compare(Sk, 0.0, cv2.CMP_GT)
    ref &= cv2.compare(lb, OCCLUDED, cv2.CMP_EQ) | cv2.compare(lb, OFF_SURFACE, cv2.CMP_EQ)
    got = np.empty((R1 - R0, C1 - C0), np.uint8)
    n = _band_candidates(S, Lband, lab, R0, C0, got)
    assert np.array_equal(got, ref) and n == cv2.countNonZero(ref) > 0
    ref &= cv2.compare(lb, UNKNOWN, cv2.CMP_NE)
    ref &= cv2.compare(lb, GAP, cv2.CMP_NE)
    got[:] = 255
    ref2 = np.full_like(got, 255)
    ref2 &= cv2.compare(lb, UNKNOWN, cv2.CMP_NE)
    ref2 &= cv2.compare(lb, GAP, cv2.CMP_NE)
    _drop_unknown_gap(lab, R0, C0, got)
    assert np.array_equal(got, ref2)


def test_grid_tables_are_opencv_s_integrals():
    """The cost and in-plane summed-area tables of a label grid in one pass: OpenCV's
    integrals of the looked-up costs and of the in-plane indicator, bit for bit."""
    from mmlearn.models.perception.detection.grid import _sats
    rng = np.random.default_rng(5)
    lut = rng.integers(0, 256, 256).astype(np.uint8)
    for shape in ((1, 1), (7, 3), (90, 130)):
        lab = rng.integers(0, 7, shape).astype(np.uint8)
        sc, si = _sats(lab, lut)
        assert np.array_equal(sc, cv2.integral(cv2.LUT(lab, lut), sdepth=cv2.CV_32S))
        assert np.array_equal(si, cv2.integral((lab == IN_PLANE).view(np.uint8),
                                               sdepth=cv2.CV_32S))
        assert sc.dtype == si.dtype == np.int32


def test_box_sums_are_opencv_s_box_filter():
    """The 5 x 5 window sums of boxsum.py: ``cv2.boxFilter(x, -1, (5, 5), normalize=False)``
    bit for bit (its reflected border, its float64 running sums down the columns), on values
    spread over many orders of magnitude (where the order of the additions shows)."""
    from mmlearn.models.perception.detection.boxsum import box_sums
    rng = np.random.default_rng(3)
    for shape in ((3, 3), (4, 9), (5, 5), (41, 66), (120, 7)):
        for _ in range(4):
            X = (rng.standard_normal(shape) * 10.0 ** rng.uniform(-30, 3, shape)).astype(
                np.float32)
            X[rng.random(shape) < 0.3] = 0.0
            got = np.empty_like(X)
            box_sums(X, got)
            ref = cv2.boxFilter(X, -1, (5, 5), normalize=False)
            assert np.array_equal(got.view(np.int32), ref.view(np.int32))


@pytest.mark.parametrize("seed", [0, 1])
def test_surface_marks_match_the_box_filter_path(seed):
    """The surface check's fused pass (deviations from the ramp, both window sums, marks) marks
    the pixels that OpenCV's box filters and the separate passes mark, with and without a ramp,
    for in-plane pixels spread and in blocks."""
    from mmlearn.models.perception.detection.boxsum import surface_marks
    from mmlearn.models.perception.detection.labels import _mark_off_surface, _surface_deviation
    rng = np.random.default_rng(seed)
    H, W = 50, 70
    S = rng.normal(0.0, 0.01, (H, W)).astype(np.float32)
    Lm = rng.uniform(0.0005, 0.01, (H, W)).astype(np.float32)
    marked = 0
    for case in range(6):
        lab = rng.choice(np.uint8([IN_PLANE, 1, 2, UNKNOWN]), (H, W), p=[0.6, 0.2, 0.1, 0.1])
        if case % 2:
            lab[:, :rng.integers(5, 40)] = 1
            lab[rng.integers(0, H):, :] = UNKNOWN
        m8 = cv2.compare(lab, IN_PLANE, cv2.CMP_EQ)
        x, y, w, h = cv2.boundingRect(m8)
        y0, y1, x0, x1 = max(0, y - 2), min(H, y + h + 2), max(0, x - 2), min(W, x + w + 2)
        for ramp in ((np.float32(1e-4), np.float32(-2e-4), np.float32(0.003), True),
                     (np.float32(0.0), np.float32(0.0), np.float32(0.0), False)):
            ref, got = lab.copy(), lab.copy()
            den = cv2.boxFilter((m8[y0:y1, x0:x1] > 0).view(np.uint8), cv2.CV_32F, (5, 5),
                                normalize=False)
            dev = np.empty((y1 - y0, x1 - x0), np.float32)
            _surface_deviation(S, m8, y0, x0, *ramp, dev)
            num = cv2.boxFilter(dev, -1, (5, 5), normalize=False)
            _mark_off_surface(num, den, Lm, m8, y0, x0, ref)
            surface_marks(S, m8, Lm, y0, y1, x0, x1, *ramp, got)
            assert np.array_equal(got, ref)
            marked += int(np.count_nonzero(ref == OFF_SURFACE))
    assert marked > 0


def test_pair_window_sums_match_the_box_filter_path():
    """The crossings' window sums of a pair of planes at their shared pixels: those of
    OpenCV's box filter on the masked distances, bit for bit, for pixels spread over the
    box and along a line."""
    from mmlearn.models.perception.detection.boxsum import pair_window_sums
    from mmlearn.models.perception.detection.labels import _pair_window_sums_cv
    rng = np.random.default_rng(7)
    H, W = 60, 90
    for case in range(8):
        Sk = rng.normal(0.0, 0.01, (H, W)).astype(np.float32)
        Sj = rng.normal(0.0, 0.01, (H, W)).astype(np.float32)
        m = rng.random((H, W)) < rng.uniform(0.01, 0.4)
        if case % 2:
            m[:] = False
            m[20:24, 10:80] = True
        by, bx = np.divmod(np.flatnonzero(m), W)
        y0, y1 = max(0, by[0] - 2), min(H, by[-1] + 3)
        x0, x1 = max(0, bx.min() - 2), min(W, bx.max() + 3)
        ak, aj = np.empty(len(by), np.float32), np.empty(len(by), np.float32)
        pair_window_sums(Sk, Sj, y0, y1, x0, x1, by, bx, ak, aj)
        rk, rj = _pair_window_sums_cv(Sk, Sj, y0, y1, x0, x1, by, bx, 5)
        assert np.array_equal(ak.view(np.int32), rk.view(np.int32))
        assert np.array_equal(aj.view(np.int32), rj.view(np.int32))
