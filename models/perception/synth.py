"""Synthetic depth images of planar scenes, rendered in numpy (tests and benchmarks of ch. 5).

A scene is a list of :class:`PlanarPatch` (finite rectangles or infinite planes) and boxes made of
six patches. :func:`render_depth` ray-casts them for a pinhole camera (Drake camera frame: x
right, y down, z forward) and returns the z-depth image in metres, NaN where no patch is hit;
:func:`add_depth_noise` adds the error of an active-stereo camera (Gaussian depth noise growing
with the square of the distance, random drop-outs). This is a stand-in for the rendered Drake
camera of the scene diagrams: quick, exact ground truth, no renderer needed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mmlearn.models.common.camera import PinholeIntrinsics

__all__ = ["PlanarPatch", "box_patches", "look_at", "render_depth", "add_depth_noise",
           "pose_from_axes", "front_pose", "kitchen_scene", "DOOR_SIZE", "DRAWER_SIZE"]

#: the thesis' door and drawer fronts (5.2.2), width x height, m
DOOR_SIZE = (0.395, 0.58)
DRAWER_SIZE = (0.395, 0.125)


@dataclass(frozen=True)
class PlanarPatch:
    """A rectangle (or an infinite plane) in the world.

    Attributes:
        X_WP: (4, 4) pose of the centre; x along the width, y along the height, z the normal.
        width, height: extents along x and y, m (``np.inf`` for an unbounded plane).
    """

    X_WP: np.ndarray
    width: float
    height: float


def pose_from_axes(x, y, z, p) -> np.ndarray:
    """(4, 4) homogeneous matrix with the columns x, y, z (unit, right-handed) and origin p."""
    X = np.eye(4)
    X[:3, 0], X[:3, 1], X[:3, 2], X[:3, 3] = x, y, z, p
    return X


def box_patches(X_WB: np.ndarray, size) -> list[PlanarPatch]:
    """The six faces of a box with centre pose ``X_WB`` and full ``size`` (sx, sy, sz), m."""
    sx, sy, sz = (float(s) for s in size)
    R, p = np.asarray(X_WB, float)[:3, :3], np.asarray(X_WB, float)[:3, 3]
    ex, ey, ez = R[:, 0], R[:, 1], R[:, 2]
    faces = []
    for n, a, b, half, wa, wb in ((ex, ey, ez, sx / 2, sy, sz), (ey, ez, ex, sy / 2, sz, sx),
                                  (ez, ex, ey, sz / 2, sx, sy)):
        for sgn in (1.0, -1.0):
            z = sgn * n
            x = a
            y = np.cross(z, x)
            faces.append(PlanarPatch(pose_from_axes(x, y, z, p + sgn * half * n), wa, wb))
    return faces


def look_at(position, target, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """Camera pose X_WC (Drake camera axes: z forward, x right, y down) at ``position`` looking
    at ``target`` with world ``up`` upwards in the image."""
    p = np.asarray(position, float)
    z = np.asarray(target, float) - p
    z /= np.linalg.norm(z)
    x = np.cross(z, np.asarray(up, float))
    if np.linalg.norm(x) < 1e-9:
        raise ValueError("look_at: the view direction is parallel to 'up'")
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return pose_from_axes(x, y, z, p)


def render_depth(patches, K: PinholeIntrinsics, X_WC) -> np.ndarray:
    """Z-depth image (K.height, K.width), metres, of the nearest patch along each pixel's ray
    (NaN where the ray hits nothing)."""
    X_WC = np.asarray(X_WC, float)
    R_WC, p_WC = X_WC[:3, :3], X_WC[:3, 3]
    u = (np.arange(K.width) - K.cx) / K.fx
    v = (np.arange(K.height) - K.cy) / K.fy
    d = np.stack(np.broadcast_arrays(u[None, :], v[:, None], np.ones((1, 1))), -1)  # z = 1
    depth = np.full((K.height, K.width), np.inf)
    for patch in patches:
        X = np.asarray(patch.X_WP, float)
        c = R_WC.T @ (X[:3, 3] - p_WC)            # patch centre in C
        a1, a2, n = (R_WC.T @ X[:3, :3]).T        # patch axes in C
        dn = d @ n
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (c @ n) / dn                        # z-depth of the hit (d_z = 1)
        q = t[..., None] * d - c
        inside = (np.abs(q @ a1) <= 0.5 * patch.width) & (np.abs(q @ a2) <= 0.5 * patch.height)
        hit = inside & np.isfinite(t) & (t > 1e-6)
        depth = np.where(hit & (t < depth), t, depth)
    depth[~np.isfinite(depth)] = np.nan
    return depth


def add_depth_noise(depth: np.ndarray, rng: np.random.Generator, *, sigma_at_1m: float = 0.0015,
                    dropout: float = 0.01, max_range: float = 4.0) -> np.ndarray:
    """Noisy copy of a depth image: z + N(0, (sigma_at_1m * z^2)^2) (so 1.5 mm at 1 m and
    9.4 mm at 2.5 m by default, metres), a share ``dropout`` of pixels set to NaN at random, and
    NaN beyond ``max_range`` (m)."""
    d = np.array(depth, float)
    d = d + rng.standard_normal(d.shape) * sigma_at_1m * d ** 2
    d[rng.random(d.shape) < dropout] = np.nan
    d[d > max_range] = np.nan
    return d


def front_pose(x, y, z, yaw=0.0) -> np.ndarray:
    """Pose of a vertical front centred at (x, y, z) facing +x rotated by ``yaw`` (rad) about
    world z: x along the (horizontal) width, y down, z the outward normal."""
    c, s = np.cos(yaw), np.sin(yaw)
    return pose_from_axes([s, -c, 0.0], [0.0, 0.0, -1.0], [c, s, 0.0], [x, y, z])


def kitchen_scene(fronts) -> list[PlanarPatch]:
    """A wall (plane x = 0, facing +x), the floor (z = 0), a cabinet carcass 0.6 m deep,
    1.2 m wide and 0.9 m high against the wall, plus ``fronts``: (size (w, h), X_WF,
    thickness) each, a thin box whose outer face is the front rectangle X_WF (m)."""
    patches = [PlanarPatch(pose_from_axes([0, 1, 0], [0, 0, -1], [1, 0, 0], [0, 0, 1.5]),
                           np.inf, np.inf),
               PlanarPatch(np.eye(4), np.inf, np.inf)]
    patches += box_patches(pose_from_axes([1, 0, 0], [0, 1, 0], [0, 0, 1], [0.3, 0.0, 0.45]),
                           [0.6, 1.2, 0.9])
    for (w, h), X, t in fronts:
        Xb = np.array(X, float)
        Xb[:3, 3] -= 0.5 * t * Xb[:3, 2]
        patches += box_patches(Xb, [w, h, t])
    return patches
