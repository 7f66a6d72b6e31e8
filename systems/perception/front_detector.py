"""FrontDetector: cabinet fronts as rectangles in depth images (thesis ch. 5.1.1-5.1.2).

A thin wrapper of :func:`mmlearn.models.perception.detection.detect_fronts`: the depth image and the
camera pose come in, the detected rectangles (world frame) and the time per stage go out.
"""

import math
import warnings

import cv2
import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.framework import LeafSystem, ValueProducer
from pydrake.systems.sensors import ImageDepth32F

from mmlearn.models.perception.detection import STAGES, FrontDetectorConfig, detect_fronts
from mmlearn.models.common.camera import PinholeIntrinsics

__all__ = ["FrontDetector", "TIMING_NAMES"]

#: entries of the ``timings`` output, seconds
TIMING_NAMES = tuple(STAGES) + ("total",)


class FrontDetector(LeafSystem):
    """Detects planar rectangles (cabinet fronts) in every depth image it is asked about.

    .. pydrake_system::

        name: FrontDetector
        input_ports:
        - depth_image
        - X_WC (optional)
        - noise_scale (optional)
        output_ports:
        - rectangles
        - timings

    ``depth_image`` is a Drake ``ImageDepth32F`` (metres; NaN, 0 and inf = no measurement),
    e.g. an ``RgbdSensor``'s ``depth_image_32f`` output or a depth-noise system after it.
    ``X_WC`` is the camera pose in the world (an abstract ``RigidTransform``, Drake camera
    frame: x right, y down, z forward); left unconnected, the camera frame is the world frame.
    ``noise_scale`` (optional ``ImageDepth32F``, unitless): each pixel's depth noise std
    relative to one frame's, from a :class:`~mmlearn.systems.DepthTemporalFilter` feeding
    ``depth_image``; the reveal test's threshold follows it (``detect_fronts``' ``noise_scale``).
    ``rectangles`` is a ``list[FrontRectangle]`` in the world frame (best first);
    ``timings`` is the wall-clock time per stage, seconds, in the order of
    :data:`TIMING_NAMES` (planes, masks, sampling, optimisation, check, total), all NaN for a
    frame that could not be processed (bad image size, broken pose): such a frame gives an
    empty list and never an exception.

    The outputs are computed on demand and cached until the inputs or the time change. The
    random draws (RANSAC samples, rectangle starts) are a pure function of ``seed`` and the
    context time (microseconds), so two simulators give the same rectangles.
    """

    def __init__(self, *, intrinsics, config: FrontDetectorConfig | None = None,
                 seed: int = 0):
        """
        Args:
            intrinsics: the camera's :class:`PinholeIntrinsics` or a Drake ``CameraInfo``.
            config: detector parameters (defaults when None); validated here.
            seed: seed of the detector's random draws (integer >= 0).
        """
        super().__init__()
        if isinstance(intrinsics, PinholeIntrinsics):
            K = intrinsics
        elif all(hasattr(intrinsics, a) for a in ("width", "height", "focal_x", "center_x")):
            K = PinholeIntrinsics.from_camera_info(intrinsics)
        else:
            raise ValueError("FrontDetector: intrinsics must be a PinholeIntrinsics or a Drake "
                             f"CameraInfo, got {type(intrinsics).__name__}")
        cfg = config or FrontDetectorConfig()
        cfg.validate()
        if not (isinstance(seed, (int, np.integer)) and seed >= 0):
            raise ValueError(f"FrontDetector: seed must be an integer >= 0, got {seed!r}")
        self._K = K
        self._cfg = cfg
        self._seed = int(seed)
        self._depth = self.DeclareAbstractInputPort(
            "depth_image", AbstractValue.Make(ImageDepth32F(K.width, K.height)))
        self._X_WC = self.DeclareAbstractInputPort("X_WC", AbstractValue.Make(RigidTransform()))
        self._scale = self.DeclareAbstractInputPort(
            "noise_scale", AbstractValue.Make(ImageDepth32F(K.width, K.height)))
        self._cache = self.DeclareCacheEntry(
            "detection",
            ValueProducer(allocate=lambda: AbstractValue.Make(([], None)),
                          calc=lambda c, v: v.set_value(self.detect(c))),
            {self.all_input_ports_ticket(), self.time_ticket()})
        prereq = {self._cache.ticket()}
        self._rects_out = self.DeclareAbstractOutputPort(
            "rectangles", lambda: AbstractValue.Make([]),
            lambda c, v: v.set_value(list(self._cache.Eval(c)[0])), prereq)
        self._timings_out = self.DeclareVectorOutputPort(
            "timings", len(TIMING_NAMES), self._calc_timings, prerequisites_of_calc=prereq)

    # -- ports ---------------------------------------------------------------------------
    def get_depth_image_input_port(self):
        return self._depth

    def get_X_WC_input_port(self):
        return self._X_WC

    def get_noise_scale_input_port(self):
        return self._scale

    def get_rectangles_output_port(self):
        return self._rects_out

    def get_timings_output_port(self):
        return self._timings_out

    @property
    def intrinsics(self) -> PinholeIntrinsics:
        return self._K

    @property
    def config(self) -> FrontDetectorConfig:
        return self._cfg

    # -- computation ---------------------------------------------------------------------
    def detect(self, context):
        """(rectangles, timings dict or None) for this system's context; never raises on a
        bad frame (it sees nothing: an empty list and None timings)."""
        t = context.get_time()
        frame = int(round(t * 1e6)) if math.isfinite(t) and t >= 0 else 0
        rng = np.random.default_rng([self._seed, frame])
        try:
            img = self._depth.Eval(context)
            depth = np.asarray(img.data, np.float32)
            X_WC = (self._X_WC.Eval(context).GetAsMatrix4() if self._X_WC.HasValue(context)
                    else None)  # (camera frame: gravity unknown)
            scale = (np.asarray(self._scale.Eval(context).data, np.float32)
                     if self._scale.HasValue(context) else None)
            rects, timings = detect_fronts(depth, self._K, X_WC, self._cfg, rng,
                                           noise_scale=scale)
        except (ValueError, FloatingPointError, np.linalg.LinAlgError, cv2.error):
            return [], None  # a bad frame (size, pose): sees nothing
        except Exception as e:  # noqa: BLE001 - a running simulation must not die on a frame
            warnings.warn(f"FrontDetector: frame at t = {t} skipped: {e!r}", RuntimeWarning)
            return [], None
        return rects, timings

    def _calc_timings(self, context, output):
        _, timings = self._cache.Eval(context)
        if timings is None:
            output.SetFromVector(np.full(len(TIMING_NAMES), np.nan))
        else:
            output.SetFromVector([timings[k] for k in TIMING_NAMES])
