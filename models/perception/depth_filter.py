"""A temporal filter for depth images of a mostly static scene.

Real depth pipelines average consecutive frames where the scene does not move (e.g. the
RealSense SDK's temporal filter: a per-pixel running mean that restarts where a pixel's new
value jumps by more than a threshold). The thesis (ch. 5) processes every stereo frame on its
own and says nothing about filtering: this is an addition, off unless a diagram inserts it.
Why it is here: a closed drawer flush with its neighbours is parted from them only by its 5 mm
reveals; at 2.2 m the reveal below it is one pixel row whose depth, at the pixel phase there,
is only 3.3 mm behind the faces, while one frame's per-pixel noise is ~8.7 mm
(:func:`mmlearn.models.common.depth_noise.predicted_depth_std`). Averaged over n static frames the
noise falls to sigma / sqrt(n) and the reveal test's threshold can follow it
(:func:`mmlearn.models.perception.detection.detect_fronts`' ``noise_scale``).

State per pixel (:class:`DepthFilterState`): the running mean (m), the number of frames in it,
and the variance of the mean relative to one frame's (``var_scale``: 1 / n while the count
is below ``max_frames``; beyond, the mean is exponential with weight 1 / ``max_frames`` and
its variance factor follows the exact recursion v <- (1 - a)^2 v + a^2). Each new frame:

* a pixel without a measurement (NaN, <= 0, inf) keeps its state; its output is NaN (the
  camera did not see it in this frame: drop-out lines, e.g. a reveal seen straight on, stay);
* a pixel whose new value differs from its mean by more than ``reset_sigmas`` x the predicted
  std of that difference, sigma(z) sqrt(1 + v) (sigma(z) = ``depth_std_at_1m`` z^2, the
  camera's per-pixel noise), restarts from the new value (an edge or occluder moved over it);
* a slow move (a drawer sliding 1 cm per frame at 2.2 m moves by ~1.3 sigma, which a
  per-pixel test cannot see) is found on the mean difference over a ``window_px`` square:
  it scatters by sigma sqrt(1 + v) / sqrt(count) and is compared with ``window_sigmas`` times
  that; every pixel within the window of a changed window restarts (so an object's border
  is reset with it);
* the other pixels are averaged: m <- m + a (z - m), a = 1 / min(n + 1, max_frames).

Assumption (stated, not measured on a real camera): the noise is independent from frame to
frame, as :func:`mmlearn.models.common.depth_noise.apply_depth_noise` draws it. A real structured
light camera also has a static per-pixel error pattern, which no temporal mean removes; its
gain is then smaller than 1 / sqrt(n).
"""

from dataclasses import dataclass

import cv2
import numpy as np

from mmlearn.models.common.config import param, validate_fields

__all__ = ["DepthFilterConfig", "DepthFilterState", "new_filter_state", "filter_depth"]


@dataclass
class DepthFilterConfig:
    """Parameters of :func:`filter_depth` (load with ``yaml_load_typed``).

    Attributes:
        depth_std_at_1m: the camera's per-pixel depth noise std at 1 m, m; it grows with z^2
            (the default noise model's: 1.6 mm noise and 1/8 px quantisation in disparity,
            1.8 mm at 1 m, :func:`mmlearn.models.common.depth_noise.predicted_depth_std`).
        reset_sigmas: a pixel whose new value is this many predicted stds from its mean
            restarts, unitless (> 0).
        window_px: side of the square window of the slow-move test, px (odd, >= 1; 1 = off).
        window_sigmas: a window whose mean difference exceeds this many of its predicted stds
            restarts, unitless (> 0).
        max_frames: the mean counts at most this many frames (beyond, exponential with weight
            1 / max_frames: a change below the tests' thresholds fades out), >= 1 (1 = no
            filtering: the output is the input).
    """

    depth_std_at_1m: float = param(0.0018, unit="m", gt=0)
    reset_sigmas: float = param(4.0, gt=0)
    window_px: int = param(9, unit="px, odd", integer=True, ge=1)
    window_sigmas: float = param(4.0, gt=0)
    max_frames: int = param(16, integer=True, ge=1)

    def validate(self) -> "DepthFilterConfig":
        """Raise ``ValueError`` naming the first bad field; return the config."""
        validate_fields(self)
        if self.window_px % 2 == 0:
            raise ValueError(f"DepthFilterConfig: window_px must be odd, got {self.window_px}")
        return self


@dataclass(frozen=True, eq=False)
class DepthFilterState:
    """Per-pixel state of :func:`filter_depth`, (H, W) arrays each. Immutable: the arrays are
    read-only and :func:`filter_depth` returns a new state, so a copy is the state itself
    (``copy.deepcopy`` returns it: a Drake abstract state holding it is copied for free).

    Attributes:
        mean: running mean depth, m (0 where the pixel has never been measured).
        count: frames in the mean since the last restart (0 = none), capped at
            ``max_frames``.
        var_scale: variance of the mean over one frame's variance (1 / count below the cap;
            1 where count is 0).
    """

    mean: np.ndarray
    count: np.ndarray
    var_scale: np.ndarray

    def __post_init__(self):
        for name in ("mean", "count", "var_scale"):
            a = getattr(self, name)
            if a.flags.writeable:  # (a copy: the caller may still write to its array)
                a = a.copy()
                a.flags.writeable = False
                object.__setattr__(self, name, a)

    @property
    def shape(self):
        return self.mean.shape

    def copy(self) -> "DepthFilterState":
        return self

    def __copy__(self):
        return self

    def __deepcopy__(self, memo):
        return self


def new_filter_state(height: int, width: int) -> DepthFilterState:
    """An empty state for (height, width) images (no pixel measured yet)."""
    for name, v in (("height", height), ("width", width)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
            raise ValueError(f"new_filter_state: {name} must be an integer >= 1, got {v!r}")
    return DepthFilterState(*_read_only(np.zeros((height, width), np.float32),
                                        np.zeros((height, width), np.int32),
                                        np.ones((height, width), np.float32)))


def _read_only(*arrays):
    """The arrays, made read-only in place (fresh arrays nobody else holds)."""
    for a in arrays:
        a.flags.writeable = False
    return arrays


def filter_depth(depth, state: DepthFilterState, config: DepthFilterConfig | None = None):
    """One frame through the temporal filter (see the module docstring).

    Args:
        depth: (H, W) or (H, W, 1) depth image, m; NaN / <= 0 / inf = no measurement.
        state: the state after the previous frame (:func:`new_filter_state` for the first);
            not modified.
        config: :class:`DepthFilterConfig` (defaults when None).

    Returns:
        (filtered, noise_scale, new_state): the filtered depth (float32 (H, W), m, NaN where
        this frame has no measurement), the std of each filtered pixel relative to one
        frame's (float32 (H, W), sqrt(var_scale), in (0, 1]; 1 where NaN), and the new state.

    Raises:
        ValueError: a depth image of another shape than the state's or not numeric, a bad
            configuration.
    """
    cfg = config or DepthFilterConfig()
    cfg.validate()
    z = np.asarray(depth)
    if z.ndim == 3 and z.shape[2] == 1:
        z = z[:, :, 0]
    if z.shape != state.shape:
        raise ValueError(f"filter_depth: depth image of shape {z.shape}, the filter's state is "
                         f"{state.shape}")
    if not (np.issubdtype(z.dtype, np.floating) or np.issubdtype(z.dtype, np.integer)):
        raise ValueError(f"filter_depth: depth image must be numeric, got dtype {z.dtype}")
    z = z.astype(np.float32, copy=False)
    with np.errstate(invalid="ignore"):
        meas = np.isfinite(z) & (z > 0)
    zz = np.where(meas, z, np.float32(0.0))
    m0, n0, v0 = state.mean, state.count, state.var_scale
    both = meas & (n0 > 0)
    # predicted std of (new - mean): sigma(z) sqrt(1 + v)
    sig = np.float32(cfg.depth_std_at_1m) * zz * zz
    sd = sig * np.sqrt(np.float32(1.0) + v0)
    diff = np.where(both, zz - m0, np.float32(0.0))
    reset = both & (np.abs(diff) > np.float32(cfg.reset_sigmas) * sd)
    w = int(cfg.window_px)
    if w > 1 and both.any():
        b = both.astype(np.float32)
        k = (w, w)
        s_diff = cv2.boxFilter(diff, -1, k, normalize=False, borderType=cv2.BORDER_CONSTANT)
        s_var = cv2.boxFilter(np.where(both, sd * sd, np.float32(0.0)), -1, k, normalize=False,
                              borderType=cv2.BORDER_CONSTANT)
        cnt = cv2.boxFilter(b, -1, k, normalize=False, borderType=cv2.BORDER_CONSTANT)
        # mean difference over the window vs its std sqrt(sum var) / count
        with np.errstate(invalid="ignore", divide="ignore"):
            moved = (s_diff * s_diff > np.float32(cfg.window_sigmas ** 2) * s_var) & (cnt >= 3)
        if moved.any():
            moved = cv2.dilate(moved.view(np.uint8), np.ones(k, np.uint8)).view(bool)
            reset |= moved & both
    start = meas & ((n0 == 0) | reset)
    upd = both & ~reset
    n1 = np.where(start, 1, np.where(upd, np.minimum(n0 + 1, int(cfg.max_frames)), n0))
    n1 = n1.astype(np.int32)
    a = np.where(upd, np.float32(1.0) / np.maximum(n1, 1).astype(np.float32), np.float32(1.0))
    m1 = np.where(start, zz, np.where(upd, m0 + a * (zz - m0), m0)).astype(np.float32)
    one_a = np.float32(1.0) - a
    v1 = np.where(start, np.float32(1.0),
                  np.where(upd, one_a * one_a * v0 + a * a, v0)).astype(np.float32)
    out = np.where(meas, m1, np.float32(np.nan)).astype(np.float32)
    scale = np.where(meas, np.sqrt(v1), np.float32(1.0)).astype(np.float32)
    return out, scale, DepthFilterState(*_read_only(m1, n1, v1))
