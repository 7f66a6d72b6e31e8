"""The front detector's parameters (:class:`FrontDetectorConfig`) and its stage names."""

import math
from dataclasses import dataclass, field, fields

import numpy as np


STAGES = ("planes", "masks", "sampling", "optimisation", "check")


@dataclass
class FrontDetectorConfig:
    """Parameters of :func:`detect_fronts` (load with ``yaml_load_typed``; :meth:`validate`
    names the first bad field).

    Attributes:
        inlier_distance: L of Eq. 5.1/5.2, m: a pixel within L of a plane is in-plane.
        inlier_distance_per_m2: L grows with the square of the pixel's depth z like the
            noise of a stereo camera: L(z) = max(inlier_distance, inlier_distance_per_m2 *
            z^2), m / m^2 (0.004: 2.5 sigma of the ~1.5 mm-at-1 m noise; 0 = fixed L).
        ransac_stride_px: RANSAC samples and scores every n-th pixel in rows and columns, px.
        ransac_hypotheses: plane hypotheses per extracted plane (scored all at once).
        ransac_local_radius_px: the 2nd and 3rd point of a hypothesis lie within this many
            pixels of the first (a box in rows and columns), px.
        max_planes: at most this many planes per frame (kept planes: rounds that only clear
            fragments or copies from the pool do not count; at most 2 x max_planes rounds).
        removal_factor: sampled points within L + (removal_factor - 1) x
            inlier_distance_per_m2 x z^2 of an extracted plane (connected to it) leave the
            pool of points later planes are drawn from: the noise tails of a far plane,
            unitless (>= 1).
        min_plane_points: a plane needs at least this many inliers among the sampled pixels.
        max_depth: pixels farther than this are not used to find planes, m.
        crossing_angle_deg: where two planes at more than this angle cross, a pixel within L of
            both and nearer to the one with the larger support is free for the other, degrees.
        crossing_smooth_px: "nearer" is decided on the distances averaged over a square of
            this many pixels (odd), px.
        surface_distance, surface_distance_per_m2: that distance, max(surface_distance,
            surface_distance_per_m2 z^2), m and m / m^2 (0.003, 0.0015: ~1 sigma of the
            camera's per-pixel noise plus half a disparity step; the mean of 25 pixels
            scatters by a fifth of sigma).
        surface_window_px: side of the neighbourhood, px (odd).
        cost_in_plane, cost_free, cost_occluded, cost_unknown: cost of a pixel per label
            (Eq. 5.3-5.5), unitless in [0, 1]; grid cells the camera does not see cost
            ``cost_free``.
        cell_size: side of the rectified grid's cells, m (grows for planes larger than
            ``max_grid_cells`` cells).
        max_grid_cells: at most this many cells along each axis of a plane's grid.
        max_plane_extent: a plane's grid covers at most this much around its inliers' median,
            m.
        starts_per_plane: random starts of the rectangle search per plane (m in 5.1.2).
        prior_size: [min, max] of the uniform prior of a start's width and height, m.
        alpha: size preference of the objective (Eq. 5.3), unitless.
        step_size: unit of the side moves, m.
        rotation_step_deg: unit of the in-plane rotation moves, degrees.
        step_factors: the side moves are these multiples of ``step_size``.
        rotation_step_factors: the rotation moves are these multiples of
            ``rotation_step_deg``.
        max_iterations: cap on greedy iterations per start.
        min_side: smallest width or height of a rectangle, m.
        min_precision, min_recall: acceptance thresholds (Eq. 5.4, 5.5).
        recall_margin: recall compares the rectangle with itself grown by this share of its
            width (height) on the left and right (top and bottom) sides, unitless.
        min_recall_margin: the growth is at least this, m.
        border_margin_px: a rectangle whose projected corner comes closer than this to the
            image border is rejected, px.
        duplicate_distance: accepted rectangles whose centres are closer than this (and
            normals within ``duplicate_angle_deg``) are one front; the better one stays, m.
        duplicate_angle_deg: see ``duplicate_distance``, degrees.
        own_pixel_refit_deg: after the labels, every plane is refitted on the pixels still
            in-plane for it after the crossings (:func:`_refit_on_own_pixels`); if a normal
            turns by this or more, deg, the labels are made again with the refitted planes
            (0 = off; a plane crossing another at a shallow angle is tilted towards it).
        edge_refine_band: the refinement looks this far on either side of a side (at most a
            third of the rectangle across), m.
        edge_refine_cell: spacing of the resampled lines, m.
        edge_refine_span: share of a side's length (its middle) the lines cover, in (0, 1].
        edge_refine_depth_step, edge_refine_depth_step_per_m2: a line whose in-plane samples
            lie on average more than max(step, step_per_m2 z^2, 3 x the inner lines' scatter)
            behind the inner lines' is beyond the side (a panel's top or edge face), m and
            m / m^2.
        component_starts: besides ``starts_per_plane`` random starts, one start at the
            centroid of each of this many largest connected in-plane regions of a plane
            with ``GAP`` cells (regions parted by reveals: the fronts of a cabinet; 0 = none).
        gap_window_px: length of the averaging window along the line, px (rounded to a
            multiple of 4: the means are taken on blocks of 4 pixels along the line).
        gap_offsets_px: distances of the side lines compared with, px (a reveal is a 1-px
            row 6-7 mm behind, or a band without return 3-5 px wide at 1.3-1.8 m and up to
            ~15 px at 0.8 m: offsets up to 5 px missed it there, no closed front was found);
            offsets above 5 px count only where o < 2 + f 0.01 m / z.
        gap_depth, gap_depth_per_m2: a line is behind when its mean depth exceeds the larger
            of its side lines' by max(gap_depth, gap_depth_per_m2 z^2), m and m / m^2 (the
            5 mm reveal seen from 25 deg above lies 6-7 mm behind the faces; the mean of a
            32-pixel line scatters by ~0.35 mm z^2 with the camera's noise).
        gap_side_tolerance_per_m2: the two side lines agree when their mean depths differ by
            less than max(0.01, this x z^2) m plus the depth change of the plane over the
            offset (the side lines must lie on one surface), m / m^2.
        gap_min_length: a detected line shorter than this (at its depth) is noise, m.
        gap_long_window_px: a second pass averages the lines over this many pixels (rounded
            to a multiple of 4; 0 = no second pass) with the depth threshold's z^2 part
            scaled by sqrt(gap_window_px / gap_long_window_px) (its mean scatters that much
            less): a reveal sampled at an unlucky pixel phase dips only ~3 mm (the closed
            drawer at 2.2 m: 3.3 mm on the clean render, below 1 mm z^2 = 4.8 mm), px. It
            runs on the rectified views only (below): on the image it splits closed fronts
            with false rows.
        gap_long_min_windows: a run of the long pass must be at least this many long windows
            long (and ``gap_min_length``): one window's scatter is not a line.
        gap_rectify_planes: both passes also run on the rectified views of up to this
            many planes (0 = none), the largest whose in-plane axes are seen more than
            ``gap_rectify_deg`` (deg) off the image's rows and columns at their region's
            centre (a front seen off its normal: its sides are slanted in the image); the
            long pass only on those among this many largest planes.
        gap_rectify_max_scale: a rectified view is at most this many times the image's
            width and height (its focal length is reduced to fit).
        gap_rectify_max_tilt_deg: only planes within this angle of vertical (deg; "down"
            from ``X_WC``) get a rectified view: fronts are vertical, and the floor or a
            countertop seen from above took the views (and 10 ms per frame) from them.
        layer_planes: offset layers (:func:`_offset_layers`) are looked for on this many
            largest planes (0 = off): a front standing 5-40 mm proud of its cabinet's face
            (a drawer pulled out by its first centimetres) lies within L (or the removal
            band) of the face's plane, so RANSAC gave it no plane of its own.
        layer_max_layers: at most this many layer planes per frame.
        layer_min_size: a layer's connected region must span at least this much in both
            directions, m (a panel's edge face seen obliquely is a strip).
        layer_min_pixels: ... and cover at least this many pixels, px.
    """

    inlier_distance: float = 0.02
    inlier_distance_per_m2: float = 0.004
    ransac_stride_px: int = 8
    ransac_hypotheses: int = 200
    ransac_local_radius_px: int = 48
    max_planes: int = 8
    removal_factor: float = 2.0
    crossing_angle_deg: float = 3.0
    crossing_smooth_px: int = 5
    surface_distance: float = 0.003
    surface_distance_per_m2: float = 0.0015
    surface_window_px: int = 5
    min_plane_points: int = 20
    max_depth: float = 5.0
    cost_in_plane: float = 0.0
    cost_free: float = 1.0
    cost_occluded: float = 20 / 255
    cost_unknown: float = 20 / 255
    cell_size: float = 0.005
    max_grid_cells: int = 400
    max_plane_extent: float = 6.0
    starts_per_plane: int = 6
    prior_size: list[float] = field(default_factory=lambda: [0.05, 0.2])
    alpha: float = 0.05
    step_size: float = 0.005
    rotation_step_deg: float = 0.5
    step_factors: list[int] = field(default_factory=lambda: [8, 4, 2, 1])
    rotation_step_factors: list[int] = field(default_factory=lambda: [2, 1])
    max_iterations: int = 200
    min_side: float = 0.03
    min_precision: float = 0.7
    min_recall: float = 0.7
    recall_margin: float = 0.25
    min_recall_margin: float = 0.05
    border_margin_px: int = 3
    duplicate_distance: float = 0.05
    duplicate_angle_deg: float = 15.0
    own_pixel_refit_deg: float = 0.5
    edge_refine_band: float = 0.05
    edge_refine_cell: float = 0.001
    edge_refine_span: float = 0.7
    edge_refine_depth_step: float = 0.002
    edge_refine_depth_step_per_m2: float = 0.0008
    component_starts: int = 12
    gap_window_px: int = 32
    gap_offsets_px: list[int] = field(default_factory=lambda: [2, 3, 4, 5, 7, 9])
    gap_depth: float = 0.0025
    gap_depth_per_m2: float = 0.001
    gap_side_tolerance_per_m2: float = 0.004
    gap_min_length: float = 0.2
    gap_long_window_px: int = 128
    gap_long_min_windows: float = 0.5
    gap_rectify_planes: int = 2
    gap_rectify_deg: float = 8.0
    gap_rectify_max_scale: float = 1.25
    gap_rectify_max_tilt_deg: float = 20.0
    layer_planes: int = 3
    layer_max_layers: int = 4
    layer_min_size: float = 0.06
    layer_min_pixels: int = 200

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first invalid field."""
        for f in fields(self):
            v = getattr(self, f.name)
            vals = v if isinstance(v, list) else [v]
            for x in vals:
                if isinstance(x, bool):
                    continue
                if not isinstance(x, (int, float, np.integer, np.floating)) or not math.isfinite(x):
                    raise ValueError(f"FrontDetectorConfig.{f.name} must be finite numbers, "
                                     f"got {v!r}")
        pos = ("inlier_distance", "ransac_stride_px", "ransac_hypotheses",
               "ransac_local_radius_px", "max_planes", "min_plane_points", "max_depth",
               "cell_size", "max_grid_cells", "max_plane_extent", "starts_per_plane",
               "step_size", "rotation_step_deg", "max_iterations", "min_side")
        for k in pos:
            if not getattr(self, k) > 0:
                raise ValueError(f"FrontDetectorConfig.{k} must be > 0, got {getattr(self, k)}")
        for k in ("cost_in_plane", "cost_free", "cost_occluded", "cost_unknown",
                  "min_precision", "min_recall"):
            if not 0.0 <= getattr(self, k) <= 1.0:
                raise ValueError(f"FrontDetectorConfig.{k} must be in [0, 1], got "
                                 f"{getattr(self, k)}")
        for k in ("edge_refine_band", "edge_refine_cell"):
            if not getattr(self, k) > 0:
                raise ValueError(f"FrontDetectorConfig.{k} must be > 0 (m), got "
                                 f"{getattr(self, k)}")
        if not 0 < self.edge_refine_span <= 1:
            raise ValueError("FrontDetectorConfig.edge_refine_span must be in (0, 1], got "
                             f"{self.edge_refine_span}")
        for k in ("edge_refine_depth_step", "edge_refine_depth_step_per_m2",
                  "own_pixel_refit_deg"):
            if getattr(self, k) < 0:
                raise ValueError(f"FrontDetectorConfig.{k} must be >= 0, got {getattr(self, k)}")
        if self.gap_window_px < 4:
            raise ValueError("FrontDetectorConfig.gap_window_px must be an integer >= 4, "
                             f"got {self.gap_window_px}")
        if self.gap_long_window_px and self.gap_long_window_px <= self.gap_window_px:
            raise ValueError("FrontDetectorConfig.gap_long_window_px must be 0 (off) or larger "
                             f"than gap_window_px ({self.gap_window_px}), got "
                             f"{self.gap_long_window_px}")
        if not (self.gap_long_min_windows >= 0 and math.isfinite(self.gap_long_min_windows)):
            raise ValueError("FrontDetectorConfig.gap_long_min_windows must be a finite number "
                             f">= 0, got {self.gap_long_min_windows}")
        for k in ("layer_planes", "layer_max_layers", "layer_min_pixels"):
            if int(getattr(self, k)) != getattr(self, k) or getattr(self, k) < 0:
                raise ValueError(f"FrontDetectorConfig.{k} must be an integer >= 0, got "
                                 f"{getattr(self, k)}")
        if not (self.layer_min_size >= 0 and math.isfinite(self.layer_min_size)):
            raise ValueError("FrontDetectorConfig.layer_min_size must be a finite number >= 0 "
                             f"(m), got {self.layer_min_size}")
        if self.gap_rectify_planes < 0:
            raise ValueError("FrontDetectorConfig.gap_rectify_planes must be an integer >= 0, "
                             f"got {self.gap_rectify_planes}")
        if not 0 <= self.gap_rectify_deg <= 90:
            raise ValueError("FrontDetectorConfig.gap_rectify_deg must be in [0, 90] deg, got "
                             f"{self.gap_rectify_deg}")
        if not 0 <= self.gap_rectify_max_tilt_deg <= 90:
            raise ValueError("FrontDetectorConfig.gap_rectify_max_tilt_deg must be in [0, 90] "
                             f"deg, got {self.gap_rectify_max_tilt_deg}")
        if not (self.gap_rectify_max_scale > 0 and math.isfinite(self.gap_rectify_max_scale)):
            raise ValueError("FrontDetectorConfig.gap_rectify_max_scale must be a finite number "
                             f"> 0, got {self.gap_rectify_max_scale}")
        if not self.gap_offsets_px or any(int(o) != o or o < 1 for o in self.gap_offsets_px):
            raise ValueError("FrontDetectorConfig.gap_offsets_px must be integers >= 1 (px), "
                             f"got {self.gap_offsets_px}")
        for k in ("gap_depth", "gap_depth_per_m2", "gap_side_tolerance_per_m2",
                  "gap_min_length"):
            if getattr(self, k) < 0:
                raise ValueError(f"FrontDetectorConfig.{k} must be >= 0, got {getattr(self, k)}")
        if self.crossing_smooth_px < 1:
            raise ValueError("FrontDetectorConfig.crossing_smooth_px must be >= 1, got "
                             f"{self.crossing_smooth_px}")
        if self.surface_window_px < 1 or self.surface_window_px % 2 != 1:
            raise ValueError("FrontDetectorConfig.surface_window_px must be an odd integer "
                             f">= 1, got {self.surface_window_px}")
        for k in ("surface_distance", "surface_distance_per_m2"):
            if getattr(self, k) < 0:
                raise ValueError(f"FrontDetectorConfig.{k} must be >= 0, got {getattr(self, k)}")
        for k in ("component_starts", "alpha", "inlier_distance_per_m2", "crossing_angle_deg",
                  "recall_margin",
                  "min_recall_margin", "border_margin_px", "duplicate_distance",
                  "duplicate_angle_deg"):
            if getattr(self, k) < 0:
                raise ValueError(f"FrontDetectorConfig.{k} must be >= 0, got {getattr(self, k)}")
        if self.removal_factor < 1:
            raise ValueError(f"FrontDetectorConfig.removal_factor must be >= 1, got "
                             f"{self.removal_factor}")
        if not self.alpha < 1:
            raise ValueError(f"FrontDetectorConfig.alpha must be < 1, got {self.alpha}")
        if len(self.prior_size) != 2 or not 0 < self.prior_size[0] <= self.prior_size[1]:
            raise ValueError("FrontDetectorConfig.prior_size must be [min, max] with "
                             f"0 < min <= max (metres), got {self.prior_size}")
        for k in ("step_factors", "rotation_step_factors"):
            v = getattr(self, k)
            if not v or any(int(s) != s or s <= 0 for s in v):
                raise ValueError(f"FrontDetectorConfig.{k} must be positive integers, got {v}")
        for k in ("ransac_stride_px", "ransac_hypotheses", "ransac_local_radius_px",
                  "max_planes", "min_plane_points", "max_grid_cells", "starts_per_plane",
                  "component_starts",
                  "crossing_smooth_px", "surface_window_px", "gap_window_px",
                  "gap_long_window_px", "gap_rectify_planes",
                  "max_iterations", "border_margin_px"):
            if int(getattr(self, k)) != getattr(self, k):
                raise ValueError(f"FrontDetectorConfig.{k} must be an integer, got "
                                 f"{getattr(self, k)}")
