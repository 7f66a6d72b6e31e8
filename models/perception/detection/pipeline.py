"""The detector: :func:`detect_fronts` runs the stages (planes, masks, sampling, optimisation,
check) on one depth image and times them."""

import math
import time

from dataclasses import dataclass

import numba
import numpy as np

from mmlearn.models.common.camera import PinholeIntrinsics, as_depth_image
from mmlearn.models.common.gp import blas_single_thread
from mmlearn.models.perception.detection.check import (_gap_bounded, _inside_border,
                                                       _precision_recall, _refit_plane, _suppress)
from mmlearn.models.perception.detection.config import FrontDetectorConfig, STAGES
from mmlearn.models.perception.detection.edges import _refine_edges
from mmlearn.models.perception.detection.gaps import _gap_mask
from mmlearn.models.perception.detection.grid import _cross3, _Grid, _make_grid, _rect_camera
from mmlearn.models.perception.detection.labels import (_label_images, _refit_on_own_pixels, GAP,
                                                        IN_PLANE)
from mmlearn.models.perception.detection.layers import _offset_layers
from mmlearn.models.perception.detection.cells import find_cell_planes
from mmlearn.models.perception.detection.planes import Plane, find_planes, refine_planes_fullres
from mmlearn.models.perception.detection.rectify import _gap_mask_rectified, _rectified_view
from mmlearn.models.perception.detection.search import (_component_starts, _greedy, _in_plane_cells,
                                                        _polish_rotations, _stack)
from mmlearn.models.perception.fronts import FrontRectangle


_VALID_CONFIGS: dict = {}  # the field values of configurations that passed validate()


def _validated(cfg: FrontDetectorConfig) -> FrontDetectorConfig:
    """``cfg.validate()``, once per set of field values (the check costs ~1 ms, a frame's
    detection ~30 ms; a tracker passes the same configuration every frame)."""
    try:
        key = tuple((k, type(v), tuple((type(x), x) for x in v) if isinstance(v, list) else v)
                    for k, v in vars(cfg).items())
        hash(key)
    except TypeError:  # (a field of an unhashable type: validate() names it)
        return cfg.validate()
    if key not in _VALID_CONFIGS:
        cfg.validate()
        if len(_VALID_CONFIGS) > 64:
            _VALID_CONFIGS.clear()
        _VALID_CONFIGS[key] = True
    return cfg


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


@dataclass
class _Frame:
    """One depth image ready for the stages: ``d`` (H, W) float32 depth, ``valid`` its measured
    pixels, ``dzero`` the depth with 0 where not measured, ``xs`` (1, W) / ``ys`` (H, 1) the
    rays' x / y per unit depth, ``Pc`` (H, W, 3) the camera-frame points (NaN where not
    measured), ``st`` / ``off`` the RANSAC sample grid's stride and offset, ``sample_pts`` the
    sampled points (m, 3), ``Limg`` the inlier distance L per pixel, ``var_scale`` the noise
    variance factor (or None), ``down_C`` gravity in the camera frame, ``surf`` the surface
    check's distance per pixel and ``Lband`` L plus the removal band's noise part per pixel
    (:func:`_offset_layers`)."""

    K: PinholeIntrinsics
    d: np.ndarray
    valid: np.ndarray
    dzero: np.ndarray
    xs: np.ndarray
    ys: np.ndarray
    Pc: np.ndarray
    st: int
    off: int
    sample_pts: np.ndarray
    grid_rc: np.ndarray
    grid_shape: tuple
    Limg: np.ndarray
    var_scale: np.ndarray | None
    down_C: np.ndarray
    surf: np.ndarray
    Lband: np.ndarray
    gravity: bool = True  # whether ``down_C`` is known (``detect_fronts`` was given X_WC)


@numba.njit(cache=True, nogil=True)
def _frame_kernel(d, xs, ys, base, per_m2, s_base, s_per_m2, band_per_m2, valid, dzero, Pc, Limg,
                  surf, Lband):
    """One pass over the rows of a float32 depth image ``d``: ``valid`` (finite and > 0),
    ``dzero`` (0 where not valid), ``Pc`` the camera-frame points (x d, y d, d; NaN where not
    valid), ``Limg`` = max(base, per_m2 z^2), ``surf`` = max(s_base, s_per_m2 z^2) and
    ``Lband`` = max(0, band_per_m2 z^2) + Limg (float32: (per_m2 z) z, then the larger one).
    Each row in four loops of few arrays each, which the compiler turns into vector
    operations (one loop writing all seven arrays stays scalar)."""
    nan, zero, inf = np.float32(np.nan), np.float32(0.0), np.float32(np.inf)
    W = d.shape[1]
    for r in range(d.shape[0]):
        dr, vr, zr = d[r], valid[r], dzero[r]
        for c in range(W):
            v = dr[c]
            ok = (v > zero) & (v < inf)  # (finite and > 0: NaN fails both)
            vr[c] = ok
            zr[c] = v if ok else zero
        Lr, br = Limg[r], Lband[r]
        for c in range(W):
            z0 = zr[c]
            b = per_m2 * z0
            b = b * z0
            lim = b if b > base else base
            Lr[c] = lim
            e = band_per_m2 * z0
            e = e * z0
            br[c] = (e if e > zero else zero) + lim
        sr = surf[r]
        for c in range(W):
            z0 = zr[c]
            s = s_per_m2 * z0
            s = s * z0
            sr[c] = s if s > s_base else s_base
        Pf, y = Pc[r].reshape(3 * W), ys[r]
        for c in range(W):
            v = dr[c]
            dz = v if (v > zero) & (v < inf) else nan
            Pf[3 * c] = xs[c] * dz
            Pf[3 * c + 1] = y * dz
            Pf[3 * c + 2] = dz


def _frame_arrays(d, K, cfg):
    """The per-pixel arrays of a float32 depth image: (valid, dzero, xs (1, W), ys (H, 1),
    Pc (H, W, 3), Limg, surf, Lband), see :class:`_Frame` (in one compiled pass)."""
    fx, fy = np.float32(1.0 / K.fx), np.float32(1.0 / K.fy)
    xs = ((np.arange(K.width, dtype=np.float32) - np.float32(K.cx)) * fx)[None, :]
    ys = ((np.arange(K.height, dtype=np.float32) - np.float32(K.cy)) * fy)[:, None]
    valid = np.empty(d.shape, bool)
    dzero = np.empty(d.shape, np.float32)
    Pc = np.empty(d.shape + (3,), np.float32)  # (H, W, 3) float32, NaN where invalid
    Limg, surf, Lband = (np.empty(d.shape, np.float32) for _ in range(3))
    _frame_kernel(np.ascontiguousarray(d, np.float32), xs[0], ys[:, 0],
                  np.float32(cfg.inlier_distance), np.float32(cfg.inlier_distance_per_m2),
                  np.float32(cfg.surface_distance), np.float32(cfg.surface_distance_per_m2),
                  np.float32((cfg.removal_factor - 1.0) * cfg.inlier_distance_per_m2),
                  valid, dzero, Pc, Limg, surf, Lband)
    return valid, dzero, xs, ys, Pc, Limg, surf, Lband


@numba.njit(cache=True, nogil=True)
def _sample_grid(valid, d, Pc, st, off, max_depth):
    """The RANSAC sample grid (every ``st``-th pixel from ``off`` in rows and columns): its
    shape, and in raster order its measured pixels no farther than ``max_depth`` (float32):
    their points (m, 3) float64 and grid (row, column) (m, 2)."""
    H, W = d.shape
    Hs, Ws = max(0, (H - off + st - 1) // st), max(0, (W - off + st - 1) // st)
    m = 0
    for i in range(Hs):
        for j in range(Ws):
            r, c = off + i * st, off + j * st
            m += 1 if valid[r, c] and d[r, c] <= max_depth else 0
    pts, rc = np.empty((m, 3)), np.empty((m, 2), np.int64)
    k = 0
    for i in range(Hs):
        for j in range(Ws):
            r, c = off + i * st, off + j * st
            if valid[r, c] and d[r, c] <= max_depth:
                pts[k, 0], pts[k, 1], pts[k, 2] = Pc[r, c, 0], Pc[r, c, 1], Pc[r, c, 2]
                rc[k, 0], rc[k, 1] = i, j
                k += 1
    return (Hs, Ws), pts, rc


def _prepare_frame(d, arrays, K, X_WC, var_scale, cfg) -> _Frame:
    """The camera-frame points of every pixel and the RANSAC sample grid of a depth image
    (``arrays``: :func:`_frame_arrays`; the grid in one compiled pass, :func:`_sample_grid`)."""
    valid, dzero, xs, ys, Pc, Limg, surf, Lband = arrays
    st = int(cfg.ransac_stride_px)
    off = st // 2
    shape, sample_pts, grid_rc = _sample_grid(valid, d, Pc, st, off, np.float32(cfg.max_depth))
    down_C = X_WC[:3, :3].T @ np.array([0.0, 0.0, -1.0])
    return _Frame(K, d, valid, dzero, xs, ys, Pc, st, off, sample_pts, grid_rc, shape, Limg,
                  var_scale, down_C, surf, Lband)


def _find_frame_planes(f: _Frame, cfg, rng) -> list[Plane]:
    """Stage ``planes``: RANSAC on the sample grid (or region growing on the cell grid,
    ``cfg.plane_method``), each plane refitted at full resolution."""
    if cfg.plane_method == "cells":
        planes, _ = find_cell_planes(f.Pc, f.st, cfg)
    else:
        planes = find_planes(f.sample_pts, f.grid_rc, f.grid_shape, cfg, rng)
    return refine_planes_fullres(planes, f.Pc, f.Limg, f.st, f.off)


def _cost_table(cfg) -> np.ndarray:
    """Label -> cost x 255 (uint8, 256 entries; costs quantised to 1/255)."""
    lut = np.zeros(256, np.uint8)
    lut[:7] = np.round(255.0 * np.array([cfg.cost_in_plane, cfg.cost_free, cfg.cost_occluded,
                                         cfg.cost_unknown, cfg.cost_free, cfg.cost_unknown,
                                         cfg.cost_free]))
    return lut


def _reveals(f: _Frame, planes, cfg):
    """The ``GAP`` masks (wide, thin) of the image: the line tests on the image, and on the
    rectified views of the largest vertical planes seen off their normal (mapped back).

    The long pass runs on the views of the ``gap_rectify_planes`` largest planes only (the
    cabinet's face: the shallow vertical reveals of flush fronts seen obliquely), never on
    the image: there it splits a closed door at 2.0-2.3 m with false rows, and across
    slanted reveals its long means smear them into false rows; on a smaller plane turned
    about the vertical (an opened door) the camera's disparity steps are vertical stripes of
    equal depth that its lowered threshold would label."""
    K = f.K
    views = []
    # the largest planes *that need a view*: a large plane seen along the image axes does
    # not take a view from a smaller oblique one (a door opened 90 deg)
    for rank, pl in enumerate(sorted(planes, key=lambda p: -p.support)):
        if len(views) >= cfg.gap_rectify_planes:
            break
        v = _rectified_view(K, pl, f.down_C, cfg, f.st, f.off)
        if v is not None:
            views.append((v, rank < cfg.gap_rectify_planes))
    gap, gap_thin = _gap_mask(f.d, f.valid, K.fx, cfg, f.dzero,
                              long_pass=False,
                              var_scale=(None if f.var_scale is None
                                         else np.where(f.valid, f.var_scale, np.float32(0.0))))
    valid_f = f.valid.view(np.uint8).astype(np.float32) if views else None
    for v, large in views:
        rect = _gap_mask_rectified(f.dzero, f.valid, K, f.xs, f.ys, v, cfg, long_pass=large,
                                   valid_f=valid_f)
        if rect is not None:  # (in place: _gap_mask's own fresh arrays)
            gap |= rect[0]
            gap_thin |= rect[1]
    return gap, gap_thin


def _labels(f: _Frame, planes, cfg, surface, gap, slot, keep_distances=False, previous=None):
    """:func:`_label_images` of the frame, into the scratch arrays of ``slot`` (the label
    images live until the next frame's call with that slot)."""
    return _label_images(f.dzero, f.valid, f.xs, f.ys, planes, f.Limg, cfg.crossing_angle_deg,
                         int(cfg.crossing_smooth_px), surface, gap, keep_distances=keep_distances,
                         previous=previous, slot=slot)


def _plane_labels(f: _Frame, planes, cfg, surface, gap):
    """The label image of every plane (Eq. 5.2 with crossings, surface check and reveals),
    after the planes tilted by a shallow crossing are refitted on their own pixels and the
    offset layers are added: (planes, labels). BLAS runs on one thread here
    (:func:`blas_single_thread`): the refits' products are small, and a BLAS thread pool
    on a busy machine made them many times slower."""
    with blas_single_thread():
        return _labels_refits_layers(f, planes, cfg, surface, gap)


def _labels_refits_layers(f: _Frame, planes, cfg, surface, gap):
    """:func:`_plane_labels`' work: the labels, the own-pixel refit and the offset layers,
    each relabelling after them from the labels before."""
    # (each call its own scratch slot: a relabelling reads the labels before it)
    labels, S = _labels(f, planes, cfg, surface, gap, 0, keep_distances=True)
    # (each relabelling takes the images of the planes that neither moved nor cross a moved
    # or new plane from the one before: _label_images' previous)
    if cfg.own_pixel_refit_deg > 0:  # planes tilted by a neighbour they cross at a shallow angle
        moved = _refit_on_own_pixels(planes, labels, f.Pc, f.Limg, cfg.own_pixel_refit_deg,
                                     cfg.crossing_angle_deg)
        if moved is not None:
            labels, S = _labels(f, moved, cfg, surface, gap, 1, keep_distances=True,
                                previous=(planes, labels))
            planes = moved
    if cfg.layer_planes > 0 and cfg.layer_max_layers > 0:
        # fronts standing a few cm proud of a larger plane (_offset_layers)
        layers = _offset_layers(planes, labels, S, f.Pc, f.Limg, f.Lband, f.K, cfg, f.st, f.off)
        if layers:
            labels = _labels(f, planes + layers, cfg, surface, gap, 2,
                             previous=(planes, labels))
            planes = planes + layers
    return planes, labels


def _front_planes(f: _Frame, planes, cfg) -> list[bool]:
    """Per plane, whether it can hold a front: the plane lies within ``front_max_tilt_deg`` of
    vertical (its normal within that angle of horizontal; every plane when gravity is not
    known)."""
    if not f.gravity or cfg.front_max_tilt_deg >= 90.0:
        return [True] * len(planes)
    lim = math.sin(math.radians(cfg.front_max_tilt_deg))
    return [abs(float(pl.n @ f.down_C)) <= lim for pl in planes]


def _grids(f: _Frame, planes, labels, cfg, lut) -> list[_Grid]:
    """The rectified grid of every plane that can hold a front (:func:`_front_planes`) with
    in-plane cells; the others get none (their label images stay: the other planes' crossings,
    refits and offset layers read them)."""
    grids = []
    front = _front_planes(f, planes, cfg)
    with blas_single_thread():  # (small products: see _plane_labels)
        for k, (pl, lab) in enumerate(zip(planes, labels)):
            if not front[k]:
                continue
            g = _make_grid(k, pl, lab, f.sample_pts, f.K, f.down_C, cfg, lut)
            if g is not None and (g.labels == IN_PLANE).any():
                grids.append(g)
    return grids


def _random_starts(g: _Grid, cfg, rng):
    """``starts_per_plane`` starts at random in-plane cells of a grid, sizes from the prior,
    plus one per region between reveals (``component_starts``): (R (m, 4), min cells)."""
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
        R = np.concatenate([R, _component_starts(g, mc, int(cfg.component_starts), rng, cfg)])
    return R, mc


def _plane_stream(key: int, plane_index: int) -> np.random.Generator:
    """The random stream of one plane's starts: derived from the frame's ``key`` and the
    plane's index among the frame's planes only, so a plane's draws do not depend on how many
    draws the other planes took, nor on which other planes are searched."""
    return np.random.Generator(np.random.PCG64(
        np.random.SeedSequence(key, spawn_key=(int(plane_index),))))


def _starts(grids, cfg, key: int):
    """Stage ``sampling``: the starts of all planes, stacked for one greedy run: plane of each
    start, rectangles (S, 4), move sizes in cells (S, k), least size in cells (S,). Each
    plane's starts are drawn from its own stream (:func:`_plane_stream` of ``key``)."""
    pid, R0, steps, min_cells = [], [], [], []
    step_m = np.asarray(sorted(set(int(f) for f in cfg.step_factors)), float) * cfg.step_size
    for gi, g in enumerate(grids):
        R, mc = _random_starts(g, cfg, _plane_stream(key, g.plane_index))
        m = len(R)
        pid.append(np.full(m, gi))
        R0.append(R)
        steps.append(np.tile(np.unique(np.maximum(1, np.round(step_m / g.c))).astype(np.int64),
                             (m, 1)))
        min_cells.append(np.full(m, mc))
    kmax = max(s.shape[1] for s in steps)
    steps = np.concatenate([np.pad(s, ((0, 0), (0, kmax - s.shape[1])), mode="edge")
                            for s in steps])
    return np.concatenate(pid), np.concatenate(R0), steps, np.concatenate(min_cells)


def _accepted(grids, pid, R, K, cfg):
    """Stage ``check`` on the greedy's results: those above the precision and recall
    thresholds and inside the image border, duplicates suppressed: (score, start, centre)."""
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
    return _suppress(cands, lambda c: grids[pid[c[1]]].n, cfg)


def _polished(kept, grids, pid, R, lab_imgs, K, cfg, lut):
    """Each accepted rectangle polished by in-plane rotations (all at once), except those
    with three or more sides along reveals (they follow the reveals, to which the grid is
    aligned): per rectangle (polished, accepted), each the grid window it lies on as
    (grid, e1, e2, u0, v0, R, labels, sat_cost, sat_in, cell)."""
    polished, jobs, unpolished = [], [], []
    for _, s, _ in kept:
        g = grids[pid[s]]
        unpolished.append((g, g.e1, g.e2, g.u0, g.v0, R[s], g.labels, g.sat_cost, g.sat_in,
                           g.c))
        if sum(_gap_bounded(g, *R[s])) >= 3:
            polished.append(unpolished[-1])
            continue
        polished.append(len(jobs))  # filled below: all rotation polishes run together
        jobs.append((g, R[s], lab_imgs[g.plane_index]))
    if jobs:
        res = _polish_rotations(jobs, K, cfg, lut)
        polished = [p if isinstance(p, tuple) else (jobs[p][0],) + res[p][1] for p in polished]
    return list(zip(polished, unpolished))


def _passing(pair, cfg):
    """The polished rectangle, or the accepted one it came from when the polish made it fail
    a test (a drawer opened 0.25 m at 2.2 m: the polish cut its height from 0.116 to 0.082 m
    and its recall below the threshold): (grid, window grid, R, precision, recall) or None."""
    for g, e1, e2, u0, v0, Rf, lab, sat_cost, sat_in, cp in pair:
        gl = _Grid(g.plane_index, g.n, g.d, g.o, e1, e2, u0, v0, cp, lab, sat_cost, sat_in)
        prec, rec = _precision_recall(gl, Rf, cfg)
        if prec >= cfg.min_precision and rec >= cfg.min_recall:
            return g, gl, Rf, prec, rec
    return None


def _final_rectangle(f: _Frame, lab_img, g, gl, Rf, prec, rec, X_WC, cfg, gap_thin):
    """A passing rectangle with its sides refined below the grid cell and its plane refitted,
    in the world frame: (score, normal, centre, FrontRectangle), or None when it leaves the
    image border."""
    K = f.K
    center, e1, e2, w, h = _rect_camera(gl, Rf)
    x0, x1, y0, y1 = (float(v) for v in Rf)
    u0, v0, cp = gl.u0, gl.v0, gl.c
    a0, a1, b0, b1 = _refine_edges(lab_img, f.dzero, f.xs, f.ys, g.n, g.d, K, g.o, e1, e2,
                                   u0 + x0 * cp, u0 + x1 * cp, v0 + y0 * cp, v0 + y1 * cp,
                                   cfg, gap_thin)
    if min(a1 - a0, b1 - b0) >= cfg.min_side:
        center = g.o + 0.5 * (a0 + a1) * e1 + 0.5 * (b0 + b1) * e2
        w, h = a1 - a0, b1 - b0
    if not _inside_border(center, e1, e2, w, h, K, cfg.border_margin_px):
        return None
    n = g.n
    fit = _refit_plane(f.Pc, lab_img, center, e1, e2, w, h, K, g.n, cfg.inlier_distance)
    if fit is not None:
        n, dn = fit
        center = center - (center @ n + dn) * n
        e1 = e1 - (e1 @ n) * n
        e1 /= math.sqrt(e1 @ e1)  # (np.linalg.norm's operations)
    e2 = _cross3(n, e1)
    X_CR = np.eye(4)
    X_CR[:3, 0], X_CR[:3, 1], X_CR[:3, 2], X_CR[:3, 3] = e1, e2, n, center
    return (prec * rec, n, center,
            FrontRectangle(X_WR=X_WC @ X_CR, width=float(w), height=float(h),
                           precision=float(prec), recall=float(rec)))


def detect_fronts(depth, K: PinholeIntrinsics, X_WC=None, config: FrontDetectorConfig | None = None,
                  rng: np.random.Generator | int | None = None, *, clock=time.perf_counter,
                  noise_scale=None):
    """Detect planar rectangles (cabinet fronts) in a depth image (thesis 5.1.1-5.1.2).

    Args:
        depth: (H, W) depth image, metres (NaN / 0 / inf = no measurement); (H, W, 1) accepted.
        K: the camera's intrinsics; the image must be ``(K.height, K.width)``.
        X_WC: (4, 4) camera pose in the world (Drake camera frame); its "down" selects the
            planes searched for fronts (``front_max_tilt_deg``). None = identity (the
            rectangles are then in the camera frame, "up" is the image's up, and every plane
            is searched: gravity is not known).
        config: :class:`FrontDetectorConfig` (default values when None).
        rng: ``numpy.random.Generator`` or seed of the RANSAC samples and the random starts
            (each plane's starts from a stream of its own, keyed by one draw after the plane
            stage and the plane's index: :func:`_plane_stream`).
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
    cfg = _validated(config or FrontDetectorConfig())
    X_WC_given = X_WC is not None
    d, X_WC = _check_inputs(depth, K, np.eye(4) if X_WC is None else X_WC)
    var_scale = _check_noise_scale(noise_scale, d.shape)
    rng = np.random.default_rng(rng)
    timings = {s: 0.0 for s in STAGES}
    out: list[FrontRectangle] = []

    def finish():
        timings["total"] = clock() - t_start
        return out, timings

    t0 = clock()
    arrays = _frame_arrays(d, K, cfg)
    if not arrays[0].any():
        timings["planes"] = clock() - t0
        return finish()
    f = _prepare_frame(d, arrays, K, X_WC, var_scale, cfg)
    f.gravity = X_WC_given
    planes = _find_frame_planes(f, cfg, rng)
    # the key of the planes' own streams of starts (:func:`_plane_stream`)
    key = int(rng.integers(0, 2 ** 63 - 1))
    timings["planes"] = clock() - t0
    if not planes:
        return finish()

    t0 = clock()
    lut = _cost_table(cfg)
    surface = (f.surf, int(cfg.surface_window_px))
    gap, gap_thin = _reveals(f, planes, cfg)
    planes, lab_imgs = _plane_labels(f, planes, cfg, surface, gap)
    grids = _grids(f, planes, lab_imgs, cfg, lut)
    timings["masks"] = clock() - t0
    if not grids:
        return finish()

    t0 = clock()
    pid, R0, steps, min_cells = _starts(grids, cfg, key)
    dims = np.array([g.shape for g in grids], np.int64)
    SC = _stack([g.sat_cost for g in grids], [g.shape for g in grids])
    timings["sampling"] = clock() - t0

    t0 = clock()
    R, _, _ = _greedy(SC, dims, pid, R0, steps, min_cells, cfg.alpha, cfg.max_iterations)
    t_opt = clock() - t0

    t0 = clock()
    kept = _accepted(grids, pid, R, K, cfg)
    t_chk = clock() - t0

    t0 = clock()
    pairs = _polished(kept, grids, pid, R, lab_imgs, K, cfg, lut)
    timings["optimisation"] = t_opt + clock() - t0

    t0 = clock()
    final = []
    for pair in pairs:
        ok = _passing(pair, cfg)
        if ok is None:
            continue
        g = ok[0]
        res = _final_rectangle(f, lab_imgs[g.plane_index], *ok, X_WC, cfg, gap_thin)
        if res is not None:
            final.append(res)
    final = _suppress(final, lambda c: c[1], cfg)
    out.extend(r[3] for r in final)
    timings["check"] = t_chk + clock() - t0
    return finish()
