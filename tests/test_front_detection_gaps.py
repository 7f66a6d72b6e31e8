"""_gap_mask's run labelling: 16-bit labels on small line images, 32-bit ones where 16 bits
could overflow (branch pview); both must give the same reveals."""

import numpy as np

from mmlearn.models.perception.detection import FrontDetectorConfig
from mmlearn.models.perception.detection.gaps import _gap_mask


def _scene(rng):
    H, W = 240, 320
    z = np.full((H, W), 1.8) + 0.0008 * np.arange(H)[:, None]
    z[100] += 0.007                      # a reveal 7 mm behind
    z[:, 200:202] = np.nan               # a reveal without return
    return (z + rng.normal(0.0, 0.0016 * 1.8 ** 2, (H, W))).astype(np.float32)


def test_gap_mask_same_with_16_and_32_bit_run_labels():
    """The scene alone (320 x 240: 16-bit labels) and in the corner of an unmeasured
    1280 x 1040 image (its line images need 32-bit labels) give the same mask there and
    nothing elsewhere; the reveals are found."""
    d = _scene(np.random.default_rng(3))
    cfg = FrontDetectorConfig()
    small_valid = np.isfinite(d)
    small = _gap_mask(np.where(small_valid, d, 0.0).astype(np.float32), small_valid, 577.0, cfg)
    big_d = np.zeros((1040, 1280), np.float32)
    big_d[:240, :320] = np.where(small_valid, d, 0.0)
    big_valid = np.zeros(big_d.shape, bool)
    big_valid[:240, :320] = small_valid
    big = _gap_mask(big_d, big_valid, 577.0, cfg)
    for s, b in zip(small, big):
        assert np.array_equal(s, b[:240, :320])
        assert not b[240:].any() and not b[:, 320:].any()
    thin = small[1]
    assert thin[100, 20:180].mean() > 0.8
    assert thin[20:220, 200:202].any(axis=1).mean() > 0.8
