"""Cabinet fronts as rectangles in dense depth images (thesis ch. 5.1.1-5.1.2).

:func:`detect_fronts` runs the detector of the thesis in five stages (the keys of its timings):

``planes``
    RANSAC plane segmentation (5.1.1, Eq. 5.1). Hypotheses are drawn from a subsampled pixel
    grid (every ``ransac_stride_px``-th pixel) and all of them are scored at once against all
    sampled points (one matrix product). The three points of a hypothesis are drawn *locally*
    (the 2nd and 3rd among the pool's points within ``ransac_local_radius_px`` of the first),
    which finds small planes (a drawer front at 2.5 m covers < 1 % of the image) with few
    hypotheses. The inlier distance grows with the depth like the camera's noise
    (``inlier_distance_per_m2``; the thesis: "L depends on the noise level of the camera").
    The best hypothesis' plane is its largest 8-connected region of inliers on the sample grid,
    refined by least squares (SVD); that region (and its points within ``removal_factor`` x L)
    leaves the pool of *sampling* points, and the search repeats for the next plane. Each plane
    is then refitted on the full-resolution pixels near it in its region's bounding box. A pixel
    may belong to several planes: the masks below are computed for every plane over all pixels.
``masks``
    One label mask per plane (Eq. 5.2): in-plane ``|s| <= L``, occluded ``s > L`` (something in
    front of the plane hides it), free ``s < -L`` (the camera sees through the plane: nothing
    there), unknown (no measurement); ``s`` is the signed distance with the plane normal
    pointing towards the camera. The mask is then *rectified*: resampled (nearest neighbour,
    one ``cv2.warpPerspective``) onto a metric grid in the plane with ``cell_size`` cells whose
    axes follow the dominant edge direction of the plane's in-plane region (gravity from
    ``X_WC`` fixes "up"). In that grid a rectangle is axis-aligned and the sums of Eq. 5.3-5.5
    are four look-ups in summed-area tables (O(1) per candidate).
    Where two planes crossing at more than ``crossing_angle_deg`` are both within L of a pixel,
    the pixel is in-plane only for the plane nearer to it (each plane's signed distances summed
    over the ``crossing_smooth_px`` square's pixels that are within L of both; free for the
    other; at crossings steeper than 30 deg only the plane with the larger support takes
    pixels from the other): otherwise an
    open door would be widened by the strip of the cabinet face next to its hinge
    (L / sin(opening angle), 4 cm at 30 deg; measured: 0.445 m instead of 0.395 m). This
    applies from ``crossing_angle_deg`` = 3 deg (it was 20: a door opened 5-20 deg came out
    7-8 cm too wide, L / sin(15 deg) = 7.7 cm; then 5: a door opened 4.8 deg, seen from 0.8 m,
    lost 5-6 cm of its hinge side). Before the masks are used, every plane is refitted on its
    own pixels (in-plane after the crossings, within L / 2 and nearer to it than to any other
    plane; :func:`_refit_on_own_pixels`, ``own_pixel_refit_deg``) and the labels are made
    again if a normal turned: RANSAC counts the cabinet's face within L beside an opened
    door's hinge as the door's and tilted its plane towards the face by ~2 deg at 5-8 deg
    openings, and the crossing then gave the face a 5 cm strip of the door.
    Then the *surface check* (``surface_check``): an in-plane pixel whose in-plane neighbours
    (``surface_window_px`` square) lie on average farther than ``max(surface_distance,
    surface_distance_per_m2 z^2)`` from the plane refitted to the in-plane pixels' distances
    (least squares, affine in the pixel, refitted twice on the pixels within twice the surface
    distance; against the detected plane itself, a plane fitted 1-2 deg off lost one side of a
    0.5 m sliding panel with its handle) becomes ``OFF_SURFACE`` (costed like unknown). Single pixels scatter by
    the camera's noise, their mean far less; the edge face of a 19 mm panel seen obliquely lies
    within L of the panel's face (wholly behind it) and widened the door by up to
    thickness x tan(incidence) (measured: 1-2 cm at 50-70 deg, tests/test_front_detection.py).
    Last, the *reveals* (``gap_label``, :func:`_gap_mask`): the 5 mm gaps between flush
    closed fronts are thin image lines that have no return or lie a few mm behind the
    surface on both sides (averaged along the line); their pixels become ``GAP``, costed like
    free space, so a closed front is no longer one rectangle with its neighbours (issue 12:
    closed fronts were found in 0 of 60-70 frames per distance). Two more passes (issue 12,
    branch pgap): a *long* pass (``gap_long_window_px``, line means over 128 px, threshold's
    z^2 part scaled by sqrt(32 / 128)): a reveal is one pixel row whose depth depends on where
    the pixel's centre falls in the ~1.2 px wide gap (the closed drawer at 2.2 m: 3.3 mm behind
    on the clean render, below 1 mm z^2 = 4.8 mm; 2.3 m and 2.4 m fall luckier); and, for the
    ``gap_rectify_planes`` largest planes whose in-plane axes are seen more than
    ``gap_rectify_deg`` off the image rows / columns (a front 30-45 deg off the normal: its
    horizontal sides slanted by ~8-15 deg), both passes on the plane's *rectified view*
    (:func:`_rectified_view`: a virtual camera at the same centre looking along the normal,
    axes along the plane's horizontal and down), mapped back. The long pass on the image is
    off by default (``gap_long_on_image``: at 2.0-2.3 m it split the closed door with false
    rows; across slanted reveals its 128 px means smear them into false rows too).
    Issue 12, branch pedge (a door opened 90 deg lies within a few mm of its compartment's
    side wall: one plane, and without its hinge seam as a reveal the door grew over the
    wall): the views go to the ``gap_rectify_planes`` largest *vertical* planes that need one
    (the cabinet face seen along the image axes took the slot before); the long pass runs
    only on the views of the largest planes (on an opened door at 2.3 m the disparity steps
    are vertical stripes of equal depth it labelled); in a view, offsets across a band
    without return count image pixels (a grazing plane's view stretches each over s >= 1 view
    pixels: the seam 4-6 image px wide is 9-12 view px wide) and the thresholds grow by
    sqrt(s along the line) (interpolated view pixels are not independent samples).
    *Offset layers* (issue 12, ``layer_*``, :func:`_offset_layers`): a drawer pulled out by
    its first 1-4 cm stands that far proud of its cabinet's face, within L or the removal band
    of the face's plane, so RANSAC took its points with the face and it had no plane of its
    own (missed in its first opening frames at every distance). On the largest planes, the
    regions whose pixels lie in front of the plane within the removal band (the surface
    check's ``OFF_SURFACE`` and ``OCCLUDED``), closed over noise holes, opened by 2/3 of
    ``layer_min_size`` (thin strips: the countertop's 3 cm edge, 2 cm proud like the drawer)
    and at least ``layer_min_size`` across, get a plane of their own (started parallel to the
    parent, refitted) when it stays within 10 deg of the parent, lies in front of it by more
    than the surface distance and is a step, not a ramp (the parent's own pixels around it
    off its plane). Inside its region (its box grown by half its size) the layer and its
    parent share pixels by the nearer-plane rule; outside it the layer has no in-plane
    pixels (its infinite plane, a degree off the face's, crosses it somewhere).
``sampling``
    ``starts_per_plane`` random starts per plane: a random in-plane cell as centre, width and
    height drawn uniformly from ``prior_size`` (5.1.1: "sample a random point from the plane
    and the other DOFs from a prior"); on planes with reveals, also one start at the centroid
    of each of the ``component_starts`` largest regions of in-plane cells between them (a
    closed drawer covers 5 % of a cabinet's face: random starts missed it).
``optimisation``
    Greedy discrete moves (5.1.2) on all starts of all planes at once (vectorised): each side
    grows or shrinks by ``step_factors`` x ``step_size``; the best improving move is taken
    until none improves or ``max_iterations``. Accepted rectangles are then polished by in-plane
    rotations (``step_factors`` x ``rotation_step_deg``, each followed by the side moves on a
    mask rectified at the new angle).
``check``
    Precision (Eq. 5.4) and recall (Eq. 5.5) above their thresholds, not touching the image
    border, duplicates suppressed; each side of an accepted rectangle is refined below the grid
    cell (``edge_refine``: where the share of in-plane samples across the side falls below 1/2,
    or the samples' depth falls behind the front's, on 1 mm lines resampled from the image;
    :func:`_refine_edges`); the plane of each accepted rectangle is refitted by least squares
    on the full-resolution in-plane pixels inside it (accuracy of the pose). Measured on the
    kitchen scene's door (README, "Door pose error"): 11.9 -> 5.1 mm at 2.3 m.

Deviations from the text, with reasons (measured on the synthetic frames of
``models/perception/synth.py`` and rendered frames of the Drake scene; see
``benchmarks/bench_front_detector.py``):

* The objective is the original code's ``g = sum(1 - cost) / n^(1 - alpha)`` rather than the
  literal Eq. 5.3 ``-sum(cost) / n^(1 + alpha)``: the latter is 0 for every rectangle inside
  the front, so a start inside the front never grows. Both prefer larger rectangles of the same
  mean cost by the factor ``n^alpha``.
* Recall (Eq. 5.5) divides the rectangle's in-plane area by the in-plane area of the rectangle
  grown by ``recall_margin`` on every side, not of the whole infinite plane: the infinite plane
  also holds the strips where other surfaces cross it and every other coplanar front, which the
  thesis' recall would count against a correct rectangle. A partial rectangle on a larger flat
  region still gets a low recall (its plane continues beyond its sides).
* Pixels are weighted by the plane area they cover (the rectified grid), not one per pixel, so
  precision and recall do not depend on the distance or the viewing angle.
* A plane is a connected region (above), not every inlier of the infinite plane, and pixels
  where two crossing planes meet go to the larger one (above).
* The ``GAP`` label (reveals between flush fronts) is not in the thesis nor in the original
  code (whose labels are Eq. 5.2's four): with it, a rectangle's side along a reveal needs
  no recall margin beyond it (the plane continues in the neighbouring front, which the
  recall would otherwise count against it), and the rotation polish is skipped for a
  rectangle with three or more sides along reveals (its sides follow them). Rotation moves
  are 0.5 and 1 deg per round (``rotation_step_factors``; 2 and 4 deg steps changed no
  detection on 90 development frames and cost 9 ms per frame).

Known limits (measured): a front is found as the part of it that is seen: an occluder crossing
the whole front (a pole from top to bottom) is a local maximum the greedy moves do not cross
unless a random start straddles it; a closed front flush with its neighbours is found only
where its reveals are seen (``GAP``: at 2.3 m a reveal is 1 px and 6-7 mm deep against
9 mm of per-pixel noise); the drop-outs of a
structured-light camera at depth edges make fronts 1-3 cm narrower at 1.8-2.5 m.
* Costs are quantised to 1/255 (as in the original code) so the summed-area tables are int32;
  occluded and unknown pixels cost 20/255 as in the original code (0.2 before: with the
  n^0.05 size preference the greedy moves then trimmed every edge row with more than ~25 %
  drop-outs, and the recall check rejected the trimmed front: a drawer at 2.3 m was found in
  54 % instead of 92 % of its frames).
* A plane's least-squares refinement ends with a round on the inliers within L / 2 (a
  pulled-out drawer's sides tilted the cabinet face's plane, which then took the drawer's
  points out of the pool); the points leaving the pool with a plane are those within
  L + (removal_factor - 1) x the noise part of L (not removal_factor x L), and a parallel
  plane is a copy of an earlier one only when its inliers' centroid is within L of it (not
  its offset within 2 L at the camera): a front standing 1.5-2 cm proud of its carcass with
  L = 0.01 m was lost otherwise.
* The greedy search takes the best improving move of all step sizes at once (steepest
  ascent, vectorised over all starts); the original code tries the largest step size first.
* Rectangles touching the image border (``border_margin_px``) are rejected (as in the original
  code): their extent is not observed. So a wall filling the view gives no rectangle; a wall
  whose four edges are in view is a rectangle like any other.
"""


import math
import time
from dataclasses import dataclass, field, fields

import cv2
import numpy as np

from mmlearn.models.common.camera import PinholeIntrinsics, as_depth_image, valid_depth_mask
from mmlearn.models.perception.fronts import FrontRectangle

__all__ = ["FrontDetectorConfig", "detect_fronts", "Plane", "STAGES"]

STAGES = ("planes", "masks", "sampling", "optimisation", "check")

# mask labels (Eq. 5.2), plus cells of the rectified grid that the camera does not see
IN_PLANE, FREE, OCCLUDED, UNKNOWN, OUTSIDE = 0, 1, 2, 3, 4
# a measured pixel within L of the plane that the surface check found off its surface (a
# panel's edge face seen obliquely): costs like UNKNOWN, but is not the plane's surface for the
# edge refinement
OFF_SURFACE = 5
# a pixel on a thin line that lies behind the measured surface on both sides of it, or has no
# return between measured lines on both sides (the reveal between two flush fronts): costs
# like FREE, and a rectangle's side along such a line is observed to end there (recall)
GAP = 6


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
        surface_check: in-plane pixels whose in-plane neighbours lie on average farther than
            the surface distance from the plane become unknown (module docstring).
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
        refine_plane: refit each accepted rectangle's plane on its full-resolution in-plane
            pixels.
        edge_refine: refine each accepted rectangle's sides below the grid cell
            (:func:`_refine_edges`).
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
        gap_label: label the reveals between flush fronts ``GAP`` (:func:`_gap_mask`): thin
            image lines (rows or columns) whose depth, averaged along the line, lies behind
            the lines ``gap_offsets_px`` away on both sides (which agree with each other), or
            that have no return between measured lines.
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
            runs on the rectified views (below), and on the image only with
            ``gap_long_on_image`` and when no plane needs a view.
        gap_long_on_image: the long pass on the image too (off: on renders of seed 2003 it
            split the closed door at 2.0 / 2.3 m with false rows, found in 1 / 2 of 5 frames
            instead of 5 / 5, while it found the closed drawer at 2.2 m in only 2-3 of 5
            noisy frames of seed 2000 instead of 0).
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
    surface_check: bool = True
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
    refine_plane: bool = True
    edge_refine: bool = True
    own_pixel_refit_deg: float = 0.5
    edge_refine_band: float = 0.05
    edge_refine_cell: float = 0.001
    edge_refine_span: float = 0.7
    edge_refine_depth_step: float = 0.002
    edge_refine_depth_step_per_m2: float = 0.0008
    gap_label: bool = True
    component_starts: int = 12
    gap_window_px: int = 32
    gap_offsets_px: list[int] = field(default_factory=lambda: [2, 3, 4, 5, 7, 9])
    gap_depth: float = 0.0025
    gap_depth_per_m2: float = 0.001
    gap_side_tolerance_per_m2: float = 0.004
    gap_min_length: float = 0.2
    gap_long_window_px: int = 128
    gap_long_min_windows: float = 0.5
    gap_long_on_image: bool = False
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


@dataclass
class Plane:
    """A plane found by RANSAC, camera frame: ``n . p + d = 0``, ``n`` unit towards the camera
    (``d > 0``); ``support`` = inliers among the sampled pixels (its largest connected region);
    ``bbox`` = (row0, row1, col0, col1) of that region on the sample grid; ``parent`` = the
    index of the plane an offset layer was split from (:func:`_offset_layers`), -1 for
    RANSAC's own planes; ``region`` = (row0, row1, col0, col1), image pixels: where an offset
    layer and its parent share pixels by the nearer-plane rule (None: everywhere)."""

    n: np.ndarray
    d: float
    support: int
    bbox: tuple = (0, 0, 0, 0)
    parent: int = -1
    region: tuple | None = None


# ------------------------------------------------------------------------------------------
# stage 1: planes
# ------------------------------------------------------------------------------------------
def _plane_from_scatter(c: np.ndarray, scatter: np.ndarray):
    """The plane through the centroid ``c`` (3,) whose normal is the least eigenvector of the
    (3, 3) ``scatter`` matrix of the points about it (fast at 3 x 3): unit normal towards
    the camera at the origin, and offset."""
    _, V = np.linalg.eigh(scatter)
    n = V[:, 0]
    if n @ c > 0:  # towards the camera at the origin
        n = -n
    return n, float(-n @ c)


def _fit_plane(P: np.ndarray):
    """Least-squares plane through points (k, 3): unit normal towards the camera and offset."""
    c = P.mean(axis=0)
    Q = P.T - c[:, None]  # (3, k): see _fit_plane_many
    return _plane_from_scatter(c, _scatter3(Q))


def _fit_plane_many(P: np.ndarray):
    """:func:`_fit_plane` for many points (the full-resolution refits): the centroid as a
    matrix-vector product (numpy's column mean of a (k, 3) array is a strided reduction, 4x
    slower) and the centred points as a (3, k) array (subtracting a 3-vector from (k, 3) rows
    is 10x slower); the same plane up to rounding (~1e-16)."""
    c = (np.ones(len(P)) @ P) * (1.0 / len(P))
    Q = P.T - c[:, None]
    return _plane_from_scatter(c, _scatter3(Q))


def _scatter3(Q: np.ndarray) -> np.ndarray:
    """Q Q^T of centred points ``Q`` (3, k) from its six distinct row products (``Q @ Q.T``
    is a rank-k update on 3 rows, 5x slower at k = 16000; the same matrix to ~1e-16
    relative)."""
    q0, q1, q2 = Q
    s01, s02, s12 = q0 @ q1, q0 @ q2, q1 @ q2
    return np.array([[q0 @ q0, s01, s02], [s01, q1 @ q1, s12], [s02, s12, q2 @ q2]])


def _components(sel, grid_rc, grid_shape):
    img = np.zeros(grid_shape, np.uint8)
    img[grid_rc[sel, 0], grid_rc[sel, 1]] = 1
    _, lab = cv2.connectedComponents(img, connectivity=8)
    return lab[grid_rc[sel, 0], grid_rc[sel, 1]]


def _largest_region(sel, grid_rc, grid_shape):
    """The points of ``sel`` (indices) in the largest 8-connected region on the sample grid."""
    if len(sel) == 0:
        return sel
    lab = _components(sel, grid_rc, grid_shape)
    return sel[lab == np.argmax(np.bincount(lab))]


def _regions_touching(sel, region, grid_rc, grid_shape):
    """The points of ``sel`` in the 8-connected regions (of ``sel``) that contain a point of
    ``region`` (a subset of ``sel``)."""
    if len(sel) == 0 or len(region) == 0:
        return sel[:0]
    lab = _components(sel, grid_rc, grid_shape)
    keep = np.zeros(lab.max() + 1, bool)
    # sel's points that are in region: a lookup table of the point indices (np.isin sorts)
    mark = np.zeros(max(int(sel.max()), int(region.max())) + 1, bool)
    mark[region] = True
    keep[lab[mark[sel]]] = True
    return sel[keep[lab]]


def _cross_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of (N, 3) arrays: the products and differences of
    ``np.cross`` (the same values), without its per-call overhead (3x faster at 200 rows)."""
    a0, a1, a2 = a[:, 0], a[:, 1], a[:, 2]
    b0, b1, b2 = b[:, 0], b[:, 1], b[:, 2]
    out = np.empty(a.shape)
    out[:, 0] = a1 * b2 - a2 * b1
    out[:, 1] = a2 * b0 - a0 * b2
    out[:, 2] = a0 * b1 - a1 * b0
    return out


def find_planes(pts: np.ndarray, grid_rc: np.ndarray, grid_shape, cfg: FrontDetectorConfig,
                rng: np.random.Generator) -> list[Plane]:
    """Sequential RANSAC (5.1.1) on sampled points ``pts`` (m, 3) whose sample-grid positions
    are ``grid_rc`` (m, 2) in a grid of ``grid_shape``; returns up to ``cfg.max_planes``
    planes."""
    Lp = np.maximum(cfg.inlier_distance, cfg.inlier_distance_per_m2 * pts[:, 2] ** 2)
    # removal band: L plus (removal_factor - 1) times the noise part of L (a fixed multiple
    # of L would also take a front standing 2 cm proud of its carcass, L = 0.01-0.015 m)
    Lr = Lp + (cfg.removal_factor - 1.0) * cfg.inlier_distance_per_m2 * pts[:, 2] ** 2
    m = len(pts)
    planes: list[Plane] = []
    if m < max(3, cfg.min_plane_points):
        return planes
    active = np.ones(m, bool)
    r = max(1, int(round(cfg.ransac_local_radius_px / cfg.ransac_stride_px)))
    # index of the active point at each grid cell (-1: none), padded by r on every side so
    # that every local offset is a valid (flat) index
    Wp = grid_shape[1] + 2 * r
    lookup = np.full((grid_shape[0] + 2 * r) * Wp, -1, np.int64)
    flat_rc = (grid_rc[:, 0] + r) * Wp + (grid_rc[:, 1] + r)
    lookup[flat_rc] = np.arange(m)
    N = int(cfg.ransac_hypotheses)
    P32 = pts.astype(np.float32)
    Lp32 = Lp.astype(np.float32)
    # max_planes counts the planes kept; rounds that only clear the pool (a copy of an earlier
    # plane, a region below min_plane_points) do not take a kept plane's turn, up to
    # 2 x max_planes rounds in all
    for _ in range(2 * int(cfg.max_planes)):
        if len(planes) >= int(cfg.max_planes):
            break
        idx = np.flatnonzero(active)
        if len(idx) < max(3, cfg.min_plane_points):
            break
        first = idx[rng.integers(0, len(idx), N)]
        # 2nd and 3rd point: the first two of T random offsets that land on active points
        T = 12
        off = rng.integers(-r, r + 1, (N, T, 2))
        cand = lookup[flat_rc[first][:, None] + (off[..., 0] * Wp + off[..., 1])]
        good = (cand >= 0) & ((off[..., 0] != 0) | (off[..., 1] != 0))
        # the first two good offsets of each hypothesis (rows with fewer are not ok)
        rows = np.arange(N)
        i1 = good.argmax(axis=1)
        g2 = good.copy()
        g2[rows, i1] = False
        i2 = g2.argmax(axis=1)
        ok = g2[rows, i2]
        other = np.column_stack([cand[rows, i1], cand[rows, i2]])
        other[~ok] = 0
        p1, p2, p3 = pts[first], pts[other[:, 0]], pts[other[:, 1]]
        nrm = _cross_rows(p2 - p1, p3 - p1)
        ln = np.linalg.norm(nrm, axis=1)
        ok &= ln > 1e-9
        if not ok.any():
            # no local triple: fall back to global triples
            tri = idx[rng.integers(0, len(idx), (N, 3))]
            p1, p2, p3 = pts[tri[:, 0]], pts[tri[:, 1]], pts[tri[:, 2]]
            nrm = _cross_rows(p2 - p1, p3 - p1)
            ln = np.linalg.norm(nrm, axis=1)
            ok = ln > 1e-9
            if not ok.any():
                break
        nrm = nrm[ok] / ln[ok, None]
        dd = -np.einsum("ij,ij->i", nrm, p1[ok])
        # |distance| of every active point to every hypothesis, (N, ma) float32, in place
        # (one buffer: a hypothesis' row is contiguous for its count)
        dist = nrm.astype(np.float32) @ P32[idx].T
        dist += dd.astype(np.float32)[:, None]
        np.abs(dist, out=dist)
        Li = Lp32[idx]
        # inliers per hypothesis: the 0/1 bytes summed per row (2x np.count_nonzero's axis)
        counts = np.less_equal(dist, Li).view(np.uint8).sum(axis=1, dtype=np.int64)
        best = int(np.argmax(counts))
        if counts[best] < cfg.min_plane_points:
            break
        inl = _largest_region(idx[dist[best] <= Li], grid_rc, grid_shape)
        n, d = nrm[best], float(dd[best])
        # least-squares refinement on the inliers, then re-select them; the second round on
        # those within L / 2 (a drawer's sides, seen from above, span the few cm between its
        # front and the cabinet face: with them the face's plane tilts towards the front and
        # then takes the front's points out of the pool)
        Pa, La = pts[idx], Lp[idx]  # the active points (gathered once)
        for shrink in (1.0, 0.5, 1.0):
            if len(inl) < 3:
                break
            n, d = _fit_plane(pts[inl])
            inl = _largest_region(idx[np.abs(Pa @ n + d) <= shrink * La], grid_rc, grid_shape)
        # The plane is its largest connected region of inliers (on the sample grid): other
        # surfaces crossing the infinite plane stay in the pool. The region's points within
        # the removal band Lr (so that the noise tails of a far plane do not come back as a
        # second copy of it) leave the pool of sampling points.
        loose = idx[np.abs(Pa @ n + d) <= Lr[idx]]
        gone = np.concatenate([_regions_touching(loose, inl, grid_rc, grid_shape), inl])
        active[gone] = False
        lookup[flat_rc[gone]] = -1
        if len(inl) < cfg.min_plane_points:
            continue
        Lq = max(cfg.inlier_distance, cfg.inlier_distance_per_m2 * d * d)
        # a copy: (nearly) the same normal and its inliers' centroid within L of an earlier
        # plane (a front standing 2 cm proud of its carcass, L = 0.01 m, is not a copy)
        cen = pts[inl].mean(axis=0)
        dup = any(abs(q.n @ n) > math.cos(math.radians(5.0)) and abs(q.n @ cen + q.d) < Lq
                  for q in planes)
        if dup:  # masks cover every pixel of a plane: a second copy adds nothing
            continue
        rc = grid_rc[inl]
        planes.append(Plane(n=n, d=d, support=len(inl),
                            bbox=(int(rc[:, 0].min()), int(rc[:, 0].max()) + 1,
                                  int(rc[:, 1].min()), int(rc[:, 1].max()) + 1)))
    return planes


def refine_plane_fullres(pl: Plane, Pc, Lmap, stride, off, max_points=20000) -> Plane:
    """Least-squares refit of a plane on the full-resolution pixels within L of it inside the
    bounding box of its sampled region (every pixel for small planes, a regular subset of at
    most ``max_points`` for large ones); two rounds, the second on the pixels within L / 2 of
    the first fit (keeps a handle or an edge strip from tilting a small front's plane)."""
    r0, r1, c0, c1 = pl.bbox
    R0, R1 = off + stride * r0 - stride, off + stride * r1 + stride
    C0, C1 = off + stride * c0 - stride, off + stride * c1 + stride
    R0, C0 = max(0, R0), max(0, C0)
    crop = Pc[R0:R1, C0:C1]
    Lc = Lmap[R0:R1, C0:C1]
    step = max(1, int(math.ceil(math.sqrt(crop.shape[0] * crop.shape[1] / max_points))))
    P = crop[::step, ::step].reshape(-1, 3)
    L = Lc[::step, ::step].reshape(-1)
    ok = np.isfinite(P[:, 2])
    # np.compress: the rows of a boolean mask (numpy's P[mask] on (k, 3) rows is 5x slower)
    P, L = np.compress(ok, P, axis=0).astype(np.float64), L[ok]
    n, d = pl.n, pl.d
    for shrink in (1.0, 0.5):
        sel = np.abs(P @ n + d) <= shrink * L
        if np.count_nonzero(sel) < 10:
            return pl
        n2, d2 = _fit_plane_many(np.compress(sel, P, axis=0))
        if n2 @ pl.n < math.cos(math.radians(10.0)):
            return pl
        n, d = n2, d2
    return Plane(n=n, d=d, support=pl.support, bbox=pl.bbox)


# ------------------------------------------------------------------------------------------
# stage 2: masks and rectified grids
# ------------------------------------------------------------------------------------------
@dataclass
class _Grid:
    """A plane's rectified label grid: cell (row i, col j) is the plane point
    ``o + (u0 + (j + 0.5) c) e1 + (v0 + (i + 0.5) c) e2`` (camera frame)."""

    plane_index: int
    n: np.ndarray
    d: float
    o: np.ndarray
    e1: np.ndarray
    e2: np.ndarray
    u0: float
    v0: float
    c: float
    labels: np.ndarray
    sat_cost: np.ndarray
    sat_in: np.ndarray
    sat_gap: tuple | None = None  # (GAP, UNKNOWN) summed-area tables: gap_sats()

    @property
    def shape(self):
        return self.labels.shape

    def gap_sats(self) -> tuple:
        """The summed-area tables (int32) of the ``GAP`` and the ``UNKNOWN`` cells of
        ``labels``, made on first use (:func:`_gap_bounded`)."""
        if self.sat_gap is None:
            self.sat_gap = _sats_gap(self.labels)
        return self.sat_gap


def _plane_axes(n: np.ndarray, down_C: np.ndarray | None):
    """In-plane axes (e1, e2) with e1 x e2 = n: e2 along gravity ("down") projected onto the
    plane, or, for a (near) horizontal plane or unknown gravity, e1 along the camera x axis."""
    # (norms as the square root of the dot product and cross products written out: what
    # np.linalg.norm and np.cross compute, the same float operations, without their ~30 us
    # of call overhead)
    if down_C is not None:
        g = down_C - (down_C @ n) * n
        ng = math.sqrt(g @ g)
        if ng > 0.5:  # plane tilted less than 60 deg from vertical
            e2 = g / ng
            return _cross3(e2, n), e2
    x = np.array([1.0, 0.0, 0.0]) - n[0] * n
    nx = math.sqrt(x @ x)
    if nx < 1e-6:
        x = np.array([0.0, 1.0, 0.0]) - n[1] * n
        nx = math.sqrt(x @ x)
    e1 = x / nx
    return e1, _cross3(n, e1)


def _cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b of two 3-vectors (float64): the products and differences of np.cross, in the
    same order, on Python floats."""
    a0, a1, a2 = a.tolist()
    b0, b1, b2 = b.tolist()
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def _rotate_axes(e1, e2, theta):
    c, s = math.cos(theta), math.sin(theta)
    return c * e1 + s * e2, -s * e1 + c * e2


def _grid_homography(K: PinholeIntrinsics, o, e1, e2, u0, v0, c, cb):
    """(M, A, H) of a plane grid (see :func:`_warp_labels`): M = [e1 e2 o] (3 x 3), A the
    grid cell -> plane coordinates (cells ``c`` x ``cb``, m, from (u0, v0)), H = K M A the
    cell -> pixel homography (the same products as before, with the intrinsics' matrix made
    once per camera and M filled in place: ~10 us less per warp, ~100 warps per frame)."""
    Km = _K_MATRICES.get(K)
    if Km is None:
        if len(_K_MATRICES) > 64:
            _K_MATRICES.clear()
        Km = _K_MATRICES[K] = np.array([[K.fx, 0, K.cx], [0, K.fy, K.cy], [0, 0, 1.0]])
    A = np.array([[c, 0, u0 + 0.5 * c], [0, cb, v0 + 0.5 * cb], [0, 0, 1.0]])
    M = np.empty((3, 3))
    M[:, 0], M[:, 1], M[:, 2] = e1, e2, o
    return M, A, Km @ M @ A


_K_MATRICES: dict = {}  # intrinsics -> their 3 x 3 matrix (read-only; K is hashable, frozen)


def _warp_labels(labels_img, K: PinholeIntrinsics, o, e1, e2, u0, v0, c, shape, cb=None,
                 outside=OUTSIDE):
    """Nearest-neighbour resampling of the image label mask onto a plane grid (cells ``c``
    along e1 and ``cb`` (default ``c``) along e2, m); cells that do not project into the
    image (or lie behind the camera) are OUTSIDE. Any uint8 image of per-pixel values works
    (a cost image ``lut[labels]``: then ``outside`` = ``lut[OUTSIDE]``, and the result is
    ``lut`` of the label grid: nearest neighbour only selects pixels)."""
    Hg, Wg = shape
    M, A, H = _grid_homography(K, o, e1, e2, u0, v0, c, c if cb is None else cb)
    out = cv2.warpPerspective(labels_img, H, (int(Wg), int(Hg)),
                              flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP,
                              borderMode=cv2.BORDER_CONSTANT, borderValue=int(outside))
    # depth of each cell is affine in (i, j): mask cells behind (or too close to) the camera
    zc = (M @ A)[2]  # z = zc[0] j + zc[1] i + zc[2]
    # affine: its least value over the grid is at a corner (most grids need no mask)
    if zc[2] + min(0.0, zc[0] * (Wg - 1)) + min(0.0, zc[1] * (Hg - 1)) < 0.05:
        jj = np.arange(Wg, dtype=np.float64)
        ii = np.arange(Hg, dtype=np.float64)
        z = zc[0] * jj[None, :] + zc[1] * ii[:, None] + zc[2]
        out[z < 0.05] = outside
    return out


def _warp_float(img, K, o, e1, e2, u0, v0, c, shape, cb=None, outside=float("nan")):
    """Like :func:`_warp_labels` for a float32 image (nearest neighbour; ``outside`` (NaN by
    default) where the cells leave the image; cells behind the camera are not masked)."""
    Hg, Wg = shape
    H = _grid_homography(K, o, e1, e2, u0, v0, c, c if cb is None else cb)[2]
    return cv2.warpPerspective(img, H, (int(Wg), int(Hg)),
                               flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP,
                               borderMode=cv2.BORDER_CONSTANT, borderValue=float(outside))


def _edge_angle(inplane: np.ndarray) -> float:
    """Dominant direction (mod 90 deg) of the edges of a binary in-plane grid, radians in
    (-pi/4, pi/4]: the argument of the magnitude-weighted mean of exp(4 i phi) / 4."""
    f = inplane.astype(np.float32)
    gx = cv2.Sobel(f, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(f, cv2.CV_32F, 0, 1, ksize=3)
    # on the edge cells only (gradient not 0: the magnitude is > 0 exactly there)
    sel = (gx != 0) | (gy != 0)
    if np.count_nonzero(sel) < 8:
        return 0.0
    gxs, gys = gx[sel], gy[sel]
    mag = np.hypot(gxs, gys)
    phi = np.arctan2(gys, gxs)
    z = np.sum(mag * np.exp(4j * phi))
    if abs(z) < 1e-6 * mag.sum():
        return 0.0
    return float(np.angle(z) / 4.0)


def _sat_cost(labels: np.ndarray, lut: np.ndarray):
    """Summed-area table (int32) of the cost x 255 of every cell (``lut``: label -> cost x 255,
    uint8; costs are quantised to 1/255 as in the original code)."""
    return cv2.integral(cv2.LUT(labels, lut), sdepth=cv2.CV_32S)


def _sat_in(labels: np.ndarray):
    """Summed-area table (int32) of the in-plane indicator."""
    return cv2.integral((labels == IN_PLANE).view(np.uint8), sdepth=cv2.CV_32S)


def _sats(labels: np.ndarray, lut: np.ndarray):
    return _sat_cost(labels, lut), _sat_in(labels)


def _surface_check(lab, S, Lm, win):
    """In place: an in-plane pixel whose in-plane neighbours (a ``win`` x ``win`` square) lie
    on average farther than ``Lm`` from the plane refitted to the in-plane pixels' distances
    (not from the detected plane, whose fit may be tilted) becomes UNKNOWN. Single pixels of a plane
    scatter around it by the camera's noise (their mean within a fraction of it); the side
    face of a panel seen around its edge (a door's 19 mm edge) lies within L of the panel's
    face too, but wholly behind it, and would otherwise widen the front by up to
    thickness x tan(incidence) (measured: 2 cm at 69 deg)."""
    m8 = cv2.compare(lab, IN_PLANE, cv2.CMP_EQ)
    x, y, w, h = cv2.boundingRect(m8)  # work on the in-plane pixels' bounding box only
    if w == 0 or h == 0:
        return
    r = win // 2
    y0, y1, x0, x1 = max(0, y - r), min(lab.shape[0], y + h + r), max(0, x - r), min(
        lab.shape[1], x + w + r)
    m8b = m8[y0:y1, x0:x1]
    inpb = m8b > 0
    in01 = inpb.view(np.uint8)
    # in-plane neighbours of each pixel (exact integers, from the 0/1 bytes)
    den = cv2.boxFilter(in01, cv2.CV_32F, (win, win), normalize=False)
    # relative to the plane refitted to the in-plane pixels' distances (an affine function
    # of the pixel, least squares), not to the fitted plane: a plane 1-2 deg off (a sliding
    # panel 4.6 cm in front of its cabinet's face) departs from one side of a 0.5 m panel by
    # more than the surface distance and the check removed that half with its handle
    # (handle regression: 0.154 m)
    Sb = S[y0:y1, x0:x1]
    vv, uu = np.nonzero(inpb[::4, ::4])  # every 4th pixel: enough for 3 numbers
    if len(vv) >= 3:
        A = np.column_stack([4.0 * uu, 4.0 * vv, np.ones(len(uu))])
        b = Sb[4 * vv, 4 * uu].astype(np.float64)
        lim = 2.0 * Lm[y0:y1, x0:x1][4 * vv, 4 * uu].astype(np.float64)
        coef = _affine_lstsq(A, b)
        # two trimmed refits on the pixels within twice the surface distance of the last
        # fit: the other surfaces within L of the plane (a neighbour's face, a panel's edge
        # face, the crossing strips) pulled the plain least-squares ramp of a door opened
        # 60 deg 2 mm off, and the check then cut a wedge out of the door (measured)
        for _ in range(2):
            keep = np.abs(A @ coef - b) <= lim
            if np.count_nonzero(keep) < 3:
                break
            coef = _affine_lstsq(np.compress(keep, A, axis=0), b[keep])
        # Sb - ramp, in place in one buffer (the ramp is (a x + b y) + c, float32)
        dev = np.add(np.float32(coef[0]) * np.arange(x1 - x0, dtype=np.float32)[None, :],
                     np.float32(coef[1]) * np.arange(y1 - y0, dtype=np.float32)[:, None])
        dev += np.float32(coef[2])
        np.subtract(Sb, dev, out=dev)
    else:
        dev = Sb.copy()
    dev *= in01.astype(np.float32)
    num = cv2.boxFilter(dev, -1, (win, win), normalize=False)
    # den >= 1 at every in-plane pixel (its own): max(den, 1) = den where it matters
    np.abs(num, out=num)
    den *= Lm[y0:y1, x0:x1]
    # bad: in-plane (label 0) and off the surface; OFF_SURFACE by or-ing it in (byte masks)
    bad = cv2.compare(num, den, cv2.CMP_GT)
    np.bitwise_and(bad, m8b, out=bad)
    np.bitwise_and(bad, np.uint8(OFF_SURFACE), out=bad)
    labb = lab[y0:y1, x0:x1]
    np.bitwise_or(labb, bad, out=labb)


def _affine_lstsq(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Least-squares coefficients of ``A`` (k, 3) = [u, v, 1] for ``b`` (k,): the normal
    equations of the centred columns (2 x 2, closed form; 10-50x faster than
    ``np.linalg.lstsq``'s SVD, the same coefficients up to rounding ~1e-15); ``lstsq`` when
    the points are (nearly) on one line."""
    u, v = A[:, 0], A[:, 1]
    k = len(b)
    mu, mv, mb = u.sum() / k, v.sum() / k, b.sum() / k
    du, dv, db = u - mu, v - mv, b - mb
    suu, svv, suv = du @ du, dv @ dv, du @ dv
    det = suu * svv - suv * suv
    if not det > 1e-9 * suu * svv:
        return np.linalg.lstsq(A, b, rcond=None)[0]
    sub, svb = du @ db, dv @ db
    a = (svv * sub - suv * svb) / det
    c = (suu * svb - suv * sub) / det
    return np.array([a, c, mb - a * mu - c * mv])


def _gap_mask(d, valid, fx, cfg, dzero=None, long_pass=True, scale_floor=False, var_scale=None,
              to_image=None):
    """Pixels on the reveals between flush fronts (``GAP``) from the depth image alone (one
    pass per frame for all planes): (wide, thin), (H, W) bool each; ``wide`` is ``thin`` one
    pixel wider on either side across the line (for the rectified grids).

    A reveal is a thin line (image rows or columns: the fronts' sides are horizontal and
    vertical seen from the front) that either has no return (a structured-light camera drops
    the pixels of a 5 mm gap seen straight on, its depth edges) or lies a few mm *behind* the
    surface on both sides (the 5 mm horizontal reveal seen from 25 deg above shows the lower
    front's top face, 6-7 mm behind: inside the inlier distance L, so in-plane for Eq. 5.2,
    and the two fronts are one plane region). Each line's depth is averaged over
    ``gap_window_px`` pixels along it (the camera's noise, ~9 mm per pixel at 2.3 m, would
    hide a one-pixel dip; the mean of 32 pixels scatters by ~1.7 mm there) and compared with
    the mean of the lines ``gap_offsets_px`` away on either side, which must agree (one
    surface on both sides: a depth step is not a reveal), and with half the threshold with
    each side's two lines (``o`` and ``2 o`` away) extended to the line (a concave crease is
    behind the mean of its sides but not behind their extensions). Lines with fewer than a third of
    their pixels measured are reveals too. Detections
    shorter than ``gap_min_length`` at their depth are dropped (noise gives short runs, a
    reveal runs along a whole front; ``dzero``: ``d`` with 0 where not ``valid``, if at
    hand). The side lines must be well measured (>= 80 % of their
    pixels: a countertop seen at grazing incidence drops a third of its pixels, and its line
    means scatter beyond the noise model). ``long_pass``: also the lines averaged over
    ``gap_long_window_px`` (threshold's z^2 part scaled by the square root of the windows'
    ratio; with ``scale_floor`` the ``gap_depth`` floor too). ``var_scale``: (H, W) float32,
    each pixel's noise variance over one frame's (a temporally filtered image,
    :mod:`mmlearn.models.perception.depth_filter`; 0 where not valid), or None (1): the threshold's z^2
    part is scaled by the square root of its mean over the line (the line mean's noise).
    ``to_image``: the 3 x 3
    homography from ``d``'s pixels to the camera image's when ``d`` is a rectified view: the
    offsets allowed across a band without return (5 px, or 2 px plus 0.01 f / z) count image
    pixels, and a plane seen at grazing incidence stretches each image pixel over s >= 1 view
    pixels (a door opened 90 deg seen 67 deg off its normal: its hinge seam, 4-6 image px
    without return, is 9-12 view px wide at s ~ 1.6)."""
    H, W = d.shape
    sub = 4  # the line means are smooth along a line: one per 4 pixels along it suffices
    z = np.where(valid, d, np.float32(0.0)) if dzero is None else dzero
    w = valid.astype(np.float32)
    Hc, Wc = H - H % sub, W - W % sub
    out = np.zeros((H, W), bool)
    thin = np.zeros((H, W), bool)
    # (window, threshold scale): the short window, and the long one whose mean scatters by
    # sqrt(short / long) of the short one's, so its threshold is scaled by that (a reveal
    # runs across a cabinet's fronts: its few-mm dip, sampled at an unlucky pixel phase, is
    # within the short window's noise but not within the long one's)
    nb0 = max(1, int(round(cfg.gap_window_px / sub)))
    scales = [(nb0, 1.0)]
    if cfg.gap_long_window_px and long_pass:
        nbl = max(nb0 + 1, int(round(cfg.gap_long_window_px / sub)))
        scales.append((nbl, math.sqrt(nb0 / nbl)))
    blocks = {}
    for horizontal, (nb, tscale) in ((h, s) for h in (True, False) for s in scales):
        Lw = nb * sub
        # block means along the line (x 4 = sums), then the window's sums: rows of (A, N)
        # run across the lines, columns along them
        if horizontal not in blocks:  # (the same blocks for both windows)
            if horizontal:
                size = (Wc // sub, H)
                A = cv2.resize(z[:, :Wc], size, interpolation=cv2.INTER_AREA)
                N = cv2.resize(w[:, :Wc], size, interpolation=cv2.INTER_AREA)
            else:
                size = (W, Hc // sub)
                A = np.ascontiguousarray(cv2.resize(z[:Hc], size, interpolation=cv2.INTER_AREA).T)
                N = np.ascontiguousarray(cv2.resize(w[:Hc], size, interpolation=cv2.INTER_AREA).T)
            V = None
            if var_scale is not None:
                V = cv2.resize(var_scale[:, :Wc] if horizontal else var_scale[:Hc],
                               size, interpolation=cv2.INTER_AREA)
                V = V if horizontal else np.ascontiguousarray(V.T)
            blocks[horizontal] = (A, N, V)
        A, N, V = blocks[horizontal]
        # block means: a window whose lines are not one surface (a step: an opened door in
        # front of the cabinet's reveals) has its middle block off the chord between its end
        # blocks (a plane's depth is close to linear along a line over 32 px)
        with np.errstate(invalid="ignore", divide="ignore"):
            B = A / N
        h0, h1 = nb // 2, nb - 1 - nb // 2
        bent = np.zeros(B.shape, bool)
        if B.shape[1] > nb:  # (in place: the same float32 operations in the same order)
            with np.errstate(invalid="ignore"):
                chord = np.add(B[:, : B.shape[1] - nb + 1], B[:, nb - 1:])
                chord *= np.float32(0.5)
                zc = B[:, h0: B.shape[1] - h1]
                tol_b = np.multiply(np.float32(cfg.gap_side_tolerance_per_m2), zc)
                tol_b *= zc
                np.maximum(np.float32(0.01), tol_b, out=tol_b)
                np.subtract(zc, chord, out=chord)
                np.abs(chord, out=chord)
                np.greater(chord, tol_b, out=bent[:, h0: B.shape[1] - h1])
        A = cv2.boxFilter(A, -1, (nb, 1), normalize=False, borderType=cv2.BORDER_CONSTANT)
        N = cv2.boxFilter(N, -1, (nb, 1), normalize=False, borderType=cv2.BORDER_CONSTANT)
        A *= np.float32(sub)
        N *= np.float32(sub)
        if V is not None:  # the line's noise std over one frame's: sqrt(mean variance factor)
            V = cv2.boxFilter(V, -1, (nb, 1), normalize=False, borderType=cv2.BORDER_CONSTANT)
            V *= np.float32(sub)
            V = np.sqrt(np.minimum(V / np.maximum(N, np.float32(1.0)), np.float32(1.0)))
        meas = N >= max(3.0, Lw / 3.0)
        # side lines: well measured and not bent (one array for both side tests)
        side_ok = (N >= 0.8 * Lw) & ~bent
        m = A / np.maximum(N, np.float32(1.0))
        m[~meas] = np.nan
        n_rows = m.shape[0]
        g = np.zeros(m.shape, bool)
        zg = np.zeros(m.shape, np.float32)  # depth of the side lines where hit
        Wm = m.shape[1]
        mf = m.reshape(-1)
        unmeas = ~meas
        gd = np.float32(cfg.gap_depth * (tscale if scale_floor else 1.0))
        gdz = np.float32(cfg.gap_depth_per_m2 * tscale)
        ref_buf, beh_buf = np.empty_like(m), np.empty_like(m)
        cand_buf = np.empty(m.shape, bool)
        # per offset, the lines that pass the first tests (candidates); the remaining tests
        # then run once on all offsets' candidates together (element-wise the same float32
        # arithmetic as one offset at a time)
        c_ic, c_ref, c_beh, c_o = [], [], [], []
        for o in cfg.gap_offsets_px:
            o = int(o)
            if n_rows <= 4 * o:
                continue
            # lines y - 2o, y - o | y | y + o, y + 2o for y in [2o, n_rows - 2o)
            r = slice(2 * o, n_rows - 2 * o)
            c = m[r]
            up, dn = m[o:n_rows - 3 * o], m[3 * o:n_rows - o]
            nr = n_rows - 4 * o  # (in buffers allocated once per pass: the same values)
            ref = np.add(up, dn, out=ref_buf[:nr])
            ref *= np.float32(0.5)
            behind = np.subtract(c, ref, out=beh_buf[:nr])
            # the selective test first on every line (behind its sides by more than
            # gap_depth <= thr, or unmeasured), the other tests only on its few candidates
            with np.errstate(invalid="ignore"):
                cand = np.greater(behind, gd, out=cand_buf[:nr])
            cand |= unmeas[r]
            # the side lines well measured and not bent (lines without return inside a
            # region of drop-outs have no measured sides): cheap boolean ANDs on every
            # line, which drop the many unmeasured lines outside a rectified view's footprint
            cand &= side_ok[o:n_rows - 3 * o]
            cand &= side_ok[3 * o:n_rows - o]
            idx = np.flatnonzero(cand)
            if not len(idx):
                continue
            c_ic.append(idx + (2 * o) * Wm)  # flat index of the line in m
            c_ref.append(ref.reshape(-1)[idx])
            c_beh.append(behind.reshape(-1)[idx])
            c_o.append(np.full(len(idx), o, np.int64))
        if c_ic:
            ic, refv, behv, ov = (np.concatenate(x) for x in (c_ic, c_ref, c_beh, c_o))
            # behind by more than thr (the candidates are behind by gap_depth), or unmeasured
            z2v = refv * refv
            thrv = np.maximum(gd, gdz * z2v * (V.reshape(-1)[ic] if V is not None else 1.0))
            if to_image is not None:
                # a rectified view interpolates each image pixel over s >= 1 view pixels
                # along the line: a window's mean holds 1 / s of the independent samples it
                # has on the image, its noise sqrt(s) times larger (false lines across a
                # door at 2.3 m opened 46 deg, its view stretched 1.4-2 x)
                thrv = thrv * np.sqrt(_view_stretch(to_image, ic, Wm, sub, horizontal,
                                                    across=False))
            unm = unmeas.reshape(-1)[ic]
            with np.errstate(invalid="ignore"):
                keep = np.flatnonzero((behv > thrv) | unm)
            ic, ov = ic[keep], ov[keep]
            refv, z2v, thrv, unm = refv[keep], z2v[keep], thrv[keep], unm[keep]
            oW = ov * Wm
            ou = ic - oW         # side lines o and 2 o away
            od = ic + oW
            upv, dnv, cv = mf[ou], mf[od], mf[ic]
            tolv = np.maximum(np.float32(0.01), np.float32(cfg.gap_side_tolerance_per_m2) * z2v)
            with np.errstate(invalid="ignore"):
                hit = np.abs(upv - dnv) < tolv  # False where either side is NaN
                # behind the sides' extrapolations too (each side's two lines extended to
                # the line): a concave crease (an opened door meeting the cabinet's face at
                # its hinge) lies behind the mean of its sides, not behind their extensions
                ext = upv + dnv - np.float32(0.5) * (mf[ou - oW] + mf[od + oW])
                hit &= (cv - ext > np.float32(0.5) * thrv) | unm
                # only near for o > 5: a 5 mm reveal's band without return is ~2 + f 0.01 / z px
                # (in a rectified view, for a line without return: its image px count s >= 1
                # view px each, o <= 5 s or 2 s + f 0.01 / z)
                near = (ov <= 5) | (refv * (ov - 2).astype(np.float32) < np.float32(0.01 * fx))
                if to_image is not None and unm.any():
                    sv = _view_stretch(to_image, ic[unm], Wm, sub, horizontal)
                    o_u, z_u = ov[unm], refv[unm]
                    near[unm] = (o_u <= 5 * sv) | (z_u * (o_u - 2 * sv) < np.float32(0.01 * fx))
                hit &= near
            ih, zh = ic[hit], refv[hit]
            g.reshape(-1)[ih] = True
            # a line hit at several offsets keeps the depth of its last one (offset by
            # offset, in order: each offset's lines are distinct)
            cut = [0, *(np.flatnonzero(np.diff(ov[hit])) + 1).tolist(), len(ih)]
            zgf = zg.reshape(-1)
            for a, b in zip(cut[:-1], cut[1:]):
                zgf[ih[a:b]] = zh[a:b]
        if not g.any():
            continue
        # keep runs along the line at least gap_min_length long at their depth
        # (16-bit labels when they cannot overflow: OpenCV's stats pass is ~2.5x faster;
        # 8-connected, at most one component per 2 x 2 pixels)
        ltype = (cv2.CV_16U if ((g.shape[0] + 1) // 2) * ((g.shape[1] + 1) // 2) < 65535
                 else cv2.CV_32S)
        n_lab, lab, stats, cent = cv2.connectedComponentsWithStats(g.view(np.uint8),
                                                                   connectivity=8, ltype=ltype)
        if n_lab <= 1:
            continue
        length = sub * stats[1:, cv2.CC_STAT_WIDTH].astype(np.float64)
        # depth of each run: its side lines' depth at its centroid (a run is a thin line:
        # the centroid is on it), else the mean over the run
        cr = np.clip(np.round(cent[1:, 1]).astype(np.int64), 0, lab.shape[0] - 1)
        cc = np.clip(np.round(cent[1:, 0]).astype(np.int64), 0, lab.shape[1] - 1)
        zrun = zg[cr, cc].astype(np.float64)
        off = np.flatnonzero(lab[cr, cc] != np.arange(1, n_lab))
        if len(off):  # (on the run pixels only: the same sums in the same order)
            on = np.flatnonzero(g)
            zsum = np.bincount(lab.reshape(-1)[on], weights=zg.reshape(-1)[on],
                               minlength=n_lab)[1:]
            zrun[off] = zsum[off] / np.maximum(stats[1 + off, cv2.CC_STAT_AREA], 1)
        # (the long pass: at least its window long, one window's scatter is not a line)
        min_px = cfg.gap_min_length * fx / np.maximum(zrun, 1e-6)
        if nb != nb0:
            min_px = np.maximum(min_px, np.float64(cfg.gap_long_min_windows * Lw))
        keep = np.concatenate([[False], length >= min_px])
        if not keep.any():
            continue
        on = np.flatnonzero(g)  # (the kept runs' pixels: on the hits only)
        g = np.zeros(g.shape, bool)
        g.reshape(-1)[on] = keep[lab.reshape(-1)[on]]
        # one pixel wider on either side across the line: a one-pixel line would fall
        # between the 5 mm cells of a plane's rectified grid (2.2 mm pixels at 1.3 m)
        wide = g.copy()
        wide[1:] |= g[:-1]
        wide[:-1] |= g[1:]
        if horizontal:  # back to every pixel along the line
            out[:, :Wc] |= np.repeat(wide, sub, axis=1)
            thin[:, :Wc] |= np.repeat(g, sub, axis=1)
        else:
            out[:Hc] |= np.repeat(np.ascontiguousarray(wide.T), sub, axis=0)
            thin[:Hc] |= np.repeat(np.ascontiguousarray(g.T), sub, axis=0)
    return out, thin


def _view_stretch(to_image, ic, Wm, sub, horizontal, across=True):
    """View pixels per image pixel across the lines (``across``; else along them; >= 1: never
    less than on the image) at
    the line pixels ``ic`` (flat indices into :func:`_gap_mask`'s line-mean array: rows across
    the lines, one column per ``sub`` pixels along them) of a rectified view whose pixels map
    to the image by the homography ``to_image``."""
    a, b = np.divmod(ic, Wm)
    b = b * sub + 0.5 * (sub - 1)
    x, y = (b, a) if horizontal else (a, b)
    Hi = to_image
    p = Hi[:, 0:1] * x + Hi[:, 1:2] * y + Hi[:, 2:3]  # (3, n)
    # across the lines: view y for rows, view x for columns; along them the other one
    k = (1 if horizontal else 0) if across else (0 if horizontal else 1)
    du = (Hi[0, k] * p[2] - p[0] * Hi[2, k]) / (p[2] * p[2])
    dv = (Hi[1, k] * p[2] - p[1] * Hi[2, k]) / (p[2] * p[2])
    return np.maximum(1.0, 1.0 / np.maximum(np.hypot(du, dv), 1e-9)).astype(np.float32)


def _view_footprint(Hm, Wv: int, Hv: int, shape, pad: int = 2):
    """The image pixels a rectified view reads: (y0, y1, x0, x1), the bounding box (padded by
    ``pad`` px for the bilinear neighbours, clipped to the image of ``shape`` = (H, W)) of the
    view's corners mapped to the image by the inverse of the image -> view homography ``Hm``
    (a view of ``Wv`` x ``Hv`` px); the whole image when a corner does not map in front of the
    camera (the quadrilateral is then not the image of the view)."""
    H, W = shape
    q = np.linalg.inv(Hm) @ np.array([[0.0, Wv, Wv, 0.0], [0.0, 0.0, Hv, Hv], [1.0] * 4])
    if not (q[2] > 1e-9).all():
        return 0, H, 0, W
    u, v = q[0] / q[2], q[1] / q[2]
    if not (np.isfinite(u).all() and np.isfinite(v).all()):
        return 0, H, 0, W
    x0 = int(min(W, max(0, math.floor(u.min()) - pad)))
    x1 = int(min(W, max(0, math.ceil(u.max()) + pad + 1)))
    y0 = int(min(H, max(0, math.floor(v.min()) - pad)))
    y1 = int(min(H, max(0, math.ceil(v.max()) + pad + 1)))
    return y0, y1, x0, x1


def _gap_mask_rectified(dzero, valid, K: PinholeIntrinsics, xs, ys, view, cfg, long_pass=True,
                        valid_f=None):
    """:func:`_gap_mask` (short and long windows, the long one's whole threshold scaled) on
    the rectified view ``view`` of a plane
    (:func:`_rectified_view`): (wide, thin) in the image, or None when nothing is found.
    ``long_pass=False``: the short windows only. ``valid_f``: ``valid`` as float32 0 / 1 if
    at hand (shared by a frame's views)."""
    Hm, R, f, Wv, Hv = view
    r3 = R[:, 2].astype(np.float32)
    # z' = d (r3 . ray) only on the image pixels the view reads (its footprint's bounding
    # box; 0 elsewhere, never read): the same float32 values where the warp reads them
    y0, y1, x0, x1 = _view_footprint(Hm, Wv, Hv, dzero.shape)
    zv = np.zeros(dzero.shape, np.float32)
    zr = (np.float32(r3[0]) * xs[:, x0:x1] + np.float32(r3[2])) + np.float32(r3[1]) * ys[y0:y1]
    np.multiply(zr, dzero[y0:y1, x0:x1], out=zv[y0:y1, x0:x1])  # 0 where not measured
    if valid_f is None:
        valid_f = valid.view(np.uint8).astype(np.float32)
    # bilinear on z' and on the measured share, normalised (unmeasured pixels do not pull
    # the depth towards 0); a pixel at least half measured is measured
    zw = cv2.warpPerspective(zv, Hm, (Wv, Hv), flags=cv2.INTER_LINEAR,
                             borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)
    ww = cv2.warpPerspective(valid_f, Hm, (Wv, Hv),
                             flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                             borderValue=0.0)
    vw = ww >= 0.5
    np.maximum(ww, np.float32(1e-6), out=ww)  # (in place: the same float32 values)
    np.divide(zw, ww, out=zw)
    zw[~vw] = 0.0
    # the long pass here with its whole threshold scaled (gap_depth too: a vertical reveal
    # seen 45 deg off the normal dips 1.6-3.7 mm at 1.5 m, where both passes' thresholds
    # are the 2.5 mm floor; on the whole image a scaled floor labelled false rows on the wall
    # and countertop at 2.2 m)
    gw, gt = _gap_mask(zw, vw, f, cfg, zw, long_pass=long_pass, scale_floor=True,
                       to_image=np.linalg.inv(Hm))
    if not gt.any():
        return None
    # both masks back to the image in one nearest-neighbour warp (bit 0 wide, bit 1 thin:
    # nearest neighbour copies each view pixel's byte whole)
    packed = np.left_shift(gt.view(np.uint8), np.uint8(1))
    packed |= gw.view(np.uint8)
    back = cv2.warpPerspective(packed, Hm, (K.width, K.height),
                               flags=cv2.WARP_INVERSE_MAP | cv2.INTER_NEAREST,
                               borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    wide = np.bitwise_and(back, np.uint8(1)).view(bool)
    thin = np.right_shift(back, np.uint8(1)).view(bool)
    return wide, thin


def _rectified_view(K: PinholeIntrinsics, pl: Plane, down_C, cfg, stride: int, off: int):
    """A plane's rectified view for :func:`_gap_mask_rectified`: (H, R, f, width, height)
    (H the image -> view homography, R the view's axes in the camera frame, f its focal
    length, px), or None when the plane's in-plane axes (e1 along its horizontal, e2 down the plane, :func:`_plane_axes`)
    are seen within ``gap_rectify_deg`` of the image rows and columns at its region's centre
    (then the image lines follow its edges already).

    Off the front's normal a front's horizontal sides are slanted in the image, and the line
    means along image rows cross the reveal instead of following it. A virtual camera at the
    same centre, rotated to look along the plane's normal with its x and y axes along e1 and
    e2 (a pure rotation: the homography K' R^T K^-1, the same rays, so the same depth samples),
    sees the plane's sides along its rows and columns and the plane at constant depth z'
    (z' = d (r3 . ray)); the reveals are found there on z' with the same tests, and mapped back
    (nearest pixel). The view covers the plane's region (``Plane.bbox``), with its focal
    length reduced so that it is at most ``gap_rectify_max_scale`` times the image's size."""
    n = np.asarray(pl.n, float)
    if down_C is not None and abs(float(n @ down_C)) > math.sin(
            math.radians(cfg.gap_rectify_max_tilt_deg)):
        return None  # not a vertical plane (floor, countertop): no front
    e1, e2 = _plane_axes(n, down_C)
    r0, r1, c0, c1 = pl.bbox
    uc = off + stride * 0.5 * (c0 + c1)
    vc = off + stride * 0.5 * (r0 + r1)
    ray_c = np.array([(uc - K.cx) / K.fx, (vc - K.cy) / K.fy, 1.0])
    den = n @ ray_c
    if not den < -1e-6:
        return None
    pc = ray_c * (-pl.d / den)

    def img_dir(e):
        q0, q1 = pc, pc + 0.05 * e
        a = np.array([K.fx * q0[0] / q0[2], K.fy * q0[1] / q0[2]])
        b = np.array([K.fx * q1[0] / q1[2], K.fy * q1[1] / q1[2]])
        return b - a
    d1, d2 = img_dir(e1), img_dir(e2)
    slant1 = math.degrees(math.atan2(abs(d1[1]), abs(d1[0]) + 1e-12))
    slant2 = math.degrees(math.atan2(abs(d2[0]), abs(d2[1]) + 1e-12))
    if max(slant1, slant2) < cfg.gap_rectify_deg:
        return None
    # virtual axes in camera coordinates: z' into the plane (away from the camera)
    R = np.column_stack([-e1, e2, -n])  # (-e1) x e2 = -n: right-handed
    # the region's corners (on the plane) in the virtual view
    us = off + stride * np.array([c0, c1 + 1, c1 + 1, c0], float)
    vs = off + stride * np.array([r0, r0, r1 + 1, r1 + 1], float)
    rays = np.column_stack([(us - K.cx) / K.fx, (vs - K.cy) / K.fy, np.ones(4)])
    q = rays @ R  # R^T ray, rows
    if not (q[:, 2] > 1e-3).all():
        return None
    uv = K.fx * q[:, :2] / q[:, 2:3]
    size = uv.max(axis=0) - uv.min(axis=0)
    smax = cfg.gap_rectify_max_scale * np.array([K.width, K.height], float)
    # a coarser virtual focal length when the region would be larger than that (seen
    # obliquely, its far side is stretched in the rotated view)
    f = K.fx * min(1.0, float(np.min(smax / np.maximum(size, 1.0))))
    uv = f * q[:, :2] / q[:, 2:3]
    lo, hi = uv.min(axis=0) - 8.0, uv.max(axis=0) + 8.0
    size = hi - lo
    Wv, Hv = int(math.ceil(size[0])), int(math.ceil(size[1]))
    if Wv < 16 or Hv < 16:
        return None
    Kv = np.array([[f, 0.0, -lo[0]], [0.0, f, -lo[1]], [0.0, 0.0, 1.0]])
    Kinv = np.array([[1.0 / K.fx, 0.0, -K.cx / K.fx], [0.0, 1.0 / K.fy, -K.cy / K.fy],
                     [0.0, 0.0, 1.0]])
    Hm = Kv @ R.T @ Kinv  # image pixel -> virtual pixel
    return Hm, R, f, Wv, Hv


def _label_images(d, valid, ray_x, ray_y, planes, L, crossing_angle_deg,
                  smooth_px=5, surface=None, gap=None, keep_distances=False):
    """Eq. 5.2 labels of every pixel for every plane n . p + dpl = 0. The signed distance of
    the pixel's point p = depth * (ray_x, ray_y, 1) is depth * (n . ray) + dpl (separable in
    rows and columns). A pixel within L of two planes that cross at more than
    ``crossing_angle_deg`` and nearer to the one with the larger support is free for the
    other: in that strip the surface seen is the larger plane's (e.g. the cabinet's face next
    to the hinge of an open door, which would otherwise widen the door by L / sin(angle)).
    An offset layer and the plane it was split from (``Plane.parent``, :func:`_offset_layers`)
    share their pixels the same way, whatever their angle; a pixel the other plane keeps is
    OCCLUDED for a plane it lies in front of and FREE for one it lies behind.
    Otherwise pixels belong to every plane they are within L of (5.1.1).
    Returns the label images (a list, one uint8 image per plane), and with
    ``keep_distances`` also the (planes, H, W) float32 signed distances."""
    P = len(planes)
    S = np.empty((P,) + d.shape, np.float32)
    L = np.broadcast_to(np.asarray(L, np.float32), d.shape).copy() if np.ndim(L) == 0 else L
    negL = -L
    unknown = np.multiply((~valid).view(np.uint8), np.uint8(UNKNOWN))  # 0 or UNKNOWN
    labs = []
    occl = np.empty(d.shape, np.uint8)
    for k, pl in enumerate(planes):
        n = pl.n
        Sk = S[k]  # n . ray, times the depth, plus the offset: in place
        np.add(np.float32(n[0]) * ray_x + np.float32(n[2]), np.float32(n[1]) * ray_y, out=Sk)
        np.multiply(Sk, d, out=Sk)
        np.add(Sk, np.float32(pl.d), out=Sk)
        lab = cv2.compare(Sk, negL, cv2.CMP_LT)
        np.bitwise_and(lab, np.uint8(FREE), out=lab)
        cv2.compare(Sk, L, cv2.CMP_GT, dst=occl)
        np.bitwise_and(occl, np.uint8(OCCLUDED), out=occl)
        lab |= occl
        lab |= unknown                                   # 3 | anything = UNKNOWN
        if pl.parent >= 0 and pl.region is not None:
            # an offset layer is its region's surface only: elsewhere its infinite plane,
            # a degree off its parent's, runs through the parent's fronts
            r0, r1, c0, c1 = pl.region
            keep = lab[r0:r1, c0:c1].copy()
            lab[lab == IN_PLANE] = FREE
            lab[r0:r1, c0:c1] = keep
        labs.append(lab)
    _crossings(labs, S, planes, valid, crossing_angle_deg, smooth_px)
    if surface is not None:  # after the crossings: their strips would bias the means
        for k in range(P):
            _surface_check(labs[k], S[k], *surface)
    if gap is not None:  # reveals (_gap_mask): GAP unless something is in front
        gi = np.flatnonzero(gap.reshape(-1))
        if len(gi):
            for lab in labs:
                flat = lab.reshape(-1)
                sub = flat[gi]
                flat[gi] = np.where(sub == OCCLUDED, sub, np.uint8(GAP))
    return (labs, S) if keep_distances else labs


_CROSSING_MIN_SHARE = 0.1


def _crossings(labs, S, planes, valid, crossing_angle_deg, smooth_px):
    """In place: where two crossing planes are both within L of a pixel, the pixel stays
    in-plane only for the nearer one (see :func:`_label_images` and below)."""
    P = len(planes)
    if P < 2:
        return
    count = np.zeros(valid.shape, np.uint8)
    for lab in labs:
        count += (lab == IN_PLANE).view(np.uint8)  # (bytes + bytes: no per-element cast)
    shared = np.flatnonzero(count > 1)
    if len(shared) == 0:
        return
    near_sh = np.array([lab.reshape(-1)[shared] == IN_PLANE for lab in labs])
    N = np.array([pl.n for pl in planes])
    sup = np.array([pl.support for pl in planes])
    # [k, j]: j may take pixels from k. Planes crossing at less than 30 deg share a wide strip
    # (L / sin(angle)): there each keeps the pixels nearer to it (letting only the plane of
    # larger support take them widened a door opened 11-16 deg and seen from 0.8 m, larger in
    # the image than the neighbouring front, by the 2-4 cm strip of that front within L of
    # the door's plane next to the hinge, measured). At steeper crossings only the plane of
    # larger support takes them: the strip is narrow, and a plane whose surface is elsewhere
    # cut a one-pixel line through a far drawer, which was then lost (measured).
    cosang = np.abs(N @ N.T)
    crossing = ((cosang < math.cos(math.radians(crossing_angle_deg)))
                & ((cosang > math.cos(math.radians(30.0))) | (sup[None, :] >= sup[:, None])))
    # a plane with under _CROSSING_MIN_SHARE of the other's support takes no pixels from it
    # (a spurious small plane of a few dozen samples tilted ~12 deg through a cabinet's face
    # cut a FREE line through a closed drawer at 2.2 m, which the greedy moves then did not
    # cross; issue 12, branch pband2)
    crossing &= sup[None, :] >= _CROSSING_MIN_SHARE * sup[:, None]
    # an offset layer and its parent plane: each keeps the pixels nearer to it, whatever
    # their angle and supports (a drawer pulled out 16 mm is parallel to the cabinet's face,
    # within L of it, and has a twentieth of its support)
    layer = np.zeros((P, P), bool)
    for j, pl in enumerate(planes):
        if 0 <= pl.parent < P:
            layer[pl.parent, j] = layer[j, pl.parent] = True
    crossing |= layer
    if not crossing.any():
        return
    # Which plane is nearer is decided on the two planes' signed distances, each summed over
    # the smooth_px x smooth_px pixels around that are within L of both (the noise of one
    # pixel would otherwise fray the edge along the crossing): the plane whose mean is nearer
    # zero keeps the pixel. Near the crossing line the surface seen beside it lies on one
    # plane on either side and off the other by x sin(angle), so the window means keep the
    # order of the centre pixel's true distances. (Averaging each plane's distance over every
    # measured pixel around, as before, mixed in the pixels of a 5 mm reveal and of the other
    # surface: at 2.3 m the door's hinge side lost ~1 cm to the cabinet's face, measured.)
    H, W = valid.shape
    ys, xs = np.divmod(shared, W)
    r = smooth_px // 2
    take = np.zeros(near_sh.shape, bool)  # [k, i]: shared pixel i is nearer another plane
    take_layer = np.zeros(near_sh.shape, bool) if layer.any() else None
    for k in range(P):
        for j in range(k + 1, P):
            if not (crossing[k, j] or crossing[j, k]):
                continue
            both = np.flatnonzero(near_sh[k] & near_sh[j])
            if len(both) == 0:
                continue
            by, bx = ys[both], xs[both]
            # the pair's pixels' bounding box with the window's margin
            y0, y1 = max(0, int(by.min()) - r), min(H, int(by.max()) + r + 1)
            x0, x1 = max(0, int(bx.min()) - r), min(W, int(bx.max()) + r + 1)
            by, bx = by - y0, bx - x0
            w = np.zeros((y1 - y0, x1 - x0), np.float32)
            w[by, bx] = 1.0
            ak = np.abs(cv2.boxFilter(S[k][y0:y1, x0:x1] * w, -1, (smooth_px, smooth_px),
                                      normalize=False)[by, bx])
            aj = np.abs(cv2.boxFilter(S[j][y0:y1, x0:x1] * w, -1, (smooth_px, smooth_px),
                                      normalize=False)[by, bx])
            if layer[k, j]:  # (a layer pair: both directions, sign-dependent labels)
                # (only in the layer's region: outside it the layer has no in-plane pixels)
                take_layer[k, both] |= aj < ak
                take_layer[j, both] |= ak < aj
                continue
            if crossing[k, j]:
                take[k, both] |= aj < ak
            if crossing[j, k]:
                take[j, both] |= ak < aj
    for k in range(P):
        if take[k].any():
            flat = labs[k].reshape(-1)
            flat[shared[take[k]]] = FREE                # in-plane -> FREE
        if take_layer is not None and take_layer[k].any():
            # the other layer keeps them: in front of plane k (s > 0) they hide it
            # (OCCLUDED), behind it the camera sees through it (FREE)
            px = shared[take_layer[k] & ~take[k]]
            flat = labs[k].reshape(-1)
            flat[px] = np.where(S[k].reshape(-1)[px] > 0, np.uint8(OCCLUDED), np.uint8(FREE))


def _refit_on_own_pixels(planes, labels, Pc, Lmap, min_change_deg, crossing_angle_deg,
                         rounds=3, max_points=40000, max_change_deg=5.0, min_support=100):
    """Planes that cross another plane at a shallow angle (between ``crossing_angle_deg`` and
    30 deg) refitted on their own pixels: those in-plane for them after the crossings
    (:func:`_crossings`), within L / 2 of them (as the second round of
    :func:`refine_plane_fullres`) and nearer to them than to any such crossing plane within L
    of the pixel; ``rounds`` times (the nearer plane is decided with the refitted planes;
    planes that are parallel within ``crossing_angle_deg``, e.g. the flush closed fronts of
    one cabinet, are left alone: their pixels lie within noise of both). None if
    no plane's normal turns by ``min_change_deg`` (deg) or more (and less than
    ``max_change_deg``); else the list with every such plane replaced. Planes of fewer than
    ``min_support`` RANSAC samples (a few rows of the sample grid) are left alone: their own
    pixels are too few for a refit that is not mostly noise (two such planes of 29-31 samples
    turned by 0.6-1.7 deg and lost a drawer at 2.3 m, measured).

    Why: RANSAC and :func:`refine_plane_fullres` count every pixel within L (then L / 2) of a
    plane. A door opened by a few degrees crosses the cabinet's face at that angle, so the
    face beside its hinge lies within L of the door's plane over L / sin(angle) (7 cm at
    8 deg) and tilts the fitted plane towards it (by 2.1 deg at 8 deg, seen from 0.8 m,
    measured on a noise-free render); the door's own surface by the hinge then lies 8 mm off
    its plane, nearer the face's plane, and the crossing gave a 5 cm strip of the door to the
    face (the door's hinge side 46-53 mm short at 5-8 deg). Refitted on the pixels nearer to
    it, the plane is the door's own; the labels are then made again.
    """
    if len(planes) < 2:
        return None
    N0 = np.array([pl.n for pl in planes])
    cosang = np.abs(N0 @ N0.T)
    partners = ((cosang < math.cos(math.radians(crossing_angle_deg)))
                & (cosang > math.cos(math.radians(30.0))))
    if not partners.any():  # (before the pixels are gathered: nothing to refit)
        return None
    H, W = labels[0].shape
    step = max(1, int(math.ceil(math.sqrt(H * W / max_points))))
    P = Pc[::step, ::step].reshape(-1, 3).astype(np.float64)
    L = Lmap[::step, ::step].reshape(-1).astype(np.float64)
    own0 = np.array([lab[::step, ::step].reshape(-1) == IN_PLANE for lab in labels])
    ok = np.isfinite(P[:, 2]) & own0.any(axis=0)
    # (np.compress: the same rows as boolean indexing, ~5x faster on 2-D arrays)
    P, L, own0 = (np.compress(ok, P, axis=0), np.compress(ok, L),
                  np.compress(ok, own0, axis=1))
    cur = list(planes)
    cos10 = math.cos(math.radians(10.0))
    # the distances are needed to the refitted planes and their partners only: those rows of
    # the (planes, pixels) distances (the same products; rows of pixels run fast)
    refit = [k for k, pl in enumerate(planes) if partners[k].any() and pl.support >= min_support]
    rows = sorted(set(refit) | set(np.flatnonzero(partners[refit].any(axis=0)).tolist()))
    row_of = {k: i for i, k in enumerate(rows)}
    if not refit:
        return None
    halfL = 0.5 * L
    for _ in range(rounds):
        N = np.array([pl.n for pl in cur])
        D = np.array([pl.d for pl in cur])
        A = (P @ N.T).T[rows]                        # (planes, pixels) distances, m
        A += D[rows, None]
        np.abs(A, out=A)
        Ain = np.where(A <= L, A, np.inf)
        nxt = list(cur)
        for k in refit:
            near = Ain[[row_of[j] for j in np.flatnonzero(partners[k])]].min(axis=0)
            ak = A[row_of[k]]
            sel = own0[k] & (ak <= halfL) & (ak <= near)
            if sel.sum() < 10:
                continue
            n, d = _fit_plane_many(np.compress(sel, P, axis=0))
            if n @ planes[k].n < cos10:
                continue
            pl = cur[k]
            nxt[k] = Plane(n=n, d=d, support=pl.support, bbox=pl.bbox)
        cur = nxt
    # a turn beyond max_change_deg is no correction of a tilt but a different surface (a
    # small plane of a few rows whose own pixels fit another plane): kept as it was
    cmin, cmax = (math.cos(math.radians(a)) for a in (min_change_deg, max_change_deg))
    keep = [b if cmax <= float(a.n @ b.n) < cmin else a for a, b in zip(planes, cur)]
    return None if all(a is b for a, b in zip(planes, keep)) else keep


_SQUARE5 = np.ones((5, 5), np.uint8)
_LAYER_MAX_RING = 0.35


def _offset_layers(planes, labels, S, Pc, Lmap, Lband, K, cfg, st, off):
    """Planes for the *offset layers* of the ``cfg.layer_planes`` largest planes: connected
    regions of a plane's region that lie a few mm to a few cm in front of it, parallel to it.
    Returns the new planes (``parent`` = the plane they were split from; none when nothing
    qualifies).

    Why: a drawer pulled out by its first 5-40 mm stands that far proud of its cabinet's
    face, within L (2 cm; the removal band: 3.3 cm at 1.8 m, 4.1 cm at 2.3 m) of the face's
    plane. RANSAC counted its points to the face and took them out of the pool, so it got no
    plane of its own; on the face's plane the surface check (window means beyond the
    surface distance) or Eq. 5.2 (beyond L) labelled it OFF_SURFACE / OCCLUDED, and the
    drawer was missed in its first 2-4 opening frames at every distance (issue 12; seeds
    6000-6009: 0.005 / 0.016 / 0.027 m missed in all runs at 1.8 m). Here those pixels (in
    front of the plane within the removal band ``Lband``, OFF_SURFACE or OCCLUDED) form
    candidate regions on the plane's region; a region spanning at least ``layer_min_size`` in
    both directions (a panel's edge face seen obliquely is a strip), of at least
    ``layer_min_pixels`` pixels, whose plane (started parallel to the parent, refitted three
    times on the pixels within L / 2 of it, at least 40 % of them) stays within 10 deg of
    the parent's normal, whose centroid lies in front of the parent by more than the surface
    distance, that is no other plane's front already and is a step rather than a ramp,
    becomes a plane. The pair then shares its pixels by the nearer-plane rule
    (:func:`_crossings`), so the face does not reach into the drawer's rectangle nor the
    drawer into the face's."""
    new: list[Plane] = []
    if cfg.layer_planes <= 0 or cfg.layer_max_layers <= 0 or not planes:
        return new
    H, W = labels[0].shape
    cos10, cos1 = math.cos(math.radians(10.0)), math.cos(math.radians(1.0))
    order = sorted(range(len(planes)), key=lambda i: -planes[i].support)
    for k in order[:int(cfg.layer_planes)]:
        pl = planes[k]
        if pl.parent >= 0:
            continue
        r0, r1, c0, c1 = pl.bbox
        R0, R1 = max(0, off + st * r0 - st), min(H, off + st * r1 + st)
        C0, C1 = max(0, off + st * c0 - st), min(W, off + st * c1 + st)
        if R1 - R0 < 3 or C1 - C0 < 3:
            continue
        lab = labels[k][R0:R1, C0:C1]
        # only in front of the plane (s > 0, towards the camera): a front pulled out of its
        # carcass stands proud of the face. (Behind it were a cabinet's bottom rail 1-2 cm
        # behind its door and the far part of a plane fitted across both: the layer split
        # the door, and the robot took its handle 7 cm off; operate_trials left_door seed 3.)
        Sk = S[k][R0:R1, C0:C1]
        cand = cv2.compare(Sk, Lband[R0:R1, C0:C1], cv2.CMP_LE)
        cand &= cv2.compare(Sk, 0.0, cv2.CMP_GT)
        off_or_occ = cv2.compare(lab, OCCLUDED, cv2.CMP_EQ)
        off_or_occ |= cv2.compare(lab, OFF_SURFACE, cv2.CMP_EQ)
        cand &= off_or_occ
        if cv2.countNonZero(cand) < cfg.layer_min_pixels:
            continue
        # opened by a square of 2/3 layer_min_size at the region's median depth (of the
        # crop's sampled pixels: a plane's own depth on a ray can be anything for a plane
        # seen edge-on): thin strips joined the drawer to its neighbours (the countertop's
        # edge, 3 cm tall and 2 cm proud of the fronts like the drawer, above it; the
        # drawer's top face seen from above), and their least-squares plane was tilted 4-6 deg
        zs = Pc[R0 + off:R1:st, C0 + off:C1:st, 2].reshape(-1)
        zs = zs[np.isfinite(zs)]
        if len(zs) == 0:
            continue
        zc = max(float(np.median(zs)), 0.1)
        # (an odd side: OpenCV dilates with the kernel unreflected, so an even square's
        # opening is shifted by a pixel and not a subset)
        ko = min(max(1, int(round(1.0 / 3.0 * cfg.layer_min_size * K.fx / zc))), 50) * 2 + 1
        # closed first (5 x 5): the pixels whose noise carries them out of the band are
        # single holes, and one hole in the opening's square takes its centre away
        cand = cv2.morphologyEx(cand, cv2.MORPH_CLOSE, _SQUARE5)
        # (but not across a reveal or a pixel without a measurement)
        cand &= cv2.compare(lab, UNKNOWN, cv2.CMP_NE)
        cand &= cv2.compare(lab, GAP, cv2.CMP_NE)
        cand = cv2.morphologyEx(cand, cv2.MORPH_OPEN, np.ones((ko, ko), np.uint8))
        if cv2.countNonZero(cand) < cfg.layer_min_pixels:
            continue
        # (the components on the candidates' bounding box only)
        bx, by, bw, bh = cv2.boundingRect(cand)
        R0, C0 = R0 + by, C0 + bx
        cand = cand[by:by + bh, bx:bx + bw]
        ncomp, cl, stats, _ = cv2.connectedComponentsWithStats(cand, connectivity=8)
        big = [i for i in range(1, ncomp) if stats[i, cv2.CC_STAT_AREA] >= cfg.layer_min_pixels]
        big.sort(key=lambda i: -stats[i, cv2.CC_STAT_AREA])
        for i in big:
            x, y, w, h = (int(v) for v in stats[i, :4])
            sub = cl[y:y + h, x:x + w] == i
            P = Pc[R0 + y:R0 + y + h, C0 + x:C0 + x + w][sub].astype(np.float64)
            Lp = Lmap[R0 + y:R0 + y + h, C0 + x:C0 + x + w][sub].astype(np.float64)
            if len(P) < 3:
                continue
            z = float(np.median(P[:, 2]))
            if min(w * z / K.fx, h * z / K.fy) < cfg.layer_min_size:
                continue
            # the layer starts parallel to the parent at the region's median offset (robust
            # to the other surfaces in the region: the top faces of the drawer and the
            # countertop seen from above tilted a plain least-squares fit by 4-7 deg), then
            # three least-squares rounds on the pixels within L / 2 (a door turned by a few
            # degrees tilts it: 5.2 deg at 2.3 m came out 3.2 deg after two rounds)
            n, d = pl.n, pl.d - float(np.median(P @ pl.n + pl.d))
            ok = True
            for _ in range(3):
                sel = np.abs(P @ n + d) <= 0.5 * Lp
                if np.count_nonzero(sel) < 0.4 * len(P):
                    ok = False
                    break
                n, d = _fit_plane_many(np.compress(sel, P, axis=0))
                if n @ pl.n < cos10:
                    ok = False
                    break
            if not ok:
                continue
            Psel = np.compress(sel, P, axis=0)
            cen = np.ones(len(Psel)) @ Psel / len(Psel)
            thr = max(cfg.surface_distance, cfg.surface_distance_per_m2 * z * z)
            if cen @ pl.n + pl.d < thr:
                continue
            # a front that has a plane already (most of the region's pixels in-plane for
            # another plane after the surface check, e.g. a door RANSAC found): nothing new.
            # (A plane RANSAC drew from the remnant of a front that the removal band thinned
            # out is tilted by a few degrees and leaves the front OFF_SURFACE: the layer is
            # kept beside it; the drawer pulled out 4 cm at 2.2 m.)
            win = (slice(R0 + y, R0 + y + h), slice(C0 + x, C0 + x + w))
            if any(q != k and 2 * np.count_nonzero(labels[q][win][sub] == IN_PLANE) >= len(P)
                   for q in range(len(planes))):
                continue
            if any(abs(q.n @ n) > cos1 and abs(q.n @ cen + q.d) < thr for q in new):
                continue
            rows = (np.array([R0 + y, R0 + y + h - 1]) - off) / st
            cols = (np.array([C0 + x, C0 + x + w - 1]) - off) / st
            # the layer's region (its only in-plane pixels): its box grown by half its size
            # on every side (room for the sides the opening trimmed, a door's hinge side
            # nearer the face than the threshold, and the recall's margin)
            gy, gx = (h + 1) // 2, (w + 1) // 2
            region = (max(0, R0 + y - gy), min(H, R0 + y + h + gy),
                      max(0, C0 + x - gx), min(W, C0 + x + w + gx))
            # a step, not a ramp: the parent's own pixels around the region lie off the
            # layer's plane (at most _LAYER_MAX_RING of them within the surface distance;
            # measured on development frames: 0-0.25 for drawers pulled out 1.6-4 cm and
            # doors turned 5 deg, whose hinge side meets the face; 0.45-0.95 for ramps and
            # for a door turned 85 deg against its compartment's wall). Where the parent is a
            # plane fitted across a door and the rail 1-2 cm behind it, the door's lower part
            # lies 5-13 mm in front of it and fits a "layer" that is the door's own plane,
            # which the door's upper part, in-plane for the parent, continues: the pair then
            # split the door in two.
            r0_, r1_, c0_, c1_ = region
            ring = labels[k][r0_:r1_, c0_:c1_] == IN_PLANE
            ring[R0 + y - r0_:R0 + y + h - r0_, C0 + x - c0_:C0 + x + w - c0_] &= ~sub
            Q = Pc[r0_:r1_, c0_:c1_][ring]
            if len(Q) and np.count_nonzero(np.abs(Q @ n + d) <= thr) > _LAYER_MAX_RING * len(Q):
                continue
            new.append(Plane(n=n, d=d, support=max(1, len(Psel) // (st * st)),
                             bbox=(max(0, int(math.floor(rows[0]))), int(math.ceil(rows[1])) + 1,
                                   max(0, int(math.floor(cols[0]))), int(math.ceil(cols[1])) + 1),
                             parent=k, region=region))
            if len(new) >= cfg.layer_max_layers:
                return new
    return new


def _make_grid(k, plane: Plane, lab_img, sample_pts, K, down_C, cfg, lut) -> _Grid | None:
    n, d = plane.n, plane.d
    Lp = np.maximum(cfg.inlier_distance, cfg.inlier_distance_per_m2 * sample_pts[:, 2] ** 2)
    inl = np.compress(np.abs(sample_pts @ n + d) <= Lp, sample_pts, axis=0)  # (5x P[mask])
    if len(inl) < 3:
        return None
    o = inl.mean(axis=0)
    o = o - (o @ n + d) * n
    e1, e2 = _plane_axes(n, down_C)
    rel = inl - o  # (the same for both extents)

    def extent(e1, e2):
        a = rel @ e1
        b = rel @ e2
        pad = 0.1
        half = 0.5 * cfg.max_plane_extent
        am, bm = np.median(a), np.median(b)
        lo_a, hi_a = max(a.min(), am - half) - pad, min(a.max(), am + half) + pad
        lo_b, hi_b = max(b.min(), bm - half) - pad, min(b.max(), bm + half) + pad
        return lo_a, hi_a, lo_b, hi_b

    def shape_of(lo_a, hi_a, lo_b, hi_b, c):
        return (max(1, int(math.ceil((hi_b - lo_b) / c))),
                max(1, int(math.ceil((hi_a - lo_a) / c))))

    # dominant edge direction on a grid of twice the cell size (a quarter of the cells)
    lo_a, hi_a, lo_b, hi_b = extent(e1, e2)
    c = max(cfg.cell_size, max(hi_a - lo_a, hi_b - lo_b) / cfg.max_grid_cells)
    coarse = _warp_labels(lab_img, K, o, e1, e2, lo_a, lo_b, 2 * c,
                          shape_of(lo_a, hi_a, lo_b, hi_b, 2 * c))
    theta = _edge_angle(coarse == IN_PLANE)
    if theta != 0.0:
        e1, e2 = _rotate_axes(e1, e2, theta)
        lo_a, hi_a, lo_b, hi_b = extent(e1, e2)
        c = max(cfg.cell_size, max(hi_a - lo_a, hi_b - lo_b) / cfg.max_grid_cells)
    lab0 = _warp_labels(lab_img, K, o, e1, e2, lo_a, lo_b, c, shape_of(lo_a, hi_a, lo_b, hi_b, c))
    sat_cost, sat_in = _sats(lab0, lut)
    return _Grid(k, n, d, o, e1, e2, lo_a, lo_b, c, lab0, sat_cost, sat_in)


# ------------------------------------------------------------------------------------------
# stages 3-4: sampling and greedy optimisation, vectorised over starts
# ------------------------------------------------------------------------------------------
# side moves on (x0, x1, y0, y1): grow left, shrink left, grow right, shrink right, same for y
_MOVES = np.array([[-1, 0, 0, 0], [1, 0, 0, 0], [0, 1, 0, 0], [0, -1, 0, 0],
                   [0, 0, -1, 0], [0, 0, 1, 0], [0, 0, 0, 1], [0, 0, 0, -1]], np.int64)
# the greedy's state per start (:func:`_greedy_flat`): x0 x1 y0 y1, the linear indices of the
# corners (y1, x1) (y0, x0) (y0, x1) (y1, x0) in the flat tables, the slacks x0, W - x1, y0,
# H - y1, w - min_cells, h - min_cells (all >= 0: a legal rectangle), w, h
_ST_CORNERS, _ST_SLACK, _ST_W, _ST_H = slice(4, 8), slice(8, 14), 14, 15
# the slack (state column) that limits each move of _MOVES: a move of s cells is legal on a
# legal rectangle iff that slack is >= s (growing left needs x0 >= s, shrinking it w - mc >= s,
# ...; every other constraint is kept by the move)
_MOVE_SLACK = np.array([8, 12, 9, 12, 10, 13, 11, 13], np.int64)


def _rect_sum(S, p, R):
    """Sums of the tables ``S[p]`` (stacked SATs) over rectangles R (..., 4) = x0 x1 y0 y1."""
    x0, x1, y0, y1 = R[..., 0], R[..., 1], R[..., 2], R[..., 3]
    _, H, W = S.shape
    flat = S.reshape(-1)  # one gather per corner on linear indices (same sums, faster)
    base = np.asarray(p) * (H * W)
    r0, r1 = base + y0 * W, base + y1 * W
    return (flat.take(r1 + x1) - flat.take(r0 + x1)) - (flat.take(r1 + x0) - flat.take(r0 + x0))


def _objective(SC, p, R, alpha):
    """g = sum(1 - cost) / n^(1 - alpha) over the rectangle's cells."""
    n = ((R[..., 1] - R[..., 0]) * (R[..., 3] - R[..., 2])).astype(np.float64)
    n = np.maximum(n, 1.0)
    return (n - _rect_sum(SC, p, R) * (1.0 / 255.0)) / n ** (1.0 - alpha)


def _greedy_flat(flat, base, stride, hw, R, steps, min_cells, alpha, max_iter):
    """Greedy side moves (steepest ascent of :func:`_objective`) for all starts at once, each
    on its own summed-area table of costs in one flat int32 buffer ``flat``: table of start i
    at ``base[i]`` with rows of ``stride[i]`` entries (the grid's width + 1); ``hw`` (S, 2) the
    grids' (H, W); R (S, 4) int rectangles x0 x1 y0 y1; steps (S, k) move sizes in cells;
    min_cells (S,). Each start moves each side by +-steps; the best legal move (inside the
    grid, both sides >= min_cells; the first of equal ones in the order steps x _MOVES) is
    taken while it improves the objective by more than 1e-12 (relative and absolute), at most
    ``max_iter`` times. Returns R (S, 4), objective (S,), iterations used.

    Per iteration and start the candidates' sums are one gather of their four corners (the
    corners' linear indices and the slacks of the legality tests are kept in the state and
    moved with it); starts stop independently and are dropped from the arrays when they do
    (the same moves, sums and objectives as move by move on the tables)."""
    R = np.asarray(R, np.int64)
    S = len(R)
    x0, x1, y0, y1 = R.T
    w, h = x1 - x0, y1 - y0
    base = np.asarray(base, np.int64)
    stride = np.asarray(stride, np.int64)
    hw = np.asarray(hw, np.int64)
    mc = np.asarray(min_cells, np.int64)
    st = np.column_stack([x0, x1, y0, y1,
                          base + y1 * stride + x1, base + y0 * stride + x0,
                          base + y0 * stride + x1, base + y1 * stride + x0,
                          x0, hw[:, 1] - x1, y0, hw[:, 0] - y1, w - mc, h - mc, w, h])
    # the initial objective (as :func:`_objective`; sizes < 1 count as 1)
    n = np.maximum((w * h).astype(np.float64), 1.0)
    v = flat.take(st[:, _ST_CORNERS])
    score = (n - ((v[:, 0] + v[:, 1]) - (v[:, 2] + v[:, 3])) * (1.0 / 255.0)) / n ** (1.0 - alpha)
    out_R, out_score = R.copy(), score.copy()
    if S == 0 or int(max_iter) < 1:
        return out_R, out_score, 0
    # per start and move m = step x 8 + move: the change of the state
    steps = np.asarray(steps, np.int64)
    M = 8 * steps.shape[1]
    dR = (steps[:, :, None, None] * _MOVES[None, None]).reshape(S, M, 4)
    dx0, dx1, dy0, dy1 = dR[..., 0], dR[..., 1], dR[..., 2], dR[..., 3]
    sr = stride[:, None]
    dw, dh = dx1 - dx0, dy1 - dy0
    DS = np.stack([dx0, dx1, dy0, dy1, dx1 + dy1 * sr, dx0 + dy0 * sr, dx1 + dy0 * sr,
                   dx0 + dy1 * sr, dx0, -dx1, dy0, -dy1, dw, dh, dw, dh], axis=-1)
    DC = np.ascontiguousarray(DS[..., _ST_CORNERS].transpose(0, 2, 1))  # (S, 4, M)
    need = np.abs(dR).sum(axis=-1)  # the move's size in cells
    kslack = np.tile(_MOVE_SLACK, steps.shape[1])
    e = 1.0 - alpha
    ids = np.arange(S)
    rows = ids
    thr = score + 1e-12 * np.abs(score) + 1e-12
    # a start that is not a legal rectangle (a grid narrower than min_cells) may move only to a
    # legal one (all slacks >= 0 after the move): tested in full in the first iteration
    full_test = not bool((st[:, _ST_SLACK] >= 0).all())
    it = 0
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        for it in range(1, int(max_iter) + 1):
            if len(ids) == 0:
                break
            # sums of the candidates (illegal ones' indices may leave the table: clipped,
            # their objective is discarded)
            v = flat.take(st[:, _ST_CORNERS, None] + DC, mode="clip")
            # (integer sizes multiplied as float64: exact, the same n)
            n = np.multiply(st[:, _ST_W, None] + dw, st[:, _ST_H, None] + dh, dtype=np.float64)
            sc = (n - ((v[:, 0] + v[:, 1]) - (v[:, 2] + v[:, 3])) * (1.0 / 255.0)) / n ** e
            if full_test:
                sc[((st[:, None, _ST_SLACK] + DS[..., _ST_SLACK]) < 0).any(axis=-1)] = -np.inf
                full_test = False
            else:
                sc[st[:, kslack] < need] = -np.inf  # illegal moves
            b = sc.argmax(axis=1)
            best = sc[rows, b]
            imp = best > thr
            if imp.all():
                st += DS[rows, b]
                score = best
            else:
                keep = np.flatnonzero(imp)
                stop = np.flatnonzero(~imp)
                out_R[ids[stop]] = st[stop, :4]
                out_score[ids[stop]] = score[stop]
                st = st[keep] + DS[keep, b[keep]]
                score = best[keep]
                ids, DS, DC, dw, dh, need = (ids[keep], DS[keep], DC[keep], dw[keep], dh[keep],
                                             need[keep])
                rows = np.arange(len(ids))
            thr = score + 1e-12 * np.abs(score) + 1e-12
    out_R[ids] = st[:, :4]
    out_score[ids] = score
    return out_R, out_score, it


def _greedy(SC, dims, pid, R, steps, min_cells, alpha, max_iter):
    """Greedy side moves for all starts at once. SC: stacked cost SATs (P, Hm+1, Wm+1);
    dims (P, 2) grid shapes; pid (S,) plane of each start; R (S, 4) int rectangles; steps (S, k)
    move sizes in cells; min_cells (S,). Returns R, objective, iterations used
    (:func:`_greedy_flat` on the stack's flat buffer)."""
    _, Hs, Ws = SC.shape
    pid = np.asarray(pid, np.int64)
    R, score, it = _greedy_flat(SC.reshape(-1), pid * (Hs * Ws), np.full(len(pid), Ws, np.int64),
                                np.asarray(dims, np.int64)[pid], R, steps, min_cells, alpha,
                                max_iter)
    return R, score, it


def _in_plane_cells(g: _Grid, r: np.ndarray) -> np.ndarray:
    """Flat indices of the ``r``-th in-plane cells of a grid in raster order (as
    ``np.flatnonzero(g.labels == IN_PLANE)[r]``): the row of each from the in-plane table's
    cumulative row totals, then a scan of that row only (not of the whole grid)."""
    rows = g.sat_in[1:, -1]  # in-plane cells in rows 0..i
    i = np.searchsorted(rows, r, side="right")
    out = np.empty(len(r), np.int64)
    for t in range(len(r)):
        before = int(rows[i[t] - 1]) if i[t] > 0 else 0
        cols = np.flatnonzero(g.labels[i[t]] == IN_PLANE)
        out[t] = int(i[t]) * g.shape[1] + int(cols[int(r[t]) - before])
    return out


_START_ERODE_CELLS = 3


def _component_starts(g: _Grid, mc: int, k: int, rng, cfg) -> np.ndarray:
    """Start rectangles (n, 4) at the centroid (if inside it) of each of the ``k`` largest
    4-connected regions of in-plane cells of a grid (at least ``mc`` x ``mc`` cells): fronts
    flush with their neighbours are one plane, parted only by ``GAP`` lines, and random
    starts over the whole plane miss a small drawer (5 % of a cabinet's face) often.
    Width and height from the prior, at most the region's bounding box."""
    # regions of the in-plane cells shrunk by _START_ERODE_CELLS (3) cells: a reveal's line
    # may have a hole of a few cells (where it meets another reveal, or a drop-out; a
    # horizontal reveal's run ends ~half a line window short of a T-junction with a vertical
    # one: 5 cells of 7.4 mm at 2.2 m, which joined a closed drawer's region to the door
    # below; 2 cells before, issue 12 branch pband2)
    r = _START_ERODE_CELLS
    inp = cv2.erode((g.labels == IN_PLANE).view(np.uint8),
                    np.ones((2 * r + 1, 2 * r + 1), np.uint8))
    n_lab, lab, stats, cent = cv2.connectedComponentsWithStats(inp, connectivity=4)
    if n_lab <= 1:
        return np.zeros((0, 4), np.int64)
    area = stats[1:, cv2.CC_STAT_AREA]
    mc = max(1, mc - 2 * r)
    big = np.flatnonzero((area >= mc * mc) & (stats[1:, cv2.CC_STAT_WIDTH] >= mc)
                         & (stats[1:, cv2.CC_STAT_HEIGHT] >= mc)) + 1
    if len(big) == 0:
        return np.zeros((0, 4), np.int64)
    big = big[np.argsort(-area[big - 1], kind="stable")][:k]
    # the region's centroid (inside a rectangular front), else a random cell of it
    cj = np.round(cent[big, 0]).astype(np.int64)
    ci = np.round(cent[big, 1]).astype(np.int64)
    for t in np.flatnonzero(lab[ci, cj] != big):
        cells = np.flatnonzero(lab.reshape(-1) == big[t])
        ci[t], cj[t] = divmod(int(cells[rng.integers(0, len(cells))]), lab.shape[1])
    m = len(big)
    wh = rng.uniform(cfg.prior_size[0], cfg.prior_size[1], (m, 2)) / g.c
    mc += 2 * r
    wc = np.clip(np.round(wh[:, 0]).astype(np.int64), mc,
                 np.maximum(mc, stats[big, cv2.CC_STAT_WIDTH]))
    hc = np.clip(np.round(wh[:, 1]).astype(np.int64), mc,
                 np.maximum(mc, stats[big, cv2.CC_STAT_HEIGHT]))
    Hg, Wg = g.shape
    x0 = np.clip(cj - wc // 2, 0, np.maximum(0, Wg - wc))
    y0 = np.clip(ci - hc // 2, 0, np.maximum(0, Hg - hc))
    return np.column_stack([x0, np.minimum(x0 + wc, Wg), y0, np.minimum(y0 + hc, Hg)])


def _stack(tables, dims):
    Hm = max(h for h, _ in dims) + 1
    Wm = max(w for _, w in dims) + 1
    out = np.zeros((len(tables), Hm, Wm), tables[0].dtype)
    for k, t in enumerate(tables):
        out[k, :t.shape[0], :t.shape[1]] = t
    return out


# ------------------------------------------------------------------------------------------
# stage 5: checks
# ------------------------------------------------------------------------------------------
def _gap_bounded(g, x0, x1, y0, y1, out_cells=3, in_cells=1, share=0.5, line=0.7):
    """(left, right, top, bottom): whether each side of the rectangle on grid ``g``
    (:class:`_Grid`) runs along a
    reveal: some grid line parallel to it, from ``in_cells`` inside to ``out_cells`` outside,
    is ``GAP`` on at least ``share`` of the side's length, or ``GAP`` on a fifth and ``GAP``
    or ``UNKNOWN`` on ``line`` of it (a reveal seen straight on has no return; the window of
    :func:`_gap_mask` does not label its last few cm before a step such as a countertop's
    edge)."""
    Hg, Wg = g.shape
    G, U = g.gap_sats()
    x0, x1, y0, y1 = int(x0), int(x1), int(y0), int(y1)
    res = []
    for lo, hi, vertical in ((x0 - out_cells, x0 + in_cells, True),
                             (x1 - in_cells, x1 + out_cells, True),
                             (y0 - out_cells, y0 + in_cells, False),
                             (y1 - in_cells, y1 + out_cells, False)):
        if vertical:
            lo, hi = max(0, lo), min(Wg, hi)
            a0, a1, length = y0, y1, y1 - y0
        else:
            lo, hi = max(0, lo), min(Hg, hi)
            a0, a1, length = x0, x1, x1 - x0
        if hi <= lo or length <= 0:
            res.append(False)
            continue
        # no GAP cell in the whole strip: not a reveal (one look-up for most sides)
        if vertical:
            tot = int(G[a1, hi] - G[a0, hi] - G[a1, lo] + G[a0, lo])
        else:
            tot = int(G[hi, a1] - G[lo, a1] - G[hi, a0] + G[lo, a0])
        if tot < 0.2 * length:
            res.append(False)
            continue
        hit = False
        for c in range(lo, hi):  # each grid line of the strip
            if vertical:
                g = int(G[a1, c + 1] - G[a0, c + 1] - G[a1, c] + G[a0, c])
                u = int(U[a1, c + 1] - U[a0, c + 1] - U[a1, c] + U[a0, c])
            else:
                g = int(G[c + 1, a1] - G[c, a1] - G[c + 1, a0] + G[c, a0])
                u = int(U[c + 1, a1] - U[c, a1] - U[c + 1, a0] + U[c, a0])
            if g >= share * length or (g >= 0.2 * length and g + u >= line * length):
                hit = True
                break
        res.append(hit)
    return res


def _sats_gap(labels):
    """Summed-area tables (int32) of the GAP and the UNKNOWN cells of a label grid."""
    return (cv2.integral((labels == GAP).view(np.uint8), sdepth=cv2.CV_32S),
            cv2.integral((labels == UNKNOWN).view(np.uint8), sdepth=cv2.CV_32S))


def _precision_recall(g: _Grid, R, cfg):
    """Eq. 5.4 and the local recall (see the module docstring) of one grid rectangle."""
    x0, x1, y0, y1 = (int(v) for v in R)
    n = (x1 - x0) * (y1 - y0)
    if n <= 0:
        return 0.0, 0.0
    S = g.sat_cost
    cost = (S[y1, x1] - S[y0, x1] - S[y1, x0] + S[y0, x0]) / 255.0
    precision = (n - cost) / n
    I = g.sat_in
    inside = I[y1, x1] - I[y0, x1] - I[y1, x0] + I[y0, x0]
    mx = max(int(round(cfg.recall_margin * (x1 - x0))), int(round(cfg.min_recall_margin / g.c)))
    my = max(int(round(cfg.recall_margin * (y1 - y0))), int(round(cfg.min_recall_margin / g.c)))
    Hg, Wg = g.shape
    # a side along a reveal (GAP) is observed to end there: no margin beyond it (the plane
    # continues in the flush neighbouring front)
    ml, mr, mt, mb = (0 if b else m for b, m in zip(
        _gap_bounded(g, x0, x1, y0, y1), (mx, mx, my, my)))
    X0, X1 = max(0, x0 - ml), min(Wg, x1 + mr)
    Y0, Y1 = max(0, y0 - mt), min(Hg, y1 + mb)
    around = I[Y1, X1] - I[Y0, X1] - I[Y1, X0] + I[Y0, X0]
    recall = inside / around if around > 0 else 0.0
    return float(precision), float(recall)


def _rect_camera(g: _Grid, R, e1=None, e2=None, u0=None, v0=None, c=None):
    """Centre (camera frame), axes and size of a grid rectangle."""
    e1 = g.e1 if e1 is None else e1
    e2 = g.e2 if e2 is None else e2
    u0 = g.u0 if u0 is None else u0
    v0 = g.v0 if v0 is None else v0
    c = g.c if c is None else c
    x0, x1, y0, y1 = (float(v) for v in R)
    a = u0 + 0.5 * (x0 + x1) * c
    b = v0 + 0.5 * (y0 + y1) * c
    return g.o + a * e1 + b * e2, e1, e2, (x1 - x0) * c, (y1 - y0) * c


def _corners_px(center, e1, e2, w, h, K):
    # the four corners center + sx w / 2 e1 + sy h / 2 e2 at once (the same products and
    # sums, in the same order, as corner by corner)
    a = np.array([sx * 0.5 * w for sx in (-1, 1, 1, -1)])[:, None]
    b = np.array([sy * 0.5 * h for sy in (-1, -1, 1, 1)])[:, None]
    corners = (center + a * e1) + b * e2
    z = corners[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        u = K.fx * corners[:, 0] / z + K.cx
        v = K.fy * corners[:, 1] / z + K.cy
    return u, v, z


def _inside_border(center, e1, e2, w, h, K, margin):
    """Whether the four corners (as :func:`_corners_px`) are in front of the camera and at
    least ``margin`` px inside the image: the same float operations on Python floats (a few
    us instead of ~20 us of small-array calls; ~50 calls per frame)."""
    c, a1, a2 = center.tolist(), e1.tolist(), e2.tolist()
    inside = True
    for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
        a, b = sx * 0.5 * w, sy * 0.5 * h
        x, y, z = ((c[i] + a * a1[i]) + b * a2[i] for i in range(3))
        if not z > 0:
            return False
        u = K.fx * x / z + K.cx
        v = K.fy * y / z + K.cy
        inside &= (margin <= u <= K.width - 1 - margin) and (margin <= v <= K.height - 1 - margin)
    return bool(inside)


def _polish_rotations(jobs, K, cfg, lut):
    """Rotate each rectangle in its plane about its centre by +-step_factors x
    rotation_step_deg; each rotation is followed by the side moves on the mask rectified at the
    new angle (a local window around the rectangle). The best improving rotation of a round is
    kept until none improves. ``jobs``: (grid, R, image label mask) per rectangle. Returns per
    job the objective and (e1, e2, u0, v0, R, labels, sat_cost, sat_in, c) of the window of the
    best angle.

    The rectangles are independent: the windows that all rectangles' current rounds need are
    rectified and moved in one batched greedy run (:func:`_greedy_flat`, each window on its own
    table: the same moves as rectangle by rectangle), round after round until every rectangle
    has stopped."""
    offsets = sorted({s * f * cfg.rotation_step_deg for f in cfg.rotation_step_factors
                      for s in (1, -1)})
    max_iter = int(cfg.max_iterations)
    states = []
    # the windows are rectified from each plane's cost image (its labels through the cost
    # table, made once per plane instead of once per window: the same cost cells); the label
    # window is made for each rectangle's best angle only
    cost_imgs = {}
    # the windows' cost tables of a round, in one buffer reused round after round (the
    # caches keep each window's result, not its table: ~25 MB of fresh pages per frame
    # otherwise)
    scratch = {}
    for g, R, lab_img in jobs:
        if id(lab_img) not in cost_imgs:
            cost_imgs[id(lab_img)] = cv2.LUT(lab_img, lut)
        c = g.c
        center, _, _, w, h = _rect_camera(g, R)
        steps_cells = sorted({max(1, int(round(f * cfg.step_size / c)))
                              for f in cfg.step_factors})  # (a list of ints)
        # window: the recall margin plus room for the largest side move
        half = (max(cfg.recall_margin * max(w, h), cfg.min_recall_margin)
                + 2 * max(cfg.step_factors) * cfg.step_size)
        x0 = int(round(half / c))
        # the start and the first round's rotations are fitted together (the round always
        # runs; each window's moves are independent of the others': the same results)
        first = [round(o, 9) for o in offsets] if max_iter > 0 else []
        states.append(dict(
            g=g, lab_img=lab_img, cost_img=cost_imgs[id(lab_img)], c=c, p=center - g.o, w=w, h=h, half=half,
            Wg=int(math.ceil((w + 2 * half) / c)), Hg=int(math.ceil((h + 2 * half) / c)),
            R0=np.array([x0, x0 + int(round(w / c)), x0, x0 + int(round(h / c))], np.int64),
            steps=steps_cells, min_cells=max(1, int(math.ceil(cfg.min_side / c))),
            cache={}, need=list(dict.fromkeys([0.0] + first)), theta=0.0, best=None,
            best_score=None, rounds=0, done=False, dir=0, streak=0))
    step_max = max(offsets) if offsets else 0.0
    while True:
        todo = []
        for j in states:
            if j["done"]:
                continue
            want = j["need"]
            if j["streak"] >= 2:
                # turning on in one direction (a front seen 10-20 deg rotated): the windows of
                # the next two rounds too, should it go on by the largest step (a cache filled
                # ahead: the same results, fewer rounds; at most 4 windows wasted per chain)
                want = list(want)
                t = j["theta"]
                for _ in range(2):
                    t = round(t + j["dir"] * step_max, 9)
                    want += [round(t + o, 9) for o in offsets]
            todo += [(j, t) for t in dict.fromkeys(want) if t not in j["cache"]]
        if todo:
            _fit_windows(todo, K, cfg, lut, scratch)
        live = False
        for j in states:
            cache = j["cache"]
            while not j["done"] and all(t in cache for t in j["need"]):
                if j["best"] is None:  # the start's window
                    j["best_score"], j["best"] = cache[0.0]
                    if max_iter == 0:
                        j["done"] = True
                        break
                else:  # a round
                    res = [cache[t] for t in j["need"]]
                    i = int(np.argmax([r[0] for r in res]))
                    j["rounds"] += 1
                    if res[i][0] > j["best_score"] + 1e-12 * abs(j["best_score"]):
                        turn = 1 if j["need"][i] > j["theta"] else -1
                        j["streak"] = j["streak"] + 1 if turn == j["dir"] else 1
                        j["dir"] = turn
                        j["best_score"], j["best"], j["theta"] = res[i][0], res[i][1], j["need"][i]
                        if j["rounds"] >= max_iter:
                            j["done"] = True
                            break
                    else:
                        j["done"] = True
                        break
                j["need"] = [round(j["theta"] + o, 9) for o in offsets]
            live |= not j["done"]
        if not live:
            break
    out = []
    for j in states:  # the best window's labels and tables, made again
        e1, e2, u0, v0, Rf = j["best"]
        g = j["g"]
        lab = _warp_labels(j["lab_img"], K, g.o, e1, e2, u0, v0, j["c"], (j["Hg"], j["Wg"]))
        out.append((j["best_score"], (e1, e2, u0, v0, Rf, lab) + _sats(lab, lut) + (j["c"],)))
    return out


def _fit_windows(todo, K, cfg, lut, scratch=None):
    """The windows (job state, angle in deg) of :func:`_polish_rotations`: each rectified,
    its cost table written into one flat buffer, all moved in one greedy run; results
    (objective, (e1, e2, u0, v0, R)) into the jobs' caches. ``scratch``: a dict whose
    ``"buf"`` (int32) is reused when large enough (and replaced by a larger one if not)."""
    dims = np.array([(j["Hg"], j["Wg"]) for j, _ in todo], np.int64)
    sizes = (dims[:, 0] + 1) * (dims[:, 1] + 1)
    base = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    total = int(sizes.sum())
    scratch = {} if scratch is None else scratch
    buf = scratch.get("buf")
    if buf is None or len(buf) < total:
        buf = scratch["buf"] = np.empty(total, np.int32)
    buf = buf[:total]
    wins = []
    for (j, t), b0, sz in zip(todo, base, sizes):
        g, c = j["g"], j["c"]
        e1, e2 = _rotate_axes(g.e1, g.e2, math.radians(t))
        u0 = j["p"] @ e1 - 0.5 * j["w"] - j["half"]
        v0 = j["p"] @ e2 - 0.5 * j["h"] - j["half"]
        Hg, Wg = j["Hg"], j["Wg"]
        cost = _warp_labels(j["cost_img"], K, g.o, e1, e2, u0, v0, c, (Hg, Wg),
                            outside=lut[OUTSIDE])
        # the window's cost table written straight into the buffer (no copy)
        cv2.integral(cost, buf[b0:b0 + sz].reshape(Hg + 1, Wg + 1), sdepth=cv2.CV_32S)
        wins.append((e1, e2, u0, v0))
    kmax = max(len(j["steps"]) for j, _ in todo)
    # each window's move sizes, padded with its last (np.pad's "edge"; on lists: ~10 us less
    # per window)
    steps = np.array([j["steps"] + j["steps"][-1:] * (kmax - len(j["steps"]))
                      for j, _ in todo], np.int64)
    Rf, sc, _ = _greedy_flat(buf, base, dims[:, 1] + 1, dims, np.array([j["R0"] for j, _ in todo]),
                             steps, np.array([j["min_cells"] for j, _ in todo], np.int64),
                             cfg.alpha, cfg.max_iterations)
    for i, (j, t) in enumerate(todo):
        j["cache"][t] = (float(sc[i]), wins[i] + (Rf[i],))


def _refit_plane(Pc, lab_img, center, e1, e2, w, h, K, n_old, L):
    """Least-squares plane through the measured in-plane pixels inside the rectangle (shrunk
    by 10 %), searched in the rectangle's image bounding box. None when too few."""
    u, v, _ = _corners_px(center, e1, e2, w, h, K)
    c0, c1 = int(max(0, np.floor(u.min()))), int(min(K.width, np.ceil(u.max()) + 1))
    r0, r1 = int(max(0, np.floor(v.min()))), int(min(K.height, np.ceil(v.max()) + 1))
    if c1 <= c0 or r1 <= r0:
        return None
    P = Pc[r0:r1, c0:c1].reshape(-1, 3)
    lab = lab_img[r0:r1, c0:c1].reshape(-1)
    P = np.compress(lab == IN_PLANE, P, axis=0)  # (rows: 5x P[mask])
    if len(P) < 10:
        return None
    # offsets to the centre as (3, k) rows (numpy's (k, 3) - (3,) broadcast and the 3 x 3
    # products of (k, 3) columns are 5-10x slower; the same plane to ~1e-16); the rows made
    # contiguous float64 first, then centred in place (the same values; subtracting from the
    # strided transpose was ~100 us slower at 90000 points)
    q = P.T.astype(np.float64, order="C")
    q -= center[:, None]
    sel = (np.abs(e1 @ q) <= 0.45 * w) & (np.abs(e2 @ q) <= 0.45 * h)
    k = int(np.count_nonzero(sel))
    if k < 10:
        return None
    # the scatter matrix of the selected points from their offsets to the centre (already at
    # hand, and small: no cancellation to speak of) minus k times their mean's outer product
    q = np.compress(sel, q, axis=1)
    mq = (q @ np.ones(k)) * (1.0 / k)
    n, d = _plane_from_scatter(center + mq, _scatter3(q) - k * np.outer(mq, mq))
    if n @ n_old < math.cos(math.radians(10.0)):
        return None
    return n, d


def _first_run(mask, k, start=1):
    """First index j >= ``start`` where ``mask[j:j + k]`` is all True (positions beyond the
    end count as True), else ``len(mask)``. ``mask``: a list of bools (short profiles: a
    Python scan is cheaper than the numpy calls it replaces)."""
    n = len(mask)
    run = 0  # consecutive Trues from j on (the end counts as an endless run)
    best = n
    for j in range(n - 1, start - 1, -1):
        if mask[j]:
            run += 1
            if run >= k or j + run >= n:
                best = j
        else:
            run = 0
    return best


def _edge_crossing(prof_in, prof_out, level, pos, step, persist=1):
    """Where a side ends along a profile of lines (positions ``pos``, inside first): the first
    line whose share of in-plane samples p = in / (in + out) falls below 1/2, or whose mean
    signed distance ``level`` (of its in-plane samples, m) lies more than ``step`` behind the
    level of the innermost quarter of lines, whichever comes first (linear interpolation
    between that line and the one before). Lines without enough measured samples take p from
    their neighbours. None when the profile does not start inside or never leaves."""
    n = prof_in + prof_out
    n_l = len(n)
    if n_l < 4:
        return None
    ok = n >= max(3.0, 0.2 * float(n.max()))
    okl = np.flatnonzero(ok)
    if len(okl) < 2:
        return None
    p = np.interp(np.arange(n_l), okl, prof_in[okl] / n[okl])
    if p[0] < 0.5:
        return None
    inner = sorted(x for x in level[: max(1, n_l // 4)].tolist() if math.isfinite(x))
    if len(inner) >= 2:
        h = len(inner) // 2  # median and (population) std of a few numbers, in Python
        ref = inner[h] if len(inner) % 2 else 0.5 * (inner[h - 1] + inner[h])
        mean = sum(inner) / len(inner)
        std = math.sqrt(sum((x - mean) ** 2 for x in inner) / len(inner))
        # behind by more than `step` (or 3 x the scatter of the inner lines' levels: a short
        # side of a far front has few pixels per line), on lines that are still mostly
        # in-plane, and on `persist` lines in a row (lines closer than a pixel see the same
        # pixels)
        thr = max(step, 3.0 * std)
        with np.errstate(invalid="ignore"):
            dev = np.where((p >= 0.5) & np.isfinite(level), ref - level, 0.0) - thr
        i_dev = _first_run((dev > 0).tolist(), persist)
    else:
        dev = None
        i_dev = n_l
    last = int(okl[-1])
    # out on 2 x `persist` lines in a row (about two pixels: a one-pixel strip where a plane
    # crossing the front takes its pixels is not its side)
    i_low = _first_run((p < 0.5).tolist(), 2 * persist)
    i = min(i_low, i_dev, last + 1)
    if i >= n_l:
        return None
    if i == i_low:
        return float(pos[i - 1] + (p[i - 1] - 0.5) / (p[i - 1] - p[i]) * (pos[i] - pos[i - 1]))
    if i == i_dev:
        # the values the run test gives its lines: > 0 on a run of `persist`, < 0 otherwise
        d1 = max(float(dev[i]), 1e-12) if persist > 1 else float(dev[i])
        d0 = float(dev[i - 1])
        if persist > 1:
            d0 = max(d0, 1e-12) if _first_run((dev[i - 1:i - 1 + persist] > 0).tolist(),
                                               persist, 0) == 0 else min(d0, -1e-12)
        f = (-d0) / (d1 - d0) if d0 < 0 else 0.0
        return float(pos[i - 1] + f * (pos[i] - pos[i - 1]))
    # the measured lines end inside the front (drop-outs to the end of the strip): its side
    # is at least there
    return float(pos[last] + 0.5 * (pos[i] - pos[i - 1]))


# the edge refinement's sample classes: in (in-plane, off the surface) 1, out (free, outside
# the image, reveal) 1 << 16, unknown / occluded 0 (they say nothing)
_EDGE_CODE = np.zeros(256, np.int32)
_EDGE_CODE[[IN_PLANE, OFF_SURFACE]] = 1
_EDGE_CODE[[FREE, OUTSIDE, GAP]] = 1 << 16


class _CropIntrinsics:
    """Intrinsics of an image crop (only what :func:`_warp_labels` uses)."""

    def __init__(self, K, r0, c0):
        self.fx, self.fy, self.cx, self.cy = K.fx, K.fy, K.cx - c0, K.cy - r0


def _refine_edges(lab_img, dzero, xs, ys, n, dpl, K, o, e1, e2, a0, a1, b0, b1, cfg,
                  gap_thin=None):
    """Sub-cell position of each side of a rectangle [a0, a1] x [b0, b1] (m, plane
    coordinates along e1, e2 from ``o``; plane n . p + dpl = 0, camera frame). The label
    image and the signed distances of the measured points to the plane are resampled on a
    strip of lines parallel to the side (``edge_refine_cell`` apart, ``edge_refine_band`` on
    either side of it, over the middle ``edge_refine_span`` of its length); going outwards,
    the side ends where the share of in-plane samples among the measured ones (in-plane,
    free, outside the image, off the surface; unknown and occluded samples say nothing)
    falls below 1/2, or where the in-plane samples' mean distance falls behind the inner
    lines' by more than max(edge_refine_depth_step, edge_refine_depth_step_per_m2 z^2) (the
    19 mm top face of a panel seen from above lies within L of its front face). A side
    without such a crossing in its strip stays. ``GAP`` samples are out, except those of
    the one-pixel widening of the reveals (``gap_thin``: the reveals themselves). Returns
    (a0, a1, b0, b1)."""
    band, cf, span = cfg.edge_refine_band, cfg.edge_refine_cell, cfg.edge_refine_span
    # image crop around the rectangle grown by the band
    P = np.array([o + a * e1 + b * e2 for a in (a0 - band, a1 + band)
                  for b in (b0 - band, b1 + band)])
    if np.any(P[:, 2] <= 0.05):
        return a0, a1, b0, b1
    u = K.fx * P[:, 0] / P[:, 2] + K.cx
    v = K.fy * P[:, 1] / P[:, 2] + K.cy
    H, W = lab_img.shape
    c0, c1 = max(0, int(np.floor(u.min())) - 1), min(W, int(np.ceil(u.max())) + 2)
    r0, r1 = max(0, int(np.floor(v.min())) - 1), min(H, int(np.ceil(v.max())) + 2)
    if c1 - c0 < 2 or r1 - r0 < 2:
        return a0, a1, b0, b1
    lab_c = lab_img[r0:r1, c0:c1]
    if gap_thin is not None:
        # the reveal itself is out; the pixel beside it that the GAP label's widening took
        # (for the rectified grids) is the front's
        ring = (lab_c == GAP) & ~gap_thin[r0:r1, c0:c1]
        if ring.any():
            lab_c = np.where(ring, np.uint8(IN_PLANE), lab_c)
    nr = (np.float32(n[0]) * xs[:, c0:c1] + np.float32(n[2])) + np.float32(n[1]) * ys[r0:r1, :]
    S = np.multiply(dzero[r0:r1, c0:c1], nr, out=nr)  # (in place: the same float32 values)
    S += np.float32(dpl)
    # the plane's surface samples only: the others 0 (they count in neither the sums nor
    # the numbers of samples, ``n_in`` below, which count exactly the surface samples)
    S[cv2.LUT(lab_c, _EDGE_CODE) != 1] = 0.0
    Kc = _CropIntrinsics(K, r0, c0)
    zc = float((o + 0.5 * (a0 + a1) * e1 + 0.5 * (b0 + b1) * e2)[2])
    step = max(cfg.edge_refine_depth_step, cfg.edge_refine_depth_step_per_m2 * zc * zc)
    persist = max(1, int(round(zc / K.fx / cf)))  # lines per pixel at the rectangle's depth
    out = [a0, a1, b0, b1]
    for side in range(4):
        along_a = side >= 2  # a horizontal side (b = const) runs along e1
        # the strip reaches at most a third of the way across the rectangle
        band = min(cfg.edge_refine_band, ((b1 - b0) if along_a else (a1 - a0)) / 3.0)
        nl = max(4, int(round(2 * band / cf)))
        lo, hi = (a0, a1) if along_a else (b0, b1)
        m = 0.5 * (1.0 - span) * (hi - lo)
        length = (hi - lo) - 2 * m
        ns = max(8, min(200, int(round(length / cf))))
        cs = length / ns
        e = (a0, a1, b0, b1)[side]
        outwards = side in (1, 3)  # a1, b1: outwards is +e1 / +e2
        start = e - band if outwards else e + band - nl * cf  # lowest line coordinate
        if along_a:  # lines are rows (along e1), the profile runs down the rows
            args = (Kc, o, e1, e2, lo + m, start, cs, (nl, ns), cf)
            axis = 1
        else:        # lines are columns (along e2), the profile runs along the columns
            args = (Kc, o, e1, e2, start, lo + m, cf, (ns, nl), cs)
            axis = 0
        lab = _warp_labels(lab_c, *args)
        # the same pixels as ``lab`` (the same homography). Cells within 5 cm of the camera
        # plane, which _warp_labels marks OUTSIDE, do not occur: the strip lies inside the
        # rectangle grown by the band (to half a 1 mm line), whose corners are > 5 cm in front
        dist = _warp_float(S, *args, outside=0.0)
        # in (1) and out (1 << 16) samples counted together (a line has < 2^16 samples)
        code = cv2.LUT(lab, _EDGE_CODE).sum(axis=axis)
        n_in = (code & 0xFFFF).astype(np.float64)
        n_out = code >> 16
        with np.errstate(all="ignore"):
            # mean of the in-plane samples' distances (the surface samples are the in-plane
            # ones, n_in of them; the others are 0 in ``dist``), NaN where none
            level = dist.sum(axis=axis, dtype=np.float64) / n_in
        pos = start + (np.arange(nl) + 0.5) * cf  # line coordinates, increasing
        if not outwards:  # inside first
            n_in, n_out, level, pos = n_in[::-1], n_out[::-1], level[::-1], pos[::-1]
        x = _edge_crossing(n_in, n_out.astype(np.float64), level, pos, step, persist)
        if x is not None:
            out[side] = x
    return tuple(out)


# ------------------------------------------------------------------------------------------
# the detector
# ------------------------------------------------------------------------------------------
def _depth_bound(dzero: np.ndarray, base: float, per_m2: float) -> np.ndarray:
    """max(base, per_m2 z^2) per pixel of the depth image ``dzero`` (m, 0 where invalid),
    float32, in one buffer (m; m / m^2)."""
    out = np.multiply(np.float32(per_m2), dzero)
    out *= dzero
    return np.maximum(out, np.float32(base), out=out)


def _check_inputs(depth, K, X_WC):
    if not isinstance(K, PinholeIntrinsics):
        raise ValueError(f"detect_fronts: K must be a PinholeIntrinsics, got {type(K).__name__}")
    d = as_depth_image(depth, K, who="detect_fronts")
    if not np.issubdtype(d.dtype, np.number):
        raise ValueError(f"detect_fronts: depth image must be numeric, got dtype {d.dtype}")
    X = np.asarray(X_WC, float)
    if X.shape != (4, 4) or not np.all(np.isfinite(X)):
        raise ValueError(f"detect_fronts: X_WC must be a finite 4x4 matrix, got shape {X.shape}")
    R = X[:3, :3]
    if not np.allclose(R.T @ R, np.eye(3), atol=1e-6):
        raise ValueError("detect_fronts: X_WC's rotation is not orthonormal")
    return d.astype(np.float32, copy=False), X


def _check_noise_scale(noise_scale, shape):
    """The variance factor image (float32, clipped to (0, 1]; non-finite = 1) of
    ``detect_fronts``' ``noise_scale``, or None."""
    if noise_scale is None:
        return None
    s = np.asarray(noise_scale)
    if s.ndim == 3 and s.shape[2] == 1:
        s = s[:, :, 0]
    if s.shape != tuple(shape) or not np.issubdtype(s.dtype, np.number):
        raise ValueError(f"detect_fronts: noise_scale must be a numeric array of the image's "
                         f"shape {tuple(shape)}, got {s.shape} {s.dtype}")
    s = np.nan_to_num(s.astype(np.float32), nan=1.0, posinf=1.0, neginf=1.0)
    s = np.clip(s, np.float32(1e-3), np.float32(1.0))
    return s * s


def detect_fronts(depth, K: PinholeIntrinsics, X_WC=None, config: FrontDetectorConfig | None = None,
                  rng: np.random.Generator | int | None = None, *, clock=time.perf_counter,
                  noise_scale=None):
    """Detect planar rectangles (cabinet fronts) in a depth image (thesis 5.1.1-5.1.2).

    Args:
        depth: (H, W) depth image, metres (NaN / 0 / inf = no measurement); (H, W, 1) accepted.
        K: the camera's intrinsics; the image must be ``(K.height, K.width)``.
        X_WC: (4, 4) camera pose in the world (Drake camera frame); None = identity (the
            rectangles are then in the camera frame and "up" is the image's up).
        config: :class:`FrontDetectorConfig` (default values when None).
        rng: ``numpy.random.Generator`` or seed of the random starts and RANSAC samples.
        clock: the timer of the stage timings (seconds): wall-clock by default;
            ``time.thread_time`` gives the CPU time of the calling thread (what a benchmark on
            a shared machine should compare).
        noise_scale: None, or (H, W) each pixel's depth noise std relative to one frame's, in
            (0, 1] (a temporally filtered image: :func:`mmlearn.models.perception.depth_filter.
            filter_depth`'s second output): the reveal test's (``gap_*``) noise-driven
            threshold part on the image follows it (its ``gap_depth`` floor does not).

    Returns:
        (rectangles, timings): a list of :class:`FrontRectangle` in the world frame (best first:
        precision x recall), and the seconds spent per stage (keys ``planes``, ``masks``,
        ``sampling``, ``optimisation``, ``check``, ``total``).

    Raises:
        ValueError: wrong image shape or type, bad intrinsics, pose or config. An image without
            any measurement gives no rectangles.
    """
    t_start = clock()
    cfg = config or FrontDetectorConfig()
    cfg.validate()
    d, X_WC = _check_inputs(depth, K, np.eye(4) if X_WC is None else X_WC)
    var_scale = _check_noise_scale(noise_scale, d.shape)
    rng = np.random.default_rng(rng)
    timings = {s: 0.0 for s in STAGES}
    out: list[FrontRectangle] = []

    def finish():
        timings["total"] = clock() - t_start
        return out, timings

    # --- planes --------------------------------------------------------------------------
    t0 = clock()
    valid = valid_depth_mask(d)
    if not valid.any():
        timings["planes"] = clock() - t0
        return finish()
    fx, fy = np.float32(1.0 / K.fx), np.float32(1.0 / K.fy)
    xs = ((np.arange(K.width, dtype=np.float32) - np.float32(K.cx)) * fx)[None, :]
    ys = ((np.arange(K.height, dtype=np.float32) - np.float32(K.cy)) * fy)[:, None]
    dz = np.where(valid, d, np.float32(np.nan))
    Pc = np.empty(d.shape + (3,), np.float32)  # (H, W, 3) float32, NaN where invalid
    np.multiply(xs, dz, out=Pc[..., 0])
    np.multiply(ys, dz, out=Pc[..., 1])
    Pc[..., 2] = dz
    st = int(cfg.ransac_stride_px)
    off = st // 2
    sub_valid = valid[off::st, off::st] & (d[off::st, off::st] <= cfg.max_depth)
    grid_shape = sub_valid.shape
    rr, cc = np.nonzero(sub_valid)
    sample_pts = Pc[off::st, off::st][rr, cc].astype(np.float64)
    planes = find_planes(sample_pts, np.column_stack([rr, cc]), grid_shape, cfg, rng)
    dzero = np.where(valid, d, np.float32(0.0))
    Limg = _depth_bound(dzero, cfg.inlier_distance, cfg.inlier_distance_per_m2)
    planes = [refine_plane_fullres(pl, Pc, Limg, st, off) for pl in planes]
    timings["planes"] = clock() - t0
    if not planes:
        return finish()

    # --- masks ---------------------------------------------------------------------------
    t0 = clock()
    lut = np.zeros(256, np.uint8)
    lut[:7] = np.round(255.0 * np.array([cfg.cost_in_plane, cfg.cost_free, cfg.cost_occluded,
                                         cfg.cost_unknown, cfg.cost_free, cfg.cost_unknown,
                                         cfg.cost_free]))
    down_C = X_WC[:3, :3].T @ np.array([0.0, 0.0, -1.0])
    lab_imgs, grids = [], []
    surface = None
    if cfg.surface_check:
        Lm = _depth_bound(dzero, cfg.surface_distance, cfg.surface_distance_per_m2)
        surface = (Lm, int(cfg.surface_window_px))
    gap = gap_thin = None
    if cfg.gap_label:
        # the largest planes seen off their normal get a rectified view; the long pass runs
        # where the lines follow the planes' sides (on the image only when no view is needed:
        # across slanted reveals its 128 px means smear them into false rows)
        # (the largest planes *that need a view*: a large plane seen along the image axes
        # does not take a view from a smaller oblique one, e.g. a door opened 90 deg)
        # The long pass only on the views of the gap_rectify_planes largest planes (the
        # cabinet's face: the shallow vertical reveals of flush fronts 45 deg off the
        # normal); on a smaller plane (an opened door) turned about the vertical, the
        # camera's disparity steps are vertical stripes of equal depth, and its lowered
        # threshold labelled them (a door at 2.3 m cut 7 cm short)
        views, large_view = [], False
        for rank, pl in enumerate(sorted(planes, key=lambda p: -p.support)):
            if len(views) >= cfg.gap_rectify_planes:
                break
            v = _rectified_view(K, pl, down_C, cfg, st, off)
            if v is not None:
                views.append((v, rank < cfg.gap_rectify_planes))
                large_view |= rank < cfg.gap_rectify_planes
        # (the image's long pass: off when one of the largest planes is seen obliquely)
        gap, gap_thin = _gap_mask(d, valid, K.fx, cfg, dzero,
                                  long_pass=cfg.gap_long_on_image and not large_view,
                                  var_scale=(None if var_scale is None
                                             else np.where(valid, var_scale, np.float32(0.0))))
        valid_f = valid.view(np.uint8).astype(np.float32) if views else None
        for v, large in views:
            rect = _gap_mask_rectified(dzero, valid, K, xs, ys, v, cfg, long_pass=large,
                                       valid_f=valid_f)
            if rect is not None:  # (in place: _gap_mask's own fresh arrays)
                gap |= rect[0]
                gap_thin |= rect[1]
    layers_on = cfg.layer_planes > 0 and cfg.layer_max_layers > 0 and surface is not None
    labels, S = _label_images(dzero, valid, xs, ys, planes, Limg, cfg.crossing_angle_deg,
                              int(cfg.crossing_smooth_px), surface, gap, keep_distances=True)
    if cfg.own_pixel_refit_deg > 0:  # planes tilted by a neighbour they cross at a shallow angle
        moved = _refit_on_own_pixels(planes, labels, Pc, Limg, cfg.own_pixel_refit_deg,
                                     cfg.crossing_angle_deg)
        if moved is not None:
            planes = moved
            labels, S = _label_images(dzero, valid, xs, ys, planes, Limg,
                                      cfg.crossing_angle_deg, int(cfg.crossing_smooth_px),
                                      surface, gap, keep_distances=True)
    if layers_on:  # fronts standing a few cm proud of a larger plane (_offset_layers)
        Lband = _depth_bound(dzero, 0.0, (cfg.removal_factor - 1.0) * cfg.inlier_distance_per_m2)
        Lband += Limg
        layers = _offset_layers(planes, labels, S, Pc, Limg, Lband, K, cfg, st, off)
        if layers:
            planes = planes + layers
            labels = _label_images(dzero, valid, xs, ys, planes, Limg, cfg.crossing_angle_deg,
                                   int(cfg.crossing_smooth_px), surface, gap)
    del S
    for k, (pl, lab) in enumerate(zip(planes, labels)):
        g = _make_grid(k, pl, lab, sample_pts, K, down_C, cfg, lut)
        lab_imgs.append(lab)
        if g is not None and (g.labels == IN_PLANE).any():
            grids.append(g)
    timings["masks"] = clock() - t0
    if not grids:
        return finish()

    # --- sampling ------------------------------------------------------------------------
    t0 = clock()
    pid, R0, steps, min_cells = [], [], [], []
    step_m = np.asarray(sorted(set(int(f) for f in cfg.step_factors)), float) * cfg.step_size
    for gi, g in enumerate(grids):
        m = int(cfg.starts_per_plane)
        pick = _in_plane_cells(g, rng.integers(0, int(g.sat_in[-1, -1]), m))
        ci, cj = np.divmod(pick, g.shape[1])
        wh = rng.uniform(cfg.prior_size[0], cfg.prior_size[1], (m, 2)) / g.c
        mc = max(1, int(math.ceil(cfg.min_side / g.c)))
        wc = np.maximum(np.round(wh[:, 0]).astype(np.int64), mc)
        hc = np.maximum(np.round(wh[:, 1]).astype(np.int64), mc)
        x0 = np.clip(cj - wc // 2, 0, np.maximum(0, g.shape[1] - wc))
        y0 = np.clip(ci - hc // 2, 0, np.maximum(0, g.shape[0] - hc))
        R = np.column_stack([x0, np.minimum(x0 + wc, g.shape[1]), y0,
                             np.minimum(y0 + hc, g.shape[0])])
        if cfg.component_starts > 0 and (g.labels == GAP).any():  # regions parted by reveals
            Rc = _component_starts(g, mc, int(cfg.component_starts), rng, cfg)
            R = np.concatenate([R, Rc])
            m = len(R)
        pid.append(np.full(m, gi))
        R0.append(R)
        steps.append(np.tile(np.unique(np.maximum(1, np.round(step_m / g.c))).astype(np.int64),
                             (m, 1)))
        min_cells.append(np.full(m, mc))
    pid = np.concatenate(pid)
    R0 = np.concatenate(R0)
    kmax = max(s.shape[1] for s in steps)
    steps = np.concatenate([np.pad(s, ((0, 0), (0, kmax - s.shape[1])), mode="edge")
                            for s in steps])
    min_cells = np.concatenate(min_cells)
    dims = np.array([g.shape for g in grids], np.int64)
    SC = _stack([g.sat_cost for g in grids], [g.shape for g in grids])
    timings["sampling"] = clock() - t0

    # --- optimisation (side moves, all starts at once) -----------------------------------
    t0 = clock()
    R, score, _ = _greedy(SC, dims, pid, R0, steps, min_cells, cfg.alpha, cfg.max_iterations)
    t_opt = clock() - t0

    # --- check: precision / recall / border, duplicates, then rotation polish ------------
    t0 = clock()
    cands = []
    seen = {}  # (plane, rectangle) -> its tests' outcome: most starts end on a shared one
    for s in range(len(R)):
        key = (int(pid[s]),) + tuple(R[s].tolist())
        res = seen.get(key)
        if res is None:
            g = grids[pid[s]]
            prec, rec = _precision_recall(g, R[s], cfg)
            res = seen[key] = None, None
            if prec < cfg.min_precision or rec < cfg.min_recall:
                continue
            center, e1, e2, w, h = _rect_camera(g, R[s])
            if not _inside_border(center, e1, e2, w, h, K, cfg.border_margin_px):
                continue
            res = seen[key] = prec * rec, center
        if res[0] is not None:
            cands.append((res[0], s, res[1]))
    kept = _suppress(cands, lambda c: grids[pid[c[1]]].n, cfg)
    t_chk = clock() - t0

    t0 = clock()
    polished, jobs, unpolished = [], [], []
    for _, s, _ in kept:
        g = grids[pid[s]]
        unpolished.append((g, g.e1, g.e2, g.u0, g.v0, R[s], g.labels, g.sat_cost, g.sat_in,
                           g.c))
        if sum(_gap_bounded(g, *R[s])) >= 3:
            # a front flush with its neighbours: its sides run along the reveals, to which the
            # grid is aligned (its dominant edge direction); rotations do not improve it
            polished.append(unpolished[-1])
            continue
        polished.append(len(jobs))  # filled below: all rotation polishes run together
        jobs.append((g, R[s], lab_imgs[g.plane_index]))
    if jobs:
        res = _polish_rotations(jobs, K, cfg, lut)
        polished = [p if isinstance(p, tuple) else (jobs[p][0],) + res[p][1] for p in polished]
    t_opt += clock() - t0
    timings["optimisation"] = t_opt

    t0 = clock()
    final = []
    for pol, unpol in zip(polished, unpolished):
        # the polished rectangle, or the accepted one it came from when the polish made it
        # fail a test (a drawer opened 0.25 m at 2.2 m: the polish cut its height from 0.116
        # to 0.082 m, and the recall fell to 0.689)
        for g, e1, e2, u0, v0, Rf, lab, sat_cost, sat_in, cp in (pol, unpol):
            gl = _Grid(g.plane_index, g.n, g.d, g.o, e1, e2, u0, v0, cp, lab, sat_cost,
                       sat_in)
            prec, rec = _precision_recall(gl, Rf, cfg)
            if prec >= cfg.min_precision and rec >= cfg.min_recall:
                break
        else:
            continue
        center, e1, e2, w, h = _rect_camera(gl, Rf)
        if cfg.edge_refine:
            x0, x1, y0, y1 = (float(v) for v in Rf)
            a0, a1, b0, b1 = _refine_edges(lab_imgs[g.plane_index], dzero, xs, ys, g.n, g.d,
                                           K, g.o, e1, e2,
                                           u0 + x0 * cp, u0 + x1 * cp, v0 + y0 * cp,
                                           v0 + y1 * cp, cfg, gap_thin)
            if min(a1 - a0, b1 - b0) >= cfg.min_side:
                center = g.o + 0.5 * (a0 + a1) * e1 + 0.5 * (b0 + b1) * e2
                w, h = a1 - a0, b1 - b0
        if not _inside_border(center, e1, e2, w, h, K, cfg.border_margin_px):
            continue
        n = g.n
        if cfg.refine_plane:
            fit = _refit_plane(Pc, lab_imgs[g.plane_index], center, e1, e2, w, h, K, g.n,
                               cfg.inlier_distance)
            if fit is not None:
                n, dn = fit
                center = center - (center @ n + dn) * n
                e1 = e1 - (e1 @ n) * n
                e1 /= math.sqrt(e1 @ e1)  # (np.linalg.norm's operations)
        e2 = _cross3(n, e1)
        X_CR = np.eye(4)
        X_CR[:3, 0], X_CR[:3, 1], X_CR[:3, 2], X_CR[:3, 3] = e1, e2, n, center
        final.append((prec * rec, n, center,
                      FrontRectangle(X_WR=X_WC @ X_CR, width=float(w), height=float(h),
                                     precision=float(prec), recall=float(rec))))
    final = _suppress(final, lambda c: c[1], cfg)
    out.extend(f[3] for f in final)
    timings["check"] = t_chk + clock() - t0
    return finish()


def _suppress(cands, normal_of, cfg):
    """Keep the best of candidates (score first, centre third element) whose centres are within
    ``duplicate_distance`` and normals within ``duplicate_angle_deg``."""
    cands = sorted(cands, key=lambda c: -c[0])
    cos_max = math.cos(math.radians(cfg.duplicate_angle_deg))
    kept = []
    for c in cands:
        dup = False
        for k in kept:
            if (np.linalg.norm(c[2] - k[2]) < cfg.duplicate_distance
                    and abs(normal_of(c) @ normal_of(k)) > cos_max):
                dup = True
                break
        if not dup:
            kept.append(c)
    return kept
