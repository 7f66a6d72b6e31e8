"""Priors from experience: sequential clustering of trajectories (thesis Sec. 4.2,
Algorithm 2, Eq. 4.41-4.46).

A *prior database* is a list of clusters; each cluster holds the (aligned) trajectories that
one link model explains and that model. A new trajectory D_new is either kept as a new model
M_new or merged into a cluster j (model M_j+new fitted to D_j u D_new), whichever gives the
lower total BIC (Eq. 4.44-4.45):

    merge into j  iff  BIC(M_j+new | D_j u D_new) - BIC(M_j | D_j) < BIC(M_new | D_new)

(the other clusters' BICs are common to both sides). While a new object is being operated,
the same test is repeated after every observation (Eq. 4.46), so the robot predicts with the
merged model - fitted to much more data - as long as the object behaves like a known one.

Merge-test BIC: the BIC of Eq. 4.34 with the same observation model as link fitting
(models/articulation/link.py: the outlier prior -w gamma n of Eq. 4.15 and the configuration prior
p(q) ~ n_eff^-d), with one refinement: the configuration prior is that of each trajectory as
one visit, uniform over the range that visit covers (LinkModel.log_likelihood_of_visits). A
partial trajectory (the first 40 % of a door's opening) is then not charged for the part of
the range it never reached when it is scored under a cluster's model. Eq. 4.27's literal
n^-d made merging impossible (pooling n1 + n2 observations costs
(n1 + n2) d log(n1 + n2) - n1 d log n1 - n2 d log n2 > 0 nats even for a perfect joint fit;
~70 nats per pair of Cody drawers against ~20 saved by the shared parameters); n_eff, the number of configurations the noise
resolves over a visit's range, does not grow with more visits.

The default observation model for priors has sigma_pos = 0.05 m (Cody's base localisation).

Alignment: each trajectory is recorded in the robot's base frame from a different stopping
place, so it is translated to start at the origin (its first observation) before any model
is fitted or a merge is tested (``align="first"``; ``"none"`` keeps it as recorded).
Long trajectories are thinned to at most ``max_points`` evenly spaced observations (the
fitting cost grows with n; default 100) - both sides of every merge test see the same data.

Joint models: by default a merge refits the cluster's model class on the joint data
(``joint_models="same"``); ``"all"`` runs the full model selection on the joint data.

Persistence: :meth:`PriorDatabase.save` writes JSON (schema below) atomically (temporary
file + rename); :meth:`PriorDatabase.load` reads it back::

    {"format": "mmlearn.articulation_priors", "version": 2,  # 1: no checksum, still read
     "config": {"sigma_pos": m, "sigma_orient": rad, "models": [...], "align": "first",
                "max_points": int, "joint_models": "same", "n_hypotheses": int},
     "clusters": [{"members": [name, ...], "data": [[[x, y, z(, qx, qy, qz, qw)], ...], ...],
                   "model": <LinkModel.to_dict()>}, ...],
     "checksum": "sha256:<hex>"}   # last key, over the content (models/common/saved_doc.py)

Loading checks every field and the checksum: a truncated, damaged or edited database is a
``ValueError`` naming the file and the field.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
import warnings
from pathlib import Path

import numpy as np

from mmlearn.models.articulation.link import ObservationModel, link_model_from_dict, make_model
from mmlearn.models.common.fileio import atomic_write_text
from mmlearn.models.articulation.structure import DEFAULT_CANDIDATES, select_link_model
from mmlearn.models.common.se3 import as_pose_array

__all__ = [
    "align_trajectory",
    "thin_trajectory",
    "PriorCluster",
    "PriorDatabase",
    "MergeDecision",
    "merge_bic",
    "learn_priors",
    "evaluate_priors",
    "FORMAT",
]

FORMAT = "mmlearn.articulation_priors"
VERSION = 2
READABLE_VERSIONS = (1, 2)  # 1: before the checksum
ALIGN_MODES = ("first", "none")



def align_trajectory(Z, mode: str = "first") -> np.ndarray:
    """Translate a trajectory ((n, 3) or (n, 7)) so that its first observation is at the
    origin (``mode="first"``) or keep it (``"none"``). Orientations are unchanged."""
    if mode not in ALIGN_MODES:
        raise ValueError(f"unknown alignment {mode!r}; choose from {', '.join(ALIGN_MODES)}")
    a = as_pose_array(Z).as_array()
    if mode == "first":
        a[:, :3] -= a[0, :3]
    return a


def merge_bic(model, trajectories=None) -> float:
    """BIC used by the merge test: the model's BIC of Eq. 4.34 with the same observation
    model as link fitting, each trajectory scored as one visit
    (LinkModel.log_likelihood_of_visits: its configurations uniform over the range it
    covers, see the module notes). ``trajectories``: the (aligned) trajectories the model
    was fitted to, in any order; None: the training track as one visit."""
    n = int(model.n_train)
    if getattr(model.obs_fit, "config_prior", "resolved") == "n":
        # databases saved before 2026-11: n^-d made merging impossible, it was left out
        return float(model.bic_ - 2.0 * n * model.dof * np.log(n))
    if trajectories is None or model.dof == 0:
        return float(model.bic_)
    return float(-2.0 * model.log_likelihood_of_visits(trajectories)
                 + model.num_params(n) * np.log(n))


def thin_trajectory(Z, max_points: int | None) -> np.ndarray:
    """At most ``max_points`` evenly spaced observations (in time) of Z (first and last kept)."""
    Z = np.asarray(Z, float)
    if max_points is None or Z.shape[0] <= max_points:
        return Z
    if max_points < 3:
        raise ValueError(f"max_points must be >= 3, got {max_points}")
    idx = np.round(np.linspace(0, Z.shape[0] - 1, max_points)).astype(int)
    return Z[idx]


@dataclass
class PriorCluster:
    """One prior model: member names, their aligned trajectories, the fitted model."""

    members: list
    data: list
    model: object

    @property
    def bic(self) -> float:
        return merge_bic(self.model, self.data)

    @property
    def stacked(self) -> np.ndarray:
        return np.vstack(self.data)


@dataclass
class MergeDecision:
    """Outcome of the merge test for one trajectory.

    Attributes:
        cluster: index of the cluster it merges into, or None (kept as a new model).
        model: the model to predict with (the joint model, or the new one).
        new_model: the model fitted to the trajectory alone.
        delta_bic: {cluster index: BIC(M_j+new) - BIC(M_j)} for every cluster tried.
        new_bic: BIC(M_new).
        joint_models: {cluster index: joint model}.
        not_tried: {cluster index: why} for the clusters whose joint model could not be
            fitted (no candidate fits their data together with the trajectory): the
            trajectory cannot merge into them, and this says so instead of leaving them out
            of ``delta_bic`` without a word.
    """

    cluster: int | None
    model: object
    new_model: object
    delta_bic: dict
    new_bic: float
    joint_models: dict = field(default_factory=dict)
    not_tried: dict = field(default_factory=dict)


class PriorDatabase:
    """Prior models learned by sequential clustering (Algorithm 2).

    Args:
        obs: observation model (default: sigma_pos = 0.05 m as on Cody, everything else the
            link-fitting defaults).
        models: candidate link models for new trajectories.
        align: "first" (translate to the first observation) or "none".
        max_points: thin every trajectory to at most this many observations (None = all).
        joint_models: "same" (refit the cluster's model class on the joint data) or "all".
        n_hypotheses: MLESAC hypotheses per fit.
    """

    def __init__(self, *, obs: ObservationModel | None = None, models=DEFAULT_CANDIDATES,
                 align: str = "first", max_points: int | None = 50,
                 joint_models: str = "same", n_hypotheses: int = 100):
        if align not in ALIGN_MODES:
            raise ValueError(f"unknown alignment {align!r}; choose from {', '.join(ALIGN_MODES)}")
        if joint_models not in ("same", "all"):
            raise ValueError(f"joint_models must be 'same' or 'all', got {joint_models!r}")
        if max_points is not None and int(max_points) < 3:
            raise ValueError(f"max_points must be >= 3, got {max_points}")
        self.obs = obs if obs is not None else ObservationModel(sigma_pos=0.05)
        self.models = tuple(models.split(",") if isinstance(models, str) else models)
        for m in self.models:
            make_model(m)  # validates names
        self.align = align
        self.max_points = None if max_points is None else int(max_points)
        self.joint_models = joint_models
        self.n_hypotheses = int(n_hypotheses)
        self.clusters: list[PriorCluster] = []

    # ----- data preparation
    def prepare(self, Z) -> np.ndarray:
        """Aligned and thinned copy of a raw trajectory."""
        a = align_trajectory(Z, self.align)
        if a.shape[0] < 3:
            raise ValueError(f"trajectory too short ({a.shape[0]} observations; need >= 3)")
        return thin_trajectory(a, self.max_points)

    def _fit_new(self, Z, rng):
        return select_link_model(Z, models=self.models, obs=self.obs, rng=rng,
                                 n_hypotheses=self.n_hypotheses).best

    def _fit_joint(self, cluster: PriorCluster, Z, rng):
        J = np.vstack(cluster.data + [Z])
        if self.joint_models == "same":
            try:
                return make_model(cluster.model.name, obs=self.obs,
                                  n_hypotheses=self.n_hypotheses).fit(J, rng=rng)
            except ValueError:
                pass
        return select_link_model(J, models=self.models, obs=self.obs, rng=rng,
                                 n_hypotheses=self.n_hypotheses).best

    # ----- Algorithm 2
    def merge_test(self, Z, *, rng=None, prepared: bool = False) -> MergeDecision:
        """Eq. 4.44-4.46 for trajectory Z against every cluster; does not change the
        database."""
        rng = np.random.default_rng(rng)
        Zp = np.asarray(Z, float) if prepared else self.prepare(Z)
        if self.clusters and Zp.shape[1] != self.clusters[0].data[0].shape[1]:
            raise ValueError(f"trajectory has {Zp.shape[1]} columns, the database holds "
                             f"{self.clusters[0].data[0].shape[1]}-column trajectories")
        new = self._fit_new(Zp, rng)
        new_bic = merge_bic(new, [Zp])
        best_j, best_d, best_model = None, new_bic, new
        deltas, joints, not_tried = {}, {}, {}
        for j, c in enumerate(self.clusters):
            try:
                mj = self._fit_joint(c, Zp, rng)
            except ValueError as e:
                not_tried[j] = f"joint fit failed: {e}"
                continue
            joints[j] = mj
            deltas[j] = merge_bic(mj, c.data + [Zp]) - c.bic
            if deltas[j] < best_d:
                best_j, best_d, best_model = j, deltas[j], mj
        return MergeDecision(best_j, best_model, new, deltas, new_bic, joints, not_tried)

    def add(self, Z, name: str | None = None, *, rng=None) -> int:
        """Algorithm 2, one step: merge Z into the best cluster or start a new one. Returns
        the cluster index."""
        Zp = self.prepare(Z)
        dec = self.merge_test(Zp, rng=rng, prepared=True)
        name = name if name is not None else f"trajectory{sum(len(c.members) for c in self.clusters)}"
        for j, why in dec.not_tried.items():
            warnings.warn(f"prior database: {name} could not be tested against cluster {j} "
                          f"({', '.join(self.clusters[j].members)}): {why}", stacklevel=2)
        if dec.cluster is None:
            self.clusters.append(PriorCluster([name], [Zp], dec.new_model))
            return len(self.clusters) - 1
        c = self.clusters[dec.cluster]
        c.members.append(name)
        c.data.append(Zp)
        c.model = dec.model
        return dec.cluster

    def remove(self, name: str, *, rng=None) -> None:
        """Remove a member (and refit its cluster, or drop the cluster if it is empty)."""
        for k, c in enumerate(self.clusters):
            if name in c.members:
                i = c.members.index(name)
                del c.members[i], c.data[i]
                if not c.members:
                    del self.clusters[k]
                else:
                    J = np.vstack(c.data)
                    c.model = make_model(c.model.name, obs=self.obs,
                                         n_hypotheses=self.n_hypotheses).fit(J, rng=np.random.default_rng(rng))
                return
        raise KeyError(f"no trajectory named {name!r} in the prior database")

    def predict_model(self, Z_partial, *, rng=None):
        """Model to predict a partially observed trajectory with (Eq. 4.46): the joint
        model of the best cluster, or the trajectory's own model. Returns the MergeDecision."""
        return self.merge_test(Z_partial, rng=rng)

    @property
    def total_bic(self) -> float:
        return float(sum(c.bic for c in self.clusters))

    def assignments(self) -> list:
        return [list(c.members) for c in self.clusters]

    def model_names(self) -> list:
        return [c.model.name for c in self.clusters]

    # ----- persistence
    def to_dict(self) -> dict:
        """The database as a plain document (schema in the module docstring), sealed with
        its checksum."""
        from mmlearn.models.common.saved_doc import seal

        return seal({
            "format": FORMAT, "version": VERSION,
            "config": {"sigma_pos": self.obs.sigma_pos, "sigma_orient": self.obs.sigma_orient,
                       "gamma_weight": self.obs.gamma_weight,
                       "gamma_prior": self.obs.gamma_prior,
                       "config_prior": self.obs.config_prior, "models": list(self.models),
                       "align": self.align, "max_points": self.max_points,
                       "joint_models": self.joint_models, "n_hypotheses": self.n_hypotheses},
            "clusters": [{"members": list(c.members), "data": [d.tolist() for d in c.data],
                          "model": c.model.to_dict()} for c in self.clusters],
        })

    @classmethod
    def from_dict(cls, d: dict) -> "PriorDatabase":
        if not isinstance(d, dict) or d.get("format") != FORMAT:
            raise ValueError(f"not a prior database (format must be {FORMAT!r})")
        version = d.get("version")
        if isinstance(version, bool) or version not in READABLE_VERSIONS:
            raise ValueError(f"version: unsupported prior database version {version!r}")
        from mmlearn.models.articulation.io import validate_prior_dict
        from mmlearn.models.common.saved_doc import check_seal

        validate_prior_dict(d)  # the fields first (naming the field), then the checksum
        check_seal(d, required=version >= 2)
        c = d["config"]
        # (databases without gamma_prior / config_prior predate 2026-11: prior once per
        # track, n^-d configuration prior)
        db = cls(obs=ObservationModel(sigma_pos=c["sigma_pos"], sigma_orient=c["sigma_orient"],
                                      gamma_weight=c.get("gamma_weight", 1.0),
                                      gamma_prior=c.get("gamma_prior", "track"),
                                      config_prior=c.get("config_prior", "n")),
                 models=c["models"], align=c["align"], max_points=c["max_points"],
                 joint_models=c["joint_models"], n_hypotheses=c["n_hypotheses"])
        for cl in d["clusters"]:
            data = [np.asarray(x, float) for x in cl["data"]]
            if len(data) != len(cl["members"]):
                raise ValueError("prior database: members and data differ in length")
            db.clusters.append(PriorCluster(list(cl["members"]), data,
                                            link_model_from_dict(cl["model"])))
        return db

    def save(self, path) -> None:
        """Write the database as JSON (atomic: temporary file + rename)."""
        atomic_write_text(path, json.dumps(self.to_dict()))

    @classmethod
    def load(cls, path) -> "PriorDatabase":
        """Read a database written by :meth:`save`. Raises FileNotFoundError for a missing
        file and ValueError naming the file and the field for anything else (binary, not
        JSON, missing or mistyped key, NaN, checksum missing or not matching)."""
        from mmlearn.models.common.saved_doc import read_document

        p = Path(path)
        if not p.is_file():
            raise FileNotFoundError(f"{p}: prior database not found")
        d = read_document(p, yaml_format=False, what="prior database")
        try:
            return cls.from_dict(d)
        except ValueError as e:
            raise ValueError(f"{p}: {e}") from None


def learn_priors(trajectories, names=None, *, rng=None, progress=None, **kw) -> PriorDatabase:
    """Algorithm 2 over trajectories in the given order. ``kw`` go to :class:`PriorDatabase`.
    ``progress``: optional callable(i) after each trajectory."""
    rng = np.random.default_rng(rng)
    trajectories = list(trajectories)
    names = list(names) if names is not None else [f"trajectory{i}" for i in range(len(trajectories))]
    if len(names) != len(trajectories):
        raise ValueError(f"{len(names)} names for {len(trajectories)} trajectories")
    if len(set(names)) != len(names):
        raise ValueError("trajectory names must be unique")
    db = PriorDatabase(**kw)
    for i, (Z, nm) in enumerate(zip(trajectories, names)):
        db.add(Z, nm, rng=rng)
        if progress is not None:
            progress(i)
    return db


def evaluate_priors(trajectories, names=None, *, fractions=np.linspace(0.1, 1.0, 10),
                    rng=None, progress=None, exact_loo: bool = False, **kw) -> dict:
    """Leave-one-out experiment of Fig. 4.15.

    For every trajectory h: the priors are the database of all other trajectories (by
    default: learned once on all trajectories, then h removed and its cluster refitted;
    with ``exact_loo`` re-clustered from scratch without h, in a random order); for each
    fraction f the first f of h is observed and the model is (a) learned from scratch, (b)
    chosen with priors (Eq. 4.46). The error is the mean position error (m) of the model's
    projection f(f^-1(z)) on the *full* aligned trajectory h.

    Returns {"fractions": [...], "error_without": (H, F), "error_with": (H, F),
    "merged": (H, F) bool, "names": [...], "seconds": float}.
    """
    t0 = time.perf_counter()
    rng = np.random.default_rng(rng)
    trajectories = list(trajectories)
    names = list(names) if names is not None else [f"trajectory{i}" for i in range(len(trajectories))]
    fractions = np.asarray(fractions, float)
    if np.any((fractions <= 0) | (fractions > 1)):
        raise ValueError("fractions must be in (0, 1]")
    if len(trajectories) < 2:
        raise ValueError("leave-one-out needs at least 2 trajectories")
    full_db = None
    if not exact_loo:
        order = rng.permutation(len(trajectories))
        full_db = learn_priors([trajectories[i] for i in order], [names[i] for i in order],
                               rng=rng, **kw)
    H, F = len(trajectories), len(fractions)
    e_wo, e_w = np.zeros((H, F)), np.zeros((H, F))
    merged = np.zeros((H, F), bool)
    for h in range(H):
        if exact_loo:
            others = [i for i in rng.permutation(H) if i != h]
            db = learn_priors([trajectories[i] for i in others], [names[i] for i in others],
                              rng=rng, **kw)
        else:
            db = PriorDatabase.from_dict(full_db.to_dict())
            db.remove(names[h], rng=rng)
        full = db.prepare(trajectories[h])
        raw = align_trajectory(trajectories[h], db.align)
        for k, f in enumerate(fractions):
            m = max(3, int(round(f * raw.shape[0])))
            part = thin_trajectory(raw[:m], db.max_points)
            dec = db.merge_test(part, rng=rng, prepared=True)
            e_wo[h, k] = dec.new_model.prediction_errors(full)[0]
            e_w[h, k] = dec.model.prediction_errors(full)[0]
            merged[h, k] = dec.cluster is not None
        if progress is not None:
            progress(h)
    return {"fractions": fractions.tolist(), "error_without": e_wo, "error_with": e_w,
            "merged": merged, "names": names, "seconds": time.perf_counter() - t0}
