"""DepthNoise: turns a rendered (clean) depth image into an active-stereo / structured-light
camera's depth image (the model and its numbers: :mod:`mmlearn.models.common.depth_noise`)."""

from __future__ import annotations

import logging
import math

import numpy as np

from pydrake.common.value import AbstractValue
from pydrake.systems.framework import LeafSystem
from pydrake.systems.sensors import ImageDepth32F

from mmlearn.models.common.depth_noise import DepthNoiseConfig, apply_depth_noise
from mmlearn.models.common.camera import PinholeIntrinsics

__all__ = ["DepthNoise"]

_log = logging.getLogger(__name__)


class DepthNoise(LeafSystem):
    """Adds the depth camera's noise, quantisation and missing pixels to a rendered image.

    .. pydrake_system::

        name: DepthNoise
        input_ports:
        - clean_depth
        output_ports:
        - depth_image

    ``clean_depth`` takes an ``ImageDepth32F`` (e.g. ``RgbdSensor``'s ``depth_image_32f``);
    ``depth_image`` is the noisy ``ImageDepth32F`` of the same size, metres, NaN where the
    camera has no measurement. It is a pure function of the input image, the configuration
    and the frame index ``k = round(t * rate_hz)`` of the context's time t (noise drawn from
    ``default_rng([config.seed, k])``), so two simulators, or a re-evaluation, give the same
    image; it is computed when evaluated (cached until the input or the time changes).

    A clean image of the wrong size or with garbage values never stops a simulation: the
    output is then an all-NaN image (no measurement) and a warning is logged.

    Args:
        intrinsics: the rendering camera's :class:`PinholeIntrinsics` (image size, focal
            length for the disparity scale).
        config: the noise parameters (:class:`DepthNoiseConfig`).
        rate_hz: camera frames per second, > 0 (sets the frame index of a time).
    """

    def __init__(self, *, intrinsics: PinholeIntrinsics, config: DepthNoiseConfig | None = None,
                 rate_hz: float = 5.0):
        super().__init__()
        cfg = config or DepthNoiseConfig()
        cfg.validate()
        if not (isinstance(rate_hz, (int, float)) and math.isfinite(rate_hz) and rate_hz > 0):
            raise ValueError(f"DepthNoise: rate_hz must be a finite number > 0 (Hz), got "
                             f"{rate_hz!r}")
        if not isinstance(intrinsics, PinholeIntrinsics):
            raise TypeError("DepthNoise: intrinsics must be a PinholeIntrinsics")
        self._K = intrinsics
        self._cfg = cfg
        self._rate = float(rate_hz)
        W, H = intrinsics.width, intrinsics.height
        self._in = self.DeclareAbstractInputPort("clean_depth",
                                                 AbstractValue.Make(ImageDepth32F(W, H)))
        self._out = self.DeclareAbstractOutputPort(
            "depth_image", lambda: AbstractValue.Make(ImageDepth32F(W, H)), self._calc,
            {self.input_port_ticket(self._in.get_index()), self.time_ticket()})

    # -- ports -----------------------------------------------------------------------------
    def get_clean_depth_input_port(self):
        return self._in

    def get_depth_image_output_port(self):
        return self._out

    @property
    def intrinsics(self) -> PinholeIntrinsics:
        return self._K

    @property
    def config(self) -> DepthNoiseConfig:
        return self._cfg

    def frame_index(self, t: float) -> int:
        """The camera frame index of time t (s)."""
        return max(int(round(t * self._rate)), 0)

    # -- computation -----------------------------------------------------------------------
    def _calc(self, context, output):
        img = self._in.Eval(context)
        out = output.get_mutable_value()
        k = self.frame_index(context.get_time())
        try:
            clean = np.asarray(img.data)
            noisy = apply_depth_noise(clean, self._K, self._cfg, frame=k)
        except (ValueError, FloatingPointError) as e:
            _log.warning("DepthNoise: frame %d has no usable depth (%s); output is all NaN", k, e)
            noisy = np.full((self._K.height, self._K.width), np.nan, np.float32)
        if out.width() != self._K.width or out.height() != self._K.height:
            out.resize(self._K.width, self._K.height)
        out.mutable_data[:, :, 0] = noisy
