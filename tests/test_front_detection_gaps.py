"""The reveal test (``_gap_mask``): thin lines behind the surface or without return are
found, steps and creases are not; the long pass finds a shallow long reveal, not noise; 16-bit
and 32-bit run labels give the same reveals."""

import dataclasses

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


def test_gap_mask_finds_a_thin_dip_but_not_a_step_or_a_crease():
    """_gap_mask on a noisy plane 1.8 m away: a one-pixel row 7 mm behind (a reveal) and a
    line of missing pixels are found along their length; a 3 cm step and a concave crease
    (two planes meeting at 150 deg) are not; nothing on the plain plane."""
    rng = np.random.default_rng(0)
    H, W = 240, 320
    z = np.full((H, W), 1.8) + 0.0008 * np.arange(H)[:, None]      # tilted like a front
    z_dip = z.copy()
    z_dip[100] += 0.007                                             # the reveal
    z_dip[:, 200:202] = np.nan                                      # a reveal without return
    z_step = z + np.where(np.arange(H)[:, None] >= 120, 0.03, 0.0)
    z_crease = z + 0.3 * np.abs(np.arange(H)[:, None] - 120) * 1.8 / 577.0
    noise = rng.normal(0.0, 0.0016 * 1.8 ** 2, (H, W))
    cfg = FrontDetectorConfig()
    masks = {}
    for name, img in (("dip", z_dip), ("plain", z), ("step", z_step), ("crease", z_crease)):
        d = (img + noise).astype(np.float32)
        valid = np.isfinite(d)
        masks[name] = _gap_mask(np.where(valid, d, np.float32(np.nan)), valid, 577.0, cfg)[1]
    dip = masks["dip"]
    assert dip[100, 20:180].mean() > 0.8                      # the row behind its sides
    assert dip[20:220, 200:202].any(axis=1).mean() > 0.8       # the column without return
    assert dip[:90].sum() + dip[110:, :190].sum() < 0.01 * H * W
    for name in ("plain", "step", "crease"):
        assert masks[name].mean() < 0.005, (name, masks[name].mean())


def test_long_pass_finds_a_shallow_long_reveal_but_not_noise():
    """_gap_mask on noisy planes 2.2 m away (Kinect-like noise 0.0016 z^2 m per pixel): a row
    3.3 mm behind its sides over 224 px (the reveal below the closed drawer at 2.2 m, as
    sampled) is found along most of its length only with the long pass; on the plain plane
    both passes label (almost) nothing."""
    H, W = 240, 480
    z = np.full((H, W), 2.2) + 0.0018 * np.arange(H)[:, None]       # tilted like a front
    z_dip = z.copy()
    z_dip[120, 120:344] += 0.0033
    cfg, short = FrontDetectorConfig(), dataclasses.replace(FrontDetectorConfig(),
                                                            gap_long_window_px=0)
    hits = {"long": [], "short": []}
    for seed in range(4):
        noise = np.random.default_rng(seed).normal(0.0, 0.0016 * 2.2 ** 2, (H, W))
        for name, c in (("long", cfg), ("short", short)):
            d = (z_dip + noise).astype(np.float32)
            dip = _gap_mask(d, np.isfinite(d), 577.0, c)[1]
            hits[name].append(dip[119:122, 150:314].any(axis=0).mean())
            plain = _gap_mask((z + noise).astype(np.float32), np.ones((H, W), bool), 577.0, c)[1]
            assert plain.mean() < 0.002, (name, seed, plain.mean())
    assert min(hits["long"]) > 0.6, hits
    assert max(hits["short"]) < 0.3, hits
