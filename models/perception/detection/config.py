"""The front detector's parameters (:class:`FrontDetectorConfig`) and its stage names."""

from dataclasses import dataclass

from mmlearn.models.common.config import param, validate_fields


STAGES = ("planes", "masks", "sampling", "optimisation", "check")


@dataclass
class FrontDetectorConfig:
    """Parameters of :func:`detect_fronts` (load with ``yaml_load_typed``; :meth:`validate`
    names the first bad field). Each field declares its unit and range (:func:`param`).

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
        plane_method: how the planes are found: ``"ransac"`` (sequential RANSAC on the
            sample grid, :mod:`.planes`) or ``"cells"`` (plane fits per cell of the organised
            image and region growing over the cells, :mod:`.cells`: faster, the planes differ
            by the cells' fits; see ``docs/perception.md``).
        cell_planarity: with ``plane_method = "cells"``, a cell is planar when the RMS
            distance of the points of a 2 x 2 block of cells containing it to the block's
            plane is at most this many L (and a cell's pixels lie near a plane when their
            RMS distance to it is), unitless.
        cell_distance: with ``plane_method = "cells"``, the cells' centroids (the mean of
            ~64 pixels: ~1/8 of a pixel's noise) are tested against a plane at this many L
            (and removal bands): a front standing 2 cm proud of its carcass stays a region
            of its own, unitless.
        cell_pixel_step: ... summing every n-th pixel of a cell in rows and columns, px.
        cell_normal_deg: ... and joins a region when its normal is within this angle of the
            region's plane (and its centroid within L of it), deg.
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
            less): a reveal sampled at an unlucky pixel phase dips less than the short
            pass's threshold (a closed drawer's on the clean render), px. It
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
        gap_rectify_max_upsample: ... and holds at most this many pixels per image pixel of
            the plane's region (its bounding box on the image; 0 = no limit, the default): a
            small plane seen at grazing incidence gets a view larger than the image, which
            costs the masks stage more than the image's own reveal pass. 4 cut the stage's
            median on the synthetic frames by a sixth, but moved a door seen opened wide
            (4 of 90 rendered frames; one of 12 perception runs by 0.05 mm), so it is off.
        gap_rectify_max_tilt_deg: only planes within this angle of vertical (deg; "down"
            from ``X_WC``) get a rectified view: fronts are vertical, and the floor or a
            countertop seen from above took the views (and their time) from them.
        front_max_tilt_deg: fronts are vertical: only the rectangles of planes within this
            angle of vertical (deg; "down" from ``X_WC``; 90 = every plane) are searched
            (greedy moves, rotation polish, checks). The others (the floor, countertops, the
            tops of drawers) are labelled and gridded as every plane, and their random starts
            drawn, so the vertical planes' rectangles do not depend on this value. Without
            ``X_WC`` every plane is searched.
        layer_planes: offset layers (:func:`_offset_layers`) are looked for on this many
            largest planes (0 = off): a front standing 5-40 mm proud of its cabinet's face
            (a drawer pulled out by its first centimetres) lies within L (or the removal
            band) of the face's plane, so RANSAC gave it no plane of its own.
        layer_max_layers: at most this many layer planes per frame.
        layer_min_size: a layer's connected region must span at least this much in both
            directions, m (a panel's edge face seen obliquely is a strip).
        layer_min_pixels: ... and cover at least this many pixels, px.
    """

    inlier_distance: float = param(0.02, unit="m", gt=0)
    inlier_distance_per_m2: float = param(0.004, unit="m / m^2", ge=0)
    ransac_stride_px: int = param(8, unit="px", integer=True, gt=0)
    ransac_hypotheses: int = param(200, integer=True, gt=0)
    ransac_local_radius_px: int = param(48, unit="px", integer=True, gt=0)
    max_planes: int = param(8, integer=True, gt=0)
    removal_factor: float = param(2.0, ge=1)
    crossing_angle_deg: float = param(3.0, unit="deg", ge=0)
    crossing_smooth_px: int = param(5, unit="px", integer=True, ge=1)
    surface_distance: float = param(0.003, unit="m", ge=0)
    surface_distance_per_m2: float = param(0.0015, unit="m / m^2", ge=0)
    surface_window_px: int = param(5, unit="px, odd", integer=True, ge=1)
    plane_method: str = param("ransac", choices=("ransac", "cells"))
    cell_planarity: float = param(0.5, gt=0)
    cell_distance: float = param(0.5, gt=0, le=1)
    cell_pixel_step: int = param(2, unit="px", integer=True, gt=0)
    cell_normal_deg: float = param(15.0, unit="deg", gt=0, le=90)
    min_plane_points: int = param(20, integer=True, gt=0)
    max_depth: float = param(5.0, unit="m", gt=0)
    cost_in_plane: float = param(0.0, ge=0, le=1)
    cost_free: float = param(1.0, ge=0, le=1)
    cost_occluded: float = param(20 / 255, ge=0, le=1)
    cost_unknown: float = param(20 / 255, ge=0, le=1)
    cell_size: float = param(0.005, unit="m", gt=0)
    max_grid_cells: int = param(400, integer=True, gt=0)
    max_plane_extent: float = param(6.0, unit="m", gt=0)
    starts_per_plane: int = param(6, integer=True, gt=0)
    prior_size: list[float] = param([0.05, 0.2], unit="m", gt=0, length=2, elements=True,
                                    factory=True)
    alpha: float = param(0.05, ge=0, lt=1)
    step_size: float = param(0.005, unit="m", gt=0)
    rotation_step_deg: float = param(0.5, unit="deg", gt=0)
    step_factors: list[int] = param([8, 4, 2, 1], integer=True, gt=0, elements=True,
                                    factory=True)
    rotation_step_factors: list[int] = param([2, 1], integer=True, gt=0, elements=True,
                                             factory=True)
    max_iterations: int = param(200, integer=True, gt=0)
    min_side: float = param(0.03, unit="m", gt=0)
    min_precision: float = param(0.7, ge=0, le=1)
    min_recall: float = param(0.7, ge=0, le=1)
    recall_margin: float = param(0.25, ge=0)
    min_recall_margin: float = param(0.05, unit="m", ge=0)
    border_margin_px: int = param(3, unit="px", integer=True, ge=0)
    duplicate_distance: float = param(0.05, unit="m", ge=0)
    duplicate_angle_deg: float = param(15.0, unit="deg", ge=0)
    own_pixel_refit_deg: float = param(0.5, unit="deg", ge=0)
    edge_refine_band: float = param(0.05, unit="m", gt=0)
    edge_refine_cell: float = param(0.001, unit="m", gt=0)
    edge_refine_span: float = param(0.7, gt=0, le=1)
    edge_refine_depth_step: float = param(0.002, unit="m", ge=0)
    edge_refine_depth_step_per_m2: float = param(0.0008, unit="m / m^2", ge=0)
    component_starts: int = param(12, integer=True, ge=0)
    gap_window_px: int = param(32, unit="px", integer=True, ge=4)
    gap_offsets_px: list[int] = param([2, 3, 4, 5, 7, 9], unit="px", integer=True, ge=1,
                                      elements=True, factory=True)
    gap_depth: float = param(0.0025, unit="m", ge=0)
    gap_depth_per_m2: float = param(0.001, unit="m / m^2", ge=0)
    gap_side_tolerance_per_m2: float = param(0.004, unit="m / m^2", ge=0)
    gap_min_length: float = param(0.2, unit="m", ge=0)
    gap_long_window_px: int = param(128, unit="px", integer=True, ge=0)
    gap_long_min_windows: float = param(0.5, ge=0)
    gap_rectify_planes: int = param(2, integer=True, ge=0)
    gap_rectify_deg: float = param(8.0, unit="deg", ge=0, le=90)
    gap_rectify_max_scale: float = param(1.25, gt=0)
    gap_rectify_max_upsample: float = param(0.0, ge=0)
    gap_rectify_max_tilt_deg: float = param(20.0, unit="deg", ge=0, le=90)
    front_max_tilt_deg: float = param(20.0, unit="deg", ge=0, le=90)
    layer_planes: int = param(3, integer=True, ge=0)
    layer_max_layers: int = param(4, integer=True, ge=0)
    layer_min_size: float = param(0.06, unit="m", ge=0)
    layer_min_pixels: int = param(200, unit="px", integer=True, ge=0)

    def validate(self) -> "FrontDetectorConfig":
        """Raise ``ValueError`` naming the first invalid field (its value and what is
        allowed); return the config."""
        validate_fields(self)
        who = type(self).__name__
        for k in ("step_factors", "rotation_step_factors", "gap_offsets_px"):
            if len(getattr(self, k)) == 0:
                raise ValueError(f"{who}: {k} must not be empty")
        if not self.prior_size[0] <= self.prior_size[1]:
            raise ValueError(f"{who}: prior_size must be [min, max] with min <= max (m), got "
                             f"{self.prior_size}")
        if self.surface_window_px % 2 != 1:
            raise ValueError(f"{who}: surface_window_px must be odd, got "
                             f"{self.surface_window_px}")
        if self.gap_long_window_px and self.gap_long_window_px <= self.gap_window_px:
            raise ValueError(f"{who}: gap_long_window_px must be 0 (no long pass) or larger "
                             f"than gap_window_px ({self.gap_window_px}), got "
                             f"{self.gap_long_window_px}")
        return self
