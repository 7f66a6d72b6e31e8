"""DepthTemporalFilter: a per-pixel running mean of a depth camera's frames where the scene
stands still (the model: :mod:`mmlearn.models.perception.depth_filter`)."""

from __future__ import annotations

import logging
import math

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import LeafSystem, ValueProducer
from pydrake.systems.sensors import ImageDepth32F

from mmlearn.models.perception.depth_filter import (DepthFilterConfig, DepthFilterState, filter_depth,
                                                    new_filter_state)
from mmlearn.models.common.camera import PinholeIntrinsics

__all__ = ["DepthTemporalFilter"]

_log = logging.getLogger(__name__)


class DepthTemporalFilter(LeafSystem):
    """Averages consecutive depth frames per pixel, restarting where the scene moves.

    .. pydrake_system::

        name: DepthTemporalFilter
        input_ports:
        - depth_image
        output_ports:
        - depth_image
        - noise_scale

    ``depth_image`` (in) is an ``ImageDepth32F`` (metres; NaN / 0 / inf = no measurement),
    e.g. :class:`~mmlearn.systems.DepthNoise`'s output. Camera frame k is the input at time
    k / ``rate_hz``; a periodic update at that rate folds it into the state (abstract: the
    per-pixel mean, count and variance factor, :class:`mmlearn.models.perception.depth_filter.
    DepthFilterState`, and the index of the last frame folded in). The state is immutable
    (read-only arrays, replaced by each update, never written): Drake's copies of it are
    the same object, not copies of three images. The outputs at time t are
    the state with the frame of t folded in (computed from the state and the input, cached;
    the update stores the same result), so a reader at a frame time sees that frame:
    ``depth_image`` (out) the filtered depth (``ImageDepth32F``, m, NaN where this frame has
    no measurement) and ``noise_scale`` (``ImageDepth32F``, unitless) each pixel's noise std
    relative to one frame's, 1 / sqrt(frames averaged); feed it to
    :class:`~mmlearn.systems.FrontDetector`'s ``noise_scale`` input.

    A frame of the wrong size or not numeric never stops a simulation: it leaves the state
    unchanged, the outputs are all NaN (scale 1) and a warning is logged.

    Args:
        intrinsics: the camera's :class:`PinholeIntrinsics` (image size).
        config: :class:`DepthFilterConfig` (its ``depth_std_at_1m`` should be the camera's
            noise, e.g. ``predicted_depth_std(1.0, K, noise_config)``).
        rate_hz: camera frames per second, > 0 (the update period is 1 / rate_hz, s).
    """

    def __init__(self, *, intrinsics: PinholeIntrinsics, config: DepthFilterConfig | None = None,
                 rate_hz: float = 5.0):
        super().__init__()
        if not isinstance(intrinsics, PinholeIntrinsics):
            raise TypeError("DepthTemporalFilter: intrinsics must be a PinholeIntrinsics")
        cfg = config or DepthFilterConfig()
        cfg.validate()
        if isinstance(rate_hz, bool) or not isinstance(rate_hz, (int, float)) \
                or not math.isfinite(rate_hz) or rate_hz <= 0:
            raise ValueError(f"DepthTemporalFilter: rate_hz must be a finite number > 0 (Hz), "
                             f"got {rate_hz!r}")
        self._K = intrinsics
        self._cfg = cfg
        self._rate = float(rate_hz)
        W, H = intrinsics.width, intrinsics.height
        self._in = self.DeclareAbstractInputPort("depth_image",
                                                 AbstractValue.Make(ImageDepth32F(W, H)))
        self._state = self.DeclareAbstractState(
            AbstractValue.Make((new_filter_state(H, W), -1)))
        self._step = self.DeclareCacheEntry(
            "filter_step",
            ValueProducer(allocate=lambda: AbstractValue.Make((None, None, None, -1)),
                          calc=lambda c, v: v.set_value(self._calc_step(c))),
            {self.all_input_ports_ticket(), self.all_state_ticket(), self.time_ticket()})
        prereq = {self._step.ticket()}
        self._out = self.DeclareAbstractOutputPort(
            "depth_image", lambda: AbstractValue.Make(ImageDepth32F(W, H)),
            lambda c, v: self._write(v, self._step.Eval(c)[0]), prereq)
        self._scale = self.DeclareAbstractOutputPort(
            "noise_scale", lambda: AbstractValue.Make(ImageDepth32F(W, H)),
            lambda c, v: self._write(v, self._step.Eval(c)[1]), prereq)
        self.DeclarePeriodicUnrestrictedUpdateEvent(1.0 / self._rate, 0.0, self._update)

    # -- ports -----------------------------------------------------------------------------
    def get_depth_image_input_port(self):
        return self._in

    def get_depth_image_output_port(self):
        return self._out

    def get_noise_scale_output_port(self):
        return self._scale

    @property
    def config(self) -> DepthFilterConfig:
        return self._cfg

    def frame_index(self, t: float) -> int:
        """The camera frame index of time t (s)."""
        return max(int(round(t * self._rate)), 0) if math.isfinite(t) else 0

    def filter_state(self, context) -> tuple[DepthFilterState, int]:
        """(state, index of the last frame folded in; -1 = none) in ``context``."""
        return context.get_abstract_state(0).get_value()

    # -- computation -----------------------------------------------------------------------
    def _calc_step(self, context):
        """(filtered, noise_scale, new state, frame index) with the frame of this time."""
        state, last = context.get_abstract_state(0).get_value()
        k = self.frame_index(context.get_time())
        H, W = self._K.height, self._K.width
        try:
            depth = np.asarray(self._in.Eval(context).data)
            if last == k:  # already folded in (an output read after the update)
                out = np.where(np.isfinite(depth[..., 0]) & (depth[..., 0] > 0), state.mean,
                               np.float32(np.nan)).astype(np.float32)
                if out.shape != state.shape:
                    raise ValueError(f"depth image of shape {out.shape}")
                scale = np.where(np.isfinite(out), np.sqrt(state.var_scale),
                                 np.float32(1.0)).astype(np.float32)
                return out, scale, state, k
            out, scale, new = filter_depth(depth, state, self._cfg)
            return out, scale, new, k
        except (ValueError, TypeError, IndexError) as e:
            _log.warning("DepthTemporalFilter: frame %d unusable (%s); output all NaN", k, e)
            return (np.full((H, W), np.nan, np.float32), np.ones((H, W), np.float32), state,
                    last)

    def _update(self, context, state):
        _, _, new, k = self._step.Eval(context)
        state.get_mutable_abstract_state(0).set_value((new, k))

    def _write(self, value, img):
        out = value.get_mutable_value()
        if out.width() != self._K.width or out.height() != self._K.height:
            out.resize(self._K.width, self._K.height)
        out.mutable_data[:, :, 0] = img
