"""Taxel pads: integrate a contact pressure field over the cells of a finger pad (ch. 6-7).

Plain numpy (no pydrake). A pad is a rectangle in its own frame P: the pad surface is the
plane z_P = 0 with its outward normal +z_P (towards the grasped object); rows run along y_P
(along the finger, row 0 at +y_P = the fingertip), columns along x_P (column 0 at -x_P). The
pressure field comes as triangles (vertices expressed in P, pressure at each vertex, linear
inside: exactly Drake's hydroelastic contact surface with its linear pressure field).

Hydroelastic contact surfaces are full of sliver triangles that can span several cells, so a
triangle's force is not assigned to the cell of its centroid. Instead every triangle is
intersected exactly with every cell it overlaps (:func:`integrate_pressure`: Liang-Barsky
and Cyrus-Beck clipping, Green's theorem for the area and centroid of each piece, all
(triangle, cell) pairs vectorised at once); the linear pressure integrates exactly over
each piece. (Until 2026-11 this sampled ``subdiv**2`` sub-triangles per face with
cloud-in-cell binning; the exact clip is both correct to rounding and faster.)

The reading of a cell is its mean normal pressure (force / cell area, Pa); a sensor maps it
to [0, 1] by dividing by its saturation pressure, adds Gaussian noise and clips
(:func:`sensor_reading`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from mmlearn.models.common.config import param, validate_fields

__all__ = ["PadLayout", "PAD_CH6", "PAD_PR2", "subdivision_points", "integrate_pressure",
           "integrate_pressure_pads",
           "sensor_reading"]


@dataclass(frozen=True)
class PadLayout:
    """Geometry of one taxel array.

    Attributes:
        rows: cells along the finger (y_P).
        cols: cells across the finger (x_P).
        length: pad extent along y_P, metres.
        width: pad extent along x_P, metres.
        p_sat: saturation pressure, Pa: the mean cell pressure that reads 1.0.
    """

    rows: int = param(integer=True, ge=1)
    cols: int = param(integer=True, ge=1)
    length: float = param(unit="m", gt=0)
    width: float = param(unit="m", gt=0)
    p_sat: float = param(unit="Pa", gt=0)

    def __post_init__(self):
        validate_fields(self)

    @property
    def cell_area(self) -> float:
        """Area of one cell, m^2."""
        return self.length * self.width / (self.rows * self.cols)


#: ch. 6 (Weiss / Schunk pads): 14 rows x 6 columns over 51 x 24 mm; saturation 250 kPa.
PAD_CH6 = PadLayout(rows=14, cols=6, length=0.051, width=0.024, p_sat=2.5e5)
#: ch. 7 PR2 fingertip: the 5 x 3 array of the inner gripping surface (the 7 cells on tip,
#: sides and back of the 22 do not touch the object in a squeeze and are not simulated),
#: about 30 x 18 mm; saturation 400 kPa.
PAD_PR2 = PadLayout(rows=5, cols=3, length=0.030, width=0.018, p_sat=4.0e5)


def subdivision_points(subdiv: int) -> np.ndarray:
    """Barycentric coordinates (subdiv**2, 3) of the centroids of the ``subdiv**2`` congruent
    sub-triangles of a triangle (each of area 1 / subdiv**2 of it)."""
    return _subdivision_points(int(subdiv)).copy()


@lru_cache(maxsize=16)
def _subdivision_points(subdiv: int) -> np.ndarray:
    """Barycentric coordinates (subdiv**2, 3) of the centroids of the ``subdiv**2`` congruent
    sub-triangles of a triangle (each of area 1 / subdiv**2 of it)."""
    n = int(subdiv)
    if n < 1:
        raise ValueError(f"subdiv must be >= 1, got {subdiv}")
    pts = []
    for i in range(n):
        for j in range(n - i):
            # upward triangle (i, j), (i+1, j), (i, j+1)
            pts.append(((3 * i + 1) / (3 * n), (3 * j + 1) / (3 * n)))
            if i + j < n - 1:  # downward triangle (i+1, j), (i, j+1), (i+1, j+1)
                pts.append(((3 * i + 2) / (3 * n), (3 * j + 2) / (3 * n)))
    a = np.array(pts)
    return np.column_stack([a, 1.0 - a.sum(axis=1)])


def _polygon_sums(P, Q, w):
    """Twice the area and twice-area-weighted centroid sums of closed boundaries given as
    directed segments ``P -> Q`` (m, s, 2) with weights ``w`` (m, s) in {0, 1} (Green's
    theorem: the shoelace terms of a closed curve add over its segments in any order)."""
    cr = (P[..., 0] * Q[..., 1] - Q[..., 0] * P[..., 1]) * w
    return cr.sum(axis=1), np.einsum("msd,ms->md", P + Q, cr)


def integrate_pressure(layout: PadLayout, tri_P: np.ndarray, pressure: np.ndarray, *,
                       max_gap: float = 0.005) -> np.ndarray:
    """Mean normal pressure (Pa) on every cell of the pad, integrated exactly.

    Each triangle, projected onto the pad plane, is intersected with every cell of its
    bounding box, all (triangle, cell) pairs at once: the boundary of the intersection is
    the triangle's edges clipped to the cell (Liang-Barsky) plus the cell's edges clipped to
    the triangle's interior (Cyrus-Beck), and Green's theorem gives its area and centroid
    from those segments. The pressure is linear over a triangle, so its integral over the
    intersection is that area times the pressure at that centroid: a sliver that spans many
    cells gives each cell exactly its share. Force outside the pad is not measured.

    Args:
        layout: the pad.
        tri_P: (n, 3, 3) triangle vertices in the pad frame P, metres.
        pressure: (n, 3) pressure at each vertex, Pa (negative values count as 0; linear
            over the triangle).
        max_gap: triangles whose centroid is farther than this from the pad plane (``|z_P|``,
            metres) are ignored (contact of another part of the finger).

    Returns:
        (rows, cols) mean pressure per cell, Pa: the normal force on the cell (pressure x
        area projected onto the pad plane) divided by the cell area. Faces with a NaN or
        infinite vertex or pressure are skipped.
    """
    return integrate_pressure_pads(layout, [tri_P], [pressure], max_gap=max_gap)[0]


def integrate_pressure_pads(layout: PadLayout, tris, pressures, *,
                            max_gap: float = 0.005) -> np.ndarray:
    """:func:`integrate_pressure` for several pads of the same layout in one vectorised
    pass (one numpy pass instead of one per pad: the arrays are small, so the per-call
    cost dominates). ``tris[i]`` (n_i, 3, 3) and ``pressures[i]`` (n_i, 3) belong to pad i,
    in that pad's frame. Returns (n_pads, rows, cols) mean pressures, Pa."""
    R, C = layout.rows, layout.cols
    n_pads = len(tris)
    if len(pressures) != n_pads:
        raise ValueError(f"pressures: expected {n_pads} arrays (one per pad), got {len(pressures)}")
    tl, pl, kl = [], [], []
    for i, (t_, p_) in enumerate(zip(tris, pressures)):
        t_ = np.asarray(t_, dtype=float).reshape(-1, 3, 3)
        p_ = np.asarray(p_, dtype=float).reshape(-1, 3)
        if p_.shape[0] != t_.shape[0]:
            raise ValueError(f"pressure: expected {t_.shape[0]} x 3 values, got {p_.shape}")
        tl.append(t_)
        pl.append(p_)
        kl.append(np.full(t_.shape[0], i))
    out = np.zeros(n_pads * R * C)
    if n_pads == 0 or sum(t_.shape[0] for t_ in tl) == 0:
        return out.reshape(n_pads, R, C)
    tri, pr, pad = np.concatenate(tl), np.concatenate(pl), np.concatenate(kl)
    cw, chh = layout.width / C, layout.length / R
    with np.errstate(invalid="ignore"):
        ok = np.isfinite(tri).all(axis=(1, 2)) & np.isfinite(pr).all(axis=1)
        ok &= np.abs(tri[:, :, 2].mean(axis=1)) <= max_gap
    # projected vertices in cell units: u along the columns, v along the rows
    uv = np.stack([(tri[:, :, 0] + 0.5 * layout.width) / cw,
                   (0.5 * layout.length - tri[:, :, 1]) / chh], axis=2)  # (n, 3, 2)
    # snap coordinates within 1e-9 cells of a grid line onto it: an edge along a cell border
    # (the border of the pad, e.g.) is then exactly on it, and the clipping below counts it
    # once (with round-off it could be taken both as the triangle's and as the cell's edge)
    with np.errstate(invalid="ignore"):
        near = np.abs(uv - np.round(uv)) < 1e-9
    uv = np.where(near, np.round(uv), uv)
    e1, e2 = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]  # twice the signed area, cell units
    lo, hi = uv.min(axis=1), uv.max(axis=1)
    with np.errstate(invalid="ignore"):
        ok &= ((np.abs(det) > 1e-12) & (hi[:, 0] > 0) & (lo[:, 0] < C) & (hi[:, 1] > 0)
               & (lo[:, 1] < R))
    if not ok.any():
        return out.reshape(n_pads, R, C)
    uv, pr, det, lo, hi = uv[ok], np.maximum(pr[ok], 0.0), det[ok], lo[ok], hi[ok]
    pad = pad[ok]
    e1, e2 = e1[ok], e2[ok]
    # pressure as an affine function of (u, v): p = p_0 + g . (x - uv_0)
    dp1, dp2 = pr[:, 1] - pr[:, 0], pr[:, 2] - pr[:, 0]
    g = np.stack([(dp1 * e2[:, 1] - dp2 * e1[:, 1]) / det,
                  (dp2 * e1[:, 0] - dp1 * e2[:, 0]) / det], axis=1)
    # counter-clockwise vertex order (interior on the left of each edge)
    cw_ = det < 0
    uv[cw_] = uv[cw_][:, [0, 2, 1]]
    # cells of the bounding box; a triangle that only touches a cell's border gets no pair
    c0 = np.clip(np.floor(lo[:, 0]), 0, C - 1).astype(int)
    c1 = np.clip(np.ceil(hi[:, 0]) - 1, 0, C - 1).astype(int)
    r0 = np.clip(np.floor(lo[:, 1]), 0, R - 1).astype(int)
    r1 = np.clip(np.ceil(hi[:, 1]) - 1, 0, R - 1).astype(int)
    nw = np.maximum(c1 - c0 + 1, 1)
    cnt = nw * np.maximum(r1 - r0 + 1, 1)
    tid = np.repeat(np.arange(len(cnt)), cnt)  # (triangle, cell) pairs
    off = np.arange(tid.size) - np.repeat(np.cumsum(cnt) - cnt, cnt)
    col = c0[tid] + off % nw[tid]
    row = r0[tid] + off // nw[tid]
    corner = np.stack([col, row], axis=1).astype(float)
    V = uv[tid] - corner[:, None, :]  # triangle in the cell's frame: the cell is [0, 1]^2
    Dt = np.roll(uv, -1, axis=1) - uv  # (n, 3, 2) edges (the same in every frame)
    D = Dt[tid]
    inf = np.inf
    # 1) triangle edges clipped to the closed cell (Liang-Barsky)
    t0, t1 = 0.0, 1.0
    with np.errstate(divide="ignore", invalid="ignore"):
        for ax in (0, 1):
            Va, Da = V[..., ax], D[..., ax]
            ta, tb = -Va / Da, (1.0 - Va) / Da  # where the edge meets 0 and 1
            par = Da == 0.0
            out_ = par & ((Va < 0.0) | (Va > 1.0))  # parallel and outside: empty
            t0 = np.maximum(t0, np.where(par, np.where(out_, inf, -inf), np.minimum(ta, tb)))
            t1 = np.minimum(t1, np.where(par, np.where(out_, -inf, inf), np.maximum(ta, tb)))
    w1 = t1 > t0
    t0, t1 = np.where(w1, t0, 0.0), np.where(w1, t1, 0.0)
    S0 = V + t0[..., None] * D
    S1 = V + t1[..., None] * D
    # 2) cell edges clipped to the open triangle (Cyrus-Beck): inside is n_j . x > h_j
    nu, nv = -D[..., 1], D[..., 0]  # (m, 3) inward normals (CCW)
    h = nu * V[..., 0] + nv * V[..., 1]
    K = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])  # CCW cell corners
    E = np.roll(K, -1, axis=0) - K
    f0 = np.stack([-h, nu - h, nu + nv - h, nv - h], axis=1)  # (m, 4, 3): n . K - h
    fd = np.stack([nu, nv, -nu, -nv], axis=1)  # n . E
    with np.errstate(divide="ignore", invalid="ignore"):
        tc = -f0 / fd
    shut = (fd == 0.0) & (f0 <= 0.0)  # parallel and not inside: empty
    lo_b = np.where(fd > 0.0, tc, np.where(shut, inf, -inf))
    hi_b = np.where(fd < 0.0, tc, np.where(shut, -inf, inf))
    s0 = np.maximum(np.maximum(np.maximum(lo_b[..., 0], lo_b[..., 1]), lo_b[..., 2]), 0.0)
    s1 = np.minimum(np.minimum(np.minimum(hi_b[..., 0], hi_b[..., 1]), hi_b[..., 2]), 1.0)
    w2 = s1 > s0
    s0, s1 = np.where(w2, s0, 0.0), np.where(w2, s1, 0.0)
    B0 = K + s0[..., None] * E
    B1 = K + s1[..., None] * E
    A2a, Ma = _polygon_sums(S0, S1, w1)
    A2b, Mb = _polygon_sums(B0, B1, w2)
    A2 = A2a + A2b  # twice the area, cell units
    keep = A2 > 1e-14
    A2s = np.where(keep, A2, 1.0)
    cen = (Ma + Mb) / (3.0 * A2s[:, None]) + corner  # centroid, cell units
    p_c = pr[tid, 0] + np.einsum("ij,ij->i", g[tid], cen - uv[tid, 0])
    force = np.where(keep, 0.5 * A2 * np.maximum(p_c, 0.0), 0.0) * (cw * chh)  # N
    out += np.bincount((pad[tid] * R + row) * C + col, weights=force, minlength=out.size)
    return (out / layout.cell_area).reshape(n_pads, R, C)


def sensor_reading(layout: PadLayout, cell_pressure: np.ndarray, *, rng: np.random.Generator,
                   noise: float = 0.01) -> np.ndarray:
    """Normalised taxel values in [0, 1]: ``clip(p / p_sat + N(0, noise), 0, 1)``; ``noise``
    is the standard deviation in units of the saturation value."""
    x = np.asarray(cell_pressure, dtype=float) / layout.p_sat
    if noise > 0:
        x = x + rng.normal(0.0, noise, x.shape)
    return np.clip(np.nan_to_num(x, nan=0.0), 0.0, 1.0)
