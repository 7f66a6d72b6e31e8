"""A noise model that makes a rendered depth image look like an active-triangulation camera.

Thesis ch. 5 used a stereo camera with a texture projector (PR2, Konolige 2010); the Kinect
(v1) is the same principle (a projector and a camera a baseline apart, depth from disparity)
and is documented in numbers by Khoshelham & Oude Elberink (2012), "Accuracy and resolution
of Kinect depth data for indoor mapping applications", Sensors 12(2):1437-1454, whose
figures this model uses as its defaults:

* **disparity, not depth, is what is measured**: ``d = f b / z`` pixels for focal length f
  (pixels, the rendered camera's) and baseline b (K&E: b ~ 7.5 cm, f ~ 580 px);
* **random error growing with the square of the distance**: Gaussian noise of constant
  std in disparity, ``sigma_d = sigma_z_at_1m * f * b`` px, gives
  ``sigma_z(z) = sigma_z_at_1m * z^2`` (first-order error propagation of z = f b / d, as
  in K&E's error model). Default ``sigma_z_at_1m = 0.0016`` m: 1.6 mm at 1 m, 1.0 cm at
  2.5 m and 4 cm at 5 m (K&E report a random error growing quadratically with distance, from
  a few millimetres to about 4 cm at the 5 m maximum range);
* **disparity quantisation**: the disparity is rounded to ``disparity_step_px`` = 1/8 px
  (the Kinect's sub-pixel resolution), so depth comes in steps of ``z^2 step / (f b)``
  (2.9 mm at 1 m, 1.8 cm at 2.5 m, 7 cm at 5 m, the depth resolution K&E report at the
  5 m maximum range). Together with the noise, the std is
  ``sqrt(sigma_d^2 + step^2 / 12) z^2 / (f b)`` (:func:`predicted_depth_std`): 1.8 mm at
  1 m, 1.1 cm at 2.5 m with the defaults;
* **missing pixels at depth discontinuities**: (a) the projector's shadow, computed
  exactly per image row: a pixel is missing when a nearer surface blocks the line from the
  projector (placed ``baseline`` to the camera's +x, or -x for a negative baseline) to it;
  (b) the matcher's correlation window straddling a depth edge: pixels next to a disparity
  jump larger than ``edge_jump_px`` (and their ``edge_dilate_px`` neighbours) are missing;
* **grazing angles** (the thresholds are this model's choice, not K&E's): the share of missing pixels grows linearly from 0 at an incidence
  angle (between the viewing ray and the surface normal of the clean render) of
  ``grazing_start_deg`` to 1 at ``grazing_full_deg`` (drawn per 2 x 2 pixel block, from
  the angle on every second row and column);
* **range**: nothing nearer than ``min_range`` or farther than ``max_range`` (K&E: 0.5 to
  5 m); beyond ``falloff_start`` the share of drop-outs grows quadratically to 1 at
  ``max_range`` (the projector's pattern fading: the thesis' sensor lost density beyond
  2.2 m; set ``falloff_start = 2.2`` to imitate it);
* **random drop-outs** (1 % of 3 x 3 blocks by default, this model's choice): blocks of ``dropout_block_px`` x ``dropout_block_px`` pixels go
  missing with probability ``dropout`` each (blobs, as in real depth images).

Missing pixels are ``NaN`` (see :mod:`mmlearn.models.perception.fronts`). The output is a pure function
of the clean image, the intrinsics, the configuration, the seed and the frame index
(``numpy.random.default_rng([seed, frame])``), like :class:`~mmlearn.systems.MarkerSensor`.

Optional: spatially correlated noise (``noise_window_px``: the mean over a window, like a
block matcher's; off by default). Not modelled: lens distortion,
the IR camera's offset from the colour camera, multi-path and reflectance effects.
"""


import math
import time
from dataclasses import dataclass

import numpy as np

from mmlearn.models.common.camera import PinholeIntrinsics, as_depth_image
from mmlearn.models.common.config import param, validate_fields

__all__ = ["DepthNoiseConfig", "apply_depth_noise", "predicted_depth_std",
           "incidence_cosine", "projector_shadow"]


@dataclass
class DepthNoiseConfig:
    """Parameters of :func:`apply_depth_noise` (load with ``yaml_load_typed``).

    Attributes:
        baseline: projector-camera baseline, m (K&E 2012: 0.075). Its sign puts the
            projector on the camera's +x (positive) or -x side. Not 0.
        sigma_z_at_1m: depth noise std at 1 m, m; it grows with z^2 (K&E: 0.0016).
        noise_window_px: the disparity noise is the mean of i.i.d. noise over a square window
            of this many pixels (scaled back to ``sigma``): spatially correlated like a
            block matcher's; 1 = independent per pixel (default; odd integer >= 1).
        disparity_step_px: disparity quantisation, px (Kinect: 1/8); 0 = none.
        edge_jump_px: a disparity jump between neighbouring pixels larger than this (px)
            is a depth edge whose pixels go missing; 0 = no edge drop-outs.
        edge_dilate_px: widen the edge band by this many pixels on each side (>= 0).
        projector_shadow: drop pixels the projector cannot see (its shadow).
        grazing_start_deg, grazing_full_deg: incidence angles (deg) where grazing drop-out
            starts (0 %) and is complete (100 %).
        min_range, max_range: measurable depth range, m.
        falloff_start: depth (m) beyond which the drop-out share grows quadratically to 1
            at ``max_range`` (>= max_range: no fall-off).
        dropout: probability that a block of pixels is missing, in [0, 1).
        dropout_block_px: edge of the drop-out blocks, px (>= 1).
        seed: seed of the noise (an integer >= 0).
    """

    baseline: float = param(0.075, unit="m")
    sigma_z_at_1m: float = param(0.0016, unit="m", ge=0)
    noise_window_px: int = param(1, unit="px", integer=True, ge=1)
    disparity_step_px: float = param(0.125, unit="px", ge=0)
    edge_jump_px: float = param(0.25, unit="px", ge=0)
    edge_dilate_px: int = param(1, unit="px", integer=True, ge=0)
    projector_shadow: bool = param(True)
    grazing_start_deg: float = param(70.0, unit="deg", ge=0, lt=90)
    grazing_full_deg: float = param(85.0, unit="deg", gt=0, le=90)
    min_range: float = param(0.5, unit="m", ge=0)
    max_range: float = param(5.0, unit="m", gt=0)
    falloff_start: float = param(3.5, unit="m")
    dropout: float = param(0.01, ge=0, lt=1)
    dropout_block_px: int = param(3, unit="px", integer=True, ge=1)
    seed: int = param(0, integer=True, ge=0)

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first bad field."""
        validate_fields(self)
        checks = [
            (self.baseline != 0, f"baseline must be non-zero (m), got {self.baseline!r}"),
            (self.grazing_start_deg < self.grazing_full_deg,
             "need grazing_start_deg < grazing_full_deg (deg), got "
             f"{self.grazing_start_deg}, {self.grazing_full_deg}"),
            (self.min_range < self.max_range,
             f"need min_range < max_range (m), got {self.min_range}, {self.max_range}"),
            (self.falloff_start > self.min_range,
             f"falloff_start must be > min_range ({self.min_range} m), got "
             f"{self.falloff_start}"),
            (self.noise_window_px % 2 == 1,
             f"noise_window_px must be odd, got {self.noise_window_px}"),
        ]
        for ok, msg in checks:
            if not ok:
                raise ValueError(f"DepthNoiseConfig: {msg}")

    def sigma_disparity_px(self, K: PinholeIntrinsics) -> float:
        """Std of the disparity noise, px, for a camera with intrinsics K."""
        return self.sigma_z_at_1m * K.fx * abs(self.baseline)


def predicted_depth_std(z, K: PinholeIntrinsics, config: DepthNoiseConfig) -> np.ndarray:
    """Std (m) of the noisy depth of a surface at depth ``z`` (m), to first order: noise and
    quantisation (uniform, step^2 / 12) in disparity, scaled by z^2 / (f b)."""
    z = np.asarray(z, float)
    fb = K.fx * abs(config.baseline)
    s_d = math.hypot(config.sigma_disparity_px(K), config.disparity_step_px / math.sqrt(12.0))
    return s_d * z * z / fb


def _check_image(depth, K: PinholeIntrinsics) -> np.ndarray:
    d = as_depth_image(depth, K)
    if not np.issubdtype(d.dtype, np.floating):
        raise ValueError(f"depth image must hold floats (metres), got dtype {d.dtype}")
    return d.astype(np.float32, copy=False)


def incidence_cosine(depth, K: PinholeIntrinsics) -> np.ndarray:
    """Cosine of the angle between each pixel's viewing ray and the surface normal, (H, W).

    For P = z (a, b, 1) with a = (u - cx) / fx, b = (v - cy) / fy, the normal of the depth
    surface is n ~ (-fx z_u, -fy z_v, fx a z_u + fy b z_v + z) and n . (a, b, 1) = z, so
    ``cos = z / (|n| |(a, b, 1)|)`` with central differences z_u, z_v. NaN where a neighbour has
    no depth."""
    z = _check_image(depth, K)
    z = np.where(np.isfinite(z) & (z > 0), z, np.float32(np.nan))
    zu = np.full_like(z, np.nan)
    zv = np.full_like(z, np.nan)
    zu[:, 1:-1] = 0.5 * (z[:, 2:] - z[:, :-2])
    zv[1:-1, :] = 0.5 * (z[2:, :] - z[:-2, :])
    a = ((np.arange(K.width, dtype=np.float32) - K.cx) / K.fx)[None, :]
    b = ((np.arange(K.height, dtype=np.float32) - K.cy) / K.fy)[:, None]
    nx = np.float32(-K.fx) * zu
    ny = np.float32(-K.fy) * zv
    nz = np.float32(K.fx) * a * zu + np.float32(K.fy) * b * zv + z
    norm_n = np.sqrt(nx * nx + ny * ny + nz * nz)
    norm_r = np.sqrt(a * a + b * b + 1.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return z / (norm_n * norm_r)


def projector_shadow(disparity: np.ndarray, baseline_sign: float = 1.0) -> np.ndarray:
    """Pixels the projector cannot see, (H, W) bool.

    ``disparity`` (px; 0 or NaN = no surface) of every pixel; the projector sits at the
    camera's +x (``baseline_sign`` > 0) and sees pixel u at column u - d(u). A pixel is in
    the shadow when a pixel to its projector side maps to the same or a smaller projector
    column (a nearer surface in the way): a running minimum along each row."""
    d = np.nan_to_num(np.asarray(disparity, np.float32), nan=0.0)
    if baseline_sign < 0:
        return projector_shadow(d[:, ::-1], 1.0)[:, ::-1]
    return _shadow(d) & (d > 0)


def _shadow(d: np.ndarray) -> np.ndarray:
    """:func:`projector_shadow` for a clean float32 disparity (>= 0, 0 = no surface) and the
    projector at +x; pixels without a surface may come out True."""
    H, W = d.shape
    up = np.arange(W, dtype=np.float32) - d  # projector column of each pixel
    up[d <= 0] = np.inf  # surface-free pixels never occlude
    run = np.minimum.accumulate(up[:, ::-1], axis=1)[:, ::-1]  # min over columns >= u
    shadow = np.zeros((H, W), bool)
    np.less_equal(run[:, 1:], up[:, :-1] - np.float32(1e-3), out=shadow[:, :-1])
    return shadow


def _drop_share_half(z: np.ndarray, K: PinholeIntrinsics, cfg: DepthNoiseConfig) -> np.ndarray:
    """Share of missing pixels from the grazing angle and the range fall-off, on every
    second row and column, ((H + 1) // 2, (W + 1) // 2) float32 (the angle of a surface and
    its depth vary slowly; where they do not, at edges, the edge band removes the pixels)."""
    H, W = z.shape
    K2 = PinholeIntrinsics(-(-W // 2), -(-H // 2), K.fx / 2, K.fy / 2, K.cx / 2, K.cy / 2)
    z2 = np.ascontiguousarray(z[::2, ::2])
    cos_inc = incidence_cosine(z2, K2)
    c0 = math.cos(math.radians(cfg.grazing_start_deg))
    c1 = math.cos(math.radians(cfg.grazing_full_deg))
    p = np.clip((np.float32(c0) - np.nan_to_num(cos_inc, nan=1.0)) / np.float32(c0 - c1),
                0.0, 1.0)
    if cfg.falloff_start < cfg.max_range:
        far = np.isfinite(z2) & (z2 > cfg.falloff_start)
        if far.any():
            p_far = np.clip((z2[far] - cfg.falloff_start) / (cfg.max_range - cfg.falloff_start),
                            0.0, 1.0) ** 2
            p[far] = 1.0 - (1.0 - p[far]) * (1.0 - p_far)
    return p


def _up2(mask: np.ndarray, H: int, W: int) -> np.ndarray:
    """Repeat a half-resolution bool mask to (H, W)."""
    return np.repeat(np.repeat(mask, 2, axis=0), 2, axis=1)[:H, :W]


def _dilate(mask: np.ndarray, r: int) -> np.ndarray:
    if r <= 0:
        return mask
    import cv2

    kernel = np.ones((2 * r + 1, 2 * r + 1), np.uint8)
    return cv2.dilate(mask.view(np.uint8), kernel).astype(bool)


def apply_depth_noise(depth, K: PinholeIntrinsics, config: DepthNoiseConfig | None = None,
                      *, frame: int = 0, rng: np.random.Generator | None = None,
                      return_masks: bool = False, timings: dict | None = None):
    """The noisy image of a clean depth render (see the module docstring), float32 (H, W), m,
    NaN where missing.

    Args:
        depth: clean depth, (H, W) or (H, W, 1), m along the optical axis; non-finite or <= 0
            pixels (Drake's too-far = inf, too-close = 0) have no surface.
        K: the camera's intrinsics (f in pixels sets the disparity scale).
        config: the noise parameters (default :class:`DepthNoiseConfig`).
        frame: frame index >= 0; the noise is drawn from
            ``default_rng([config.seed, frame])`` unless ``rng`` is given.
        return_masks: also return a dict of the bool masks ``shadow``, ``edge``, ``grazing``,
            ``range``, ``dropout`` (pixels each cause removed; they may overlap).
        timings: if a dict, the CPU seconds (this thread's) spent per stage are added to it
            (``disparity``,
            ``shadow``, ``edges``, ``grazing``, ``dropout``, ``noise``, ``compose``).

    Raises:
        ValueError: wrong image shape or dtype, negative frame, bad configuration.
    """
    cfg = config or DepthNoiseConfig()
    cfg.validate()
    z = _check_image(depth, K)
    if int(frame) < 0:
        raise ValueError(f"apply_depth_noise: frame must be >= 0, got {frame}")
    if rng is None:
        rng = np.random.default_rng([int(cfg.seed), int(frame)])
    H, W = z.shape
    clock = [time.thread_time()]

    def _tick(stage):
        if timings is not None:
            now = time.thread_time()
            timings[stage] = timings.get(stage, 0.0) + now - clock[0]
            clock[0] = now

    fb = np.float32(K.fx * abs(cfg.baseline))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        disp = fb / z  # px; inf (z = 0), NaN and negatives below mean "no surface"
    disp = np.nan_to_num(disp, copy=False, nan=0.0, posinf=0.0, neginf=0.0)
    np.maximum(disp, 0.0, out=disp)
    surface = disp > 0
    in_range = (disp >= fb / np.float32(cfg.max_range)) & (
        disp <= (fb / np.float32(cfg.min_range) if cfg.min_range > 0 else np.inf))
    _tick("disparity")
    # (a) projector shadow, (b) matcher failures at disparity jumps
    if not cfg.projector_shadow:
        shadow = np.zeros((H, W), bool)
    elif cfg.baseline > 0:
        shadow = _shadow(disp)
    else:
        shadow = _shadow(np.ascontiguousarray(disp[:, ::-1]))[:, ::-1]
    _tick("shadow")
    edge = np.zeros((H, W), bool)
    if cfg.edge_jump_px > 0:
        jh = np.abs(disp[:, 1:] - disp[:, :-1]) > cfg.edge_jump_px
        jv = np.abs(disp[1:, :] - disp[:-1, :]) > cfg.edge_jump_px
        edge[:, 1:] |= jh
        edge[:, :-1] |= jh
        edge[1:, :] |= jv
        edge[:-1, :] |= jv
        edge = _dilate(edge, int(cfg.edge_dilate_px))
    _tick("edges")
    # grazing angles and range fall-off: one draw per 2 x 2 block (blob-like losses)
    p_half = _drop_share_half(z, K, cfg)
    grazing = _up2(rng.random(p_half.shape, dtype=np.float32) < p_half, H, W)
    _tick("grazing")
    # blocks of random drop-outs
    b = int(cfg.dropout_block_px)
    cells = rng.random((-(-H // b), -(-W // b))) < cfg.dropout
    dropped = np.repeat(np.repeat(cells, b, axis=0), b, axis=1)[:H, :W]
    _tick("dropout")

    # noise and quantisation in disparity
    noisy = rng.standard_normal((H, W), dtype=np.float32)
    n = int(cfg.noise_window_px)
    if n > 1:  # window mean, scaled back to unit std (away from the border)
        import cv2

        noisy = cv2.blur(noisy, (n, n), borderType=cv2.BORDER_REFLECT) * np.float32(n)
    noisy *= np.float32(cfg.sigma_disparity_px(K))
    noisy += disp
    if cfg.disparity_step_px > 0:
        step = np.float32(cfg.disparity_step_px)
        noisy /= step
        np.round(noisy, out=noisy)
        noisy *= step
    _tick("noise")
    keep = in_range & (noisy > 0)
    keep &= ~(shadow | edge | grazing | dropped)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.divide(fb, noisy, out=np.full((H, W), np.nan, np.float32), where=keep)
    _tick("compose")
    if return_masks:
        masks = {"shadow": shadow & surface, "edge": edge & surface,
                 "grazing": grazing & surface,
                 "range": surface & ~in_range, "dropout": dropped & surface}
        return out, masks
    return out
