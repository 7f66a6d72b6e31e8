"""DepthNoise: the Kinect-like noise model's statistics and its LeafSystem (no rendering)."""

import math

import numpy as np
import pytest
from pydrake.common.yaml import yaml_load_typed
from pydrake.systems.sensors import ImageDepth32F

from mmlearn.models.common.depth_noise import (DepthNoiseConfig, apply_depth_noise, incidence_cosine,
                                               predicted_depth_std, projector_shadow)
from mmlearn.models.common.camera import PinholeIntrinsics
from mmlearn.systems import DepthNoise

K = PinholeIntrinsics.from_fov(640, 480, 58.0)


def _flat(z):
    return np.full((K.height, K.width), z, np.float32)


def _plane(normal, z0):
    """Clean depth of the plane through (0, 0, z0) with the given normal (camera frame)."""
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    u, v = np.meshgrid(np.arange(K.width), np.arange(K.height))
    r = np.stack([(u - K.cx) / K.fx, (v - K.cy) / K.fy, np.ones_like(u, float)], -1)
    with np.errstate(divide="ignore"):
        t = n[2] * z0 / (r @ n)
    return np.where(t > 0, t, np.inf).astype(np.float32)


def test_std_grows_with_the_square_of_the_distance():
    """The std on a flat wall matches the first-order prediction within 5 % and the
    Khoshelham & Elberink (2012) figures the defaults are taken from: 1-2 mm at 1 m, ~1 cm
    at 2.5 m; no bias beyond 1 mm."""
    cfg = DepthNoiseConfig(dropout=0.0)
    stds = {}
    for z in (1.0, 1.5, 2.0, 2.5):
        out = apply_depth_noise(_flat(z), K, cfg, frame=1)
        assert np.isfinite(out).all()
        stds[z] = float(np.std(out))
        assert stds[z] == pytest.approx(predicted_depth_std(z, K, cfg), rel=0.05)
        assert abs(float(np.mean(out)) - z) < 1e-3
    assert 0.001 <= stds[1.0] <= 0.002
    assert 0.008 <= stds[2.5] <= 0.013
    ratio = stds[2.5] / stds[1.0]
    assert ratio == pytest.approx(2.5**2, rel=0.1)


def test_correlated_noise_keeps_its_std():
    cfg = DepthNoiseConfig(dropout=0.0, disparity_step_px=0.0, noise_window_px=5)
    out = apply_depth_noise(_flat(2.0), K, cfg, frame=2)
    r = out[10:-10, 10:-10] - 2.0
    assert np.std(r) == pytest.approx(cfg.sigma_z_at_1m * 4.0, rel=0.1)
    # neighbours share 4 of 5 window columns: correlation ~0.8 (independent: ~0)
    c = np.corrcoef(r[:, 1:].ravel(), r[:, :-1].ravel())[0, 1]
    assert 0.7 < c < 0.9
    iid = apply_depth_noise(_flat(2.0), K, DepthNoiseConfig(dropout=0.0, disparity_step_px=0.0),
                            frame=2) - 2.0
    assert abs(np.corrcoef(iid[:, 1:].ravel(), iid[:, :-1].ravel())[0, 1]) < 0.02
    with pytest.raises(ValueError, match="odd"):
        DepthNoiseConfig(noise_window_px=4).validate()


def test_disparity_is_quantised():
    cfg = DepthNoiseConfig(sigma_z_at_1m=0.0, dropout=0.0)
    out = apply_depth_noise(_plane([0.0, -0.3, -1.0], 1.8), K, cfg, frame=0)
    fb = K.fx * cfg.baseline
    d = fb / out[np.isfinite(out)] / cfg.disparity_step_px
    np.testing.assert_allclose(d, np.round(d), atol=2e-3)
    # noise-free steps in depth at 2.5 m: z^2 * step / (f b) = 1.8 cm
    levels = np.unique(np.round(apply_depth_noise(_flat(2.5), K, cfg)[0], 6))
    assert levels.size == 1
    assert abs(levels[0] - 2.5) <= 0.5 * 2.5**2 * cfg.disparity_step_px / fb + 1e-6


def test_dropout_rate():
    cfg = DepthNoiseConfig(dropout=0.05, dropout_block_px=3)
    rates = [np.isnan(apply_depth_noise(_flat(1.5), K, cfg, frame=k)).mean() for k in range(4)]
    assert np.mean(rates) == pytest.approx(0.05, abs=0.005)
    assert np.isnan(apply_depth_noise(_flat(1.5), K, DepthNoiseConfig(dropout=0.0))).sum() == 0


def test_missing_pixels_at_a_depth_edge():
    """A box 0.5 m in front of a wall: the projector (at +x) shadows a band of
    f b (1/z_fg - 1/z_bg) px on the wall left of the box, none on its right; the edge band
    removes the pixels along the box's outline; the rest stays."""
    d = _flat(2.0)
    r0, r1, c0, c1 = 150, 330, 220, 420
    d[r0:r1, c0:c1] = 1.5
    cfg = DepthNoiseConfig(dropout=0.0, edge_dilate_px=0)
    out, masks = apply_depth_noise(d, K, cfg, frame=0, return_masks=True)
    width = K.fx * cfg.baseline * (1 / 1.5 - 1 / 2.0)  # 7.2 px
    rows = slice(r0 + 5, r1 - 5)
    left = masks["shadow"][rows, : c0]
    band = left.sum(axis=1)
    assert np.all(np.abs(band - width) <= 1.0), band
    assert left[:, c0 - int(width) + 1:].all()  # adjacent to the box
    assert not masks["shadow"][rows, c1:].any()
    assert not masks["shadow"][rows, c0:c1].any()  # the box itself is lit
    # the outline is missing, the inside of the box and of the wall are measured
    assert np.isnan(out[rows, c0 - 1]).all() and np.isnan(out[rows, c1]).all()
    assert np.isnan(out[r0 - 1, c0 + 20:c1 - 20]).all()
    assert np.isfinite(out[r0 + 3:r1 - 3, c0 + 3:c1 - 3]).all()
    assert np.isfinite(out[rows, c1 + 3:]).all()
    # the reverse baseline puts the shadow on the right
    m2 = apply_depth_noise(d, K, DepthNoiseConfig(baseline=-0.075, dropout=0.0), frame=0,
                           return_masks=True)[1]
    assert m2["shadow"][rows, c1:].sum(axis=1).mean() == pytest.approx(width, abs=1.0)
    assert not m2["shadow"][rows, :c0].any()


def test_grazing_angles():
    cfg = DepthNoiseConfig(dropout=0.0)
    tilt = lambda deg: [0.0, math.sin(math.radians(deg)), -math.cos(math.radians(deg))]  # noqa
    # the plane's normal tilted by 80 deg about the camera's x axis: the incidence angle
    # at the image centre is 80 deg (more than 85 at some rows): most pixels are missing
    d80 = _plane(tilt(80.0), 1.5)
    cos = incidence_cosine(d80, K)
    assert math.degrees(math.acos(cos[240, 320])) == pytest.approx(80.0, abs=0.5)
    missing = np.isnan(apply_depth_noise(d80, K, cfg))[200:280].mean()
    assert missing > 0.5
    # tilted 40 deg (at most 40 + 22.5 deg at the image's top and bottom rows) no pixel is
    # lost to the grazing angle
    d40 = _plane(tilt(40.0), 1.5)
    assert not apply_depth_noise(d40, K, cfg, return_masks=True)[1]["grazing"].any()


def test_seeded_reproducibility():
    d = _flat(1.8)
    d[100:200, 100:300] = 1.2
    cfg = DepthNoiseConfig(seed=7)
    a = apply_depth_noise(d, K, cfg, frame=3)
    b = apply_depth_noise(d, K, DepthNoiseConfig(seed=7), frame=3)
    np.testing.assert_array_equal(a, b)  # NaN at the same places, same values
    assert not np.array_equal(a, apply_depth_noise(d, K, cfg, frame=4), equal_nan=True)
    assert not np.array_equal(a, apply_depth_noise(d, K, DepthNoiseConfig(seed=8), frame=3),
                              equal_nan=True)


def test_no_surface_and_bad_images():
    cfg = DepthNoiseConfig()
    for img in (np.full((480, 640), np.nan, np.float32), np.zeros((480, 640), np.float32),
                np.full((480, 640), np.inf, np.float32), -np.ones((480, 640), np.float32)):
        assert np.isnan(apply_depth_noise(img, K, cfg)).all()
    out = apply_depth_noise(_flat(6.0), K, cfg)  # beyond the 5 m range
    assert np.isnan(out).all()
    with pytest.raises(ValueError, match="shape"):
        apply_depth_noise(np.ones((480, 639), np.float32), K, cfg)
    with pytest.raises(ValueError, match="float"):
        apply_depth_noise(np.ones((480, 640), np.int32), K, cfg)
    with pytest.raises(ValueError, match="frame"):
        apply_depth_noise(_flat(1.0), K, cfg, frame=-1)
    # a (H, W, 1) image is accepted (Drake's layout)
    assert apply_depth_noise(_flat(1.0)[..., None], K, cfg).shape == (480, 640)


@pytest.mark.parametrize("field, value, needle", [
    ("sigma_z_at_1m", -0.001, "sigma_z_at_1m"),
    ("baseline", 0.0, "baseline"),
    ("dropout", 1.0, "dropout"),
    ("grazing_start_deg", 88.0, "grazing"),
    ("min_range", 6.0, "min_range"),
    ("dropout_block_px", 0, "dropout_block_px"),
    ("seed", -1, "seed"),
    ("sigma_z_at_1m", float("nan"), "sigma_z_at_1m"),
])
def test_bad_config(field, value, needle):
    cfg = DepthNoiseConfig()
    setattr(cfg, field, value)
    with pytest.raises(ValueError, match=needle):
        cfg.validate()
    with pytest.raises(ValueError, match=needle):
        DepthNoise(intrinsics=K, config=cfg)


def test_config_yaml():
    cfg = yaml_load_typed(schema=DepthNoiseConfig, data="sigma_z_at_1m: 0.002\nseed: 4\n")
    assert cfg.sigma_z_at_1m == 0.002 and cfg.seed == 4
    with pytest.raises(RuntimeError, match="sigma_z_at1m"):
        yaml_load_typed(schema=DepthNoiseConfig, data="sigma_z_at1m: 0.002\n")


def test_projector_shadow_on_a_slanted_plane_is_empty():
    d = _plane([0.4, -0.3, -1.0], 1.5)
    fb = K.fx * 0.075
    assert not projector_shadow(np.where(np.isfinite(d), fb / d, 0.0)).any()


def test_depth_noise_system():
    sys_ = DepthNoise(intrinsics=K, config=DepthNoiseConfig(seed=3), rate_hz=10.0)
    ctx = sys_.CreateDefaultContext()
    img = ImageDepth32F(K.width, K.height)
    img.mutable_data[:, :, 0] = _flat(1.2)
    sys_.get_clean_depth_input_port().FixValue(ctx, img)
    ctx.SetTime(0.3)
    out = np.array(sys_.get_depth_image_output_port().Eval(ctx).data)[..., 0]
    np.testing.assert_array_equal(out, apply_depth_noise(_flat(1.2), K, DepthNoiseConfig(seed=3),
                                                         frame=3))
    assert sys_.frame_index(0.3) == 3
    # a wrong-sized image never stops a simulation: no measurement at all
    bad = ImageDepth32F(320, 240)
    bad.mutable_data[:] = 1.0
    sys_.get_clean_depth_input_port().FixValue(ctx, bad)
    out = np.array(sys_.get_depth_image_output_port().Eval(ctx).data)
    assert out.shape == (480, 640, 1) and np.isnan(out).all()
    with pytest.raises(ValueError, match="rate_hz"):
        DepthNoise(intrinsics=K, rate_hz=0.0)
