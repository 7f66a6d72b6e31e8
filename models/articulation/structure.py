"""Model selection for one link and kinematic-tree estimation (thesis Sec. 4.1.3).

- :func:`select_link_model`: fit all candidate link models (or a subset) to one relative track
  and choose the lowest BIC (Eq. 4.34-4.35); all candidates stay available for inspection.
  A candidate whose travel is within the noise, or a revolute candidate whose bow over the
  observed range is below sigma_pos, is not selected (see ``_unresolved``).
- :func:`fit_kinematic_tree`: for p parts, fit every pair's relative track z_ij = y_i^-1 y_j
  (time steps where either part is unobserved are left out for that pair), edge cost = BIC of
  the best model of the pair (Eq. 4.40), minimum spanning tree (networkx, Kruskal). The result
  is an :class:`ArticulatedObject`: edges (parent, child, link model) oriented away from the
  root part, total BIC and the object's DOF (sum of the DOF of the tree's links).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mmlearn.models.articulation.geom import _Data
from mmlearn.models.articulation.link import LinkModel, ObservationModel, make_model
from mmlearn.models.common.se3 import as_pose_array, relative_poses

__all__ = [
    "DEFAULT_CANDIDATES",
    "track_scale_problem",
    "MAX_TRACK_EXTENT_M",
    "MAX_EXTENT_NOISE_RATIO",
    "LinkSelection",
    "select_link_model",
    "ArticulatedObject",
    "LinkEdge",
    "fit_kinematic_tree",
    "fit_pair_models",
    "spanning_tree_edges",
    "relative_track",
]

DEFAULT_CANDIDATES = ("rigid", "prismatic", "revolute", "gp")



@dataclass
class LinkSelection:
    """Result of model selection for one link.

    Attributes:
        best: the selected (lowest-BIC) fitted model.
        candidates: name -> fitted model, for every candidate that could be fitted.
        bic: name -> BIC (inf for candidates that failed).
        errors: name -> error message for candidates that could not be fitted.
        demoted: name -> reason, for fitted candidates that are not selected although their
            BIC may be lowest (a revolute model whose bow is below the noise).
    """

    best: LinkModel
    candidates: dict
    bic: dict
    errors: dict = field(default_factory=dict)
    demoted: dict = field(default_factory=dict)

    @property
    def selected(self) -> str:
        return self.best.name


def select_link_model(Z, *, models=DEFAULT_CANDIDATES, obs: ObservationModel | None = None,
                      rng=None, n_hypotheses: int = 100,
                      identifiability: bool = True) -> LinkSelection:
    """Fit ``models`` (names, see :func:`make_model`) to the relative track Z ((n, 7),
    (n, 4, 4) or (n, 3)) and select the lowest BIC. ``rng``: Generator or seed.
    ``identifiability=False`` selects by BIC alone (no ``_unresolved`` test; for comparisons).
    Raises ValueError if no candidate can be fitted (e.g. too short / NaN track)."""
    rng = np.random.default_rng(rng)
    obs = obs if obs is not None else ObservationModel()
    if isinstance(models, str):
        models = [m for m in models.split(",") if m.strip()]
    if len(models) == 0:
        raise ValueError("select_link_model: empty candidate list")
    d = _Data(as_pose_array(Z))  # validates shape / NaN once; arrays shared by the candidates
    cands, bic, errs = {}, {}, {}
    for name in models:
        m = make_model(name, obs=obs, n_hypotheses=n_hypotheses)
        try:
            m.fit(d, rng=rng)
        except (ValueError, np.linalg.LinAlgError) as e:
            if d.n < 3:
                raise
            errs[m.name] = str(e)
            bic[m.name] = float("inf")
            continue
        cands[m.name] = m
        bic[m.name] = float(m.bic_)
    if not cands:
        raise ValueError("no candidate model could be fitted: " + "; ".join(
            f"{k}: {v}" for k, v in errs.items()))
    demoted = {}
    for name, m in cands.items():
        reason = _unresolved(m) if identifiability else None
        if reason and len(cands) > 1:
            demoted[name] = reason
    eligible = [m for k, m in cands.items() if k not in demoted] or list(cands.values())
    best = min(eligible, key=lambda m: m.bic_)
    return LinkSelection(best=best, candidates=cands, bic=bic, errors=errs, demoted=demoted)


#: no articulated object a robot operates spans more than this, m (a track beyond it is
#: almost surely not in metres, e.g. millimetres)
MAX_TRACK_EXTENT_M = 50.0
#: a track spanning more than this many times the assumed position noise is fitted against a
#: noise model far below its resolution (every small deviation becomes an outlier)
MAX_EXTENT_NOISE_RATIO = 1e5


def track_scale_problem(Z, sigma_pos: float) -> str | None:
    """Why the positions of the track ``Z`` ((n, 3) or (n, 7), m) cannot be fitted in a
    meaningful way with the position noise ``sigma_pos`` (m), or None. A track that spans
    more than :data:`MAX_TRACK_EXTENT_M` or more than :data:`MAX_EXTENT_NOISE_RATIO` times
    ``sigma_pos`` (a door track scaled by 1e6 would otherwise be "fitted" as a revolute
    kilometres across, nearly every pose an outlier)."""
    P = np.asarray(Z, float)
    if P.ndim != 2 or P.shape[1] < 3:
        return None
    P = P[np.all(np.isfinite(P[:, :3]), axis=1), :3]
    if P.shape[0] < 2:
        return None
    extent = float(np.max(P.max(axis=0) - P.min(axis=0)))
    if extent > MAX_TRACK_EXTENT_M:
        return (f"the positions span {extent:.3g} m, more than any object a robot operates "
                f"({MAX_TRACK_EXTENT_M:g} m): are they in metres?")
    if sigma_pos > 0 and extent > MAX_EXTENT_NOISE_RATIO * sigma_pos:
        return (f"the positions span {extent:.3g} m, {extent / sigma_pos:.3g} times the "
                f"assumed position noise {sigma_pos:g} m (more than "
                f"{MAX_EXTENT_NOISE_RATIO:g}): raise the noise (--sigma-pos) or check the "
                "units")
    return None


def noise_range_threshold(n: int) -> float:
    """Largest spread, in units of the noise across the path, that n observations of a part
    that does not move show along their principal direction (isotropic 3-D Gaussian noise,
    ~99th percentile for n >= 12: 7.6 at n = 12, 7.8 at 100, 8.9 at 1000; measured by
    simulation, 300 draws each): 2 sqrt(2 ln n) + 1.5 + 20 / n."""
    n = max(int(n), 2)
    return float(2.0 * np.sqrt(2.0 * np.log(n)) + 1.5 + 20.0 / n)


def _unresolved(model: LinkModel) -> str | None:
    """Why a fitted candidate cannot be told from a simpler one, or None.

    - Motion below the noise: a model with DOFs whose travel over the observed range is
      within what noise alone spreads n observations of a still part along one direction
      (:func:`noise_range_threshold`), measured in units of the noise the data show across
      the path (the inliers' residuals; where the assumed sigma is too small, as for two
      noisy parts of one rigid body, the assumed sigma would turn noise into "motion"), in
      position and in orientation, is not selected.
    - A revolute model whose bow over the observed range (the sagitta r (1 - cos(dq / 2)))
      stays below sigma_pos describes a path that the observation model cannot tell from a
      straight line: its radius and centre fit systematic wobble (the robot base's motion,
      handle play) that the assumed noise declares meaningless, so it is not selected --
      unless the track has orientations and the rotation over the range is beyond the
      noise spread (as in the first test, on the orientation): a prismatic or rigid part
      cannot rotate, so the rotation resolves the hinge whatever the bow.
    """
    if model.dof == 0:
        return None
    rms = getattr(model, "residual_rms_", None)
    if rms is not None:
        lp, lr = model.path_length()
        t = noise_range_threshold(model.n_train)
        sp = max(rms[0], 1e-9)
        ratio = lp / sp
        if rms[1] is not None:
            ratio = max(ratio, lr / max(rms[1], 1e-9))
        if ratio < t:
            return (f"travel {lp:.4f} m / {np.degrees(lr):.2f} deg is {ratio:.1f} times the "
                    f"noise across the path (< {t:.1f}: a still part's noise spread)")
    if model.name != "revolute":
        return None
    dq = float(model.q_max[0] - model.q_min[0])
    bow = model.radius * (1.0 - np.cos(min(dq, np.pi) / 2.0))
    if bow < model.obs_fit.sigma_pos:
        # with full poses the rotation itself tells a hinge from a straight path (a
        # prismatic or rigid part keeps its orientation): a rotation over the range beyond
        # what noise alone spreads (the test above, on the orientation alone) resolves the
        # revolute model even where its positions bow less than sigma_pos (a door seen
        # near its hinge, e.g. a rectangle's corner or centre tracked in depth images)
        # (noise: the larger of the residuals' and the assumed sigma_orient -- on a few
        # observations the 12 parameters fit the orientations far below their noise)
        if rms is not None and rms[1] is not None:
            _, lr = model.path_length()
            noise = max(rms[1], model.obs_fit.sigma_orient, 1e-9)
            if lr / noise >= noise_range_threshold(model.n_train):
                return None
        return (f"bow {bow:.4f} m over the observed {np.degrees(dq):.1f} deg is below "
                f"sigma_pos {model.obs_fit.sigma_pos:g} m")
    return None



def relative_track(y_i, y_j):
    """Relative poses z_ij = y_i^-1 y_j at time steps where both parts are observed.

    Args:
        y_i, y_j: (T, 7) / (T, 3) / (T, 4, 4) arrays; rows containing NaN mean "not observed".
    Returns:
        (PoseArray of the common observations, index array of the used time steps).
    """
    a = np.asarray(y_i, float)
    b = np.asarray(y_j, float)
    if a.shape[0] != b.shape[0]:
        raise ValueError(f"part tracks differ in length ({a.shape[0]} vs {b.shape[0]})")
    ok = np.isfinite(a.reshape(a.shape[0], -1)).all(1) & np.isfinite(
        b.reshape(b.shape[0], -1)).all(1)
    idx = np.flatnonzero(ok)
    if idx.size == 0:
        return None, idx
    return relative_poses(a[idx], b[idx]), idx


@dataclass
class LinkEdge:
    """One link of the kinematic tree: the pose of ``child`` in the frame of ``parent`` is
    ``model.forward(q)``."""

    parent: int
    child: int
    model: LinkModel
    bic: dict = field(default_factory=dict)

    @property
    def dof(self) -> int:
        return self.model.dof


class ArticulatedObject:
    """A learned kinematic tree over p parts.

    Attributes:
        part_names: names of the parts (index = part id).
        root: id of the root part (its frame is the object frame).
        edges: LinkEdge list in breadth-first order from the root.
        total_bic: sum of the BICs of the tree's links.
        pair_bic: {(i, j): {model: BIC}} for every fitted pair (i < j), for inspection.
    """

    def __init__(self, part_names, root, edges, pair_bic=None):
        self.part_names = list(part_names)
        self.root = int(root)
        self.edges = list(edges)
        self.pair_bic = dict(pair_bic or {})

    def __repr__(self) -> str:
        links = ", ".join(f"{self.part_names[e.parent]}-{self.part_names[e.child]}: "
                          f"{e.model.name}" for e in self.edges)
        return (f"ArticulatedObject(parts={self.part_names}, root={self.part_names[self.root]!r}"
                f", dof={self.dof}, links=[{links}])")

    @property
    def total_bic(self) -> float:
        return float(sum(e.model.bic_ for e in self.edges))

    @property
    def dof(self) -> int:
        return int(sum(e.dof for e in self.edges))

    @property
    def num_parts(self) -> int:
        return len(self.part_names)

    def _slices(self):
        out, k = [], 0
        for e in self.edges:
            out.append(slice(k, k + e.dof))
            k += e.dof
        return out

    def configuration(self, part_poses) -> np.ndarray:
        """Configuration vector (dof,) from one observation of all parts ((p, 7), (p, 3) or
        (p, 4, 4)); links whose parts are unobserved (NaN) give NaN entries."""
        Y = np.asarray(part_poses, float)
        q = np.full(self.dof, np.nan)
        for e, sl in zip(self.edges, self._slices()):
            if e.dof == 0:
                continue
            a, b = Y[e.parent], Y[e.child]
            if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
                continue
            z = relative_poses(a[None], b[None])
            if e.model.has_orientation and z.rotations is None:
                continue
            q[sl] = e.model.inverse(z)[0]
        return q

    def forward(self, q) -> np.ndarray:
        """Poses (p, 4, 4) of all parts in the root frame at configuration q (dof,)."""
        q = np.asarray(q, float).reshape(-1)
        if q.size != self.dof:
            raise ValueError(f"q must have {self.dof} entries, got {q.size}")
        T = np.full((self.num_parts, 4, 4), np.nan)
        T[self.root] = np.eye(4)
        for e, sl in zip(self.edges, self._slices()):
            Tl = e.model.forward_matrices(q[sl][None] if e.dof else None)[0]
            T[e.child] = T[e.parent] @ Tl
        return T

    def jacobian(self, q) -> np.ndarray:
        """Block-diagonal Jacobian (6 * num_edges, dof) of each link's relative pose (rows
        vx vy vz wx wy wz in the parent frame; orientation rows zero for position-only
        links) w.r.t. the configuration vector."""
        q = np.asarray(q, float).reshape(-1)
        J = np.zeros((6 * len(self.edges), self.dof))
        for i, (e, sl) in enumerate(zip(self.edges, self._slices())):
            if e.dof == 0:
                continue
            Jl = e.model.jacobian(q[sl][None])[0]
            J[6 * i:6 * i + Jl.shape[0], sl] = Jl
        return J

    def summary(self) -> dict:
        return {
            "parts": self.part_names, "root": self.root, "dof": self.dof,
            "total_bic": self.total_bic,
            "edges": [{"parent": self.part_names[e.parent], "child": self.part_names[e.child],
                       "model": e.model.name, "bic": e.bic, "params": e.model.params()}
                      for e in self.edges],
        }


def fit_pair_models(part_tracks, *, models=DEFAULT_CANDIDATES, obs: ObservationModel | None = None,
                    rng=None, min_common: int = 5, n_hypotheses: int = 100) -> dict:
    """Fit and select a link model for every pair (i < j) of parts observed together at
    least ``min_common`` times (rows with NaN: not observed). ``part_tracks``: sequence of p
    arrays (T, 7) / (T, 3) / (T, 4, 4) or one array (p, T, ...). Returns
    {(i, j): LinkSelection}; the model describes part j in the frame of part i. Pairs whose
    models cannot be fitted get no entry."""
    rng = np.random.default_rng(rng)
    obs = obs if obs is not None else ObservationModel()
    tracks = [np.asarray(t, float) for t in part_tracks]
    out = {}
    for i in range(len(tracks)):
        for j in range(i + 1, len(tracks)):
            z, _ = relative_track(tracks[i], tracks[j])
            if z is None or len(z) < max(3, min_common):
                continue
            try:
                out[(i, j)] = select_link_model(z, models=models, obs=obs, rng=rng,
                                                n_hypotheses=n_hypotheses)
            except (ValueError, np.linalg.LinAlgError):
                continue
    return out


def spanning_tree_edges(pair_models: dict, num_parts: int, *, extra_cost=None) -> tuple:
    """Minimum spanning tree over the pairs, edge cost = BIC of the pair's best model
    (Eq. 4.40; networkx, Kruskal), plus ``extra_cost[(i, j)]`` where given (a structure
    prior's ``-2 log p`` of the edge). Returns sorted (i, j) edge tuples; raises ValueError if
    the parts are not connected."""
    import networkx as nx

    extra = extra_cost or {}
    G = nx.Graph()
    G.add_nodes_from(range(num_parts))
    for (i, j), s in pair_models.items():
        G.add_edge(i, j, weight=float(getattr(s, "best", s).bic_) + float(extra.get((i, j), 0.0)))
    if not nx.is_connected(G):
        comps = [sorted(c) for c in nx.connected_components(G)]
        raise ValueError(f"parts cannot be connected (too few common observations): {comps}")
    T = nx.minimum_spanning_tree(G, weight="weight", algorithm="kruskal")
    return tuple(sorted((min(a, b), max(a, b)) for a, b in T.edges()))


def fit_kinematic_tree(part_tracks, *, part_names=None, models=DEFAULT_CANDIDATES,
                       obs: ObservationModel | None = None, rng=None, root: int = 0,
                       min_common: int = 5, n_hypotheses: int = 100) -> ArticulatedObject:
    """Learn a kinematic tree from synchronised observations of p parts.

    Args:
        part_tracks: sequence of p arrays (T, 7) / (T, 3) / (T, 4, 4), or one array
            (p, T, 7); rows with NaN are time steps where that part was not observed.
        part_names: optional names (default "part0", ...).
        models: candidate link models per pair.
        obs: observation model (noise levels).
        rng: Generator or seed.
        root: part whose frame is the object frame.
        min_common: pairs observed together fewer times get no edge.
    Returns:
        ArticulatedObject. Raises ValueError if the parts cannot be connected.
    """
    import networkx as nx

    rng = np.random.default_rng(rng)
    tracks = [np.asarray(t, float) for t in part_tracks]
    p = len(tracks)
    if p < 2:
        raise ValueError(f"fit_kinematic_tree needs at least 2 parts, got {p}")
    T = tracks[0].shape[0]
    for k, t in enumerate(tracks):
        if t.shape[0] != T or t.ndim not in (2, 3) or (t.ndim == 2 and t.shape[1] not in (3, 7)):
            raise ValueError(f"part {k}: expected ({T}, 7), ({T}, 3) or ({T}, 4, 4) array, got "
                             f"{t.shape}")
    names = list(part_names) if part_names is not None else [f"part{k}" for k in range(p)]
    if len(names) != p:
        raise ValueError(f"{len(names)} part names for {p} parts")
    if not 0 <= root < p:
        raise ValueError(f"root {root} out of range for {p} parts")
    obs = obs if obs is not None else ObservationModel()
    sel = fit_pair_models(tracks, models=models, obs=obs, rng=rng, min_common=min_common,
                          n_hypotheses=n_hypotheses)
    pair_bic = {e: dict(s.bic) for e, s in sel.items()}
    mst = nx.Graph(spanning_tree_edges(sel, p))
    mst.add_nodes_from(range(p))
    edges = []
    for parent, child in nx.bfs_edges(mst, root):
        i, j = min(parent, child), max(parent, child)
        s = sel[(i, j)]
        model = s.best
        if parent != i:  # fitted as child-in-parent the other way round: refit reversed
            z, _ = relative_track(tracks[parent], tracks[child])
            model = make_model(s.best.name, obs=obs, n_hypotheses=n_hypotheses).fit(z, rng=rng)
        edges.append(LinkEdge(parent, child, model, dict(s.bic)))
    return ArticulatedObject(names, root, edges, pair_bic)
