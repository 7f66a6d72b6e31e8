"""How sure is the robot of its reproduction? The likelihood of its own trajectory under the
learned DBN, against the demonstrations' own (thesis Sec. 9.1's failure detection for
interactive teaching).

The DBN of constraints (:func:`mmlearn.models.imitation.dbn.learn_task`) holds per time slice
``k`` a Gaussian ``N(mu_c[k], Sigma_c[k])`` for every Cartesian constraint ``r_c = x_c - x_E``
(object minus hand). The reproduction fuses them weighted by their precisions; with too few
demonstrations the model cannot tell the relevant constraints from the irrelevant ones, the
fused step satisfies none of them in a new scene and the trajectory is improbable under the
model. The measure here is the *surprise* of a hand position at slice ``k``:

    s_k = sum_c w_c d_c^2 / D,    d_c^2 = (r_c - mu_c[k])^T Sigma_c[k]^-1 (r_c - mu_c[k]),
    w_c = tr(Sigma_c[k]^-1) / sum_c' tr(Sigma_c'[k]^-1),

the precision-weighted mean squared Mahalanobis distance per dimension (the negative
log-likelihood of the slice up to its normaliser, with each constraint weighted by how much it
steers the reproduction: a violated constraint the model itself considers irrelevant costs
little). :func:`demonstration_surprise` evaluates the demonstrations under the model they
taught (aligned as for learning) and :func:`reference_surprise` takes the largest smoothed
value over them: how surprising a correct execution is to this model. A reproduction is
*unsure* (:class:`SurpriseMonitor`) once its smoothed surprise exceeds ``factor`` times that
reference (a surprise of 50 is a deviation of about 7 standard deviations, on average, along the
constraints that steer the reproduction).

Plain numpy; no pydrake import.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mmlearn.models.common.config import param, validate_fields
from mmlearn.models.imitation.types import ImitationDataError, TaskModel

__all__ = ["ConfidenceConfig", "slice_surprise", "trajectory_surprise",
           "demonstration_surprise", "reference_surprise", "smooth", "SurpriseMonitor"]


@dataclass
class ConfidenceConfig:
    """When a reproduction counts as unsure.

    Attributes:
        factor: unsure when the smoothed surprise exceeds this times the demonstrations'
            largest smoothed surprise (dimensionless).
        floor: the reference surprise is at least this (dimensionless; a single
            demonstration explains itself almost perfectly).
        window: width of the moving average over the surprise, s.
        ignore_start: the first seconds of a reproduction are not judged: the robot starts
            from its own rest pose, not the teacher's, and the first slices' constraints
            describe the teacher's.
    """

    factor: float = param(50.0, gt=1)
    floor: float = param(1.0, gt=0)
    window: float = param(1.0, unit="s", gt=0)
    ignore_start: float = param(2.0, unit="s", ge=0)

    def validate(self) -> "ConfidenceConfig":
        validate_fields(self)
        return self


def _constraint_terms(model: TaskModel, ks: np.ndarray, hand: np.ndarray, objects: dict):
    """Per Cartesian constraint with an observed object: (d^2 (T,), tr(Sigma^-1) (T,))."""
    out = []
    for c in model.constraints:
        if not c.startswith("obj:") or c[4:] not in objects:
            continue
        o = np.asarray(objects[c[4:]], float)
        if o.shape != hand.shape:
            raise ImitationDataError(f"object {c[4:]!r}: shape {o.shape} differs from the "
                                     f"hand's {hand.shape}")
        e = (o - hand) - np.asarray(model.mean[c], float)[ks]
        v = np.asarray(model.var[c], float)[ks]
        if v.ndim == 2:                                       # diagonal variances (T, D)
            d2 = np.sum(e * e / v, axis=1)
            tr = np.sum(1.0 / v, axis=1)
        else:                                                 # full covariances (T, D, D)
            P = np.linalg.inv(v)
            d2 = np.einsum("td,tde,te->t", e, P, e)
            tr = np.trace(P, axis1=1, axis2=2)
        out.append((d2, tr))
    return out


def trajectory_surprise(model: TaskModel, ks, hand, objects: dict) -> np.ndarray:
    """The surprise ``s`` (module docstring) of hand positions ``hand`` (T, D) at slices
    ``ks`` (T,) with the objects at ``objects`` (name -> (T, D), m); NaN where the hand or
    every object is unknown."""
    hand = np.atleast_2d(np.asarray(hand, float))
    ks = np.clip(np.asarray(ks, int).reshape(-1), 0, model.S - 1)
    if ks.shape[0] != hand.shape[0]:
        raise ImitationDataError(f"trajectory_surprise: {ks.shape[0]} slices for "
                                 f"{hand.shape[0]} hand positions")
    terms = _constraint_terms(model, ks, hand, objects)
    if not terms:
        raise ImitationDataError("trajectory_surprise: no object of the model's Cartesian "
                                 f"constraints given (model: {model.objects})")
    d2 = np.stack([t[0] for t in terms])                      # (C, T)
    tr = np.stack([t[1] for t in terms])
    ok = np.isfinite(d2)
    w = np.where(ok, tr, 0.0)
    wsum = w.sum(axis=0)
    s = np.where(wsum > 0, np.sum(np.where(ok, d2, 0.0) * w, axis=0) / np.where(wsum > 0, wsum, 1.0),
                 np.nan)
    return s / hand.shape[1]


def slice_surprise(model: TaskModel, k: int, hand, objects: dict) -> float:
    """The surprise of one hand position ``hand`` (D,) at slice ``k``."""
    objs = {n: np.asarray(p, float)[None, :] for n, p in objects.items()}
    return float(trajectory_surprise(model, [k], np.asarray(hand, float)[None, :], objs)[0])


def smooth(s, n: int) -> np.ndarray:
    """Trailing moving average of ``s`` over ``n`` samples (NaN left out; NaN where a
    window holds no finite value)."""
    s = np.asarray(s, float)
    n = max(1, int(n))
    ok = np.isfinite(s)
    c = np.concatenate([[0.0], np.cumsum(np.where(ok, s, 0.0))])
    m = np.concatenate([[0], np.cumsum(ok)])
    i = np.arange(1, s.shape[0] + 1)
    lo = np.maximum(0, i - n)
    cnt = m[i] - m[lo]
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(cnt > 0, (c[i] - c[lo]) / np.maximum(cnt, 1), np.nan)


def demonstration_surprise(model: TaskModel, demos) -> list[np.ndarray]:
    """The surprise of each demonstration under ``model`` (aligned onto the model's time
    base as :func:`~mmlearn.models.imitation.dbn.learn_task` aligns them; one array per
    demonstration)."""
    from mmlearn.models.imitation.dbn import align_demonstrations

    demos = list(demos)
    if not demos:
        raise ImitationDataError("demonstration_surprise: no demonstrations given")
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        al = align_demonstrations(demos, dt=model.meta.get("dt"))
    out = []
    for d in al:
        T = min(d.T, model.S)
        out.append(trajectory_surprise(model, np.arange(T), d.hand[:T],
                                       {n: v[:T] for n, v in d.objects.items()}))
    return out


def reference_surprise(model: TaskModel, demos, *, window: float = 1.0,
                       floor: float = 1.0) -> float:
    """The largest smoothed surprise (moving average over ``window`` s) of the
    demonstrations under the model they taught, at least ``floor``."""
    dt = float(model.meta.get("dt") or (model.t[1] - model.t[0] if model.S > 1 else 0.2))
    n = max(1, int(round(window / dt)))
    peaks = [np.nanmax(smooth(s, n)) for s in demonstration_surprise(model, demos)
             if np.any(np.isfinite(s))]
    return float(max([floor] + [p for p in peaks if np.isfinite(p)]))


class SurpriseMonitor:
    """Watches a reproduction sample by sample: :meth:`update` with the slice, the hand and
    the objects, returns True once the smoothed surprise exceeds the threshold (and stays
    flagged). Plain Python state; it lives beside a simulation loop, not in a Drake system.

    Args:
        model: the learned task.
        demos: the demonstrations it was learned from (the reference).
        sample_period: period of the samples given to :meth:`update`, s.
        config: :class:`ConfidenceConfig`.
    """

    def __init__(self, model: TaskModel, demos, *, sample_period: float,
                 config: ConfidenceConfig | None = None):
        if not (np.isfinite(sample_period) and sample_period > 0):
            raise ImitationDataError(f"SurpriseMonitor: sample_period must be > 0 s, "
                                     f"got {sample_period!r}")
        self.config = (config or ConfidenceConfig()).validate()
        self.model = model
        self.reference = reference_surprise(model, demos, window=self.config.window,
                                            floor=self.config.floor)
        self.threshold = self.config.factor * self.reference
        self._n = max(1, int(round(self.config.window / sample_period)))
        self._skip = int(round(self.config.ignore_start / sample_period))
        self.samples: list[float] = []
        self.flag_index: int | None = None

    def update(self, k: int, hand, objects: dict) -> bool:
        """Add one sample; True when the reproduction is (or was already) unsure."""
        s = float("nan")
        if len(self.samples) >= self._skip:
            try:
                s = slice_surprise(self.model, int(k), hand, objects)
            except ImitationDataError:      # nothing observed: no evidence either way
                pass
        self.samples.append(s)
        if self.flag_index is None:
            recent = np.asarray(self.samples[-self._n:], float)
            if np.count_nonzero(np.isfinite(recent)) >= self._n \
                    and np.nanmean(recent) > self.threshold:
                self.flag_index = len(self.samples) - 1
        return self.flag_index is not None

    @property
    def flagged(self) -> bool:
        """True once the reproduction was found unsure."""
        return self.flag_index is not None

    def peak(self) -> float:
        """The largest smoothed surprise so far (NaN before any finite sample)."""
        if not self.samples:
            return float("nan")
        sm = smooth(self.samples, self._n)
        return float(np.nanmax(sm)) if np.any(np.isfinite(sm)) else float("nan")

    def summary(self, sample_period: float) -> dict:
        """JSON-able: the reference, threshold, peak (as a multiple of the reference) and the
        time of the flag (s from the start, None when not flagged)."""
        peak = self.peak()
        return {"reference_surprise": self.reference, "threshold": self.threshold,
                "peak_surprise": peak, "peak_ratio": peak / self.reference,
                "unsure": self.flagged,
                "unsure_at_s": None if self.flag_index is None
                else (self.flag_index + 1) * sample_period}
