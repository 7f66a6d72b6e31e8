"""Tactile grasps (thesis ch. 6-7): the shared data types of the simulation and the learners.

This module is what the (later) Drake side -- the ``TactileSensor`` integrating hydroelastic
pressure over finger-pad cells and the ``TactileGraspController`` of Eq. 7.8 -- produces, and
what :mod:`mmlearn.models.tactile.recognition`, :mod:`mmlearn.models.tactile.state` and
:mod:`mmlearn.models.tactile.liquid` consume. Plain numpy, no pydrake import.

Conventions
-----------
* **Tactile images** are float arrays ``(rows, cols)`` in [0, 1] (0 = no pressure, 1 = the
  sensor's saturation / maximum response; thesis 6.1: "normalised to the sensor's maximum
  response"). ``rows`` runs along the finger (the *vertical* axis of Eq. 6.2: shifts move
  content along axis -2), ``cols`` across it. The ch. 6 pad is 14 rows x 6 cols over 51 x 24 mm.
* **Time series** of one grasp share one time base ``t`` (seconds, strictly increasing, uniform
  at ``rate_hz``). A time series of images is ``(T, rows, cols)``.
* **Finger distance** ``p`` (metres): the distance between the two fingers (it *decreases* as
  the gripper closes); ``v = dp/dt`` (m/s, negative while closing); ``f`` the summed normal force
  over all cells of all pads (newtons); ``finger_force`` ``(T, n_fingers)`` the same per finger
  (used for the "both fingers in contact" test of Eq. 7.1). A real robot's data can stand in
  with other units (the iCub hand gives joint-angle closure and raw taxel counts, see
  :mod:`mmlearn.models.tactile.icub_grasp`); the features of ch. 7 only need consistent units.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["TactileGrasp", "TactileObservation", "TactileDataError", "check_series"]


class TactileDataError(ValueError):
    """Tactile data that cannot be used (wrong shape, NaN, out of range); the message says
    which field and why."""


def check_series(name: str, a, *, ndim: int | None = None, length: int | None = None,
                 lo: float | None = None, hi: float | None = None) -> np.ndarray:
    """Return ``a`` as a float array after checking its dimension, leading length, finiteness
    and range; raises :class:`TactileDataError` naming ``name``."""
    try:
        x = np.asarray(a, dtype=float)
    except (TypeError, ValueError):
        raise TactileDataError(f"{name}: not a numeric array") from None
    if ndim is not None and x.ndim != ndim:
        raise TactileDataError(f"{name}: expected {ndim} dimension(s), got shape {x.shape}")
    if length is not None and (x.ndim == 0 or x.shape[0] != length):
        raise TactileDataError(f"{name}: expected {length} samples, got shape {x.shape}")
    if x.size and not np.all(np.isfinite(x)):
        bad = np.argwhere(~np.isfinite(x))[0]
        raise TactileDataError(f"{name}: NaN or infinite value at index {tuple(int(i) for i in bad)}")
    if lo is not None and x.size and x.min() < lo:
        raise TactileDataError(f"{name}: values below {lo:g} (min {x.min():g})")
    if hi is not None and x.size and x.max() > hi:
        raise TactileDataError(f"{name}: values above {hi:g} (max {x.max():g})")
    return x


@dataclass
class TactileObservation:
    """One static grasp observation of ch. 6: ``z = (Z_left, Z_right, h, w)``.

    Attributes:
        left, right: tactile images ``(rows, cols)`` in [0, 1] of the two finger pads, read
            once the gripper has established its grasp force.
        height: grasp height h along the object, metres (the action of Sec. 6.2).
        width: finger distance w at the grasp (object width), metres.
        label: class name (None when unknown, e.g. at test time).
    """

    left: np.ndarray
    right: np.ndarray
    height: float
    width: float
    label: str | None = None

    def __post_init__(self):
        self.left = check_series("left", self.left, ndim=2, lo=0.0, hi=1.0)
        self.right = check_series("right", self.right, ndim=2, lo=0.0, hi=1.0)
        if self.left.shape != self.right.shape:
            raise TactileDataError(f"left {self.left.shape} and right {self.right.shape} "
                                   f"images differ in shape")
        for k in ("height", "width"):
            v = getattr(self, k)
            if not np.isfinite(v):
                raise TactileDataError(f"{k}: expected a finite number, got {v!r}")
            setattr(self, k, float(v))


@dataclass
class TactileGrasp:
    """Everything recorded during one grasp (ch. 7; its last frame is a ch. 6 observation).

    Attributes:
        t: (T,) sample times, seconds, strictly increasing.
        p: (T,) finger distance, metres (decreasing while the gripper closes).
        f: (T,) summed normal force over all cells of all pads, newtons (>= 0).
        v: (T,) finger velocity dp/dt, m/s; None: central differences of ``p`` over ``t``.
        finger_force: (T, n_fingers) force per finger, newtons; None: only ``f`` is known.
        pads: name -> (T, rows, cols) tactile images in [0, 1] (e.g. ``{"left": ..,
            "right": ..}``); may be empty.
        height: grasp height along the object, metres (ch. 6 action); None if not applicable.
        weight: weight of the grasped object from the wrist force sensor, newtons; None if
            not measured.
        label: class / object name; container, state: ch. 7 container class and internal
            state (e.g. ``"odwalla"``, ``"full_closed"``); None when unknown.
    """

    t: np.ndarray
    p: np.ndarray
    f: np.ndarray
    v: np.ndarray | None = None
    finger_force: np.ndarray | None = None
    pads: dict = field(default_factory=dict)
    height: float | None = None
    weight: float | None = None
    label: str | None = None
    container: str | None = None
    state: str | None = None

    def __post_init__(self):
        self.t = check_series("t", self.t, ndim=1)
        T = self.t.shape[0]
        if T < 2:
            raise TactileDataError(f"t: a grasp needs at least 2 samples, got {T}")
        if np.any(np.diff(self.t) <= 0):
            i = int(np.argmax(np.diff(self.t) <= 0))
            raise TactileDataError(f"t: not strictly increasing at sample {i + 1}")
        self.p = check_series("p", self.p, ndim=1, length=T)
        self.f = check_series("f", self.f, ndim=1, length=T, lo=0.0)
        if self.v is None:
            self.v = np.gradient(self.p, self.t)
        else:
            self.v = check_series("v", self.v, ndim=1, length=T)
        if self.finger_force is not None:
            self.finger_force = check_series("finger_force", self.finger_force, ndim=2,
                                             length=T, lo=0.0)
        pads = {}
        for name, imgs in dict(self.pads).items():
            pads[name] = check_series(f"pads[{name!r}]", imgs, ndim=3, length=T, lo=0.0, hi=1.0)
        self.pads = pads
        for k in ("height", "weight"):
            val = getattr(self, k)
            if val is not None:
                if not np.isfinite(val):
                    raise TactileDataError(f"{k}: expected a finite number, got {val!r}")
                setattr(self, k, float(val))

    @property
    def n(self) -> int:
        """Number of samples T."""
        return int(self.t.shape[0])

    @property
    def rate_hz(self) -> float:
        """Mean sample rate, Hz."""
        return float((self.n - 1) / (self.t[-1] - self.t[0]))

    def observation(self, *, index: int = -1) -> TactileObservation:
        """The ch. 6 observation at sample ``index`` (default: the last, after the grasp
        force is established): needs pads ``"left"`` and ``"right"`` and a ``height``."""
        if "left" not in self.pads or "right" not in self.pads:
            raise TactileDataError("observation: the grasp has no 'left' and 'right' pads")
        if self.height is None:
            raise TactileDataError("observation: the grasp has no height")
        return TactileObservation(self.pads["left"][index], self.pads["right"][index],
                                  self.height, float(self.p[index]), self.label)
