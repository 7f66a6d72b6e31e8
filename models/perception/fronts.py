"""Cabinet fronts seen as rectangles in depth images (thesis ch. 5): the shared data types.

This module holds what the detector, the tracker, the depth-noise model and the apps agree on;
it has no pydrake.systems import (ARCHITECTURE.md: ``models/`` is plain numpy).

Conventions
-----------
* **Depth images** are ``(H, W)`` float arrays in metres along the camera's optical axis (Drake's
  ``ImageDepth32F`` data, squeezed). A pixel without a measurement is ``NaN`` (what the
  depth-noise model writes, the ROS convention for 32-bit depth); every consumer also treats
  ``0``, negative values and ``inf`` (Drake's too-close / too-far codes) as "no measurement"
  (:func:`valid_depth_mask`).
* **Camera frame** C is Drake's: x right, y down, z forward (optical axis). ``X_WC`` is the
  camera pose in the world as a 4x4 homogeneous matrix at this layer.
* **A rectangle** R (:class:`FrontRectangle`): its pose ``X_WR`` is the centre of the
  rectangle with x along the width, y along the height and z the plane normal pointing
  towards the camera that saw it; ``width`` >= 0 along x and ``height`` >= 0 along y, metres.
  The same physical rectangle has 8 such parameterisations (which corner / side is "first",
  thesis 5.1.3): the tracker resolves that ambiguity, the detector returns any one of them with
  z towards the camera.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["FrontRectangle"]


@dataclass(frozen=True)
class FrontRectangle:
    """A planar rectangle in the world (a cabinet front), as detected in one depth image.

    Attributes:
        X_WR: (4, 4) pose of the centre: x along the width, y along the height, z the plane
            normal towards the camera.
        width: extent along x, m.
        height: extent along y, m.
        precision: share of the rectangle's projected pixels that lie in its plane (Eq. 5.4).
        recall: share of the plane's in-plane pixels near the rectangle that it covers (Eq. 5.5).
    """

    X_WR: np.ndarray
    width: float
    height: float
    precision: float = 1.0
    recall: float = 1.0

    def __post_init__(self):
        X = np.asarray(self.X_WR, float)
        if X.shape != (4, 4) or not np.all(np.isfinite(X)):
            raise ValueError(f"FrontRectangle.X_WR must be a finite 4x4 matrix, got shape {X.shape}")
        if not (np.isfinite(self.width) and np.isfinite(self.height)) or self.width < 0 or self.height < 0:
            raise ValueError(f"FrontRectangle: width/height must be finite and >= 0, got "
                             f"{self.width}, {self.height}")
        object.__setattr__(self, "X_WR", X)

    @property
    def center(self) -> np.ndarray:
        return self.X_WR[:3, 3].copy()

    @property
    def normal(self) -> np.ndarray:
        return self.X_WR[:3, 2].copy()

    def corners(self) -> np.ndarray:
        """(4, 3) world corners, counter-clockwise seen from +z: (-w/2, -h/2), (+, -), (+, +), (-, +)."""
        hw, hh = 0.5 * self.width, 0.5 * self.height
        local = np.array([[-hw, -hh, 0.0], [hw, -hh, 0.0], [hw, hh, 0.0], [-hw, hh, 0.0]])
        return local @ self.X_WR[:3, :3].T + self.X_WR[:3, 3]

    def pose7(self) -> np.ndarray:
        """(7,) x y z qx qy qz qw of ``X_WR`` (the track format of ``models/``)."""
        from mmlearn.models.common.se3 import matrix_to_pose7
        return np.asarray(matrix_to_pose7(self.X_WR[None]), float)[0]
