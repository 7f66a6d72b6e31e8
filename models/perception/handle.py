"""Where is the handle? From detected cabinet fronts to the handle the robot hooks
(thesis 4.3 with the detector of 5.1).

Plain numpy (no pydrake.systems): :func:`select_front` picks the detected rectangle that is
the front to open, :func:`handle_from_front` derives the handle's centre from it and the depth
image.

How the handle is found. The rectangle gives the front's plane (its outward normal ``n``), its
horizontal axis ``e_y = up x n`` (the furniture's +y: to the robot's right when it faces the
front... see ``sdf/mechanisms.py``: the robot looks along -x, its left is -y) and its vertical
extent. The handle is a bar standing off the front (``sdf/mechanisms.py``: 0.07 m, radius
0.01 m): the measured points in front of the rectangle between ``bar_min_standoff`` and
``bar_max_standoff`` are the bar and its posts; their median along ``e_y`` and the in-plane
up axis is the bar's centre (posts at both ends of the bar keep the median centred), their
95th percentile off the plane minus the bar's radius its standoff. When fewer than
``min_bar_points`` such points are seen, the handle is placed by the object kind's convention
(the rectangle alone):

* left_door: the hinge is on the front's left edge as seen from the robot (-e_y, the kind's
  definition), the handle ``handle_offset`` m inside the right (free) edge;
  right_door: mirrored; both ``handle_height`` m above the front's lower edge;
* dishwasher: centred, ``dishwasher_handle_offset`` m below the top edge (hinge at the bottom);
* drawer: the centre of the front (the mechanism's bar is at mid height);
* sliding_door: ``handle_offset`` m left of the centre of the (sliding) panel, at
  ``handle_height``.

The hinge side is thus known from the kind (which the robot is told, as with the click), not
seen.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mmlearn.models.common.camera import PinholeIntrinsics, depth_to_points
from mmlearn.models.common.config import param, validate_fields
from mmlearn.models.perception.fronts import FrontRectangle

__all__ = ["HandleFromFrontConfig", "HandleEstimate", "front_axes", "select_front",
           "handle_from_front"]

_KINDS = ("left_door", "right_door", "dishwasher", "drawer", "sliding_door")


@dataclass
class HandleFromFrontConfig:
    """Parameters of :func:`select_front` and :func:`handle_from_front`.

    Attributes:
        min_width, max_width: plausible front width (horizontal extent), m.
        min_height, max_height: plausible front height (vertical extent), m.
        max_tilt_deg: the front's normal is at most this far from horizontal, deg.
        max_view_angle_deg: the normal is at most this far from the direction to the
            camera (the front faces the robot), deg.
        max_target_distance: the chosen front's centre is at most this far from where the
            robot was sent, m.
        handle_offset: door / sliding-door handle's distance from the free edge (sliding:
            from the panel's centre) when the bar is not seen, m.
        handle_height: door / sliding-door handle's height above the front's lower edge when
            the bar is not seen, m.
        dishwasher_handle_offset: dishwasher handle's distance below the top edge when the
            bar is not seen, m.
        bar_min_standoff, bar_max_standoff: points this far in front of the front's plane are
            the handle's, m.
        bar_radius: radius of the handle bar (its seen surface is this much in front of its
            centre), m.
        search_margin: the bar's points are searched over the rectangle grown by this, m.
        min_bar_points: fewer bar points than this: place the handle by the kind's
            convention.
        floor_clearance: points lower than this above the floor (world z = 0) are never
            the handle's (in front of a front detected down to the plinth lies the floor),
            m.
    """

    min_width: float = param(0.2, unit="m", gt=0)
    max_width: float = param(0.8, unit="m", ge=0)
    min_height: float = param(0.1, unit="m", gt=0)
    max_height: float = param(0.9, unit="m", ge=0)
    max_tilt_deg: float = param(20.0, unit="deg", ge=0)
    max_view_angle_deg: float = param(70.0, unit="deg", ge=0)
    max_target_distance: float = param(0.3, unit="m", ge=0)
    handle_offset: float = param(0.07, unit="m", ge=0)
    handle_height: float = param(0.325, unit="m", ge=0)
    dishwasher_handle_offset: float = param(0.065, unit="m", ge=0)
    bar_min_standoff: float = param(0.035, unit="m", ge=0)
    bar_max_standoff: float = param(0.15, unit="m", ge=0)
    bar_radius: float = param(0.01, unit="m", ge=0)
    search_margin: float = param(0.03, unit="m", ge=0)
    min_bar_points: int = param(20, integer=True, ge=0)
    floor_clearance: float = param(0.05, unit="m", ge=0)

    def validate(self) -> "HandleFromFrontConfig":
        """Raise ``ValueError`` naming the first bad field; return the config."""
        validate_fields(self)
        if not self.min_width <= self.max_width:
            raise ValueError("HandleFromFrontConfig: need min_width <= max_width (m), got "
                             f"{self.min_width} > {self.max_width}")
        if not self.min_height <= self.max_height:
            raise ValueError("HandleFromFrontConfig: need min_height <= max_height (m), got "
                             f"{self.min_height} > {self.max_height}")
        if not self.bar_min_standoff < self.bar_max_standoff:
            raise ValueError("HandleFromFrontConfig: need bar_min_standoff < bar_max_standoff "
                             f"(m), got {self.bar_min_standoff} >= {self.bar_max_standoff}")
        return self


@dataclass
class HandleEstimate:
    """A handle derived from a front.

    Attributes:
        handle: (3,) handle centre, world, m.
        normal: (3,) the front's outward normal (horizontal, unit), world.
        bar: (3,) the bar's direction (unit), world.
        e_y: (3,) the front's horizontal axis (the furniture's +y), world.
        front: the chosen :class:`FrontRectangle`.
        source: "bar" (from the bar's points) or "rectangle" (the kind's convention).
        bar_points: number of points seen on the bar.
    """

    handle: np.ndarray
    normal: np.ndarray
    bar: np.ndarray
    e_y: np.ndarray
    front: FrontRectangle
    source: str
    bar_points: int


def front_axes(rect: FrontRectangle):
    """(n, e_y, e_z, extents): the horizontal outward normal, the horizontal in-plane axis
    ``up x n``, the in-plane up axis, and the corners' (y_min, y_max, z_min, z_max) relative
    to the centre along e_y, e_z (m)."""
    n = rect.normal.copy()
    n[2] = 0.0
    norm = np.linalg.norm(n)
    if norm < 1e-6:
        raise ValueError("front_axes: the rectangle's normal is vertical")
    n /= norm
    e_y = np.cross([0.0, 0.0, 1.0], n)
    e_z = np.cross(rect.normal, e_y)
    e_z /= np.linalg.norm(e_z)
    rel = rect.corners() - rect.center
    y, z = rel @ e_y, rel @ e_z
    return n, e_y, e_z, (float(y.min()), float(y.max()), float(z.min()), float(z.max()))


def select_front(rects, camera_position, target, config: HandleFromFrontConfig | None = None):
    """The rectangle that is the front to open: plausible size, facing the robot (the
    camera), nearest to ``target`` (where the robot was sent, world, m) and within
    ``max_target_distance`` of it; None when none qualifies."""
    cfg = config or HandleFromFrontConfig()
    cfg.validate()
    cam = np.asarray(camera_position, float)
    target = np.asarray(target, float)
    if cam.shape != (3,) or target.shape != (3,) or not (np.all(np.isfinite(cam))
                                                         and np.all(np.isfinite(target))):
        raise ValueError("select_front: camera_position and target must be finite 3-vectors")
    best, best_d = None, math.inf
    for r in rects:
        nz = abs(float(r.normal[2]))
        if nz > math.sin(math.radians(cfg.max_tilt_deg)):
            continue
        to_cam = cam - r.center
        to_cam /= max(np.linalg.norm(to_cam), 1e-9)
        if float(r.normal @ to_cam) < math.cos(math.radians(cfg.max_view_angle_deg)):
            continue
        _, _, _, (y0, y1, z0, z1) = front_axes(r)
        w, h = y1 - y0, z1 - z0
        if not (cfg.min_width <= w <= cfg.max_width and cfg.min_height <= h <= cfg.max_height):
            continue
        d = float(np.linalg.norm(r.center - target))
        if d <= cfg.max_target_distance and d < best_d:
            best, best_d = r, d
    return best


def handle_from_front(kind: str, rect: FrontRectangle, depth, K: PinholeIntrinsics,
                      X_WC, config: HandleFromFrontConfig | None = None) -> HandleEstimate:
    """The handle of a front of the given kind (see the module docstring) from its rectangle
    and the depth image it was detected in (``depth`` (H, W) m, ``X_WC`` (4, 4) the camera
    pose the rectangle is expressed with)."""
    cfg = config or HandleFromFrontConfig()
    cfg.validate()
    if kind not in _KINDS:
        raise ValueError(f"handle_from_front: kind must be one of {_KINDS}, got {kind!r}")
    X_WC = np.asarray(X_WC, float)
    if X_WC.shape != (4, 4) or not np.all(np.isfinite(X_WC)):
        raise ValueError("handle_from_front: X_WC must be a finite 4x4 matrix")
    n, e_y, e_z, (y0, y1, z0, z1) = front_axes(rect)
    c = rect.center
    P = depth_to_points(depth, K).reshape(-1, 3)
    P = P[np.isfinite(P[:, 2])]
    P = P @ X_WC[:3, :3].T + X_WC[:3, 3]
    rel = P - c
    s, y, z = rel @ rect.normal, rel @ e_y, rel @ e_z
    m = cfg.search_margin
    sel = ((s >= cfg.bar_min_standoff) & (s <= cfg.bar_max_standoff)
           & (y >= y0 - m) & (y <= y1 + m) & (z >= z0 - m) & (z <= z1 + m)
           & (P[:, 2] >= cfg.floor_clearance))
    count = int(sel.sum())
    vertical = kind in ("left_door", "right_door", "sliding_door")
    bar = e_z.copy() if vertical else e_y.copy()
    if count >= cfg.min_bar_points:
        # the bar's own surface: the points within a bar diameter of the outermost ones
        # (the posts reach back to the front); along the bar the middle of its seen extent
        # (the camera sees one post better than the other), across it the median; off the
        # front the mean of the seen half-cylinder, which is pi / 4 r in front of its axis
        s_top = float(np.percentile(s[sel], 95))
        on_bar = sel & (s >= s_top - 2 * cfg.bar_radius)
        along, across = (z, y) if vertical else (y, z)
        lo, hi = np.percentile(along[on_bar], [2, 98])
        a_c, x_c = 0.5 * float(lo + hi), float(np.median(across[on_bar]))
        hy, hz = (x_c, a_c) if vertical else (a_c, x_c)
        hs = float(np.mean(s[on_bar])) - math.pi / 4 * cfg.bar_radius
        source = "bar"
    else:
        hs = 0.07  # sdf/mechanisms.py's standoff (MechanismSpec.handle_standoff)
        zc = 0.5 * (z0 + z1)
        hz_door = float(np.clip(z0 + cfg.handle_height, min(zc, z0 + 0.1), max(zc, z1 - 0.1)))
        if kind == "left_door":
            hy, hz = y1 - cfg.handle_offset, hz_door
        elif kind == "right_door":
            hy, hz = y0 + cfg.handle_offset, hz_door
        elif kind == "sliding_door":
            hy, hz = 0.5 * (y0 + y1) - cfg.handle_offset, hz_door
        elif kind == "dishwasher":
            hy, hz = 0.5 * (y0 + y1), z1 - cfg.dishwasher_handle_offset
        else:
            hy, hz = 0.5 * (y0 + y1), zc
        source = "rectangle"
    handle = c + hy * e_y + hz * e_z + hs * rect.normal
    return HandleEstimate(handle=handle, normal=n, bar=bar, e_y=e_y, front=rect,
                          source=source, bar_points=count)
