"""Simulated articulated links with known ground truth (thesis Sec. 4.4.4, Fig. 4.19).

:func:`simulate_link` draws relative-pose tracks of a link type with Gaussian noise
(``sigma_pos`` metres per axis, ``sigma_orient`` radians per rotation-vector axis) and uniform
outliers (ratio ``gamma``: uniform position in the cube of side max(1 m, extent + 6 sigma)
centred on the track, the same volume the observation model assumes, and uniformly random
orientation).

Link types (configuration q drawn uniformly over the range unless ``q`` is given):

- ``rigid``: fixed pose.
- ``prismatic`` / ``drawer``: translation along a unit axis, q in [0, 0.5] m.
- ``revolute`` / ``microwave``: door of radius 0.3 m about a vertical axis, q in [0, pi/2].
- ``rollup``: roll-up garage door (Fig. 4.19): a vertical segment of 1 m, a quarter circle of
  radius 0.5 m, then a horizontal segment of 1 m; q in [0, 2 + pi/4] m path length; the door
  segment's orientation follows the tangent of the path.
- ``garage``: the same roll-up path scaled by 2 (a garage-size door).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

__all__ = ["SimulatedTrack", "simulate_link", "true_pose", "LINK_TYPES", "drawer_with_lid_tracks"]

LINK_TYPES = ("rigid", "prismatic", "drawer", "revolute", "microwave", "rollup", "garage")

_BASE_R = Rotation.from_euler("xyz", [0.1, -0.2, 0.3])
_BASE_P = np.array([0.5, -0.2, 0.8])


@dataclass
class SimulatedTrack:
    """Noisy observations ``Z`` (n, 7), noise-free poses ``Z_true`` (n, 7), true configurations
    ``q`` (n,), outlier mask (n,)."""

    Z: np.ndarray
    Z_true: np.ndarray
    q: np.ndarray
    outlier: np.ndarray
    kind: str


def _q_range(kind):
    if kind in ("prismatic", "drawer"):
        return 0.0, 0.5
    if kind in ("revolute", "microwave"):
        return 0.0, np.pi / 2
    if kind == "rollup":
        return 0.0, 2.0 + np.pi / 4
    if kind == "garage":
        return 0.0, 2.0 * (2.0 + np.pi / 4)
    return 0.0, 0.0


def _rollup(s):
    """Path (n, 3) and tangent angle (n,) of the roll-up door at path length s (metres)."""
    s = np.asarray(s, float)
    r = 0.5
    P = np.zeros(s.shape + (3,))
    ang = np.zeros(s.shape)
    a = s <= 1.0
    P[a, 2] = s[a]
    b = (s > 1.0) & (s <= 1.0 + np.pi * r / 2)
    t = (s[b] - 1.0) / r
    P[b, 0] = r - r * np.cos(t)
    P[b, 2] = 1.0 + r * np.sin(t)
    ang[b] = t
    c = s > 1.0 + np.pi * r / 2
    P[c, 0] = r + (s[c] - 1.0 - np.pi * r / 2)
    P[c, 2] = 1.0 + r
    ang[c] = np.pi / 2
    return P, ang


def true_pose(kind: str, q) -> np.ndarray:
    """Noise-free relative poses (n, 7) of link type ``kind`` at configurations q (n,)."""
    q = np.atleast_1d(np.asarray(q, float))
    n = q.shape[0]
    if kind == "rigid":
        P = np.zeros((n, 3)) + [0.3, 0.1, 0.0]
        R = Rotation.from_euler("z", (np.zeros(n) + 0.2)[:, None])
    elif kind in ("prismatic", "drawer"):
        e = np.array([1.0, 0.2, 0.1])
        e /= np.linalg.norm(e)
        P = np.array([0.2, 0.0, 0.3]) + q[:, None] * e
        R = Rotation.from_euler("z", (np.zeros(n) + 0.1)[:, None])
    elif kind in ("revolute", "microwave"):
        r = 0.3
        P = np.stack([r * np.cos(q), r * np.sin(q), np.zeros(n)], axis=1) + [0.1, 0.4, 0.0]
        R = Rotation.from_euler("z", q[:, None])
    elif kind in ("rollup", "garage"):
        sc = 2.0 if kind == "garage" else 1.0
        P, ang = _rollup(q / sc)
        P = P * sc
        R = Rotation.from_euler("y", ang[:, None])
    else:
        raise ValueError(f"unknown link type {kind!r}; choose from {LINK_TYPES}")
    P = _BASE_P + _BASE_R.apply(P)
    R = _BASE_R * R
    return np.hstack([P, R.as_quat()])


def simulate_link(kind: str, n: int, *, sigma_pos: float = 0.002,
                  sigma_orient: float = np.deg2rad(2.0), gamma: float = 0.0, rng=None,
                  q=None, exact_ratio: bool = False) -> SimulatedTrack:
    """n noisy observations of a simulated link (see module docstring). ``rng``: Generator
    or seed. Each observation is an outlier with probability ``gamma``; with
    ``exact_ratio=True`` exactly round(gamma * n) randomly chosen observations are outliers
    (a sequence "with outlier ratio gamma", as in the thesis' Fig. 4.21/4.22)."""
    if kind not in LINK_TYPES:
        raise ValueError(f"unknown link type {kind!r}; choose from {LINK_TYPES}")
    if n < 1:
        raise ValueError(f"n must be >= 1, got {n}")
    if not 0.0 <= gamma <= 1.0:
        raise ValueError(f"gamma must be in [0, 1], got {gamma}")
    rng = np.random.default_rng(rng)
    lo, hi = _q_range(kind)
    qs = rng.uniform(lo, hi, n) if q is None else np.asarray(q, float)
    Zt = true_pose(kind, qs)
    P = Zt[:, :3] + rng.normal(0.0, sigma_pos, (n, 3))
    R = Rotation.from_rotvec(rng.normal(0.0, sigma_orient, (n, 3))) * Rotation.from_quat(Zt[:, 3:])
    Z = np.hstack([P, R.as_quat()])
    if exact_ratio:
        out = np.zeros(n, bool)
        out[rng.choice(n, int(round(gamma * n)), replace=False)] = True
    else:
        out = rng.random(n) < gamma
    k = int(out.sum())
    if k:
        allP = true_pose(kind, np.linspace(lo, hi, 50))[:, :3]
        ctr = 0.5 * (allP.min(0) + allP.max(0))
        side = max(float(np.max(np.ptp(allP, axis=0))) + 6 * sigma_pos, 1.0)
        Z[out, :3] = ctr + rng.uniform(-side / 2, side / 2, (k, 3))
        Z[out, 3:] = Rotation.random(k, random_state=int(rng.integers(2**31 - 1))).as_quat()
    return SimulatedTrack(Z=Z, Z_true=Zt, q=qs, outlier=out, kind=kind)


def drawer_with_lid_tracks(seed, n: int = 80, *, sigma_pos: float = 0.005,
                           sigma_orient: float = 0.02) -> np.ndarray:
    """Part tracks ``(3, n, 7)`` (carcass, drawer, lid; x y z qx qy qz qw, m) of a drawer
    sliding in a carcass with a lid hinged on the drawer: the drawer slides out 0.3 m, the
    lid opens 1.2 rad, the drawer slides in with the lid open, the lid closes. A front that
    really hangs on another front (the unambiguous counterpart of two drawers pulled
    together). Gaussian noise ``sigma_pos`` per axis and ``sigma_orient`` per rotation-vector
    axis."""
    rng = np.random.default_rng(seed)
    m = n // 4
    x = np.concatenate([np.linspace(0, .3, m), np.full(m, .3), np.linspace(.3, 0, m),
                        np.zeros(n - 3 * m)])
    th = np.concatenate([np.zeros(m), np.linspace(0, 1.2, m), np.full(m, 1.2),
                         np.linspace(1.2, 0, n - 3 * m)])
    drawer = np.array([0.02, 0, 0.6]) + np.outer(x, [-1, 0, 0])
    r_lid = Rotation.from_rotvec(np.outer(th, [0, 1, 0]))
    lid = drawer + [0, 0, 0.1] + r_lid.apply([-0.15, 0, 0])
    out = []
    for p, r in ((np.tile([0, 0, 0.4], (n, 1)), Rotation.identity(n)),
                 (drawer, Rotation.identity(n)), (lid, r_lid)):
        r = Rotation.from_rotvec(rng.normal(0, sigma_orient, (n, 3))) * r
        out.append(np.hstack([p + rng.normal(0, sigma_pos, p.shape), r.as_quat()]))
    return np.stack(out)
