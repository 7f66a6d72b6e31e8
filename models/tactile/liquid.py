"""Liquid detection from the high-frequency part of the tactile signal (thesis Sec. 7.3).

The robot holds a closed container and rolls it with the wrist at about 0.6 Hz; liquid
sloshing inside gives pressure spikes at every reversal of the roll. Per trial:

1. every taxel's signal (``(T, n_taxels)``, sampled at ``rate_hz`` = 24 Hz on the PR2) goes
   through a first-order Butterworth high-pass with a 5 Hz cut-off (``scipy.signal.butter`` +
   causal ``lfilter``, so it can run online; the filter starts in its steady state for the
   first sample, so a constant load gives no start-up transient);
2. the filtered signals are combined by the Euclidean norm over the taxels (Eq. 7.9);
3. the feature is the standard deviation of that norm over the roll, ``sigma`` of Eq. 7.11
   (n - 1 in the denominator); optionally the object's weight from the wrist force sensor is a
   second feature (Sec. 7.3.3).

**Coast-phase feature (a deviation).** The thesis takes the spread over the whole
roll. With a smooth roll the rigid response *during* each reversal (the couple of the
container's rotational inertia, the leak of the weight shift) is as large as the liquid's
ringing, so a rigid dummy of a half-full bottle's weight looks like a weak liquid. The robot
knows its own roll command, so :func:`coast_mask` keeps only the samples where the commanded
roll rate is constant (between the reversals, optionally from ``delay`` s after each reversal
ends): there a rigid body's load on the pads changes only slowly, with gravity, while a liquid
keeps moving after the container's motion stops changing. The same filter (run over the
whole roll, so its state is continuous), the same norm and the same spread, restricted to those
samples (``liquid_feature(..., mask=...)``; ``RollRecord.coast``; ``feature="coast"`` in
:func:`liquid_features`, :func:`liquid_table`, :func:`evaluate_liquid`; ``"whole"`` is the
thesis' feature). That alone is not enough for a heavy rigid body: within a coast phase
gravity shifts its load from one pad to the other as the wrist turns, smoothly, and the
first-order high-pass passes ~20 % of that shift. :func:`coast_feature`
(``feature="coast_detrended"``) therefore takes the spread of the filtered norm about a
quadratic trend fitted within each coast phase: what remains is what does not follow the
slow gravity load -- the liquid's ringing at its sloshing frequency (3.5-3.9 Hz, about two
periods per phase).

A decision tree (:func:`mmlearn.models.tactile.state.make_classifier`) learns "liquid" versus
"no liquid" from these features; :func:`mmlearn.models.tactile.state.cross_validate` gives the
10-fold rate.

The liquid itself (:func:`first_slosh_mode`) is the standard equivalent mechanical model of
the first antisymmetric sloshing mode of a liquid in an upright circular cylinder (Abramson,
NASA SP-106, 1966; Ibrahim, *Liquid Sloshing Dynamics*, 2005, ch. 6-8): a mass ``m1`` on a
spring ``k1 = m1 w1^2`` (a pendulum of length ``L1 = g / w1^2`` for small angles) with the
viscous damping of the boundary layer, and -- as in the impact-pendulum models of large
sloshing (Pilipchuk and Ibrahim, J. Sound Vib. 1997) -- rigid barriers at the travel where
the free surface, tilted against the container, reaches the cap. With ``xi = 1.841`` (first
zero of J1'), inner radius ``R`` (m), liquid depth ``h`` (m), liquid mass ``m`` (kg),
kinematic viscosity ``nu`` (m^2/s), ``g = 9.81`` m/s^2:

* ``w1^2 = g xi / R tanh(xi h / R)`` (rad/s)^2 -- 3.5 Hz for a half-full Odwalla bottle;
* ``m1 = m 2 R / (xi (xi^2 - 1) h) tanh(xi h / R)`` kg -- about 30 % of the liquid when half
  full, 16 % when nearly full (the rest moves with the container);
* damping ratio ``zeta = delta / (2 pi)`` with the logarithmic decrement
  ``delta = 4.98 sqrt(nu) R^-3/4 g^-1/4 (1 + 0.318 / sinh(xi h / R) (1 + (1 - h / R) /
  cosh(xi h / R)))`` (Mikishev and Dorozhkin, in SP-106 ch. 4) -- 0.006 for water in a 36 mm
  radius bottle;
* barrier travel ``x_b = L1 sin(atan(s / R))`` m with the head space ``s = H_eq - h`` (m)
  above the liquid in the equivalent cylinder ``H_eq = V / (pi R^2)``: a statically tilted
  free surface (tilt ``theta``) rises ``R tan(theta)`` at the wall, the pendulum then stands
  at ``L1 sin(theta)``. In the plant the barrier is the slosh joint's limit, which Drake's
  SAP solver enforces as a near-rigid, inelastic (damped) constraint: the liquid hits the cap
  and stops, it does not bounce.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import signal

from mmlearn.models.tactile.types import TactileDataError, check_series

__all__ = ["SloshMode", "first_slosh_mode", "RollRecord", "highpass", "filtered_norm",
           "liquid_feature", "liquid_features", "coast_mask", "coast_feature", "liquid_table",
           "evaluate_liquid", "FEATURES", "COAST_DETREND_DEGREE", "COAST_MIN_SAMPLES",
           "HIGHPASS_CUTOFF_HZ", "TACTILE_RATE_HZ"]

FEATURES = ("coast_detrended", "coast", "whole")
"""Tactile features: "coast_detrended" (:func:`coast_feature`: the spread of the filtered
norm about its slow trend within each coast phase), "coast" (its plain spread over the coast
samples) and "whole" (over the whole roll, thesis Eq. 7.11)."""

COAST_DETREND_DEGREE = 2
"""Degree of the polynomial (in time) removed from the filtered norm in each coast phase by
:func:`coast_feature`."""

COAST_MIN_SAMPLES = 6
"""Coast phases with fewer samples are left out of :func:`coast_feature` (a quadratic fit
needs a few more samples than its 3 coefficients; 6 samples = 0.25 s at 24 Hz)."""

HIGHPASS_CUTOFF_HZ = 5.0
"""Cut-off of the high-pass, Hz (thesis: 5 Hz, the lower end of the 5-50 Hz band of human
tactile receptors)."""

TACTILE_RATE_HZ = 24.0
"""Sample rate of the PR2 fingertip arrays in Sec. 7.3, Hz."""


SLOSH_XI = 1.841
"""First zero of the derivative of the Bessel function J1 (first antisymmetric mode)."""

G = 9.81  # m/s^2


@dataclass(frozen=True)
class SloshMode:
    """The first sloshing mode of a liquid in a cylinder (see the module docstring).

    Attributes:
        mass: sloshing mass m1, kg.
        omega: natural frequency w1, rad/s.
        zeta: viscous damping ratio (dimensionless).
        stiffness: k1 = m1 w1^2, N/m.
        damping: c1 = 2 zeta m1 w1, N s/m.
        length: equivalent pendulum length L1 = g / w1^2, m.
        barrier: travel of m1 at which the liquid reaches the cap, m (capped at ``radius``).
    """

    mass: float
    omega: float
    zeta: float
    stiffness: float
    damping: float
    length: float
    barrier: float


def first_slosh_mode(*, radius: float, depth: float, liquid_mass: float,
                     container_height: float, viscosity: float = 1.0e-6) -> SloshMode:
    """The equivalent spring-mass of the first sloshing mode (module docstring).

    Args:
        radius: inner radius of the container, m.
        depth: liquid depth in the equivalent cylinder, m (> 0).
        liquid_mass: mass of all the liquid, kg.
        container_height: height of the equivalent cylinder (inner volume / (pi R^2)), m.
        viscosity: kinematic viscosity of the liquid, m^2/s (water 1e-6, juices ~2e-6).
    """
    for k, v in (("radius", radius), ("depth", depth), ("liquid_mass", liquid_mass),
                 ("container_height", container_height), ("viscosity", viscosity)):
        if not (np.isfinite(v) and v > 0):
            raise ValueError(f"first_slosh_mode: {k} must be a finite number > 0, got {v!r}")
    if depth >= container_height:
        raise ValueError(f"first_slosh_mode: depth {depth:g} m must be below the container "
                         f"height {container_height:g} m")
    xi, R, h = SLOSH_XI, float(radius), float(depth)
    th = np.tanh(xi * h / R)
    w2 = G * xi / R * th
    w = float(np.sqrt(w2))
    m1 = float(liquid_mass * 2 * R / (xi * (xi**2 - 1) * h) * th)
    delta = 4.98 * np.sqrt(viscosity) * R**-0.75 * G**-0.25 * (
        1 + 0.318 / np.sinh(xi * h / R) * (1 + (1 - h / R) / np.cosh(xi * h / R)))
    zeta = float(delta / (2 * np.pi))
    L1 = G / w2
    barrier = float(min(L1 * np.sin(np.arctan((container_height - h) / R)), R))
    return SloshMode(mass=m1, omega=w, zeta=zeta, stiffness=float(m1 * w2),
                     damping=2 * zeta * m1 * w, length=float(L1), barrier=barrier)


@dataclass
class RollRecord:
    """The tactile signals of one roll of a grasped container.

    Attributes:
        taxels: (T, n_taxels) per-cell force (or pressure) while rolling, newtons.
        rate_hz: sample rate, Hz (must exceed twice the cut-off).
        weight: weight of the held object from the wrist force sensor, newtons; None if not
            measured.
        liquid: True / False ground truth (None when unknown).
        container: container name (for per-container tables).
        coast: (T,) bool, the samples of the coast phases (constant commanded roll rate,
            :func:`coast_mask`), or None when unknown (then only the "whole" feature exists).
    """

    taxels: np.ndarray
    rate_hz: float = TACTILE_RATE_HZ
    weight: float | None = None
    liquid: bool | None = None
    container: str | None = None
    coast: np.ndarray | None = None

    def __post_init__(self):
        self.taxels = check_series("taxels", self.taxels, ndim=2)
        if self.taxels.shape[0] < 3 or self.taxels.shape[1] < 1:
            raise TactileDataError(f"taxels: expected at least 3 samples of at least 1 taxel, "
                                   f"got shape {self.taxels.shape}")
        if not (np.isfinite(self.rate_hz) and self.rate_hz > 0):
            raise TactileDataError(f"rate_hz: expected a number > 0, got {self.rate_hz!r}")
        if self.weight is not None and not np.isfinite(self.weight):
            raise TactileDataError(f"weight: expected a finite number, got {self.weight!r}")
        if self.coast is not None:
            m = _check_mask("coast", self.coast, self.taxels.shape[0])
            if m.sum() < 2:
                raise TactileDataError("coast: fewer than 2 coast samples")
            self.coast = m


def _check_mask(name: str, mask, n: int) -> np.ndarray:
    """``mask`` as a (n,) bool array, or a :class:`TactileDataError` naming ``name``."""
    m = np.asarray(mask)
    if m.shape != (n,) or m.dtype != bool:
        raise TactileDataError(f"{name}: expected a bool array of shape ({n},), got "
                               f"{m.dtype} {m.shape}")
    return m


def highpass(x, *, rate_hz: float = TACTILE_RATE_HZ, cutoff_hz: float = HIGHPASS_CUTOFF_HZ,
             order: int = 1) -> np.ndarray:
    """Butterworth high-pass along axis 0 of ``x`` ``(T, ...)`` (causal, steady initial state).

    Args:
        rate_hz: sample rate, Hz. cutoff_hz: -3 dB frequency, Hz (< rate_hz / 2).
        order: filter order (thesis: 1).
    """
    x = np.asarray(x, float)
    if not (0 < cutoff_hz < rate_hz / 2):
        raise ValueError(f"cutoff_hz: expected 0 < cut-off < rate/2 = {rate_hz / 2:g} Hz, got "
                         f"{cutoff_hz!r}")
    if x.shape[0] < 1:
        raise ValueError("highpass: empty signal")
    b, a = signal.butter(order, cutoff_hz, "highpass", fs=rate_hz)
    zi = signal.lfilter_zi(b, a)
    zi = zi.reshape((-1,) + (1,) * (x.ndim - 1)) * x[:1]
    y, _ = signal.lfilter(b, a, x, axis=0, zi=zi)
    return y


def filtered_norm(taxels, *, rate_hz: float = TACTILE_RATE_HZ,
                  cutoff_hz: float = HIGHPASS_CUTOFF_HZ) -> np.ndarray:
    """Eq. 7.9: ``f_filtered(t) = || highpass(taxels)(t) ||_2`` over the taxels, (T,)."""
    x = check_series("taxels", taxels, ndim=2)
    return np.linalg.norm(highpass(x, rate_hz=rate_hz, cutoff_hz=cutoff_hz), axis=1)


def liquid_feature(taxels, *, rate_hz: float = TACTILE_RATE_HZ,
                   cutoff_hz: float = HIGHPASS_CUTOFF_HZ, mask=None) -> float:
    """Eq. 7.10-7.11: the sample standard deviation (n - 1) of :func:`filtered_norm` over the
    roll, in the taxels' unit; with ``mask`` ((T,) bool) over the masked samples only (the
    filter still runs over every sample: the coast-phase feature, :func:`coast_mask`)."""
    f = filtered_norm(taxels, rate_hz=rate_hz, cutoff_hz=cutoff_hz)
    if mask is not None:
        f = f[_check_mask("mask", mask, len(f))]
    if len(f) < 2:
        raise TactileDataError("taxels: at least 2 samples are needed for a spread")
    return float(np.std(f, ddof=1))


def coast_mask(t, windows, *, start: float, end: float, delay: float = 0.0) -> np.ndarray:
    """The coast samples of a roll: times ``t`` (s, (T,)) inside ``[start, end]`` (the roll,
    s) and outside every interval ``[a, b + delay]`` of ``windows`` ((k, 2) s: where the
    commanded roll rate changes -- the start, the reversals and the stop), i.e. where the
    wrist turns at a constant commanded rate and, ``delay`` s (>= 0) after the last change.
    Returns a (T,) bool array."""
    t = np.asarray(t, float)
    w = np.asarray(windows, float).reshape(-1, 2)
    if t.ndim != 1 or not np.all(np.isfinite(t)):
        raise TactileDataError("coast_mask: t must be a finite 1-D array of times")
    if not np.all(np.isfinite(w)) or np.any(w[:, 1] < w[:, 0]):
        raise TactileDataError("coast_mask: windows must be finite (start, end) pairs with "
                               "start <= end")
    if not (np.isfinite(delay) and delay >= 0):
        raise TactileDataError(f"coast_mask: delay must be a finite number >= 0 s, got "
                               f"{delay!r}")
    inside = (t >= start) & (t <= end)
    busy = ((t[:, None] >= w[None, :, 0]) & (t[:, None] <= w[None, :, 1] + delay)).any(axis=1)
    return inside & ~busy


def _runs(mask: np.ndarray) -> list[np.ndarray]:
    """Index arrays of the contiguous True runs of a 1-D bool mask."""
    idx = np.flatnonzero(mask)
    if not len(idx):
        return []
    return np.split(idx, np.flatnonzero(np.diff(idx) > 1) + 1)


def coast_feature(taxels, mask, *, rate_hz: float = TACTILE_RATE_HZ,
                  cutoff_hz: float = HIGHPASS_CUTOFF_HZ, degree: int = COAST_DETREND_DEGREE,
                  min_samples: int = COAST_MIN_SAMPLES) -> float:
    """The spread of the high-passed taxel norm (:func:`filtered_norm`, Eq. 7.9, the filter run
    over every sample) about its slow trend within each coast phase, in the taxels' unit.

    Each contiguous run of ``mask`` ((T,) bool, :func:`coast_mask`) with at least
    ``min_samples`` samples is one coast phase; in each, a polynomial of ``degree`` in time is
    fitted to the filtered norm by least squares and removed; the feature is the root mean
    square of the residuals over all phases with ``n - p`` in the denominator (n residuals,
    p fitted coefficients). Why: in a coast phase a rigid object's load on the pads is a
    smooth function of the roll angle (gravity shifts it from one pad to the other as the
    wrist turns at a constant rate), and the first-order 5 Hz high-pass passes that shift at
    ~20 % as a smooth curve; a liquid keeps ringing at its sloshing frequency (3.5-3.9 Hz here,
    about two periods per phase), which a quadratic does not follow. A deviation from the
    thesis' Eq. 7.11 (see the module docstring)."""
    x = check_series("taxels", taxels, ndim=2)
    m = _check_mask("mask", mask, x.shape[0])
    if not (isinstance(degree, (int, np.integer)) and 0 <= degree
            and min_samples > degree + 1):
        raise ValueError(f"coast_feature: need degree >= 0 and min_samples > degree + 1, got "
                         f"degree {degree!r}, min_samples {min_samples!r}")
    runs = [r for r in _runs(m) if len(r) >= min_samples]
    if not runs:
        raise TactileDataError(f"coast_feature: no coast phase of at least {min_samples} "
                               f"samples (the roll's constant-rate phases are too short)")
    f = filtered_norm(x, rate_hz=rate_hz, cutoff_hz=cutoff_hz)
    ss, n, p = 0.0, 0, 0
    for r in runs:
        u = (r - r.mean()) / max(len(r) - 1, 1)  # centred, scaled time: well-conditioned
        V = np.vander(u, degree + 1)
        coef, *_ = np.linalg.lstsq(V, f[r], rcond=None)
        ss += float(np.sum((f[r] - V @ coef) ** 2))
        n, p = n + len(r), p + degree + 1
    return float(np.sqrt(ss / (n - p)))


def _record_feature(r, feature: str, cutoff_hz: float) -> float:
    if feature not in FEATURES:
        raise ValueError(f"feature: expected one of {', '.join(FEATURES)}, got {feature!r}")
    if feature != "whole" and r.coast is None:
        raise TactileDataError(f"the {feature} feature needs the record's coast mask (a roll "
                               f"with constant-rate phases: sweep or triangle)")
    if feature == "coast":
        return liquid_feature(r.taxels, rate_hz=r.rate_hz, cutoff_hz=cutoff_hz, mask=r.coast)
    if feature == "coast_detrended":
        return coast_feature(r.taxels, r.coast, rate_hz=r.rate_hz, cutoff_hz=cutoff_hz)
    return liquid_feature(r.taxels, rate_hz=r.rate_hz, cutoff_hz=cutoff_hz)


def liquid_features(records, *, with_weight: bool = False,
                    cutoff_hz: float = HIGHPASS_CUTOFF_HZ, feature: str = "whole") -> np.ndarray:
    """Feature matrix of many :class:`RollRecord`: ``(n, 1)`` = sigma, or ``(n, 2)`` = (sigma,
    weight in N) with ``with_weight`` (every record then needs a weight). ``feature``:
    "whole" (the thesis' spread over the whole roll), "coast" (over the coast samples,
    ``RollRecord.coast``) or "coast_detrended" (:func:`coast_feature`)."""
    rows = []
    for i, r in enumerate(records):
        s = _record_feature(r, feature, cutoff_hz)
        if with_weight:
            if r.weight is None:
                raise TactileDataError(f"record {i}: with_weight needs a weight")
            rows.append([s, r.weight])
        else:
            rows.append([s])
    if not rows:
        raise TactileDataError("liquid_features: no records")
    return np.asarray(rows, dtype=float)


def liquid_table(records, *, cutoff_hz: float = HIGHPASS_CUTOFF_HZ,
                 feature: str = "whole") -> list[dict]:
    """Table 7.4: per (container, liquid) the number of trials, mean weight (N) and the mean
    and standard deviation of the tactile feature ``feature`` (taxel unit), sorted by
    container."""
    recs = list(records)
    if not recs:
        raise TactileDataError("liquid_table: no records")
    feat = liquid_features(recs, cutoff_hz=cutoff_hz, feature=feature)[:, 0]
    groups: dict = {}
    for r, v in zip(recs, feat):
        groups.setdefault((str(r.container), r.liquid), []).append((v, r.weight))
    rows = []
    for (c, liq), vals in sorted(groups.items(), key=lambda kv: (kv[0][0], str(kv[0][1]))):
        v = np.array([x for x, _ in vals])
        w = [x for _, x in vals if x is not None]
        rows.append({"container": c, "liquid": liq, "trials": len(v),
                     "weight_n": float(np.mean(w)) if w else None,
                     "feature_mean": float(v.mean()),
                     "feature_std": float(v.std(ddof=1)) if len(v) > 1 else 0.0})
    return rows


def evaluate_liquid(records, *, with_weight: bool = False, classifier: str = "tree",
                    folds: int = 10, seed: int = 0, feature: str = "whole"):
    """Stratified ``folds``-fold cross-validation of liquid / no liquid from the tactile
    feature ``feature`` (see :func:`liquid_features`; and the weight); returns a
    :class:`~mmlearn.models.tactile.state.ClassificationReport` with labels "liquid" and
    "no_liquid"."""
    from mmlearn.models.tactile.state import cross_validate

    recs = list(records)
    for i, r in enumerate(recs):
        if r.liquid is None:
            raise TactileDataError(f"record {i}: no liquid ground truth")
    X = liquid_features(recs, with_weight=with_weight, feature=feature)
    y = np.array(["liquid" if r.liquid else "no_liquid" for r in recs])
    return cross_validate(X, y, classifier=classifier, folds=folds, seed=seed)
