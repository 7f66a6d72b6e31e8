"""The temporal depth filter (models/perception/depth_filter.py, systems/perception/depth_temporal_filter.py) and the
reveal test's threshold following its noise (the closed drawer at 2.2 m)."""

import math

import numpy as np
import pytest

from mmlearn.models.perception.depth_filter import DepthFilterConfig, filter_depth, new_filter_state
from mmlearn.models.perception.detection import FrontDetectorConfig, detect_fronts
from mmlearn.models.perception.detection.gaps import _gap_mask
from mmlearn.models.common.camera import PinholeIntrinsics

SIG1 = 0.0018  # the default camera's per-pixel depth std at 1 m, m
K = PinholeIntrinsics.from_fov(320, 240, 58.0)


def _plane(H=120, W=160, z0=2.2):
    """A front-like plane (depth rising down the image, as seen from above), m."""
    return (np.full((H, W), z0) + 0.0008 * np.arange(H)[:, None]).astype(np.float32)


def _noisy(clean, rng):
    return (clean + rng.normal(0.0, 1.0, clean.shape) * SIG1 * clean ** 2).astype(np.float32)


def _run(frames, cfg=None):
    st = new_filter_state(*frames[0].shape)
    outs = []
    for f in frames:
        out, scale, st = filter_depth(f, st, cfg)
        outs.append((out, scale))
    return outs, st


def test_static_scene_noise_falls_as_one_over_sqrt_n():
    rng = np.random.default_rng(0)
    clean = _plane()
    outs, st = _run([_noisy(clean, rng) for _ in range(16)])
    for n in (1, 4, 16):
        out, scale = outs[n - 1]
        err = (out - clean) / (SIG1 * clean ** 2)
        full = scale <= 1.0 / math.sqrt(n) + 1e-6  # pixels never restarted
        assert np.sqrt(np.mean(err[full] ** 2)) == pytest.approx(1.0 / math.sqrt(n), rel=0.1)
        # each pixel's reported scale is its std (restarted pixels too)
        assert np.sqrt(np.mean((err / scale) ** 2)) == pytest.approx(1.0, rel=0.1)
        assert np.median(scale) == pytest.approx(1.0 / math.sqrt(n), rel=1e-5)
        assert full.mean() > 0.9  # false restarts (window test at 4 sigma) stay rare
    assert np.median(st.count) == 16


def test_beyond_max_frames_the_mean_is_exponential_with_the_right_variance():
    rng = np.random.default_rng(1)
    clean = _plane()
    cfg = DepthFilterConfig(max_frames=4)
    outs, st = _run([_noisy(clean, rng) for _ in range(30)], cfg)
    out, scale = outs[-1]
    a = 1.0 / 4
    v_inf = a / (2.0 - a)  # the stationary variance factor of an exponential mean
    assert np.median(scale) ** 2 == pytest.approx(v_inf, rel=0.05)
    rms = np.sqrt(np.mean(((out - clean) / (SIG1 * clean ** 2)) ** 2))
    assert rms == pytest.approx(math.sqrt(v_inf), rel=0.12)
    assert st.count.max() == 4


def test_a_moved_region_restarts_and_a_slow_move_is_caught_by_the_window_test():
    rng = np.random.default_rng(2)
    clean = _plane()
    frames = [_noisy(clean, rng) for _ in range(8)]
    outs, st = _run(frames)
    # a block jumps 5 cm nearer (an occluder), another drifts 1.1 cm (1.3 sigma at 2.2 m:
    # a drawer sliding out, per frame), the rest stays
    moved = clean.copy()
    moved[20:60, 20:60] -= 0.05
    moved[70:110, 90:150] -= 0.011
    f = _noisy(moved, rng)
    out, scale, st2 = filter_depth(f, st)
    for sl in (np.s_[20:60, 20:60], np.s_[70:110, 90:150]):
        assert (st2.count[sl] == 1).all()
        np.testing.assert_array_equal(out[sl], f[sl])
        assert (scale[sl] == 1.0).all()
    still = np.ones(clean.shape, bool)
    still[10:70, 10:70] = False          # the moved blocks and the window test's margin
    still[60:120, 80:160] = False
    assert (st2.count[still] == 9).mean() > 0.97
    # with the window test off, the slow move is averaged into the old mean (a lag)
    _, _, st3 = filter_depth(f, st, DepthFilterConfig(window_px=1))
    assert (st3.count[75:105, 95:145] == 9).mean() > 0.9


def test_missing_pixels_keep_their_state_and_stay_missing():
    rng = np.random.default_rng(3)
    clean = _plane()
    outs, st = _run([_noisy(clean, rng) for _ in range(3)])
    f = _noisy(clean, rng)
    f[:10] = np.nan
    f[10:20] = 0.0
    f[20:30] = np.inf
    out, scale, st2 = filter_depth(f, st)
    assert np.isnan(out[:30]).all() and (scale[:30] == 1.0).all()
    np.testing.assert_array_equal(st2.mean[:30], st.mean[:30])
    np.testing.assert_array_equal(st2.count[:30], st.count[:30])
    assert (st2.count[40:] >= 3).mean() > 0.97


def test_bad_input_and_config_raise_clear_errors():
    st = new_filter_state(20, 30)
    with pytest.raises(ValueError, match="shape"):
        filter_depth(np.ones((30, 20), np.float32), st)
    with pytest.raises(ValueError, match="numeric"):
        filter_depth(np.full((20, 30), "x"), st)
    out, scale, st2 = filter_depth(np.full((20, 30, 1), np.nan, np.float32), st)  # all NaN
    assert out.shape == (20, 30) and np.isnan(out).all() and (st2.count == 0).all()
    for kw in ({"reset_sigmas": 0.0}, {"window_px": 4}, {"max_frames": 0},
               {"depth_std_at_1m": float("nan")}, {"window_sigmas": -1.0}):
        with pytest.raises(ValueError, match=next(iter(kw))):
            DepthFilterConfig(**kw).validate()
    with pytest.raises(ValueError, match="height"):
        new_filter_state(0, 5)
    with pytest.raises(ValueError, match="noise_scale"):
        detect_fronts(np.full((K.height, K.width), 2.0, np.float32), K,
                      noise_scale=np.ones((3, 3), np.float32))


def _reveal_row_masks(n_frames, seed):
    """_gap_mask's thin mask on a plane 2.2 m away with a one-pixel row 3.3 mm behind (the
    closed drawer's reveal at the unlucky pixel phase) and on the plain plane, after n frames
    of the temporal filter (its noise scale passed on), and the row index."""
    rng = np.random.default_rng(seed)
    H, W = 160, 320
    clean = _plane(H, W)
    dip = clean.copy()
    row = 80
    dip[row, 40:280] += 0.0033  # 0.33 m at 2.2 m: a drawer's width and more
    masks = {}
    for name, img in (("dip", dip), ("plain", clean)):
        st = new_filter_state(H, W)
        for _ in range(n_frames):
            out, scale, st = filter_depth(_noisy(img, rng), st)
        valid = np.isfinite(out)
        vs = np.where(valid, scale * scale, np.float32(0.0)).astype(np.float32)
        masks[name] = _gap_mask(out, valid, 577.0, FrontDetectorConfig(),
                                np.where(valid, out, np.float32(0.0)), long_pass=False,
                                var_scale=vs)[1]
    return masks, row


def test_a_3mm_one_row_reveal_at_2_2m_is_found_after_n_frames_not_in_one():
    hit = {}
    for n in (1, 16):
        for seed in (0, 1):
            masks, row = _reveal_row_masks(n, seed)
            hit[n, seed] = masks["dip"][row, 60:260].mean()
            # nothing on the plain plane, nor off the row
            assert masks["plain"].mean() < 0.002, (n, seed)
            assert masks["dip"][: row - 2].mean() + masks["dip"][row + 3:].mean() < 0.004
    assert max(hit[1, s] for s in (0, 1)) < 0.3, hit   # 3.3 mm < 1 mm z^2 = 4.8 mm
    assert min(hit[16, s] for s in (0, 1)) > 0.9, hit  # 4.8 / 4 = 1.2 mm -> floor 2.5 mm


def test_noise_scale_of_ones_leaves_the_detector_unchanged():
    """noise_scale None and all ones give the same rectangles (a filter that has seen one
    frame changes nothing), and a smaller scale changes only the reveal threshold."""
    from mmlearn.models.perception.synth import (DRAWER_SIZE, add_depth_noise, front_pose,
                                                 kitchen_scene, look_at, render_depth)

    Kf = PinholeIntrinsics.from_fov(640, 480, 58.0)
    X = front_pose(0.75, 0.2, 0.6)
    X_WC = look_at(X[:3, 3] + np.array([1.6, 0.0, 0.0]) + [0, 0, 0.5], X[:3, 3])
    depth = add_depth_noise(render_depth(kitchen_scene([(DRAWER_SIZE, X, 0.02)]), Kf, X_WC),
                            np.random.default_rng(4))
    r0, _ = detect_fronts(depth, Kf, X_WC, FrontDetectorConfig(), rng=4)
    r1, _ = detect_fronts(depth, Kf, X_WC, FrontDetectorConfig(), rng=4,
                          noise_scale=np.ones(depth.shape, np.float32))
    assert len(r0) == len(r1) > 0
    for a, b in zip(r0, r1):
        np.testing.assert_array_equal(a.X_WR, b.X_WR)
        assert (a.width, a.height) == (b.width, b.height)


def _filter_diagram(H=24, W=32, rate=10.0, bad_frame=5):
    """A source of noisy frames (one per 1 / rate s; a wrong-sized one at ``bad_frame``) ->
    DepthTemporalFilter; returns (diagram, filter)."""
    from pydrake.common.value import AbstractValue
    from pydrake.systems.framework import DiagramBuilder, LeafSystem
    from pydrake.systems.sensors import ImageDepth32F

    from mmlearn.systems import DepthTemporalFilter

    clean = _plane(H, W)

    class Source(LeafSystem):
        def __init__(self):
            super().__init__()
            self.DeclareAbstractOutputPort("depth", lambda: AbstractValue.Make(
                ImageDepth32F(W, H)), self._calc, {self.time_ticket()})

        def _calc(self, context, out):
            k = int(round(context.get_time() * rate))
            if k == bad_frame:
                img = ImageDepth32F(W + 1, H)
                img.mutable_data[:, :, 0] = 1.0
            else:
                img = ImageDepth32F(W, H)
                img.mutable_data[:, :, 0] = _noisy(clean, np.random.default_rng(k))
            out.set_value(img)

    b = DiagramBuilder()
    src = b.AddSystem(Source())
    filt = b.AddSystem(DepthTemporalFilter(intrinsics=PinholeIntrinsics.from_fov(W, H, 58.0),
                                           rate_hz=rate))
    b.Connect(src.get_output_port(), filt.get_depth_image_input_port())
    return b.Build(), filt


def test_depth_temporal_filter_system_in_a_diagram():
    from pydrake.systems.analysis import Simulator

    from mmlearn.systems import DepthTemporalFilter

    rate = 10.0
    diagram, filt = _filter_diagram(rate=rate)
    sims = [Simulator(diagram) for _ in range(2)]  # two side by side: the same outputs
    for s in sims:
        s.Initialize()
    scales = []
    for k in range(8):
        outs = []
        for s in sims:
            s.AdvanceTo(k / rate)
            fctx = filt.GetMyContextFromRoot(s.get_context())
            sc = np.asarray(filt.get_noise_scale_output_port().Eval(fctx).data)[:, :, 0].copy()
            out = np.asarray(filt.get_depth_image_output_port().Eval(fctx).data)[:, :, 0].copy()
            outs.append((sc, out))
        np.testing.assert_array_equal(outs[0][0], outs[1][0])
        np.testing.assert_array_equal(outs[0][1], outs[1][1])
        scales.append(float(np.median(outs[0][0])))
        if k == 5:  # the bad frame: all NaN out, scale 1, the state kept
            assert np.isnan(outs[0][1]).all() and (outs[0][0] == 1.0).all()
    assert scales[:5] == pytest.approx([1 / math.sqrt(n) for n in range(1, 6)], rel=1e-5)
    assert scales[6] == pytest.approx(1 / math.sqrt(6), rel=1e-5)  # frame 5 skipped
    for bad in (0.0, float("nan"), True):
        with pytest.raises(ValueError, match="rate_hz"):
            DepthTemporalFilter(intrinsics=PinholeIntrinsics.from_fov(32, 24, 58.0), rate_hz=bad)
    with pytest.raises(TypeError, match="intrinsics"):
        DepthTemporalFilter(intrinsics=(32, 24), rate_hz=5.0)


def test_the_filter_state_is_immutable_and_copies_are_free():
    """The state's arrays are read-only, a deep copy is the state itself, and a frame gives
    a new state without touching the old one."""
    import copy

    st = new_filter_state(6, 8)
    assert copy.deepcopy(st) is st and copy.copy(st) is st
    for a in (st.mean, st.count, st.var_scale):
        assert not a.flags.writeable
        with pytest.raises(ValueError):
            a[0, 0] = 1
    depth = np.full((6, 8), 2.0, np.float32)
    _, _, st2 = filter_depth(depth, st, DepthFilterConfig())
    assert st2 is not st and not st2.mean.flags.writeable
    assert np.all(st.count == 0) and np.all(st2.count == 1) and np.all(st2.mean == 2.0)
    # a caller's writeable arrays are copied: writing to them later does not change the state
    mine = np.ones((6, 8), np.float32)
    own = type(st)(mine, np.ones((6, 8), np.int32), np.ones((6, 8), np.float32))
    mine[:] = 5.0
    assert np.all(own.mean == 1.0)
