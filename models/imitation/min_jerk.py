"""Minimum-jerk trajectories through via points (human-like reaching, Flash & Hogan 1985).

A human hand moving through via points at given times follows, to a good approximation, the
path that minimises the integrated squared jerk. Between two *stops* (points where the hand
rests: the start, the end, a grasp) the minimiser through interior via points at fixed times
is a piecewise quintic that is C4 at the via points with zero velocity and acceleration at
both stops: exactly the degree-5 interpolating B-spline with those end conditions, which
``scipy.interpolate.make_interp_spline`` computes. A run without interior via points reduces
to the classic 10 s^3 - 15 s^4 + 6 s^5 profile. A stop may carry a dwell time (the hand rests
there, e.g. while the fingers close).

Plain numpy / scipy (no Drake). Units: positions in metres (any dimension D), times in
seconds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import make_interp_spline

__all__ = ["MinJerkTrajectory", "min_jerk_segment", "segment_times"]


def min_jerk_segment(x0, x1, duration: float, t) -> np.ndarray:
    """The rest-to-rest minimum-jerk move from ``x0`` to ``x1`` (each (D,)) in ``duration``
    seconds, evaluated at times ``t`` (n,) (clamped to [0, duration]); returns (n, D)."""
    x0, x1 = np.asarray(x0, float), np.asarray(x1, float)
    if not duration > 0:
        raise ValueError(f"min_jerk_segment: duration must be > 0 s, got {duration}")
    s = np.clip(np.asarray(t, float) / duration, 0.0, 1.0)[:, None]
    return x0 + (x1 - x0) * (10 * s**3 - 15 * s**4 + 6 * s**5)


def segment_times(points, *, speed: float, min_duration: float = 0.3) -> np.ndarray:
    """Durations (m-1,) of the moves between consecutive ``points`` (m, D): the distance
    over ``speed`` (m/s, the mean speed of the move), at least ``min_duration`` s."""
    P = np.asarray(points, float)
    if not speed > 0:
        raise ValueError(f"segment_times: speed must be > 0 m/s, got {speed}")
    d = np.linalg.norm(np.diff(P, axis=0), axis=1)
    return np.maximum(d / speed, min_duration)


@dataclass
class _Run:
    t0: float
    t1: float
    spline: object | None  # None: a rest (constant position)
    x: np.ndarray


class MinJerkTrajectory:
    """Minimum-jerk trajectory through via points at given times.

    Args:
        times: (m,) strictly increasing times at which the hand passes ``points``, s.
        points: (m, D) via points, m.
        stops: (m,) bool: the hand rests at this point (zero velocity and acceleration).
            The first and last points are always stops. Default: only those two.
        dwell: (m,) rest time at each stop, s (ignored for non-stops); the times of the
            points after a dwell are shifted by it.

    ``value(t)`` is vectorised; before the first time it returns the first point, after
    the end (:attr:`duration`) the last one.
    """

    def __init__(self, times, points, *, stops=None, dwell=None, optimize_times=False):
        t = np.asarray(times, float)
        P = np.asarray(points, float)
        if P.ndim == 1:
            P = P[:, None]
        if t.ndim != 1 or P.ndim != 2 or P.shape[0] != t.size:
            raise ValueError(f"MinJerkTrajectory: times (m,) and points (m, D) must match, "
                             f"got {t.shape} and {np.shape(points)}")
        if t.size < 2:
            raise ValueError("MinJerkTrajectory: needs at least 2 via points")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(P))):
            raise ValueError("MinJerkTrajectory: times and points must be finite")
        if np.any(np.diff(t) <= 0):
            raise ValueError("MinJerkTrajectory: times must be strictly increasing")
        m = t.size
        st = np.zeros(m, bool) if stops is None else np.asarray(stops, bool).copy()
        if st.shape != (m,):
            raise ValueError(f"MinJerkTrajectory: stops must have {m} entries")
        st[0] = st[-1] = True
        dw = np.zeros(m) if dwell is None else np.asarray(dwell, float)
        if dw.shape != (m,) or np.any(dw < 0) or not np.all(np.isfinite(dw)):
            raise ValueError(f"MinJerkTrajectory: dwell must be {m} finite values >= 0 s")
        dw = np.where(st, dw, 0.0)
        shift = np.concatenate([[0.0], np.cumsum(dw)[:-1]])
        t = t + shift  # arrival times after the dwells before each point
        self.dim = P.shape[1]
        self.start_time = float(t[0])
        runs: list[_Run] = []
        idx = np.flatnonzero(st)
        for a, b in zip(idx[:-1], idx[1:]):
            if dw[a] > 0:
                runs.append(_Run(t[a], t[a] + dw[a], None, P[a]))
            tt, pp = t[a:b + 1].copy(), P[a:b + 1]
            tt[0] += dw[a]
            if tt.size > 2 and np.any(np.diff(tt) <= 0):
                raise ValueError("MinJerkTrajectory: a dwell overlaps the next via point")
            if tt.size == 2:  # the classic profile (scipy needs >= 6 conditions)
                spline = _classic(pp[0], pp[1], tt[0], tt[1])
            else:
                if optimize_times:
                    tt = _best_times(tt, pp)
                    t[a + 1:b] = tt[1:-1]
                spline = _quintic(tt, pp)
            runs.append(_Run(float(tt[0]), float(tt[-1]), spline, pp[-1]))
        if dw[-1] > 0:
            runs.append(_Run(t[-1], t[-1] + dw[-1], None, P[-1]))
        self._runs = runs
        self.end_time = float(runs[-1].t1)
        self.via_times = t
        self.points = P
        self.stops = st

    @property
    def duration(self) -> float:
        """End time minus start time, s."""
        return self.end_time - self.start_time

    def value(self, t, derivative: int = 0) -> np.ndarray:
        """Position (or its ``derivative``-th time derivative) at times ``t`` (n,); (n, D)."""
        tt = np.atleast_1d(np.asarray(t, float))
        out = np.zeros((tt.size, self.dim))
        if derivative == 0:
            out[:] = self.points[0]
            out[tt >= self.end_time] = self.points[-1]
        for r in self._runs:
            sel = (tt >= r.t0) & (tt <= r.t1)
            if not np.any(sel):
                continue
            if r.spline is None:
                out[sel] = r.x if derivative == 0 else 0.0
            else:
                out[sel] = r.spline(tt[sel], nu=derivative) if derivative else r.spline(tt[sel])
        return out


def _quintic(tt, pp):
    """The C4 quintic through ``pp`` at ``tt`` at rest (zero velocity and acceleration)
    at both ends."""
    z = np.zeros(pp.shape[1])
    return make_interp_spline(tt, pp, k=5, bc_type=([(1, z), (2, z)], [(1, z), (2, z)]))


def _jerk_cost(tt, pp, grid=200) -> float:
    """Integrated squared jerk of :func:`_quintic` (trapezoid rule on ``grid`` points)."""
    sp = _quintic(tt, pp)
    g = np.linspace(tt[0], tt[-1], grid)
    j = sp(g, nu=3)
    return float(np.trapezoid(np.sum(j * j, axis=1), g))


def _best_times(tt, pp) -> np.ndarray:
    """Interior times of a run minimising :func:`_jerk_cost` (start and end fixed): the
    segment durations are a softmax of free parameters (so they stay positive and sum to
    the run's duration), started from the given ones."""
    from scipy.optimize import minimize

    T0, T = tt[0], tt[-1] - tt[0]
    d0 = np.diff(tt) / T

    def times(z):
        w = np.exp(z - z.max())
        w = np.maximum(w / w.sum(), 0.02)
        w /= w.sum()
        return np.concatenate([[T0], T0 + T * np.cumsum(w)])

    z0 = np.log(d0)
    res = minimize(lambda z: _jerk_cost(times(z), pp), z0, method="Nelder-Mead",
                   options={"xatol": 1e-3, "fatol": 1e-6, "maxfev": 400})
    out = times(res.x if res.fun <= _jerk_cost(times(z0), pp) else z0)
    out[-1] = tt[-1]
    return out


class _classic:
    """The rest-to-rest quintic as a callable with derivatives (like a BSpline)."""

    def __init__(self, x0, x1, t0, t1):
        self.x0, self.dx, self.t0, self.T = x0, x1 - x0, t0, t1 - t0

    def __call__(self, t, nu: int = 0):
        s = np.clip((np.asarray(t, float) - self.t0) / self.T, 0, 1)[:, None]
        coeffs = [np.array([0, 0, 0, 10, -15, 6.0])]
        for _ in range(nu):
            c = coeffs[-1]
            coeffs.append(np.array([c[i + 1] * (i + 1) for i in range(5)] + [0.0]))
        c = coeffs[nu]
        poly = sum(c[i] * s**i for i in range(6))
        if nu == 0:
            return self.x0 + self.dx * poly
        return self.dx * poly / self.T**nu
