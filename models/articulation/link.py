"""Link models for articulated objects (thesis Sec. 4.1, Eq. 4.13-4.34).

A *link model* M describes the relative motion z = y_i^-1 y_j of two object parts through a
latent configuration q in R^d: forward kinematics f(q) -> pose, inverse f^-1(z) -> q.
Candidates (Table 4.1):

=========== === ======================= ==========================================
model       d   k (full pose / pos-only) parameters
=========== === ======================= ==========================================
rigid       0   6 / 3                   fixed transform
prismatic   1   9 / 6                   origin a in SE(3), unit axis e (Eq. 4.19-20)
revolute    1   12 / 9                  centre frame c in SE(3) (axis = its z), r (4.21-22)
gp          1-5 1 + d + 6n / 1 + d + 3n latent q by PCA/LLE, GP back to the pose (4.23-25)
=========== === ======================= ==========================================

For position-only tracks ((n, 3): orientation unknown) the orientation terms drop out of the
likelihood and errors and k loses the parameters that only describe the part's orientation.

Observation model (Eq. 4.13-4.15): an inlier is the true pose plus Gaussian noise, isotropic
with standard deviation ``sigma_pos`` (metres) on the position and ``sigma_orient`` (radians)
on the rotation vector of the orientation error; an outlier (probability gamma) is uniform over
a position volume V (m^3, by default the cube whose side is the largest extent of the training
positions plus 6 sigma_pos, at least 1 m^3) times SO(3) (volume 8 pi^2). The data
log-likelihood (Eq. 4.26-4.32) of a track of n observations is

    log L = sum_t log[(1 - gamma) N(z_t | f(q_t)) p(q_t | M) + gamma U] - w gamma n,
    q_t = f^-1(z_t),

and BIC = -2 log L + k log n (Eq. 4.34). The reading of the thesis this implements:

- Outlier prior (Eq. 4.15): p(gamma) ~ exp(-w gamma) multiplies the likelihood of *every*
  observation, so a track pays -w gamma n; w = ln(100) / 0.05 ~ 92 (an outlier ratio of 0.05
  costs a factor 100 per observation), and gamma is the maximum-likelihood estimate of the
  mixture by EM: the prior compares models with different outlier ratios (the thesis' words)
  and leaves the estimate alone. This is what the thesis' implementation does
  (tum-vision/articulation, generic_model.cpp). Read as a prior on the estimate (MAP), w n
  pulls gamma to ~0 whatever the data (|gamma - 0.3| = 0.30 on a link with 30 % outliers);
  applied once per track (mmlearn before 2026-11), "rigid plus a track of outliers" wins at
  the thesis' sigma 0.05 m on every real track. ``ObservationModel.gamma_prior`` keeps both
  for comparison (``articulation_experiments --only selection``).
- Configuration prior (Eq. 4.26-4.28): all configurations over the observed range equally
  likely. Eq. 4.27 writes p(q) ~ n^-d ("n estimated configurations") and Eq. 4.29-4.31
  evaluate the integral at q_hat only; that charges d log n per observation, which grows
  with the number of observations of the same motion: at sigma 0.1 m every real Cody track
  selects rigid (log 265 = 5.6 nats per observation against ~1.2 nats of the rigid misfit).
  Here the integral along the path is evaluated (:meth:`LinkModel.config_terms`): ~log c per
  observation, c the number of configurations the noise can tell apart over the range
  (range in noise units / sqrt(2 pi)), falling to the rigid likelihood as the range shrinks
  to nothing, and n^-d where the n configurations are sparser than the noise (n < c).
  ``ObservationModel.config_prior="n"`` restores n^-d.
- Identifiability (models/articulation/structure.py): a candidate whose travel is within the
  noise the data show across the path, or a revolute whose bow is below sigma_pos, is not
  selected.

Fitting (Sec. 4.1.1): MLESAC on minimal samples (rigid 1, prismatic 2, revolute 3
observations; 100 hypotheses scored at once, vectorised, gamma by EM per hypothesis), then
refinement of the mixture likelihood + log p(gamma) from the best hypothesis, one method per
model class (``LinkModel.refinement``, models/articulation/refine.py):

- rigid, prismatic (``"em"``): EM with closed-form M-steps (responsibility-weighted mean
  position / weighted principal axis, weighted geodesic mean orientation, gamma): one
  residual evaluation per iteration;
- revolute (``"lm"``): a closed-form re-estimate on the consensus set (plane + circle fit;
  kept only if it scores better), then Levenberg-Marquardt on the responsibility-weighted
  residuals (Jacobian by batched forward differences; gauge freedoms of the
  parametrisation held fixed), gamma re-estimated by EM in between;
- ``"lbfgs"`` (the default of LinkModel, for a model with neither a closed-form weighted
  fit nor residual vectors, and the tests' reference): quasi-Newton (scipy L-BFGS-B) on
  the same objective;
- gp: no refinement (closed-form reduction + GP hyper-parameters by marginal likelihood).

The BFGS of the thesis is replaced by these because they need far fewer likelihood
evaluations for the same (or a better) optimum.

Where this deviates from or resolves the thesis text:

- Outlier prior and configuration prior: see above.
- The uniform outlier density needs a volume the thesis does not give: see above.
- Revolute f^-1 uses position and orientation (weighted circular mean), not only Eq. 4.22;
  this also handles position-only tracks and small radii.
- GP: 6 outputs (position + rotation vector about the mean orientation) instead of 12 matrix
  entries; at most ``max_train`` (50) training points (k counts those); see GPModel.

Configuration conventions: q = 0 at the first inlier observation of the training track and
increases in the direction of motion; prismatic q in metres, revolute q in radians.
Jacobian df/dq: (m, 6, d) rows (vx, vy, vz, wx, wy, wz) = derivative of the position and the
angular velocity, both expressed in the parent (part i) frame; (m, 3, d) for position-only
models.

Code layout (this module is the public facade; import from here):

- models/articulation/obs.py: ObservationModel, em_gamma (Eq. 4.13-4.15);
- models/articulation/geom.py: track arrays, rotation helpers;
- models/articulation/base.py: LinkModel (fit, MLESAC, evaluation, configuration prior,
  persistence);
- models/articulation/refine.py: the refinements ("em", "lm", "lbfgs");
- models/articulation/links.py: RigidModel, PrismaticModel, RevoluteModel (a section each);
- models/articulation/gp_link.py: GPModel.
"""

from __future__ import annotations

from mmlearn.models.articulation.base import LinkModel
# private helpers other modules and the tests import from here
from mmlearn.models.articulation.geom import _log_rot, _m2rv, _rv2m  # noqa: F401
from mmlearn.models.articulation.gp_link import GPModel
from mmlearn.models.articulation.links import PrismaticModel, RevoluteModel, RigidModel
from mmlearn.models.articulation.obs import (DEFAULT_GAMMA_WEIGHT, GAMMA_PRIOR_MODES, ObservationModel,
                                             em_gamma)

__all__ = [
    "ObservationModel",
    "LinkModel",
    "RigidModel",
    "PrismaticModel",
    "RevoluteModel",
    "GPModel",
    "MODEL_CLASSES",
    "make_model",
    "link_model_from_dict",
    "DEFAULT_GAMMA_WEIGHT",
    "GAMMA_PRIOR_MODES",
    "em_gamma",
]

MODEL_CLASSES = {"rigid": RigidModel, "prismatic": PrismaticModel, "revolute": RevoluteModel,
                 "gp": GPModel}


def make_model(name: str, *, obs: ObservationModel | None = None, **kw) -> LinkModel:
    """Create an unfitted model by name: rigid, prismatic, revolute, gp, gp1..gp5,
    gp-lle / gp2-lle (LLE reduction)."""
    key = name.strip().lower()
    if key in ("rigid", "prismatic", "revolute"):
        return MODEL_CLASSES[key](obs=obs, **kw)
    if key.startswith("gp"):
        red = "pca"
        if key.endswith("-lle"):
            red, key = "lle", key[:-4]
        elif key.endswith("-pca"):
            key = key[:-4]
        dof = int(key[2:]) if len(key) > 2 else 1
        return GPModel(dof=dof, reduction=red, obs=obs, **kw)
    raise ValueError(f"unknown link model {name!r}; choose from rigid, prismatic, revolute, "
                     "gp, gp1..gp5, gp-lle")


def link_model_from_dict(dct: dict) -> LinkModel:
    """Rebuild a fitted link model from :meth:`LinkModel.to_dict`."""
    t = dct.get("type")
    key = "gp" if isinstance(t, str) and t.startswith("gp") else t
    if key not in MODEL_CLASSES:
        raise ValueError(f"unknown link model type {t!r}")
    return MODEL_CLASSES[key]._from_dict(dct)
