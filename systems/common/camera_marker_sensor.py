"""CameraMarkerSensor: marker observations read from rendered colour images (ArUco).

A drop-in alternative to :class:`~mmlearn.systems.common.marker_sensor.MarkerSensor`: the same
``observations`` output (:class:`~mmlearn.systems.common.observations.MarkerObservations`) and
``stats`` output, but the poses come from real images: one or more Drake ``RgbdSensor``
colour images (RenderEngineVtk) of the scene whose marker squares carry ArUco textures
(``mmlearn.diagrams.common.marker_camera.AddArucoMarkers``). Each frame, every image is searched
with OpenCV's ArUco detector (sub-pixel corner refinement), each marker's pose in the camera
frame comes from ``solvePnP`` (IPPE_SQUARE) and is taken to the world with the camera's pose.
A marker seen by several cameras: the two solutions of each camera (a small square's pose is
ambiguous between two mirror tilts) are matched across the cameras, the best agreeing
choice is used (from the camera in which the marker looks largest), and a marker whose
cameras disagree by more than ``max_disagreement_deg`` is not reported. A small square seen
from 2 m is nearly always ambiguous, and its better solution is the mirror tilt (tens of
degrees off) in about a tenth of the detections: with ``use_depth`` (default) the camera's
depth image decides, by how well each solution's plane predicts the depth pixels inside the
square (noise-aware, so that a structured-light camera's noisy depth, ``depth_noise``,
works too). Without depth, or when the depth cannot tell, a marker seen by one camera only
is reported as detected when its mirror solution reprojects clearly worse
(``min_unambiguous_ratio``); an ambiguous
one takes the solution nearer to its last report (``track_max_age_s``,
``track_max_angle_deg``; the reports live in the Context's discrete state) or is not
reported.

There is no noise model: the noise is what rendering, pixel quantisation and the detector
make of the geometry (see ``benchmarks/bench_camera_marker_sensor.py`` for its size against
distance and viewing angle). Visibility is physical: a marker is reported when it is in some
image, large enough, not cut by the image border and not occluded so that its pattern
cannot be decoded. ``outlier`` is always False (the sensor cannot know).
"""


import itertools
import math
from dataclasses import dataclass

import cv2
import numpy as np

from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.systems.framework import EventStatus, LeafSystem
from pydrake.systems.sensors import ImageDepth32F, ImageRgba8U

from mmlearn.models.common.config import param, validate_fields
from mmlearn.models.common.depth_noise import DepthNoiseConfig
from mmlearn.models.common.marker_detection import (DetectorConfig, MarkerDetections, quad_depth_pixels,
                                                    detect_marker_poses, make_detector,
                                                    mirror_test_from_depth)
from mmlearn.models.common.se3 import project_to_so3
from mmlearn.sdf.aruco import ArucoSpec

from mmlearn.systems.common.marker_sensor import CameraConfig
from mmlearn.systems.common.observations import MarkerObservations

__all__ = ["CameraMarkerSensor", "CameraMarkerSensorConfig", "CameraView",
           "default_marker_cameras", "marker_normal_from_depth"]


def default_marker_cameras(radius: float = 2.0, height: float = 1.2,
                           look_at_height: float = 0.5) -> list[CameraConfig]:
    """Three cameras ``radius`` m from the arm's base at 0, +120 and -120 degrees around it,
    ``height`` m high, looking at (0, 0, ``look_at_height``) m: every marker normal in the
    horizontal plane is within 60 degrees of some camera's line of sight."""
    cams = []
    for a in (0.0, 2 * math.pi / 3, -2 * math.pi / 3):
        cams.append(CameraConfig(position=[radius * math.cos(a), radius * math.sin(a), height],
                                 look_at=[0.0, 0.0, look_at_height], fov_x_deg=70.0,
                                 fov_y_deg=55.0, max_range=6.0))
    return cams


@dataclass
class CameraMarkerSensorConfig:
    """Configuration of the camera marker sensor and of the cameras and textures the scene
    adds for it (load with ``yaml_load_typed``).

    Attributes:
        bodies: parts whose markers are textured and reported (empty = every body of the
            model instance with a ``<body>_marker`` frame).
        rate_hz: frames per second (> 0); every frame renders every camera.
        cameras: fixed cameras in the world. The image uses ``fov_y_deg`` (vertical field of
            view, degrees) and the aspect ratio width / height (square pixels), so
            ``fov_x_deg`` is not used; ``max_range`` is the far clipping distance, m.
        width, height: image size, pixels. 1920 x 1440: the arms' 0.04 m markers seen from
            the default cameras 2 m away are 20-28 pixels wide (3.5-4.5 px per module of a
            4x4 marker) at fov_y 55 degrees. On random 2-DOF arm poses a smaller image
            gives larger position errors per part, and at 640 x 480 a single marker is not
            found from 1.5 m on; the price of the larger image is its rendering time (the
            body-schema page's design notes give the figures per image size, made by
            ``benchmarks/bench_camera_marker_sensor.py --arm 2dof``).
        near: near clipping distance, m.
        principal_point_shift_px: calibration of the rendered cameras: added to the
            principal point (cx, cy) of Drake's ``CameraInfo`` before detection, pixels.
            RenderEngineVtk's images are offset by half a pixel from the principal point
            ``CameraInfo`` documents (w/2 - 0.5, h/2 - 0.5): marker corners land at
            -0.50 +- 0.01 px in x and y at 640, 1280 and 1920 px wide images
            (``benchmarks/bench_camera_marker_sensor.py --calibrate`` measures it).
        max_disagreement_deg: a marker seen by several cameras is reported only when one
            of the two pose solutions (the square's mirror ambiguity) per camera agree in
            orientation within this angle, degrees; the agreeing solution is used.
        use_depth: resolve the mirror ambiguity with the cameras' depth images (the
            RgbdSensors render them anyway). ``depth_test`` "residual" (default): each of
            IPPE_SQUARE's two solutions predicts the depth of the pixels inside the detected
            square (its plane, distance left free); the one whose prediction fits clearly
            better (log-likelihood ratio >= ``depth_min_log_ratio`` under the depth noise
            estimated from the pixels themselves) is kept; when the depth cannot tell, the
            rules below decide; a detection whose better solution is both more than
            ``depth_max_angle_deg`` off the plane fitted to the pixels and inconsistent
            with them (robust chi-square above the fitted plane's by more than
            ``depth_max_excess_chi2``) is dropped
            (:func:`mmlearn.models.common.marker_detection.mirror_test_from_depth`). "normal" (the
            first version): the normal of a plane fitted to the pixels picks the solution
            within ``depth_max_angle_deg`` of it, else the detection is dropped; right on
            Drake's exact depth, but with a structured-light camera's noise (``depth_noise``)
            the fitted normal of a 0.04 m marker 2 m away leans 14-22 deg towards the
            line of sight (the noise lies along it), and on the 2-DOF arm's babbling frames
            the gate let through far fewer reports than the residual test, neither with a
            flipped orientation (``--babble 6 --seed 3``). Without a depth image (or False)
            the rules below decide. On the 2-DOF arm's babbling frames
            (``benchmarks/bench_camera_marker_sensor.py --babble``) almost every detection
            of the 0.04 m markers 2 m away is ambiguous by reprojection (the mirror solution
            reprojects within a fraction of a pixel), and the mirror one wins in some of
            the reports.
        depth_test: "residual" or "normal", see ``use_depth``.
        depth_max_angle_deg: see ``use_depth``, degrees.
        depth_min_log_ratio: see ``use_depth`` (natural log; 3 = the better solution
            explains the depth pixels e^3 ~ 20 times more likely).
        depth_max_excess_chi2: see ``use_depth`` (13.8 = the 0.999 quantile of a
            chi-square with the free plane's 2 extra parameters).
        depth_sigma_floor_m: the smallest depth noise the residual test assumes, m
            (rendered depth is exact; a PnP tilt error of ~1 deg changes the depth inside a
            0.04 m square by ~0.2 mm).
        depth_noise: when set, the depth images go through a
            :class:`~mmlearn.systems.common.depth_noise.DepthNoise` (a structured-light camera's
            noise, quantisation and missing pixels, :mod:`mmlearn.models.common.depth_noise`)
            before the sensor sees them; camera ``i`` draws with seed
            ``depth_noise.seed + i``. None (default): Drake's exact rendered depth.
        min_unambiguous_ratio: a marker seen by one camera only is taken at face value
            when the reprojection error of IPPE_SQUARE's worse (mirror) solution is at least
            this many times the better one's, or the two solutions differ by less than
            ``detector.ambiguity_angle_deg``. Otherwise the detection is ambiguous: the
            solution closer to the marker's last reported orientation is used when that
            report is at most ``track_max_age_s`` old and the solution lies within
            ``track_max_angle_deg`` of it, else the marker is reported not visible (1 = the
            old behaviour: always the better solution). A weak guide, the fallback without
            depth: on random 2-DOF arm poses most mirror-flipped detections had ratios like
            those of many right ones, a few larger; on babbling frames it lowered the flips
            a little (``--babble``), the depth rule to none.
        track_max_age_s: how old the last report of a marker may be to resolve an
            ambiguous detection, seconds.
        track_max_angle_deg: an ambiguous detection's chosen solution must be within this
            angle of the last report, degrees (the arms turn up to ~10 degrees per frame at
            10 Hz; the mirror solution is typically 30-150 degrees away).
        aruco: the printed markers (dictionary, size, quiet zone).
        detector: OpenCV detector settings and the filters of the detections. The
            mirror-ambiguity filter is off by default: on the 2-DOF arm (25 samples,
            ``learn_body_schema --sensor camera``) ``min_ambiguity_ratio=3`` lowered the
            learned model's prediction error but always dropped the static base marker x1
            (seen nearly face-on), so the schema lost its root part.
    """

    bodies: list[str] = param([], factory=True)
    rate_hz: float = param(10.0, unit="Hz", gt=0)
    cameras: list[CameraConfig] = param(default_factory=default_marker_cameras,
                                        nested=CameraConfig, length=(1, None))
    width: int = param(1920, unit="px", integer=True, ge=16, le=8192)
    height: int = param(1440, unit="px", integer=True, ge=16, le=8192)
    near: float = param(0.05, unit="m", gt=0)
    principal_point_shift_px: list[float] = param([-0.5, -0.5], unit="px", length=2, gt=-10,
                                                  lt=10, factory=True)
    max_disagreement_deg: float = param(10.0, unit="deg", gt=0, le=180)
    use_depth: bool = param(True)
    depth_test: str = param("residual", choices=("residual", "normal"))
    depth_max_angle_deg: float = param(15.0, unit="deg", gt=0, le=90)
    depth_min_log_ratio: float = param(3.0, ge=0)
    depth_max_excess_chi2: float = param(13.8, ge=0)
    depth_sigma_floor_m: float = param(2e-4, unit="m", ge=0)
    depth_noise: DepthNoiseConfig | None = param(None, optional=True, nested=DepthNoiseConfig)
    min_unambiguous_ratio: float = param(2.5, ge=1)
    track_max_age_s: float = param(0.25, unit="s", ge=0)
    track_max_angle_deg: float = param(20.0, unit="deg", gt=0, le=180)
    aruco: ArucoSpec = param(default_factory=ArucoSpec, nested=ArucoSpec)
    detector: DetectorConfig = param(default_factory=lambda: DetectorConfig(min_side_px=12.0),
                                     nested=DetectorConfig)

    def validate(self) -> None:
        """Raise ValueError naming the first invalid field."""
        validate_fields(self)
        for i, cam in enumerate(self.cameras):
            if not cam.max_range > self.near:
                raise ValueError(f"CameraMarkerSensorConfig: cameras[{i}].max_range must be "
                                 f"> near ({self.near} m), got {cam.max_range}")

    def intrinsics(self, cam: CameraConfig) -> np.ndarray:
        """K (3, 3) the detector uses for ``cam``: Drake's ``CameraInfo(width, height,
        fov_y)`` with the principal point shifted by ``principal_point_shift_px``."""
        f = 0.5 * self.height / math.tan(0.5 * math.radians(cam.fov_y_deg))
        dx, dy = self.principal_point_shift_px
        return np.array([[f, 0.0, self.width / 2 - 0.5 + dx],
                         [0.0, f, self.height / 2 - 0.5 + dy], [0.0, 0.0, 1.0]])


@dataclass
class CameraView:
    """One fixed colour camera as the sensor sees it.

    Attributes:
        X_WC: pose of the camera frame (x right, y down, z forward) in the world.
        K: (3, 3) intrinsic matrix, pixels.
        width, height: image size, pixels.
    """

    X_WC: RigidTransform
    K: np.ndarray
    width: int
    height: int


class CameraMarkerSensor(LeafSystem):
    """Marker observations from ArUco detections in colour images.

    .. pydrake_system::

        name: CameraMarkerSensor
        input_ports:
        - color_image_0
        - ...
        - color_image_{k-1}
        - depth_image_0 (with use_depth)
        - ...
        output_ports:
        - observations
        - stats

    ``color_image_<i>`` takes an ``ImageRgba8U`` (an ``RgbdSensor``'s ``color_image``) of
    camera ``cameras[i]``. ``observations`` is an abstract
    :class:`~mmlearn.systems.common.observations.MarkerObservations` with one entry per name in
    ``marker_ids``, refreshed at ``rate_hz`` (first frame at t = 0); ``stats`` is [frames,
    marker observations, visible ones] since the start, as MarkerSensor's. The discrete
    state also holds each marker's last report (time, orientation, position), against which
    the next frames resolve ambiguous single-camera detections.

    A camera image that is missing, of the wrong size or cannot be processed contributes no
    detections (the frame still happens); the simulation never stops for it.
    """

    def __init__(self, *, marker_ids: list[str], aruco_ids: list[int],
                 cameras: list[CameraView], config: CameraMarkerSensorConfig | None = None):
        super().__init__()
        cfg = config or CameraMarkerSensorConfig()
        cfg.validate()
        names = list(marker_ids)
        ids = [int(i) for i in aruco_ids]
        if not names:
            raise ValueError("CameraMarkerSensor: marker_ids must not be empty")
        if len(ids) != len(names):
            raise ValueError(f"CameraMarkerSensor: {len(names)} marker_ids but {len(ids)} "
                             "aruco_ids")
        if len(set(ids)) != len(ids) or len(set(names)) != len(names):
            raise ValueError("CameraMarkerSensor: marker_ids and aruco_ids must be unique")
        if not cameras:
            raise ValueError("CameraMarkerSensor: give at least one camera")
        for i, cam in enumerate(cameras):
            K = np.asarray(cam.K, float)
            if K.shape != (3, 3) or not np.all(np.isfinite(K)):
                raise ValueError(f"CameraMarkerSensor: cameras[{i}].K must be a finite (3, 3)")
        self._cfg = cfg
        self._names = names
        self._ids = ids
        self._slot = {a: k for k, a in enumerate(ids)}
        self._cams = [CameraView(c.X_WC, np.asarray(c.K, float).copy(), int(c.width),
                                 int(c.height)) for c in cameras]
        # the textured plate Q lies above the marker frame M, turned about its normal
        self._X_QM = cfg.aruco.X_MQ().inverse()
        self._detector = make_detector(cfg.aruco.dictionary, cfg.detector)
        self._images = [self.DeclareAbstractInputPort(
            f"color_image_{i}", AbstractValue.Make(ImageRgba8U(c.width, c.height)))
            for i, c in enumerate(self._cams)]
        self._depths = ([self.DeclareAbstractInputPort(
            f"depth_image_{i}", AbstractValue.Make(ImageDepth32F(c.width, c.height)))
            for i, c in enumerate(self._cams)] if cfg.use_depth else [])
        self._obs_index = self.DeclareAbstractState(AbstractValue.Make(MarkerObservations()))
        self._stats_index = self.DeclareDiscreteState(3)
        # per marker: [time of its last report (NaN = never), R_WM row-major (9), p_WM (3)]
        track0 = np.zeros((len(names), 13))
        track0[:, 0] = np.nan
        self._track_index = self.DeclareDiscreteState(track0.ravel())
        self.DeclarePeriodicUnrestrictedUpdateEvent(1.0 / cfg.rate_hz, 0.0, self._update)
        self._out = self.DeclareAbstractOutputPort(
            "observations", lambda: AbstractValue.Make(MarkerObservations()),
            self._calc_observations, {self.abstract_state_ticket(self._obs_index)})
        self._stats_out = self.DeclareStateOutputPort("stats", self._stats_index)

    # -- ports ---------------------------------------------------------------------------
    def get_color_image_input_port(self, i: int = 0):
        if not 0 <= i < len(self._images):
            raise IndexError(f"camera {i} of {len(self._images)}")
        return self._images[i]

    def get_depth_image_input_port(self, i: int = 0):
        """Camera ``i``'s depth image input (only with ``config.use_depth``)."""
        if not 0 <= i < len(self._depths):
            raise IndexError(f"depth image {i} of {len(self._depths)} (use_depth="
                             f"{self._cfg.use_depth})")
        return self._depths[i]

    def get_observations_output_port(self):
        return self._out

    def get_stats_output_port(self):
        return self._stats_out

    @property
    def marker_ids(self) -> list[str]:
        return list(self._names)

    @property
    def aruco_ids(self) -> list[int]:
        return list(self._ids)

    @property
    def config(self) -> CameraMarkerSensorConfig:
        return self._cfg

    @property
    def cameras(self) -> list[CameraView]:
        return list(self._cams)

    # -- computation ---------------------------------------------------------------------
    def detect(self, image, camera: int) -> MarkerDetections:
        """Detections of this sensor's markers in ``image`` (H, W, 3|4) uint8 of camera
        ``camera`` (poses in that camera's frame, at the textured plate's surface)."""
        cam = self._cams[camera]
        img = np.asarray(image)
        if img.shape[:2] != (cam.height, cam.width):
            raise ValueError(f"camera {camera}: image is {img.shape[1]}x{img.shape[0]}, "
                             f"expected {cam.width}x{cam.height}")
        return detect_marker_poses(img, cam.K, marker_size=self._cfg.aruco.marker_size,
                                   detector=self._detector, config=self._cfg.detector,
                                   ids=set(self._ids))

    def observe(self, context, frame: int | None = None) -> MarkerObservations:
        """Detect the markers in the current images of this system's ``context`` (renders
        them when the inputs come from an RgbdSensor). Ambiguous single-camera detections
        are resolved against the last reports stored in ``context`` (see
        ``min_unambiguous_ratio``). ``frame`` is accepted for compatibility with
        :meth:`MarkerSensor.observe` and ignored (no random draws)."""
        return self._observe(context)[0]

    def observe_and_remember(self, context) -> MarkerObservations:
        """For use outside a simulation (a context the caller owns): :meth:`observe`, then
        store the reports in ``context`` as the periodic update does, so that the next call
        (at a later ``context`` time) can resolve ambiguous detections against them."""
        obs, track = self._observe(context)
        context.get_mutable_discrete_state(self._track_index).set_value(track.ravel())
        return obs

    def _observe(self, context):
        """(observations, new per-marker track rows (m, 13)) of the current images."""
        m = len(self._names)
        track = np.array(context.get_discrete_state(self._track_index).get_value(),
                         float).reshape(m, 13)
        images, depths = [], []
        for i, port in enumerate(self._images):
            img = None
            try:
                if port.HasValue(context):
                    img = port.Eval(context).data
            except (RuntimeError, TypeError, ValueError):
                img = None
            images.append(img)
            depth = None
            if self._depths:
                try:
                    if self._depths[i].HasValue(context):
                        depth = self._depths[i].Eval(context).data
                except (RuntimeError, TypeError, ValueError):
                    depth = None
            depths.append(depth)
        return self.observe_images(context.get_time(), images, depths, track)

    def observe_images(self, t: float, images: list, depths: list | None = None,
                       track: np.ndarray | None = None, *, detections: list | None = None):
        """The frame's observations from images given as arrays (what :meth:`observe` does
        with the input ports' images; for benchmarks that compare settings on the same
        renders). Returns ``(observations, track)``.

        Args:
            t: the frame's time, s.
            images: per camera an (H, W, 3|4) uint8 image or None (no image).
            depths: per camera an (H, W) or (H, W, 1) depth image, m, or None (no depth;
                ignored unless ``config.use_depth``).
            track: (m, 13) the markers' last reports (see the class docstring; None = none).
            detections: per camera the :class:`MarkerDetections` of ``images`` when already
                computed (then ``images`` is not searched again).
        """
        m = len(self._names)
        if track is None:
            track = np.zeros((m, 13))
            track[:, 0] = np.nan
        track = np.array(track, float).reshape(m, 13)
        # per marker: (image side px, ambiguity ratio, [X_WM, X_WM mirror])
        cands = [[] for _ in range(m)]
        for i, cam in enumerate(self._cams):
            try:
                if detections is not None and detections[i] is not None:
                    det = detections[i]
                elif i < len(images) and images[i] is not None:
                    det = self.detect(images[i], i)
                else:
                    continue
            except (ValueError, RuntimeError, TypeError, cv2.error):
                continue  # a bad image: no detections from this camera in this frame
            depth = None
            if self._cfg.use_depth and depths is not None and i < len(depths) \
                    and depths[i] is not None:
                try:
                    depth = np.asarray(depths[i], float)
                    if depth.ndim == 3 and depth.shape[2] == 1:
                        depth = depth[..., 0]
                    if depth.shape != (cam.height, cam.width):
                        depth = None
                except (TypeError, ValueError):
                    depth = None
            X_WC = cam.X_WC
            for a, T, T2, side, amb, corners in zip(det.ids, det.T_CM, det.T_CM_other,
                                                    det.side_px, det.ambiguity, det.corners):
                if depth is not None:
                    j = self._depth_choice(depth, corners, cam.K, T, T2)
                    if j == -1:
                        continue  # neither solution lies in the seen plane
                    if j is not None:
                        T, T2, amb = (T, T, np.inf) if j == 0 else (T2, T2, np.inf)
                sols = [X_WC @ RigidTransform(RotationMatrix(project_to_so3(S[:3, :3])),
                                              S[:3, 3]) @ self._X_QM for S in (T, T2)]
                cands[self._slot[int(a)]].append((float(side), float(amb), sols))
        poses = [RigidTransform() for _ in range(m)]
        visible = np.zeros(m, bool)
        for k, c in enumerate(cands):
            last = None
            if (np.isfinite(track[k, 0]) and 0 <= t - track[k, 0] <= self._cfg.track_max_age_s):
                last = project_to_so3(track[k, 1:10].reshape(3, 3))
            X = self._fuse(c, last)
            if X is not None:
                poses[k], visible[k] = X, True
                track[k, 0] = t
                track[k, 1:10] = np.asarray(X.rotation().matrix()).ravel()
                track[k, 10:] = X.translation()
        obs = MarkerObservations(time=t, marker_ids=list(self._names), poses=poses,
                                 visible=visible, outlier=np.zeros(m, bool))
        return obs, track

    def _depth_choice(self, depth, corners, K, T, T2):
        """0 / 1: the solution the depth image decides for, -1: neither lies in the seen
        plane (drop the detection), None: the depth cannot tell (too few pixels, or the
        two solutions predict the depth about equally well)."""
        cfg = self._cfg
        if cfg.depth_test == "normal":
            n = marker_normal_from_depth(depth, corners, K)
            if n is None:
                return None
            e = [math.degrees(math.acos(float(np.clip(n @ S[:3, 2], -1, 1)))) for S in (T, T2)]
            j = int(np.argmin(e))
            return -1 if e[j] > cfg.depth_max_angle_deg else j
        test = mirror_test_from_depth(depth, corners, K, T, T2,
                                      sigma_floor_m=cfg.depth_sigma_floor_m)
        if test is None:
            return None
        return test.choice(min_log_ratio=cfg.depth_min_log_ratio,
                           max_angle_deg=cfg.depth_max_angle_deg,
                           max_excess_chi2=cfg.depth_max_excess_chi2)

    def _fuse(self, cands, last_R=None):
        """One pose from the detections of a marker in several cameras (None = not seen).

        One camera: its better solution if unambiguous (``min_unambiguous_ratio``, or both
        solutions within ``detector.ambiguity_angle_deg``); else the solution nearer to
        ``last_R`` (the last reported orientation, None = none recent) if within
        ``track_max_angle_deg`` of it; else None. Several: the choice of one of the two
        solutions per camera whose orientations agree best (smallest largest pairwise
        angle); if even those differ by more than ``max_disagreement_deg`` the marker is not
        reported; else the chosen pose of the camera in which the marker is largest."""
        if not cands:
            return None
        if len(cands) == 1:
            _, ratio, sols = cands[0]
            if ratio >= self._cfg.min_unambiguous_ratio:
                return sols[0]
            R = [np.asarray(X.rotation().matrix()) for X in sols]
            if _angle(R[0], R[1]) <= math.radians(self._cfg.detector.ambiguity_angle_deg):
                return sols[0]
            if last_R is None:
                return None
            d = [_angle(last_R, Ri) for Ri in R]
            j = int(np.argmin(d))
            return sols[j] if d[j] <= math.radians(self._cfg.track_max_angle_deg) else None
        cands = sorted(cands, key=lambda c: -c[0])[:3]
        R = [[np.asarray(X.rotation().matrix()) for X in c[2]] for c in cands]
        best, best_choice = np.inf, None
        for choice in itertools.product((0, 1), repeat=len(cands)):
            worst = 0.0
            for a, b in itertools.combinations(range(len(cands)), 2):
                worst = max(worst, _angle(R[a][choice[a]], R[b][choice[b]]))
            # prefer each camera's better solution when the agreement is the same
            key = worst + 1e-6 * sum(choice)
            if key < best:
                best, best_choice = key, choice
        if best > math.radians(self._cfg.max_disagreement_deg):
            return None
        return cands[0][2][best_choice[0]]

    def _update(self, context, state):
        obs, track = self._observe(context)
        state.get_mutable_abstract_state(self._obs_index).set_value(obs)
        stats = state.get_mutable_discrete_state(self._stats_index)
        stats.set_value(stats.get_value() + np.array([1.0, len(obs), obs.visible.sum()]))
        state.get_mutable_discrete_state(self._track_index).set_value(track.ravel())
        return EventStatus.Succeeded()

    def _calc_observations(self, context, output):
        output.set_value(context.get_abstract_state(self._obs_index).get_value())


def marker_normal_from_depth(depth, corners, K, *, shrink: float = 0.7,
                             min_points: int = 30):
    """Unit normal (3,) of the plane through the depth pixels inside a detected marker, in
    the camera frame, pointing towards the camera (None when too few valid pixels).

    Args:
        depth: (H, W) depth image, m (NaN, inf or <= 0 = no measurement).
        corners: (4, 2) image corners of the marker, pixels.
        K: (3, 3) intrinsics, pixels.
        shrink: the quad is shrunk towards its centre by this factor first (keeps the
            pixels off the marker's border, where depth edges and the carrier begin).
        min_points: fewest valid depth pixels for a fit.
    """
    pix = quad_depth_pixels(depth, corners, shrink=shrink, min_points=min_points)
    if pix is None:
        return None
    u, v, z = pix
    P = np.column_stack([(u - K[0, 2]) / K[0, 0] * z, (v - K[1, 2]) / K[1, 1] * z, z])
    mu = P.mean(axis=0)
    _, sv, Vt = np.linalg.svd(P - mu, full_matrices=False)
    if not (np.all(np.isfinite(sv)) and sv[1] > 0):
        return None
    n = Vt[2]
    return -n if n @ mu > 0 else n


def _angle(Ra, Rb) -> float:
    """Angle between two rotation matrices, radians."""
    return math.acos(float(np.clip((np.trace(Ra.T @ Rb) - 1) / 2, -1, 1)))
