"""ArUco marker detection and pose estimation in one colour image (OpenCV, no Drake systems).

:func:`detect_marker_poses` finds the markers of an ArUco dictionary in an image
(``cv2.aruco.ArucoDetector``, sub-pixel corner refinement) and estimates each marker's pose
in the camera frame with ``cv2.solvePnPGeneric`` (``SOLVEPNP_IPPE_SQUARE``: the planar
square solver, which returns the two mirror solutions of a square; the one with the smaller
reprojection error is kept).

Frames: the camera frame C is the OpenCV / Drake camera frame (x right, y down, z along the
optical axis); the marker frame M has its origin at the marker's centre, x to the right of
the printed marker, y up and z out of the printed face (towards a camera that sees it).
"""


import math
from dataclasses import dataclass

import numpy as np

from mmlearn.models.common.config import param, validate_fields

__all__ = ["DepthMirrorTest", "DetectorConfig", "MarkerDetections", "detect_marker_poses",
           "make_detector", "mirror_test_from_depth"]

_REFINE = {"edges": "CORNER_REFINE_SUBPIX", "subpix": "CORNER_REFINE_SUBPIX",
           "contour": "CORNER_REFINE_CONTOUR", "apriltag": "CORNER_REFINE_APRILTAG",
           "none": "CORNER_REFINE_NONE"}


@dataclass
class DetectorConfig:
    """How markers are detected and which detections are kept.

    Attributes:
        corner_refinement: "edges" (OpenCV's sub-pixel refinement, then
            :func:`refine_corners_by_edges`: straight lines fitted to the sub-pixel
            positions of the black border's outer edge, corners where they meet),
            "subpix" (``cv2.cornerSubPix`` on the corners only), "contour", "apriltag" or
            "none". OpenCV's own refinements leave the corners of small rendered markers
            a fraction of a pixel inside the border (a scale error of small markers,
            measured by ``benchmarks/bench_camera_marker_sensor.py``); "edges" removes most
            of it.
        refine_window_px: half size of the sub-pixel refinement window, pixels (OpenCV's
            ``cornerRefinementWinSize``); keep it below half a module of the smallest
            marker in the image.
        refine_max_iterations: iterations of the corner refinement.
        refine_min_accuracy: stop the refinement when a corner moves less, pixels.
        min_side_px: detections whose mean side is shorter are dropped, pixels (their pose,
            in particular the orientation, is too uncertain).
        max_reprojection_px: detections whose RMS corner reprojection error after solvePnP
            exceeds this are dropped, pixels.
        min_border_px: detections with a corner closer than this to the image border are
            dropped (a marker partly outside the image), pixels.
        min_ambiguity_ratio: a square's pose from four corners has two solutions (the
            marker tilted one way or the mirror way); a detection whose worse solution does
            not reproject at least this many times worse than the better one, while the two
            differ by more than ``ambiguity_angle_deg`` in orientation, is dropped (1 = keep
            all). Small, far markers are often ambiguous and then flip by tens of degrees.
        ambiguity_angle_deg: see ``min_ambiguity_ratio``, degrees.
    """

    corner_refinement: str = param("edges", choices=tuple(_REFINE))
    refine_window_px: int = param(2, unit="px", integer=True, ge=1)
    refine_max_iterations: int = param(50, integer=True, ge=1)
    refine_min_accuracy: float = param(0.01, unit="px", ge=0)
    min_side_px: float = param(10.0, unit="px", ge=0)
    max_reprojection_px: float = param(1.5, unit="px", ge=0)
    min_border_px: float = param(2.0, unit="px", ge=0)
    min_ambiguity_ratio: float = param(1.0, ge=0)
    ambiguity_angle_deg: float = param(10.0, unit="deg", ge=0)

    def validate(self) -> None:
        validate_fields(self)


@dataclass
class MarkerDetections:
    """The markers found in one image.

    Attributes:
        ids: ArUco ids (n,), each at most once.
        T_CM: marker poses in the camera frame (n, 4, 4), metres.
        corners: refined image corners (n, 4, 2), pixels, in ArUco order (top-left,
            top-right, bottom-right, bottom-left of the printed marker).
        side_px: mean side length in the image (n,), pixels.
        reprojection_px: RMS corner reprojection error of the kept solution (n,), pixels.
        ambiguity: reprojection error of the other solution over the kept one's (n,)
            (large = unambiguous).
        T_CM_other: the other (mirror) solution of each marker (n, 4, 4); a copy of T_CM
            where the solver returned only one.
    """

    ids: np.ndarray
    T_CM: np.ndarray
    corners: np.ndarray
    side_px: np.ndarray
    reprojection_px: np.ndarray
    ambiguity: np.ndarray
    T_CM_other: np.ndarray = None

    def __post_init__(self):
        if self.T_CM_other is None:
            self.T_CM_other = np.array(self.T_CM, float, copy=True)

    def __len__(self) -> int:
        return int(self.ids.size)

    @staticmethod
    def empty() -> "MarkerDetections":
        return MarkerDetections(np.zeros(0, int), np.zeros((0, 4, 4)), np.zeros((0, 4, 2)),
                                np.zeros(0), np.zeros(0), np.zeros(0))


def make_detector(dictionary_name: str, config: DetectorConfig | None = None):
    """A ``cv2.aruco.ArucoDetector`` for the dictionary with the configured refinement."""
    import cv2

    cfg = config or DetectorConfig()
    cfg.validate()
    if not (isinstance(dictionary_name, str) and dictionary_name.startswith("DICT_")
            and hasattr(cv2.aruco, dictionary_name)):
        raise ValueError(f"unknown ArUco dictionary {dictionary_name!r} (e.g. DICT_4X4_50)")
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = getattr(cv2.aruco, _REFINE[cfg.corner_refinement])
    params.cornerRefinementWinSize = int(cfg.refine_window_px)
    params.cornerRefinementMaxIterations = int(cfg.refine_max_iterations)
    params.cornerRefinementMinAccuracy = float(cfg.refine_min_accuracy)
    return cv2.aruco.ArucoDetector(
        cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary_name)), params)


def _grey(image) -> np.ndarray:
    img = np.asarray(image)
    if img.ndim == 3 and img.shape[2] in (3, 4):
        if img.dtype != np.uint8:
            raise ValueError(f"colour image must be uint8, got {img.dtype}")
        rgb = img[..., :3].astype(np.float32)
        return np.clip(rgb @ np.array([0.299, 0.587, 0.114], np.float32) + 0.5, 0,
                       255).astype(np.uint8)
    if img.ndim == 2 or (img.ndim == 3 and img.shape[2] == 1):
        img = img.reshape(img.shape[0], img.shape[1])
        if img.dtype != np.uint8:
            raise ValueError(f"grey image must be uint8, got {img.dtype}")
        return np.ascontiguousarray(img)
    raise ValueError(f"image must be (H, W), (H, W, 3) or (H, W, 4), got shape {img.shape}")


def detect_marker_poses(image, K, *, marker_size: float, detector,
                        config: DetectorConfig | None = None,
                        ids: "set[int] | None" = None) -> MarkerDetections:
    """Detect markers in ``image`` and estimate their poses in the camera frame.

    Args:
        image: (H, W, 3|4) uint8 RGB(A) or (H, W) uint8 grey image.
        K: (3, 3) pinhole intrinsic matrix, pixels (no lens distortion).
        marker_size: outer edge of the markers' black border, m.
        detector: from :func:`make_detector`.
        config: the filters (min_side_px, max_reprojection_px, min_border_px).
        ids: report only these ids (None = every id of the dictionary).

    An id found more than once in the image is dropped altogether (the markers are unique,
    so one of the detections is wrong and we cannot tell which).

    Raises:
        ValueError: on a malformed image, K or marker size.
    """
    import cv2

    cfg = config or DetectorConfig()
    grey = _grey(image)
    K = np.asarray(K, float)
    if K.shape != (3, 3) or not np.all(np.isfinite(K)) or K[0, 0] <= 0 or K[1, 1] <= 0:
        raise ValueError(f"K must be a finite (3, 3) intrinsic matrix with positive focal "
                         f"lengths, got {K!r}")
    if not (math.isfinite(marker_size) and marker_size > 0):
        raise ValueError(f"marker_size must be > 0 m, got {marker_size}")
    h, w = grey.shape
    if h < 8 or w < 8:
        return MarkerDetections.empty()
    corners, found, _ = detector.detectMarkers(grey)
    if found is None or len(found) == 0:
        return MarkerDetections.empty()
    found = np.asarray(found).ravel().astype(int)
    C = np.asarray(corners, float).reshape(-1, 4, 2)
    if cfg.corner_refinement == "edges":
        C = refine_corners_by_edges(grey, C)
    keep = np.ones(found.size, bool)
    if ids is not None:
        keep &= np.isin(found, list(ids))
    uniq, counts = np.unique(found, return_counts=True)
    keep &= ~np.isin(found, uniq[counts > 1])
    side = np.linalg.norm(C - np.roll(C, -1, axis=1), axis=2).mean(axis=1)
    keep &= side >= cfg.min_side_px
    b = cfg.min_border_px
    keep &= np.all((C[..., 0] >= b) & (C[..., 0] <= w - 1 - b)
                   & (C[..., 1] >= b) & (C[..., 1] <= h - 1 - b), axis=1)
    s = 0.5 * marker_size
    obj = np.array([[-s, s, 0], [s, s, 0], [s, -s, 0], [-s, -s, 0]], float)
    out_ids, out_T, out_c, out_side, out_err, out_amb, out_T2 = [], [], [], [], [], [], []
    for i in np.flatnonzero(keep):
        try:
            n, rvecs, tvecs, errs = cv2.solvePnPGeneric(
                obj, C[i], K, None, flags=cv2.SOLVEPNP_IPPE_SQUARE)
        except cv2.error:
            continue
        if not n:
            continue
        errs = np.asarray(errs, float).ravel()
        k = int(np.argmin(errs))
        if not (np.isfinite(errs[k]) and errs[k] <= cfg.max_reprojection_px):
            continue
        other = np.delete(errs, k)
        amb = float(other.min() / max(errs[k], 1e-9)) if other.size else np.inf
        R, _ = cv2.Rodrigues(np.asarray(rvecs[k], float))
        t = np.asarray(tvecs[k], float).ravel()
        if not (np.all(np.isfinite(R)) and np.all(np.isfinite(t))) or t[2] <= 0:
            continue
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R, t
        T2 = T.copy()
        if other.size:
            k2 = int(np.argsort(errs)[1])
            R2, _ = cv2.Rodrigues(np.asarray(rvecs[k2], float))
            t2 = np.asarray(tvecs[k2], float).ravel()
            if np.all(np.isfinite(R2)) and np.all(np.isfinite(t2)):
                T2[:3, :3], T2[:3, 3] = R2, t2
        if amb < cfg.min_ambiguity_ratio:
            c = float(np.clip((np.trace(R.T @ T2[:3, :3]) - 1) / 2, -1, 1))
            if math.degrees(math.acos(c)) > cfg.ambiguity_angle_deg:
                continue
        out_ids.append(found[i])
        out_T.append(T)
        out_c.append(C[i])
        out_side.append(side[i])
        out_err.append(errs[k])
        out_amb.append(amb)
        out_T2.append(T2)
    if not out_ids:
        return MarkerDetections.empty()
    return MarkerDetections(np.array(out_ids, int), np.array(out_T), np.array(out_c),
                            np.array(out_side), np.array(out_err), np.array(out_amb),
                            np.array(out_T2))


def refine_corners_by_edges(grey, corners, *, samples_per_px: float = 1.0,
                            min_contrast: float = 25.0) -> np.ndarray:
    """Refine marker corners by fitting lines to the outer edge of the black border.

    For every side of every quad, intensity profiles are sampled (bilinear) across the side
    at ``samples_per_px`` positions per pixel of its length (the middle 70 %, away from
    the corners), from 0.45 modules inside to 0.75 modules outside (a module = side / 6 of a
    4x4 marker, at least 0.8 px), where the profile crosses half-way between its darkest and
    brightest value is the edge's sub-pixel position. A total-least-squares line through
    those positions per side; the corners are the intersections of adjacent lines. A quad
    with a side of fewer than 3 usable profiles (contrast below ``min_contrast`` grey levels)
    keeps its corners.

    Args:
        grey: (H, W) uint8 image.
        corners: (n, 4, 2) corners in pixels, in order around the quad.
    Returns:
        (n, 4, 2) refined corners.
    """
    import cv2

    C = np.asarray(corners, float).reshape(-1, 4, 2)
    n = C.shape[0]
    if n == 0:
        return C.copy()
    img = np.asarray(grey, np.float32)
    out = C.copy()
    centre = C.mean(axis=1)  # (n, 2)
    side = np.linalg.norm(C - np.roll(C, -1, axis=1), axis=2)  # (n, 4)
    module = np.maximum(side.mean(axis=1) / 6.0, 0.8)  # px
    J = 25
    prof = np.linspace(-0.45, 0.75, J)  # offsets across the edge, modules (+ = outward)
    for i in range(n):
        lines = []
        for s in range(4):
            a, b = C[i, s], C[i, (s + 1) % 4]
            d = b - a
            L = float(np.linalg.norm(d))
            if L < 3:
                break
            d /= L
            nrm = np.array([-d[1], d[0]])
            if np.dot(nrm, 0.5 * (a + b) - centre[i]) < 0:
                nrm = -nrm
            m = max(5, int(L * 0.7 * samples_per_px))
            t = np.linspace(0.15, 0.85, m) * L
            o = prof * module[i]
            P = a[None, None, :] + t[:, None, None] * d + o[None, :, None] * nrm  # (m, J, 2)
            vals = cv2.remap(img, P[..., 0].astype(np.float32), P[..., 1].astype(np.float32),
                             cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
            lo, hi = vals.min(axis=1), vals.max(axis=1)
            thr = 0.5 * (lo + hi)
            up = (vals[:, :-1] < thr[:, None]) & (vals[:, 1:] >= thr[:, None])
            ok = up.any(axis=1) & (hi - lo >= min_contrast)
            # the crossing closest to the rough edge (offset 0)
            cand = np.where(up, np.abs(0.5 * (o[:-1] + o[1:]))[None, :], np.inf)
            j = np.argmin(cand, axis=1)
            rows = np.arange(m)
            v0, v1 = vals[rows, j], vals[rows, j + 1]
            frac = np.clip((thr - v0) / np.maximum(v1 - v0, 1e-6), 0.0, 1.0)
            off = o[j] + frac * (o[j + 1] - o[j])
            pts = a + t[:, None] * d + off[:, None] * nrm
            pts = pts[ok]
            if len(pts) < 3:
                break
            mu = pts.mean(axis=0)
            _, _, Vt = np.linalg.svd(pts - mu, full_matrices=False)
            lines.append((mu, Vt[0]))
        if len(lines) != 4:
            continue
        new = np.empty((4, 2))
        good = True
        for s in range(4):
            (p1, d1), (p2, d2) = lines[(s - 1) % 4], lines[s]
            A = np.column_stack([d1, -d2])
            if abs(np.linalg.det(A)) < 1e-6:
                good = False
                break
            u = np.linalg.solve(A, p2 - p1)
            new[s] = p1 + u[0] * d1
        # corner s is where side s-1 (corner s-1 -> s) meets side s (corner s -> s+1)
        if good and np.all(np.isfinite(new)) and np.max(np.abs(new - C[i])) < 0.5 * module[i] + 1:
            out[i] = new
    return out


@dataclass
class DepthMirrorTest:
    """Which of a square marker's two pose solutions the depth image supports
    (:func:`mirror_test_from_depth`).

    Attributes:
        n_points: depth pixels used (inside the shrunk square, finite, on the plane).
        chi2: (2,) robust chi-square of each solution's plane against the depth pixels
            (with its distance from the camera left free), in units of the noise.
        chi2_plane: the same for the best-fitting free plane (3 parameters).
        log_ratio: ``(chi2[1] - chi2[0]) / 2``: the log-likelihood ratio of solution 0 over
            solution 1 (> 0 favours solution 0).
        angle_deg: (2,) angle between each solution's normal and the free plane's, degrees.
        sigma_depth_m: the depth noise estimated from the free plane's residuals (robust,
            at least the floor), m at the marker's depth.
    """

    n_points: int
    chi2: np.ndarray
    chi2_plane: float
    log_ratio: float
    angle_deg: np.ndarray
    sigma_depth_m: float

    def choice(self, *, min_log_ratio: float, max_angle_deg: float,
               max_excess_chi2: float) -> "int | None":
        """0 or 1: the solution the depth decides for; -1: neither (the better one is both
        more than ``max_angle_deg`` off the seen plane and inconsistent with the depth
        pixels, its chi-square above the free plane's by more than ``max_excess_chi2``);
        None: undecided (``|log_ratio| < min_log_ratio``)."""
        j = 0 if self.log_ratio >= 0 else 1
        if (self.angle_deg[j] > max_angle_deg
                and self.chi2[j] - self.chi2_plane > max_excess_chi2):
            return -1
        if abs(self.log_ratio) < min_log_ratio:
            return None
        return j


def quad_depth_pixels(depth, corners, *, shrink: float = 0.7, min_points: int = 30):
    """The valid depth pixels inside a detected marker: ``(u, v, z)`` (column, row, depth in
    m) of the pixels inside the marker's quad shrunk towards its centre by ``shrink``, or
    None when fewer than ``min_points`` have a measurement (NaN, inf or <= 0 = none) or the
    corners are not finite. ``depth``: (H, W) or (H, W, 1) image, m; ``corners``: (4, 2)
    pixels."""
    import cv2

    depth = np.asarray(depth)
    if depth.ndim == 3 and depth.shape[2] == 1:
        depth = depth[..., 0]
    if depth.ndim != 2:
        raise ValueError(f"depth must be (H, W), got shape {depth.shape}")
    c = np.asarray(corners, float).reshape(4, 2)
    if not np.all(np.isfinite(c)):
        return None
    centre = c.mean(axis=0)
    q = centre + shrink * (c - centre)
    h, w = depth.shape
    x0, y0 = np.floor(q.min(axis=0)).astype(int)
    x1, y1 = np.ceil(q.max(axis=0)).astype(int)
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w - 1), min(y1, h - 1)
    if x1 <= x0 or y1 <= y0:
        return None
    mask = np.zeros((y1 - y0 + 1, x1 - x0 + 1), np.uint8)
    cv2.fillConvexPoly(mask, np.round(q - [x0, y0]).astype(np.int32), 1)
    v, u = np.nonzero(mask)
    u, v = u + x0, v + y0
    z = np.asarray(depth[v, u], float)
    ok = np.isfinite(z) & (z > 0)
    if ok.sum() < min_points:
        return None
    return u[ok], v[ok], z[ok]


def mirror_test_from_depth(depth, corners, K, T_a, T_b, *, shrink: float = 0.7,
                           min_points: int = 30, sigma_floor_m: float = 2e-4,
                           clip_sigmas: float = 3.0) -> "DepthMirrorTest | None":
    """Compare the two mirror pose solutions of a marker by how well their planes predict
    the depth pixels inside the detected square (None when too few valid pixels).

    Works in inverse depth ``w = 1 / z``: a plane n . P = c seen through the normalised
    pixel ray d = (x, y, 1) has ``w = (n . d) / c``, linear in (x, y); an active
    triangulation camera measures disparity ``f b w``, so its noise is constant in ``w``.
    Each solution's plane (its normal from the PnP pose) is fitted with its distance free
    (``w ~ alpha (n . d)``, one parameter: a range error of the PnP pose does not count),
    the free plane with three (``w ~ a x + b y + e``). The noise ``sigma_w`` is estimated
    from the free plane's residuals (1.4826 x their median absolute value, not below
    ``sigma_floor_m / z^2``); pixels farther than ``clip_sigmas`` sigma from the free plane
    (holes' edges, an occluder) are left out, and each residual's square is clipped at
    ``clip_sigmas^2``. With exact (rendered) depth the floor sets the scale and the
    comparison is as sharp as the old normal-angle gate; with noisy depth a tilt
    difference the noise cannot resolve gives a small ``log_ratio`` instead of a wrong
    choice.

    Args:
        depth: (H, W) depth image, m (NaN, inf or <= 0 = no measurement).
        corners: (4, 2) image corners of the marker, pixels.
        K: (3, 3) intrinsics, pixels.
        T_a, T_b: (4, 4) the two pose solutions of the marker in the camera frame (z out
            of the marker's face).
        shrink: the quad is shrunk towards its centre by this factor first (keeps the
            pixels off the marker's border and its carrier's edges).
        min_points: fewest valid depth pixels for a test.
        sigma_floor_m: the smallest depth noise assumed, m (rendered depth is exact up to
            float rounding; a PnP tilt error of ~1 deg moves the depth inside a 0.04 m
            square by ~0.2 mm).
        clip_sigmas: residuals are clipped at this many sigma (robust chi-square).
    """

    K = np.asarray(K, float)
    pix = quad_depth_pixels(depth, corners, shrink=shrink, min_points=min_points)
    if pix is None:
        return None
    u, v, z = pix
    x = (u - K[0, 2]) / K[0, 0]
    y = (v - K[1, 2]) / K[1, 1]
    wv = 1.0 / z
    A = np.column_stack([x, y, np.ones_like(x)])
    z_med = float(np.median(z))
    floor_w = sigma_floor_m / z_med ** 2
    # free plane, then once more on the points near it
    coef = np.linalg.lstsq(A, wv, rcond=None)[0]
    r = wv - A @ coef
    sig = max(1.4826 * float(np.median(np.abs(r))), floor_w)
    inl = np.abs(r) <= clip_sigmas * sig
    if inl.sum() < min_points:
        return None
    A, wv = A[inl], wv[inl]
    coef = np.linalg.lstsq(A, wv, rcond=None)[0]
    r = wv - A @ coef
    sig = max(1.4826 * float(np.median(np.abs(r))), floor_w)
    cap = clip_sigmas ** 2

    def chi2(res):
        return float(np.minimum((res / sig) ** 2, cap).sum())

    n_free = -coef / np.linalg.norm(coef)  # towards the camera (w > 0 on the points)
    chis, angs = np.zeros(2), np.zeros(2)
    for k, T in enumerate((T_a, T_b)):
        n = np.asarray(T, float)[:3, 2]
        g = A @ n
        alpha = float(g @ wv) / max(float(g @ g), 1e-300)
        chis[k] = chi2(wv - alpha * g)
        angs[k] = math.degrees(math.acos(float(np.clip(n @ n_free, -1.0, 1.0))))
    return DepthMirrorTest(n_points=int(inl.sum()), chi2=chis, chi2_plane=chi2(r),
                           log_ratio=float(chis[1] - chis[0]) / 2, angle_deg=angs,
                           sigma_depth_m=float(sig * z_med ** 2))
