"""Observation model of the articulation link models (thesis Eq. 4.13-4.15) and EM for the
outlier ratio; see models/articulation/link.py for the whole model and the reading of the thesis.

An inlier is the true pose plus isotropic Gaussian noise (``sigma_pos`` metres on the
position, ``sigma_orient`` radians on the rotation vector of the orientation error); an
outlier (probability gamma) is uniform over a position volume V (m^3) times SO(3) (volume
8 pi^2). ``ObservationModel.gamma_prior`` says how p(gamma) ~ exp(-w gamma) enters the
likelihood (default ``"plugin"``: ML gamma by EM, -w gamma per observation),
``config_prior`` how p(q | M) does (LinkModel.config_terms).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np

from mmlearn.models.common.config import param, validate_fields
from mmlearn.models.articulation.kernels import em_gamma_full

__all__ = ["ObservationModel", "DEFAULT_GAMMA_WEIGHT", "GAMMA_PRIOR_MODES", "em_gamma"]

_LOG_2PI = float(np.log(2 * np.pi))
_LOG_SO3_VOLUME = float(np.log(8 * np.pi**2))

#: default weight w of the outlier-ratio prior p(gamma) ~ exp(-w gamma), applied per
#: observation: an outlier ratio of 0.05 costs a factor 100 per observation (w = ln(100) /
#: 0.05 ~ 92.1), the value of the thesis' implementation (tum-vision/articulation).
DEFAULT_GAMMA_WEIGHT = float(np.log(100.0) / 0.05)

#: how p(gamma) enters the data likelihood (see ObservationModel.gamma_prior)
GAMMA_PRIOR_MODES = ("observation", "plugin", "track")


@dataclass
class ObservationModel:
    """Gaussian + uniform-outlier observation model (Eq. 4.13-4.15).

    Attributes:
        sigma_pos: position noise standard deviation, metres (per axis).
        sigma_orient: orientation noise standard deviation, radians (per rotation-vector axis).
        gamma_weight: w of the outlier-ratio prior p(gamma) ~ exp(-w gamma) (dimensionless).
        outlier_volume_m3: volume of the uniform position-outlier distribution, m^3; None means
            "set from the training track at fit time" (cube of the largest extent + 6 sigma,
            at least 1 m^3).
        gamma_prior: how p(gamma) of Eq. 4.15 enters the likelihood of a track of n
            observations. ``"plugin"`` (default; the thesis' implementation,
            tum-vision/articulation): gamma is the maximum-likelihood EM estimate of the
            mixture, and every observation's likelihood is multiplied by p(gamma), so log L
            gets -w gamma n. ``"observation"``: the same -w gamma n, with gamma the MAP
            estimate under it (Eq. 4.15 read as a prior on the estimate: far below the true
            outlier ratio, see articulation_experiments --only selection). ``"track"``
            (mmlearn before 2026-11): the normalised prior once per track, MAP gamma.
        config_prior: the configuration prior p(q | M) of Eq. 4.27-4.28: ``"resolved"``
            (default) Eq. 4.26's integral over the configurations evaluated along the path
            (LinkModel.log_config_prior: ~ min(n, c)^-d, c the number of configurations the
            noise can tell apart over the observed range);
            ``"n"``: n^-d as Eq. 4.27 writes it (mmlearn before 2026-11).
    """

    sigma_pos: float = param(0.01, unit="m", gt=0)
    sigma_orient: float = param(np.deg2rad(5.0), unit="rad", gt=0)
    gamma_weight: float = param(DEFAULT_GAMMA_WEIGHT, ge=0)
    outlier_volume_m3: float | None = param(None, unit="m^3", gt=0, optional=True)
    gamma_prior: str = param("plugin", choices=GAMMA_PRIOR_MODES)
    config_prior: str = param("resolved", choices=("resolved", "n"))

    #: lower bound of the automatic outlier volume (a 1 m cube: the robot's workspace); a
    #: volume as small as a short track would make "everything is an outlier" too likely.
    min_outlier_volume_m3 = 1.0

    def __post_init__(self):
        validate_fields(self)
        for name in ("sigma_pos", "sigma_orient", "gamma_weight"):
            setattr(self, name, float(getattr(self, name)))
        if self.outlier_volume_m3 is not None:
            self.outlier_volume_m3 = float(self.outlier_volume_m3)

    def with_volume_from(self, positions: np.ndarray) -> "ObservationModel":
        if self.outlier_volume_m3 is not None:
            return self
        ext = float(np.max(np.ptp(positions, axis=0))) if len(positions) > 1 else 0.0
        side = ext + 6.0 * self.sigma_pos
        vol = max(side**3, self.min_outlier_volume_m3)
        # a copy with the volume set (dataclasses.replace would validate every field again,
        # once per candidate model; the volume is positive by construction)
        out = copy.copy(self)
        out.outlier_volume_m3 = float(vol)
        return out

    def log_inlier(self, ep2: np.ndarray, eo: np.ndarray | None) -> np.ndarray:
        """log N for squared position errors ep2 (m^2) and orientation errors eo (rad)."""
        sp2 = self.sigma_pos**2
        out = -0.5 * ep2 / sp2 - 1.5 * (_LOG_2PI + np.log(sp2))
        if eo is not None:
            so2 = self.sigma_orient**2
            out = out - 0.5 * eo * eo / so2 - 1.5 * (_LOG_2PI + np.log(so2))
        return out

    def log_outlier(self, has_orientation: bool) -> float:
        v = -float(np.log(self.outlier_volume_m3))
        return v - _LOG_SO3_VOLUME if has_orientation else v

    def map_weight(self, n: int) -> float:
        """Weight of the prior in the EM M-step for a track of n observations (0: ML)."""
        if self.gamma_prior == "observation":
            return self.gamma_weight * n
        if self.gamma_prior == "plugin":
            return 0.0
        return self.gamma_weight

    def log_gamma_prior(self, gamma, n: int):
        """log p(gamma) as it enters the log-likelihood of a track of n observations."""
        g = np.asarray(gamma, float)
        w = self.gamma_weight
        if w <= 0:
            return np.zeros_like(g)
        if self.gamma_prior == "track":
            return np.log(w) - w * g - np.log1p(-np.exp(-w))
        return -w * g * n


def _obs_from_dict(d: dict) -> ObservationModel:
    """ObservationModel from its asdict(); files saved before ``gamma_prior`` existed used
    the prior once per track."""
    d = dict(d)
    d.setdefault("gamma_prior", "track")
    d.setdefault("config_prior", "n")
    return ObservationModel(**d)


def em_gamma(log_in: np.ndarray, log_out: float, w: float, *, iters: int = 30,
             gamma0: float = 0.3, tol: float = 1e-7, responsibilities: bool = True):
    """EM for the outlier ratio, vectorised over hypotheses.

    Fixed point: the outlier responsibilities g / ((1 - g) L + g) (L the inlier / outlier
    likelihood ratio, clipped at exp(+-700): responsibilities saturate long before) summed,
    then the MAP M-step (:func:`_gamma_map`), until no gamma moves by ``tol``; then the
    mixture log-likelihood. Compiled (kernels.em_gamma_full).

    Args:
        log_in: (H, n) inlier log densities.
        log_out: outlier log density (scalar).
        w: weight of the prior p(gamma) ~ exp(-w gamma) in the M-step (the whole track's:
            ObservationModel.map_weight(n); 0 for maximum likelihood).
        responsibilities: also return the responsibilities (else None in their place).
    Returns:
        gamma (H,), mixture log-likelihood sum (H,) (without the prior), inlier
        responsibilities (H, n).
    """
    log_in = np.ascontiguousarray(np.atleast_2d(log_in), dtype=float)
    g, ll, resp = em_gamma_full(log_in, float(log_out), float(gamma0), float(w), int(iters),
                                float(tol), bool(responsibilities))
    return g, ll, (resp if responsibilities else None)


def _gamma_map(A, n: int, w: float):
    """MAP outlier ratio (EM M-step) for the summed outlier responsibilities A (n
    observations, prior p(gamma) ~ exp(-w gamma))."""
    if w > 0:
        s = n + w
        g = (s - np.sqrt(np.maximum(s * s - 4 * w * A, 0.0))) / (2 * w)
    else:
        g = A / n
    return np.clip(g, 1e-6, 1 - 1e-6)

