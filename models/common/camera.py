"""Pinhole cameras and depth images: the conventions every depth consumer shares.

* **Depth images** are ``(H, W)`` float arrays in metres along the camera's optical axis (Drake's
  ``ImageDepth32F`` data, squeezed). A pixel without a measurement is ``NaN`` (what the
  depth-noise model writes, the ROS convention for 32-bit depth); every consumer also treats
  ``0``, negative values and ``inf`` (Drake's too-close / too-far codes) as "no measurement"
  (:func:`valid_depth_mask`).
* **Camera frame** C is Drake's: x right, y down, z forward (optical axis). ``X_WC`` is the
  camera pose in the world as a 4x4 homogeneous matrix at this layer.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["PinholeIntrinsics", "valid_depth_mask", "as_depth_image", "depth_to_points"]


@dataclass(frozen=True)
class PinholeIntrinsics:
    """A pinhole camera without distortion (Drake's ``CameraInfo``).

    Attributes:
        width, height: image size, pixels.
        fx, fy: focal lengths, pixels.
        cx, cy: principal point, pixels (column, row of the optical axis).
    """

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float

    @classmethod
    def from_fov(cls, width: int, height: int, fov_x_deg: float) -> "PinholeIntrinsics":
        """Square pixels, principal point in the image centre (Drake's ``CameraInfo(w, h, fov_y)``
        convention for the centre: ``(w - 1) / 2``, ``(h - 1) / 2``), horizontal field of view in
        degrees."""
        if width <= 0 or height <= 0:
            raise ValueError(f"PinholeIntrinsics: image size must be positive, got {width}x{height}")
        if not 0.0 < fov_x_deg < 180.0:
            raise ValueError(f"PinholeIntrinsics: fov_x_deg must be in (0, 180), got {fov_x_deg}")
        f = 0.5 * width / np.tan(0.5 * np.deg2rad(fov_x_deg))
        return cls(int(width), int(height), float(f), float(f),
                   0.5 * (width - 1), 0.5 * (height - 1))

    @classmethod
    def from_camera_info(cls, info) -> "PinholeIntrinsics":
        """From a ``pydrake.systems.sensors.CameraInfo`` (duck-typed: no import needed)."""
        return cls(int(info.width()), int(info.height()), float(info.focal_x()),
                   float(info.focal_y()), float(info.center_x()), float(info.center_y()))

    @property
    def fov_x_deg(self) -> float:
        return float(np.rad2deg(2.0 * np.arctan(0.5 * self.width / self.fx)))


def valid_depth_mask(depth: np.ndarray) -> np.ndarray:
    """Pixels with a measurement: finite and > 0 (NaN, inf, 0 and negative mean "none")."""
    d = np.asarray(depth)
    return np.isfinite(d) & (d > 0.0)


def as_depth_image(depth, K: PinholeIntrinsics, *, who: str = "") -> np.ndarray:
    """``depth`` as an ``(K.height, K.width)`` array (a trailing channel axis of 1, as in
    Drake's ``ImageDepth32F`` data, is dropped; no copy). Raises ``ValueError`` when the shape
    does not fit the intrinsics; ``who`` (e.g. ``"detect_fronts"``) prefixes the message."""
    d = np.asarray(depth)
    if d.ndim == 3 and d.shape[2] == 1:
        d = d[..., 0]
    if d.shape != (K.height, K.width):
        raise ValueError(f"{who + ': ' if who else ''}depth image has shape "
                         f"{np.asarray(depth).shape}, expected ({K.height}, {K.width}) for "
                         "these intrinsics")
    return d


def depth_to_points(depth: np.ndarray, K: PinholeIntrinsics) -> np.ndarray:
    """Back-project a depth image to camera-frame points, (H, W, 3), NaN where there is no
    measurement. Raises ``ValueError`` when the image's shape is not ``(K.height, K.width)``
    (a trailing channel axis of 1 is accepted)."""
    d = as_depth_image(depth, K).astype(float, copy=False)
    d = np.where(valid_depth_mask(d), d, np.nan)
    u = np.arange(K.width, dtype=float)[None, :]
    v = np.arange(K.height, dtype=float)[:, None]
    x = (u - K.cx) / K.fx * d
    y = (v - K.cy) / K.fy * d
    return np.stack([x, y, d], axis=-1)
