"""Tracking cabinet fronts over frames (thesis Sec. 5.1.3): rectangles -> pose tracks.

Plain numpy (no pydrake.systems): :func:`track_frame` is a pure function from a
:class:`TrackingState` and one frame's ``list[FrontRectangle]`` to the next state; the
FrontTracker LeafSystem (systems/perception/front_tracker.py) keeps that state in its Context.

The 8 parameterisations of a rectangle
--------------------------------------
A rectangle (``models/perception/fronts.py``: centre pose X_WR, x along the width, y along the height,
z the normal) is the same physical rectangle under the proper rotations that map it onto
itself: the dihedral group D4 of order 8, ``Rz(k 90 deg)`` and ``Rx(180 deg) Rz(k 90 deg)``,
k = 0..3 (which corner is "first" x which side is the front, thesis 5.1.3). The rotations
by an odd multiple of 90 deg swap width and height; the centre is the same for all 8.
Two parameterisations differ by at least 90 deg, so the one closest to a reference pose is
unique while the angular gate is below 45 deg (:func:`align_rectangle`). Every new
rectangle is re-parameterised into the track it joins, so a track's orientations form a
smooth trajectory (a detector that flips its x axis or swaps width and height between frames
would otherwise add 90 / 180 deg jumps that no link model explains).

Association (thesis: "fixed thresholds on pose change and ... the object size"; the original
system's defaults, tum-vision/articulation ``articulation_perception/src/detector.cpp``:
0.10 m, 20 deg, 0.05 m): a rectangle may join a track when, after alignment, its centre is
within ``max_distance_m``, its orientation within ``max_angle_deg`` and its width and height
within ``max_size_diff_m`` of *some* observation of that track (the original compares with
every observation too, so a front that left the view re-joins its track wherever it had been
seen); among the candidates the cost ``d / max_d + angle / max_angle + size / max_size``
(the nearest observation of each track) is minimised jointly over the frame's rectangles
(scipy's ``linear_sum_assignment``), one rectangle per track and frame. A rectangle that
gates with a track taken by a better rectangle of the same frame is a duplicate detection
of that front (dropped and counted); any other starts a new track. A track is *published*
(handed to the articulation models) from ``min_observations`` observations on (5 in the
original system).

Which pose is tracked
---------------------
The centre pose. Any frame fixed to a rigid front moves exactly as the front: for a door on a
hinge it moves on a circle about the hinge axis while its orientation turns about that axis,
which is the revolute model of Eq. 4.21 with radius = the centre's distance from the axis
(w/2 for a hinge on an edge); a drawer's centre moves on a line with constant orientation
(prismatic). A *corner* is the worse choice: the corner on the hinge barely moves (radius
~0, its positions alone do not show a hinge), and a corner moves with every error of the
detected size; the centre moves with half of it.

The real tracks (tests/data/articulation_logs/rectangle_door.txt, rectangle_drawer.txt,
copies of shared/data/articulation_logs/rectangle_tracks) give the pose of a *corner*: the
original detector's rectangle spans [0, w] x [0, h] in its frame (tum-vision/articulation,
detector.cpp), and the door's geometry agrees (the far edge, corner + w, turns on a 0.389 m
radius for the 0.395 m door). :func:`rectangles_from_poses` with ``origin="corner"``
converts them. Measured on the door (413 observations; ``python -m
mmlearn.apps.fit_articulation tests/data/articulation_logs/rectangle_door.txt --rectangles
corner --sigma-pos S --sigma-orient 0.0524 --expect revolute``):

* why it selected GP at sigma_pos >= 0.02 m: not parameterisation flips (there are none: the
  largest rotation between consecutive observations is 17.6 deg, and :func:`align_track`
  changes nothing), but the corner pose and two limits of the selection for full poses:
  (1) the corner lies ~0.09 m from the hinge, so over the 74 deg its positions bow 0.017 m,
  below sigma_pos, and the identifiability test (models/articulation_structure._unresolved)
  rejected the revolute model although the orientation turns 74 deg with ~1.5 deg noise;
  (2) at 0.05 m no three positions of the short arc are 2 sigma_pos apart, so the revolute
  MLESAC had no hypothesis at all. Fixed: the bow test now passes a full-pose revolute
  whose rotation over the range exceeds the noise spread, and RevoluteModel falls back to
  hypotheses from pairs of poses when no 3-point sample exists (every fit that had 3-point
  hypotheses is unchanged);
* centre pose: revolute at sigma_pos 0.005-0.05 m (sigma_orient 3 deg), r = 0.160-0.166 m,
  hinge axis 0.6-2.2 deg from the door's height edge, 5-fold cross-validated prediction error
  0.009-0.011 m / 1.35-2.2 deg (thesis: 0.01 m / 3.5 deg); with 60 observations drawn in
  temporal order (the thesis' protocol, 50 draws) revolute in every draw from n = 15 on
  (sigma 0.01-0.05; from 20 at 0.005), in 92-98 % of the draws at n = 10 and 38-44 % at
  n = 5 (thesis: mostly rigid for the first ~10, right after 30); held-out prediction error
  at n = 30: 0.010-0.011 m / 1.4-1.7 deg (sigma 0.01-0.05);
* the corner pose (read as if it were the centre) now selects revolute too, r = 0.085 m, but
  predicts twice as badly (0.020 m);
* the rectangles are 0.42-0.54 m wide for a 0.395 m door (the detector takes in the coplanar
  cabinet frame on the hinge side when the door is nearly closed), so the centre's radius is
  ~0.03-0.06 m short of half the detected width: a bias of the data, not of the fit.

The drawer (19 observations, sub-sampled: steps up to 0.10 m, so the default 0.10 m gate
splits it in two when it is re-tracked; :func:`align_track` keeps it one track): prismatic
at 0.005-0.05 m, axis 1.6 deg from the front's normal, travel 0.346 m, cross-validated error
0.0066 m / 4.8 deg (thesis: 0.01 m / 7 deg), right from n = 4 / 5 / 11 observations at
sigma_pos 0.01 / 0.02 / 0.05 m (file order).
"""

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.spatial.transform import Rotation

from mmlearn.models.common.config import param, validate_fields
from mmlearn.models.perception.fronts import FrontRectangle

__all__ = [
    "RECTANGLE_SYMMETRIES",
    "SWAPS_SIZE",
    "rectangle_parameterisations",
    "align_rectangle",
    "corner_to_centre",
    "rectangles_from_poses",
    "FrontTrackingConfig",
    "FrontTrack",
    "TrackingState",
    "FrameResult",
    "track_frame",
    "track_rectangles",
    "as_rectangle",
    "FRONT_SIGMA_POS_M",
    "FRONT_SIGMA_ORIENT_RAD",
    "front_observation_model",
    "TrackModel",
    "fit_track_model",
    "selection_vs_observations",
    "simulate_front_rectangles",
    "align_track",
    "axis_errors",
    "cross_validated_errors",
    "subsampled_selection",
]


def _rz(k: int) -> np.ndarray:
    c, s = [(1, 0), (0, 1), (-1, 0), (0, -1)][k % 4]
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


_RX180 = np.diag([1.0, -1.0, -1.0])

#: (8, 3, 3) the proper rotations S that map a rectangle centred at the origin in the xy plane
#: onto itself: Rz(k 90 deg), then Rx(180 deg) Rz(k 90 deg) (the back side), k = 0..3.
#: X_WR @ S (rotation part) is the same physical rectangle.
RECTANGLE_SYMMETRIES = np.stack([_rz(k) for k in range(4)] + [_RX180 @ _rz(k) for k in range(4)])
RECTANGLE_SYMMETRIES.setflags(write=False)
#: (8,) True where the symmetry swaps width and height (odd multiples of 90 deg about z)
SWAPS_SIZE = np.array([k % 2 == 1 for k in range(4)] * 2)
SWAPS_SIZE.setflags(write=False)


def rectangle_parameterisations(X_WR, width: float, height: float):
    """All 8 parameterisations of one rectangle.

    Args:
        X_WR: (4, 4) centre pose (x along the width, y along the height, z the normal).
        width, height: extents along x and y, m.
    Returns:
        (Xs (8, 4, 4), sizes (8, 2) width height), in the order of RECTANGLE_SYMMETRIES.
    """
    X = np.asarray(X_WR, float)
    Xs = np.repeat(X[None], 8, axis=0)
    Xs[:, :3, :3] = X[:3, :3] @ RECTANGLE_SYMMETRIES
    sizes = np.where(SWAPS_SIZE[:, None], [[height, width]], [[width, height]]).astype(float)
    return Xs, sizes


def _angles_to(R_ref: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Rotation angles (rad) between R_ref (..., 3, 3) and R S_j for all 8 symmetries:
    (..., 8). Broadcasts R_ref against R."""
    M = np.swapaxes(R_ref, -1, -2) @ R  # R_ref^T R
    tr = np.einsum("...ab,jba->...j", M, RECTANGLE_SYMMETRIES)  # trace(M S_j)
    return np.arccos(np.clip(0.5 * (tr - 1.0), -1.0, 1.0))


def align_rectangle(X_ref, X_WR, width: float, height: float):
    """The parameterisation of a rectangle closest in orientation to a reference pose.

    Args:
        X_ref: (4, 4) reference pose (e.g. the last pose of a track).
        X_WR, width, height: the rectangle as detected (m).
    Returns:
        (X (4, 4), width, height, angle) with ``angle`` the remaining rotation from X_ref, rad.
    """
    X = np.asarray(X_WR, float)
    ang = _angles_to(np.asarray(X_ref, float)[:3, :3], X[:3, :3])
    j = int(np.argmin(ang))
    out = X.copy()
    out[:3, :3] = X[:3, :3] @ RECTANGLE_SYMMETRIES[j]
    w, h = (height, width) if SWAPS_SIZE[j] else (width, height)
    return out, float(w), float(h), float(ang[j])


def corner_to_centre(X_corner, width, height) -> np.ndarray:
    """Centre pose of rectangles given by the pose of a corner, the rectangle spanning
    [0, w] x [0, h] in that corner's frame (the original detector's convention).

    Args:
        X_corner: (4, 4) or (n, 4, 4) corner poses.
        width, height: scalars or (n,), m.
    Returns:
        The centre poses, same shape as ``X_corner`` (orientation unchanged).
    """
    X = np.array(X_corner, float)
    one = X.ndim == 2
    X = X.reshape(-1, 4, 4)
    w = np.broadcast_to(np.asarray(width, float), (X.shape[0],))
    h = np.broadcast_to(np.asarray(height, float), (X.shape[0],))
    off = np.stack([0.5 * w, 0.5 * h, np.zeros_like(w)], axis=1)
    X[:, :3, 3] += np.einsum("nij,nj->ni", X[:, :3, :3], off)
    return X[0] if one else X


def rectangles_from_poses(poses, sizes, *, origin: str = "centre") -> list:
    """FrontRectangles from (n, 7) poses x y z qx qy qz qw and (n, 2) width / height (the
    9-column track files, models/common/track_io.py).

    Args:
        origin: where the file's pose sits on the rectangle: ``"centre"`` (this project's
            convention) or ``"corner"`` (the original detector's, tum-vision/articulation:
            the rectangle spans [0, w] x [0, h] in the pose's frame).
    """
    if origin not in ("centre", "corner"):
        raise ValueError(f"origin must be 'centre' or 'corner', got {origin!r}")
    P = np.asarray(poses, float)
    S = np.asarray(sizes, float)
    if P.ndim != 2 or P.shape[1] != 7:
        raise ValueError(f"poses must have shape (n, 7), got {P.shape}")
    if S.shape != (P.shape[0], 2):
        raise ValueError(f"sizes must have shape ({P.shape[0]}, 2), got {S.shape}")
    if not (np.all(np.isfinite(P)) and np.all(np.isfinite(S))):
        raise ValueError("poses / sizes contain NaN or inf")
    nq = np.linalg.norm(P[:, 3:], axis=1)
    if np.any(nq < 1e-9):
        raise ValueError(f"zero quaternion in row {int(np.argmin(nq))}")
    X = np.tile(np.eye(4), (P.shape[0], 1, 1))
    X[:, :3, :3] = Rotation.from_quat(P[:, 3:] / nq[:, None]).as_matrix()
    X[:, :3, 3] = P[:, :3]
    if origin == "corner":
        X = corner_to_centre(X, S[:, 0], S[:, 1])
    return [FrontRectangle(X[i], float(S[i, 0]), float(S[i, 1])) for i in range(len(X))]


@dataclass
class FrontTrackingConfig:
    """Association and track bookkeeping (defaults: the original system's, see module doc).
    Load with ``yaml_load_typed``; :func:`track_frame` validates it again (YAML sets the
    fields after construction).

    Attributes:
        max_distance_m: largest centre distance of a rectangle from a track observation, m.
        max_angle_deg: largest rotation from it after choosing the closest of the 8
            parameterisations, degrees (< 45 keeps the choice unique).
        max_size_diff_m: largest difference of width and of height, m.
        min_observations: a track is published from this many observations on.
        max_observations: observations kept per track (oldest dropped), >= min_observations.
        max_tracks: tracks kept; beyond it the least recently seen unpublished track (else the
            least recently seen track) is forgotten.
        min_precision, min_recall: rectangles below these (Eq. 5.4-5.5) are ignored (the
            detector already accepts at 0.7; 0 keeps all it returns).
        min_side_m: rectangles whose shorter side is below this are ignored, m: a cabinet
            front is larger (the thesis' drawer is 0.125 m high), while the detector also
            returns slivers (gaps, edges, 3-6 cm wide in the kitchen scene) whose plane
            estimate jumps between frames (a strip beside an opening drawer turned over
            the frames, which a revolute model explains).
    """

    max_distance_m: float = param(0.10, unit="m", gt=0)
    max_angle_deg: float = param(20.0, unit="deg", gt=0, lt=45)
    max_size_diff_m: float = param(0.05, unit="m", gt=0)
    min_observations: int = param(5, integer=True, ge=1)
    max_observations: int = param(500, integer=True, ge=1)
    max_tracks: int = param(50, integer=True, ge=1)
    min_precision: float = param(0.0, ge=0, le=1)
    min_recall: float = param(0.0, ge=0, le=1)
    min_side_m: float = param(0.08, unit="m", ge=0)

    def __post_init__(self):
        self.validate()

    def validate(self) -> "FrontTrackingConfig":
        """Raise ValueError naming the first bad field (``max_angle_deg`` < 45: above it two
        of the 8 parameterisations could both pass); return the config."""
        validate_fields(self)
        if self.max_observations < self.min_observations:
            raise ValueError("FrontTrackingConfig: max_observations must be >= min_observations"
                             f" ({self.min_observations}), got {self.max_observations}")
        return self


def _ro(a) -> np.ndarray:
    a = np.asarray(a, float)
    a.setflags(write=False)
    return a


@dataclass(frozen=True)
class FrontTrack:
    """One tracked front: its observations in one consistent parameterisation.

    Immutable (read-only arrays): :func:`track_frame` returns new tracks.

    Attributes:
        track_id: unique id (never reused).
        poses: (n, 7) centre poses x y z qx qy qz qw (quaternion signs continuous), m.
        sizes: (n, 2) width, height in this parameterisation, m.
        times: (n,) observation times, s.
        quality: (n, 2) precision, recall of each detection.
        total: observations ever added (>= n when old ones were dropped).
        rotations: (n, 3, 3) the orientations as matrices (computed from ``poses`` when
            not given; kept for the association).
    """

    track_id: int
    poses: np.ndarray
    sizes: np.ndarray
    times: np.ndarray
    quality: np.ndarray
    total: int
    rotations: np.ndarray | None = None

    def __post_init__(self):
        if self.rotations is None:
            object.__setattr__(self, "rotations",
                               Rotation.from_quat(np.asarray(self.poses, float)[:, 3:]).as_matrix())
        for name in ("poses", "sizes", "times", "quality", "rotations"):
            object.__setattr__(self, name, _ro(getattr(self, name)))

    def __deepcopy__(self, memo):
        return self

    @property
    def n(self) -> int:
        return int(self.poses.shape[0])

    @property
    def last_time(self) -> float:
        return float(self.times[-1])

    def matrices(self) -> np.ndarray:
        """(n, 4, 4) centre poses."""
        X = np.tile(np.eye(4), (self.n, 1, 1))
        X[:, :3, :3] = self.rotations
        X[:, :3, 3] = self.poses[:, :3]
        return X

    def rectangle(self, i: int = -1) -> FrontRectangle:
        """Observation ``i`` as a FrontRectangle (in the track's parameterisation)."""
        X = np.eye(4)
        X[:3, :3] = Rotation.from_quat(self.poses[i, 3:]).as_matrix()
        X[:3, 3] = self.poses[i, :3]
        return FrontRectangle(X, float(self.sizes[i, 0]), float(self.sizes[i, 1]),
                              float(self.quality[i, 0]), float(self.quality[i, 1]))


@dataclass(frozen=True)
class TrackingState:
    """All tracks and counters (immutable; :func:`track_frame` returns a new one).

    Attributes:
        tracks: the current tracks.
        next_id: id of the next new track.
        num_frames: frames processed.
        num_invalid: rectangles rejected as invalid (wrong type, NaN, bad rotation).
        num_duplicates: rectangles dropped as a second detection of a front already
            matched in the same frame.
        num_ignored: valid rectangles ignored by the config's thresholds (precision,
            recall, smallest side).
    """

    tracks: tuple = ()
    next_id: int = 0
    num_frames: int = 0
    num_invalid: int = 0
    num_duplicates: int = 0
    num_ignored: int = 0

    def __deepcopy__(self, memo):
        return self

    def published(self, config: FrontTrackingConfig) -> tuple:
        """The tracks with at least ``config.min_observations`` observations."""
        return tuple(t for t in self.tracks if t.total >= config.min_observations)

    def track(self, track_id: int) -> FrontTrack | None:
        for t in self.tracks:
            if t.track_id == track_id:
                return t
        return None


@dataclass(frozen=True)
class FrameResult:
    """What happened to one frame's rectangles (index = position in the input list).

    Attributes:
        track_ids: track joined or started by each rectangle; -1 = invalid, ignored
            (precision / recall / size thresholds), or a duplicate.
        new_tracks: ids of the tracks started in this frame.
    """

    track_ids: tuple
    new_tracks: tuple


def as_rectangle(r) -> FrontRectangle | None:
    """A valid FrontRectangle (re-validated: a proper rotation, finite, sizes >= 0) or None.
    Accepts FrontRectangle and duck-typed objects with X_WR, width, height."""
    try:
        X = np.asarray(r.X_WR, float)
        w, h = float(r.width), float(r.height)
        p = float(getattr(r, "precision", 1.0))
        q = float(getattr(r, "recall", 1.0))
    except (AttributeError, TypeError, ValueError):
        return None
    if X.shape != (4, 4) or not np.all(np.isfinite(X)):
        return None
    if not (np.isfinite(w) and np.isfinite(h) and w >= 0 and h >= 0 and np.isfinite(p)
            and np.isfinite(q)):
        return None
    R = X[:3, :3]
    if not (np.allclose(R.T @ R, np.eye(3), atol=1e-4) and np.linalg.det(R) > 0):
        return None
    if isinstance(r, FrontRectangle):
        return r
    try:
        return FrontRectangle(X, w, h, p, q)
    except ValueError:
        return None


def _pose7(X: np.ndarray, q_prev: np.ndarray | None) -> np.ndarray:
    q = Rotation.from_matrix(X[:3, :3]).as_quat()
    if q_prev is not None and float(np.dot(q, q_prev)) < 0:
        q = -q
    return np.concatenate([X[:3, 3], q])


def _gate_costs(tracks, rects, cfg: FrontTrackingConfig):
    """Cost (T, k) of each rectangle against each track (inf = outside the gate) and, per
    pair, the index of the best symmetry. Vectorised over all stored observations of all
    tracks; orientations and sizes are compared only where the centres pass the distance
    gate."""
    T, k = len(tracks), len(rects)
    cost = np.full((T, k), np.inf)
    sym = np.zeros((T, k), int)
    if T == 0 or k == 0:
        return cost, sym
    RX = np.stack([r.X_WR for r in rects])  # (k, 4, 4)
    WH = np.array([[r.width, r.height] for r in rects])  # (k, 2)
    P = np.concatenate([t.poses[:, :3] for t in tracks])  # (M, 3)
    owner = np.repeat(np.arange(T), [t.n for t in tracks])  # (M,)
    d = np.linalg.norm(P[:, None] - RX[None, :, :3, 3], axis=-1)  # (M, k)
    mi, ki = np.nonzero(d <= cfg.max_distance_m)
    if mi.size == 0:
        return cost, sym
    R = np.concatenate([t.rotations for t in tracks])[mi]  # (L, 3, 3)
    S = np.concatenate([t.sizes for t in tracks])[mi]  # (L, 2)
    ang = _angles_to(R, RX[ki, :3, :3])  # (L, 8)
    wh = np.where(SWAPS_SIZE[None, :, None], WH[ki][:, None, ::-1], WH[ki][:, None, :])
    ds = np.abs(S[:, None, :] - wh).max(axis=-1)  # (L, 8)
    max_ang = np.deg2rad(cfg.max_angle_deg)
    c = d[mi, ki][:, None] / cfg.max_distance_m + ang / max_ang + ds / cfg.max_size_diff_m
    c = np.where((ang <= max_ang) & (ds <= cfg.max_size_diff_m), c, np.inf)
    j = np.argmin(c, axis=1)
    cb = c[np.arange(c.shape[0]), j]
    ok = np.isfinite(cb)
    if not ok.any():
        return cost, sym
    pair = owner[mi[ok]] * k + ki[ok]
    cb, j = cb[ok], j[ok]
    order = np.lexsort((cb, pair))  # by pair, then cost
    first = order[np.r_[True, pair[order][1:] != pair[order][:-1]]]
    cost.flat[pair[first]] = cb[first]
    sym.flat[pair[first]] = j[first]
    return cost, sym


def _append(t: FrontTrack, r: FrontRectangle, j: int, time: float, cfg) -> FrontTrack:
    X = r.X_WR.copy()
    X[:3, :3] = X[:3, :3] @ RECTANGLE_SYMMETRIES[j]
    wh = (r.height, r.width) if SWAPS_SIZE[j] else (r.width, r.height)
    p7 = _pose7(X, t.poses[-1, 3:])
    keep = cfg.max_observations
    return FrontTrack(t.track_id, np.vstack([t.poses, p7[None]])[-keep:],
                      np.vstack([t.sizes, [wh]])[-keep:], np.append(t.times, time)[-keep:],
                      np.vstack([t.quality, [[r.precision, r.recall]]])[-keep:], t.total + 1,
                      np.concatenate([t.rotations, X[None, :3, :3]])[-keep:])


def _new_track(track_id: int, r: FrontRectangle, time: float) -> FrontTrack:
    return FrontTrack(track_id, _pose7(r.X_WR, None)[None], np.array([[r.width, r.height]]),
                      np.array([time]), np.array([[r.precision, r.recall]]), 1)


def track_frame(state: TrackingState, rectangles, time: float,
                config: FrontTrackingConfig | None = None):
    """Associate one frame's rectangles with the tracks (see the module docstring).

    Args:
        state: the tracks so far.
        rectangles: iterable of FrontRectangle (invalid entries are counted and skipped;
            None or an empty list is a frame without detections).
        time: the frame's time, s.
        config: thresholds (default FrontTrackingConfig()).
    Returns:
        (new TrackingState, FrameResult).
    """
    cfg = config if config is not None else FrontTrackingConfig()
    cfg.validate()
    try:
        items = list(rectangles) if rectangles is not None else []
    except TypeError:
        items = [rectangles]
    valid, idx, invalid, ignored = [], [], 0, 0
    result = [-1] * len(items)
    for i, r in enumerate(items):
        rr = as_rectangle(r)
        if rr is None:
            invalid += 1
            continue
        if (rr.precision < cfg.min_precision or rr.recall < cfg.min_recall
                or min(rr.width, rr.height) < cfg.min_side_m):
            ignored += 1
            continue
        valid.append(rr)
        idx.append(i)
    # best detections first (for duplicates among new tracks)
    order = sorted(range(len(valid)), key=lambda a: -valid[a].precision * valid[a].recall)
    valid = [valid[a] for a in order]
    idx = [idx[a] for a in order]
    tracks = list(state.tracks)
    cost, sym = _gate_costs(tracks, valid, cfg)
    assigned = {}
    if tracks and valid:
        big = 1e6
        C = np.where(np.isfinite(cost), cost, big)
        rows, cols = linear_sum_assignment(C)
        for ti, ri in zip(rows, cols):
            if np.isfinite(cost[ti, ri]):
                assigned[ri] = ti
    dups = 0
    new_ids = []
    next_id = state.next_id
    new_tracks = []
    for ri, r in enumerate(valid):
        if ri in assigned:
            ti = assigned[ri]
            tracks[ti] = _append(tracks[ti], r, int(sym[ti, ri]), time, cfg)
            result[idx[ri]] = tracks[ti].track_id
            continue
        if np.isfinite(cost[:, ri]).any():
            dups += 1  # gates with a track another rectangle of this frame took
            continue
        # a second detection of a front that starts a track in this same frame
        c2, _ = _gate_costs(new_tracks, [r], cfg)
        if np.isfinite(c2).any():
            dups += 1
            continue
        t = _new_track(next_id, r, time)
        new_tracks.append(t)
        new_ids.append(next_id)
        result[idx[ri]] = next_id
        next_id += 1
    tracks.extend(new_tracks)
    if len(tracks) > cfg.max_tracks:
        # forget the least recently seen: unpublished tracks first
        key = sorted(range(len(tracks)), key=lambda a: (
            tracks[a].total >= cfg.min_observations, tracks[a].last_time))
        drop = set(key[:len(tracks) - cfg.max_tracks])
        tracks = [t for a, t in enumerate(tracks) if a not in drop]
    new_state = TrackingState(tuple(tracks), next_id, state.num_frames + 1,
                              state.num_invalid + invalid, state.num_duplicates + dups,
                              state.num_ignored + ignored)
    return new_state, FrameResult(tuple(result), tuple(new_ids))


def track_rectangles(frames, times=None, config: FrontTrackingConfig | None = None,
                     state: TrackingState | None = None) -> TrackingState:
    """Run :func:`track_frame` over a sequence of frames (each a list of rectangles, or a
    single FrontRectangle). ``times`` default to 0, 1, 2, ... s."""
    st = state if state is not None else TrackingState()
    for i, f in enumerate(frames):
        if isinstance(f, FrontRectangle):
            f = [f]
        st, _ = track_frame(st, f, float(i if times is None else times[i]), config)
    return st


# --------------------------------------------------------------------------- link models
#: observation noise for fitting front tracks: the thesis' detector error (< 0.015 m, < 3 deg,
#: Sec. 5.2.1) rounded up; see FrontTracker and the measurements in the module docstring.
FRONT_SIGMA_POS_M = 0.02
FRONT_SIGMA_ORIENT_RAD = float(np.deg2rad(3.0))


def front_observation_model(sigma_pos: float = FRONT_SIGMA_POS_M,
                            sigma_orient: float = FRONT_SIGMA_ORIENT_RAD):
    """The ObservationModel for front tracks (sigma_pos m, sigma_orient rad)."""
    from mmlearn.models.articulation.link import ObservationModel
    return ObservationModel(sigma_pos=sigma_pos, sigma_orient=sigma_orient)


@dataclass(frozen=True)
class TrackModel:
    """The link model learned from one track (the track's pose in the world frame: the world
    is the fixed part).

    Attributes:
        track_id: the track.
        n: observations it was fitted to.
        selected: name of the selected model ("rigid", "prismatic", "revolute", "gp").
        model: the fitted LinkModel (not mutated after the fit).
        bic: candidate name -> BIC.
        demoted: candidates not selectable (motion below the noise), name -> reason.
    """

    track_id: int
    n: int
    selected: str
    model: object
    bic: dict
    demoted: dict

    def __deepcopy__(self, memo):
        return self


def fit_track_model(poses, *, track_id: int = -1, obs=None, models=None, rng=None) -> TrackModel:
    """Select a link model for one track ((n, 7) centre poses) by BIC (models/articulation*).
    ``obs`` defaults to :func:`front_observation_model`. Raises ValueError if nothing fits."""
    from mmlearn.models.articulation.structure import DEFAULT_CANDIDATES, select_link_model
    obs = obs if obs is not None else front_observation_model()
    sel = select_link_model(np.asarray(poses, float), models=models or DEFAULT_CANDIDATES,
                            obs=obs, rng=rng)
    return TrackModel(int(track_id), int(len(poses)), sel.selected, sel.best, dict(sel.bic),
                      dict(sel.demoted))


def selection_vs_observations(poses, *, expected: str, ns=None, obs=None, models=None,
                              seed: int = 0) -> dict:
    """Model selection on the first n observations of a track, for each n in ``ns``.

    Args:
        poses: (N, 7) track.
        expected: the right model's name.
        ns: prefix lengths (default 3, 4, ..., N).
        obs: ObservationModel (default :func:`front_observation_model`).
        seed: MLESAC seed (the same for every prefix).
    Returns:
        {"n": [...], "selected": [...], "model_right_from": first n from which every
        evaluated prefix selects ``expected`` (None if the last one does not),
        "heldout_pos_error_m" / "heldout_orient_error_rad": per n, the errors of the selected
        model's prediction f(f^-1(z)) on the observations after the prefix (NaN for n = N)}.
    """
    P = np.asarray(poses, float)
    N = P.shape[0]
    ns = list(range(3, N + 1)) if ns is None else [int(n) for n in ns]
    sel, ep, eo = [], [], []
    for n in ns:
        try:
            tm = fit_track_model(P[:n], obs=obs, models=models, rng=seed)
        except ValueError:
            sel.append(None)
            ep.append(np.nan)
            eo.append(np.nan)
            continue
        sel.append(tm.selected)
        if n < N:
            a, b = tm.model.prediction_errors(P[n:])
            ep.append(a)
            eo.append(np.nan if b is None else b)
        else:
            ep.append(np.nan)
            eo.append(np.nan)
    right_from = None
    for i in range(len(ns) - 1, -1, -1):
        if sel[i] != expected:
            break
        right_from = ns[i]
    return {"n": ns, "selected": sel, "model_right_from": right_from,
            "heldout_pos_error_m": ep, "heldout_orient_error_rad": eo}


def simulate_front_rectangles(kind: str, n: int, *, rng=None, travel: float | None = None,
                              width: float = 0.395, height: float | None = None,
                              sigma_pos: float = 0.01, sigma_orient: float = np.deg2rad(2.0),
                              parameterisations: int = 4, X_WO=None) -> list:
    """Synthetic detections of a moving front (tests, experiments): n rectangles along one
    opening motion, with Gaussian noise and a random parameterisation each.

    The object frame O: the closed front lies in O's xz plane, centred at x = width / 2
    (a door's hinge is O's z axis), its normal -y (towards a camera on O's -y side);
    a drawer moves along -y, a door turns about +z (opening towards -y).

    Args:
        kind: "drawer", "door" or "rigid".
        n: number of rectangles.
        rng: numpy Generator or seed.
        travel: total opening, m (drawer, default 0.3) or rad (door, default 1.4).
        width, height: the front's size, m (height default 0.125 drawer / 0.58 door).
        sigma_pos: position noise per axis, m; sigma_orient: rotation noise per axis, rad.
        parameterisations: each rectangle is given in one of the first ``parameterisations``
            of RECTANGLE_SYMMETRIES, chosen at random (4: z towards the camera, like the
            detector; 8: either side; 1: always the same).
        X_WO: (4, 4) pose of O in the world (default identity).
    Returns:
        list of n FrontRectangle (the width / height swapped where the parameterisation says).
    """
    if kind not in ("drawer", "door", "rigid"):
        raise ValueError(f"kind must be 'drawer', 'door' or 'rigid', got {kind!r}")
    if not 1 <= int(parameterisations) <= 8:
        raise ValueError("parameterisations must be in 1..8")
    rng = np.random.default_rng(rng)
    h = height if height is not None else (0.125 if kind == "drawer" else 0.58)
    if travel is None:
        travel = 0.3 if kind == "drawer" else 1.4
    s = np.linspace(0.0, travel, int(n)) if kind != "rigid" else np.zeros(int(n))
    R0 = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # x, y=+z, z=-y
    X_WO = np.eye(4) if X_WO is None else np.asarray(X_WO, float)
    out = []
    for si in s:
        X = np.eye(4)
        if kind == "door":
            Rz = Rotation.from_rotvec([0.0, 0.0, si]).as_matrix()
            X[:3, :3] = Rz @ R0
            X[:3, 3] = Rz @ [0.5 * width, 0.0, 0.0]
        else:
            X[:3, :3] = R0
            X[:3, 3] = [0.5 * width, -si, 0.0]
        X = X_WO @ X
        X[:3, 3] += rng.normal(0.0, sigma_pos, 3)
        X[:3, :3] = Rotation.from_rotvec(rng.normal(0.0, sigma_orient, 3)).as_matrix() @ X[:3, :3]
        j = int(rng.integers(0, parameterisations))
        X[:3, :3] = X[:3, :3] @ RECTANGLE_SYMMETRIES[j]
        w, hh = (h, width) if SWAPS_SIZE[j] else (width, h)
        out.append(FrontRectangle(X, w, hh))
    return out


def align_track(rectangles) -> list:
    """One file's rectangles as one track: every rectangle re-parameterised to the one of its
    8 parameterisations closest to the previous (aligned) rectangle, without gating (a
    recorded track is already associated; its steps may exceed the tracker's gates when
    it was sub-sampled)."""
    out = []
    for r in rectangles:
        if out:
            X, w, h, _ = align_rectangle(out[-1].X_WR, r.X_WR, r.width, r.height)
            r = FrontRectangle(X, w, h, r.precision, r.recall)
        out.append(r)
    return out


def axis_errors(model, rectangles) -> dict:
    """Geometry of a fitted model against the rectangles it was fitted to (no ground truth
    needed): a door's hinge lies along one of the front's edges, a drawer moves along the
    front's normal.

    Returns:
        {"axis_error_deg": revolute: angle between the rotation axis and the nearer of the
        rectangle's mean x / y edge directions; prismatic: angle between the axis and the
        mean normal; None otherwise, "hinge_edge": "x" / "y" (revolute), "half_size_m": half
        the mean extent across the hinge (revolute: the centre's radius if the hinge is on
        the far edge), "radius_m" (revolute)}.
    """
    X = np.stack([r.X_WR for r in rectangles])
    sizes = np.array([[r.width, r.height] for r in rectangles])
    mean_axes = []
    for k in range(3):
        v = X[:, :3, k].mean(axis=0)
        mean_axes.append(v / max(np.linalg.norm(v), 1e-12))
    out = {"axis_error_deg": None}
    if model.name == "revolute":
        a = np.asarray(model.axis, float)
        ang = [np.degrees(np.arccos(min(1.0, abs(float(a @ e))))) for e in mean_axes[:2]]
        k = int(np.argmin(ang))
        out.update(axis_error_deg=float(ang[k]), hinge_edge="xy"[k],
                   half_size_m=float(0.5 * sizes[:, 1 - k].mean()),
                   radius_m=float(model.radius))
    elif model.name == "prismatic":
        a = np.asarray(model.axis, float)
        out["axis_error_deg"] = float(np.degrees(np.arccos(min(1.0, abs(float(a @ mean_axes[2]))))))
    return out


def cross_validated_errors(poses, model_name: str, *, obs=None, folds: int = 5,
                           seed: int = 0) -> tuple:
    """Prediction errors of ``model_name`` by k-fold cross-validation (interleaved folds:
    observation i is in fold i mod k): mean over the held-out observations of the position
    (m) and orientation (rad) error of f(f^-1(z)). Folds whose fit fails are skipped;
    (nan, nan) if all fail."""
    from mmlearn.models.articulation.link import make_model
    P = np.asarray(poses, float)
    obs = obs if obs is not None else front_observation_model()
    ep, eo, cnt = 0.0, 0.0, 0
    for k in range(int(folds)):
        test = np.arange(P.shape[0]) % folds == k
        if test.sum() == 0 or (~test).sum() < 3:
            continue
        m = make_model(model_name, obs=obs)
        try:
            m.fit(P[~test], rng=seed)
        except ValueError:
            continue
        a, b = m.prediction_errors(P[test])
        ep += a * test.sum()
        eo += (0.0 if b is None else b) * test.sum()
        cnt += int(test.sum())
    if cnt == 0:
        return float("nan"), float("nan")
    return ep / cnt, eo / cnt


def subsampled_selection(poses, *, expected: str, n_sample: int = 60, repeats: int = 50,
                         ns=None, obs=None, seed: int = 0, progress=None) -> dict:
    """The protocol of thesis Sec. 5.2.2: draw ``n_sample`` observations uniformly from the
    track (kept in temporal order), select a model on the first n of them for each n in
    ``ns`` (default 5, 10, ..., n_sample), repeat ``repeats`` times.

    Returns:
        {"n": ns, "right_fraction": per n the share of repeats that select ``expected``,
        "selected_counts": per n {model: count}, "model_right_from": per repeat the first n
        from which every later n selects ``expected`` (None if the last does not),
        "heldout_pos_error_m" / "heldout_orient_error_rad": per n the mean over repeats of
        the error on the drawn observations after the first n (NaN at n = n_sample)}.
    """
    P = np.asarray(poses, float)
    n_sample = min(int(n_sample), P.shape[0])
    ns = list(range(5, n_sample + 1, 5)) if ns is None else [int(n) for n in ns]
    rng = np.random.default_rng(seed)
    right = np.zeros(len(ns))
    counts = [dict() for _ in ns]
    ep = np.zeros(len(ns))
    eo = np.zeros(len(ns))
    nerr = np.zeros(len(ns))
    first = []
    for r in range(int(repeats)):
        idx = np.sort(rng.choice(P.shape[0], n_sample, replace=False))
        res = selection_vs_observations(P[idx], expected=expected, ns=ns, obs=obs, seed=seed + r)
        first.append(res["model_right_from"])
        for i, name in enumerate(res["selected"]):
            counts[i][str(name)] = counts[i].get(str(name), 0) + 1
            right[i] += name == expected
            if np.isfinite(res["heldout_pos_error_m"][i]):
                ep[i] += res["heldout_pos_error_m"][i]
                eo[i] += res["heldout_orient_error_rad"][i]
                nerr[i] += 1
        if progress is not None:
            progress(r)
    with np.errstate(invalid="ignore", divide="ignore"):
        return {"n": ns, "right_fraction": (right / max(int(repeats), 1)).tolist(),
                "selected_counts": counts, "model_right_from": first,
                "heldout_pos_error_m": (ep / nerr).tolist(),
                "heldout_orient_error_rad": (eo / nerr).tolist()}
