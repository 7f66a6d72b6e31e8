"""Taxel pads: integrate a contact pressure field over the cells of a finger pad (ch. 6-7).

Plain numpy (no pydrake). A pad is a rectangle in its own frame P: the pad surface is the
plane z_P = 0 with its outward normal +z_P (towards the grasped object); rows run along y_P
(along the finger, row 0 at +y_P = the fingertip), columns along x_P (column 0 at -x_P). The
pressure field comes as triangles (vertices expressed in P, pressure at each vertex, linear
inside: exactly Drake's hydroelastic contact surface with its linear pressure field).

Hydroelastic contact surfaces are full of sliver triangles that can span several cells, so a
triangle's force is not assigned to the cell of its centroid. Instead each triangle is split
into ``subdiv**2`` congruent sub-triangles and each sub-triangle's force (pressure at its
centroid times its area -- exact for the linear field inside each sub-triangle) is binned at
the sub-triangle centroid (projected onto the pad plane). Each triangle gets enough
sub-triangles that none is longer than half a cell side, and each sample's force is
shared between the cells that a half-cell patch around it overlaps (cloud-in-cell), so
a face on a cell border splits by area instead of jumping to one side. Triangles with the same subdivision are processed at
once (vectorised).

The reading of a cell is its mean normal pressure (force / cell area, Pa); a sensor maps it
to [0, 1] by dividing by its saturation pressure, adds Gaussian noise and clips
(:func:`sensor_reading`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

__all__ = ["PadLayout", "PAD_CH6", "PAD_PR2", "subdivision_points", "integrate_pressure",
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

    rows: int
    cols: int
    length: float
    width: float
    p_sat: float

    def __post_init__(self):
        if self.rows < 1 or self.cols < 1:
            raise ValueError(f"PadLayout: rows and cols must be >= 1, got {self.rows} x {self.cols}")
        for k in ("length", "width", "p_sat"):
            v = getattr(self, k)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"PadLayout.{k}: expected a finite number > 0, got {v!r}")

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


def integrate_pressure(layout: PadLayout, tri_P: np.ndarray, pressure: np.ndarray, *,
                       subdiv: int = 2, max_subdiv: int = 32,
                       max_gap: float = 0.005) -> np.ndarray:
    """Mean normal pressure (Pa) on every cell of the pad.

    Args:
        layout: the pad.
        tri_P: (n, 3, 3) triangle vertices in the pad frame P, metres.
        pressure: (n, 3) pressure at each vertex, Pa (>= 0; linear over the triangle).
        subdiv: least number of sub-triangles per edge (subdiv**2 samples per triangle);
            a triangle gets ``ceil(longest edge / spacing)`` per edge (spacing: half
            of the smaller cell side, rounded up to one of 1, 2, 3, 4, 6, 8, 12, ...), at most ``max_subdiv``.
        max_subdiv: cap on the sub-triangles per edge.
        max_gap: samples farther than this from the pad plane (|z_P|, m) are ignored (contact
            of another part of the finger).

    Returns:
        (rows, cols) mean pressure per cell, Pa: the normal force on the cell (pressure x
        area, projected onto the pad normal) divided by the cell area.
    """
    tri = np.asarray(tri_P, dtype=float).reshape(-1, 3, 3)
    pr = np.asarray(pressure, dtype=float).reshape(-1, 3)
    out = np.zeros(layout.rows * layout.cols)
    if tri.shape[0] == 0:
        return out.reshape(layout.rows, layout.cols)
    if pr.shape[0] != tri.shape[0]:
        raise ValueError(f"pressure: expected {tri.shape[0]} x 3 values, got {pr.shape}")
    ok = np.isfinite(tri).all(axis=(1, 2)) & np.isfinite(pr).all(axis=1)
    tri, pr = tri[ok], np.maximum(pr[ok], 0.0)
    e1 = tri[:, 1] - tri[:, 0]
    e2 = tri[:, 2] - tri[:, 0]
    # area projected onto the pad normal z_P: the normal force of a sample is p * area_z
    a_z = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])  # (n,)
    # sub-triangles no longer than spacing (half of the smaller cell side), at least
    # ``subdiv`` per edge: large faces (coarse compliant meshes) get many samples
    cw, chh = layout.width / layout.cols, layout.length / layout.rows
    h = min(cw, chh) / 2.0
    hx, hy = cw / 2.0, chh / 2.0
    edge = np.max(np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2), axis=1)
    n_sub = np.clip(np.ceil(edge / h).astype(int), subdiv, max_subdiv)
    # a few subdivision levels only, so the loop below runs a few times
    levels = np.array([1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64])
    n_sub = np.minimum(levels[np.searchsorted(levels, n_sub)], max_subdiv)
    for n in np.unique(n_sub):
        sel = n_sub == n
        B = _subdivision_points(int(n))  # (s, 3)
        pts = np.matmul(B, tri[sel])  # (m, s, 3)
        force = (pr[sel] @ B.T) * (a_z[sel, None] / B.shape[0])  # (m, s) N
        x, y, z = pts[..., 0], pts[..., 1], pts[..., 2]
        uc = (x + 0.5 * layout.width) / cw  # sample position in cells
        vc = (0.5 * layout.length - y) / chh
        near = ((np.abs(z) <= max_gap) & (uc >= 0) & (uc < layout.cols) & (vc >= 0)
                & (vc < layout.rows))
        # each sample stands for a patch of (hx, hy), split over the (at most 2 x 2) cells it
        # overlaps ("cloud in cell"): a sample on a cell border is shared, not rounded; a
        # patch is kept inside the pad (the pad ends there)
        u = np.clip(uc[near] - 0.5 * hx / cw, 0.0, layout.cols - hx / cw)  # patch start
        v = np.clip(vc[near] - 0.5 * hy / chh, 0.0, layout.rows - hy / chh)
        fw = force[near]
        c0, r0 = np.floor(u).astype(int), np.floor(v).astype(int)
        fc = np.clip((c0 + 1 - u) * cw / hx, 0.0, 1.0)  # share of column c0
        fr = np.clip((r0 + 1 - v) * chh / hy, 0.0, 1.0)
        for dc, wc in ((0, fc), (1, 1.0 - fc)):
            for dr, wr in ((0, fr), (1, 1.0 - fr)):
                col, row = c0 + dc, r0 + dr
                keep = (col >= 0) & (col < layout.cols) & (row >= 0) & (row < layout.rows)
                out += np.bincount(row[keep] * layout.cols + col[keep],
                                   weights=(fw * wc * wr)[keep], minlength=out.size)
    return (out / layout.cell_area).reshape(layout.rows, layout.cols)


def sensor_reading(layout: PadLayout, cell_pressure: np.ndarray, *, rng: np.random.Generator,
                   noise: float = 0.01) -> np.ndarray:
    """Normalised taxel values in [0, 1]: ``clip(p / p_sat + N(0, noise), 0, 1)``; ``noise``
    is the standard deviation in units of the saturation value."""
    x = np.asarray(cell_pressure, dtype=float) / layout.p_sat
    if noise > 0:
        x = x + rng.normal(0.0, noise, x.shape)
    return np.clip(np.nan_to_num(x, nan=0.0), 0.0, 1.0)
