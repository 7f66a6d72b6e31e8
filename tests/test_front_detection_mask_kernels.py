"""The masks stage's compiled passes against the OpenCV and numpy expressions they replace,
bit for bit on random inputs: the offset layers' candidate masks."""

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
