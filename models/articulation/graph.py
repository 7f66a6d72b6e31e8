"""Kinematic graphs with loops and object DOFs (thesis Sec. 4.2, Eq. 4.47-4.56).

Given the link models of all part pairs (fitted with
:func:`mmlearn.models.articulation.structure.select_link_model`), a *kinematic graph* is a
connected set of edges (pairs of parts) each carrying its pair's best link model. Trees and
graphs with closed chains are evaluated the same way:

1. Link configurations: for every edge (i, j) and time step t, q_ij^t = f_ij^-1(y_i^-1 y_j).
   Stacked over the edges they form q_links^t in R^{D_links} (Eq. 4.55).
2. Object DOFs (optional, Eq. 4.56; for graphs with closed chains - a tree's DOFs are the sum
   of its links' DOFs, Sec. 4.2): PCA of the stacked configurations; for a candidate
   object DOF D < D_links the configurations are replaced by their projection onto the first
   D principal components, q_links ~ mean + P^T P (q_links - mean), which costs
   k_PCA = D * D_links extra parameters.
3. Pose-graph optimisation (the thesis used HOG-Man; here a batched Gauss-Newton with analytic
   Jacobians, vectorised over the time steps): the part poses x_1..x_p at each time step
   minimise sum_i |x_i (-) y_i|^2_Sigma_y + sum_(ij in E) s^2 |(x_i^-1 x_j) (-) Delta_ij|^2_Sigma_y
   with Delta_ij = f_ij(q_ij) the predicted relative transform and ``stiffness`` s (default 30)
   that makes the kinematic constraints nearly hard. All parts are treated alike (no root is
   clamped to its observation).
4. Global likelihood (Eq. 4.49-4.54): log p(D_y | G) = sum_t sum_i log N(x_i (-) y_i; Sigma_y)
   - n D log n, and BIC = -2 log p + k log n with k = sum of the links' k plus k_PCA
   (n = number of time steps used: those where every part is observed).

Structure search: ``tree`` = minimum spanning tree over the pairs' BICs (Eq. 4.40);
``local`` = from that tree, repeatedly move to a graph that adds or removes one edge
(staying connected) and lowers the BIC (first improvement, candidates ordered by their link
BICs), until no neighbour improves (never worse than the tree); ``exhaustive`` = every
connected edge subset (a reference for small p; 38 graphs for p = 4).

Poses are (T, 7) arrays x y z qx qy qz qw (metres) or (T, 4, 4); NaN rows = not observed.
Orientations are required (the pose graph constrains full poses).
"""

from __future__ import annotations

import itertools
import time
from dataclasses import dataclass, field

import numpy as np

from mmlearn.models.articulation.link import ObservationModel
from mmlearn.models.articulation.base import distinguishable_configurations
from mmlearn.models.articulation.structure import DEFAULT_CANDIDATES, fit_pair_models, spanning_tree_edges
from mmlearn.models.common.se3 import MAX_COORDINATE, as_pose_array

__all__ = [
    "GraphEvaluation",
    "StructureResult",
    "KinematicGraphEvaluator",
    "fit_pair_models",
    "as_part_tracks",
    "spanning_tree_edges",
    "search_structure",
    "fit_structure",
    "pca_projection",
    "SEARCH_MODES",
    "read_parts_csv",
    "write_parts_csv",
    "CSV_HEADER",
]

SEARCH_MODES = ("tree", "local", "exhaustive")


# --------------------------------------------------------------------------- small SO(3) helpers
def _skew(v: np.ndarray) -> np.ndarray:
    S = np.zeros(v.shape[:-1] + (3, 3))
    S[..., 0, 1], S[..., 0, 2] = -v[..., 2], v[..., 1]
    S[..., 1, 0], S[..., 1, 2] = v[..., 2], -v[..., 0]
    S[..., 2, 0], S[..., 2, 1] = -v[..., 1], v[..., 0]
    return S


def _exp(w: np.ndarray) -> np.ndarray:
    """Rotation vectors (..., 3) -> matrices (..., 3, 3) (Rodrigues)."""
    th = np.linalg.norm(w, axis=-1)[..., None, None]
    K = _skew(w)
    small = th < 1e-8
    ths = np.where(small, 1.0, th)
    a = np.where(small, 1.0 - th**2 / 6.0, np.sin(ths) / ths)
    b = np.where(small, 0.5 - th**2 / 24.0, (1.0 - np.cos(ths)) / ths**2)
    return np.eye(3) + a * K + b * (K @ K)


def _log(R: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) -> rotation vectors (..., 3)."""
    tr = np.clip((np.trace(R, axis1=-2, axis2=-1) - 1.0) / 2.0, -1.0, 1.0)
    th = np.arccos(tr)
    v = np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0],
                  R[..., 1, 0] - R[..., 0, 1]], axis=-1)
    s = np.sin(th)
    small = th < 1e-6
    f = np.where(small, 0.5 + th**2 / 12.0, th / (2.0 * np.where(small, 1.0, s)))
    w = f[..., None] * v
    near_pi = th > np.pi - 1e-3
    if np.any(near_pi):  # axis from the symmetric part
        Rp = R[near_pi]
        B = (Rp + np.swapaxes(Rp, -1, -2)) / 2.0 - np.eye(3) * np.cos(th[near_pi])[:, None, None]
        k = np.argmax(np.diagonal(B, axis1=-2, axis2=-1), axis=-1)
        ax = B[np.arange(len(k)), k]
        ax /= np.linalg.norm(ax, axis=-1, keepdims=True)
        sgn = np.sign(np.einsum("ni,ni->n", ax, v[near_pi]))
        sgn[sgn == 0] = 1.0
        w[near_pi] = ax * (sgn * th[near_pi])[:, None]
    return w


def _angle(R: np.ndarray) -> np.ndarray:
    tr = np.clip((np.trace(R, axis1=-2, axis2=-1) - 1.0) / 2.0, -1.0, 1.0)
    return np.arccos(tr)


def _jr_inv(w: np.ndarray) -> np.ndarray:
    """Inverse right Jacobian of SO(3) at rotation vectors w (..., 3)."""
    th = np.linalg.norm(w, axis=-1)[..., None, None]
    K = _skew(w)
    small = th < 1e-6
    ths = np.where(small, 1.0, th)
    c = np.where(small, 1.0 / 12.0,
                 1.0 / ths**2 - (1.0 + np.cos(ths)) / (2.0 * ths * np.sin(np.where(
                     small, 1.0, np.clip(ths, 1e-6, np.pi - 1e-6)))))
    return np.eye(3) + 0.5 * K + c * (K @ K)


# --------------------------------------------------------------------------- input handling
def as_part_tracks(part_tracks) -> np.ndarray:
    """Validate and convert part observations to one (p, T, 7) array (NaN = not observed).

    Accepts a sequence of p arrays (T, 7) or (T, 4, 4), or one (p, T, 7) array."""
    if isinstance(part_tracks, np.ndarray) and part_tracks.ndim == 3 and part_tracks.shape[-1] == 7:
        tracks = [part_tracks[k] for k in range(part_tracks.shape[0])]
    else:
        tracks = [np.asarray(t, float) for t in part_tracks]
    p = len(tracks)
    if p < 2:
        raise ValueError(f"need at least 2 parts, got {p}")
    T = tracks[0].shape[0]
    out = np.full((p, T, 7), np.nan)
    for k, t in enumerate(tracks):
        t = np.asarray(t, float)
        if t.shape[0] != T:
            raise ValueError(f"part {k}: {t.shape[0]} time steps, part 0 has {T}")
        if t.ndim == 3 and t.shape[1:] == (4, 4):
            ok = np.isfinite(t.reshape(T, -1)).all(axis=1)
            if ok.any():
                out[k, ok] = as_pose_array(t[ok], what=f"part {k}").as_array()
        elif t.ndim == 2 and t.shape[1] == 7:
            ok = np.isfinite(t).all(axis=1)
            bad = ~ok & np.isfinite(t).any(axis=1)
            if bad.any():
                raise ValueError(f"part {k}: rows {np.flatnonzero(bad)[:10].tolist()} are "
                                 "partly NaN (a row must be all NaN = unobserved, or finite)")
            if ok.any():
                out[k, ok] = as_pose_array(t[ok], what=f"part {k}").as_array()
        elif t.ndim == 2 and t.shape[1] == 3:
            raise ValueError(f"part {k}: position-only track; kinematic graphs need full poses "
                             "(x y z qx qy qz qw)")
        else:
            raise ValueError(f"part {k}: expected a (T, 7) or (T, 4, 4) array, got {t.shape}")
    return out



def pca_projection(Q: np.ndarray, dof: int):
    """Projection of configurations Q (n, D_links) onto their first ``dof`` principal
    components (Eq. 4.56). Returns (Q_hat (n, D_links), P (dof, D_links), mean (D_links,),
    explained variance ratio (D_links,))."""
    Q = np.asarray(Q, float)
    mu = Q.mean(axis=0)
    if Q.shape[1] == 0:
        return Q.copy(), np.zeros((0, 0)), mu, np.zeros(0)
    _, S, Vt = np.linalg.svd(Q - mu, full_matrices=False)
    var = S**2
    ratio = var / var.sum() if var.sum() > 0 else np.zeros_like(var)
    ratio = np.concatenate([ratio, np.zeros(Q.shape[1] - ratio.size)])
    P = Vt[:dof]
    return mu + (Q - mu) @ P.T @ P, P, mu, ratio


# --------------------------------------------------------------------------- results
@dataclass
class GraphEvaluation:
    """Global evaluation of one kinematic graph.

    Attributes:
        edges: sorted (i, j) pairs.
        models: link model name per edge.
        dof: object DOFs D (after PCA reduction, if any).
        dof_links: D_links = sum of the links' DOFs.
        log_likelihood: log p(D_y | G) of Eq. 4.54 (includes -n D log n).
        k: number of parameters (links + k_PCA).
        n: number of time steps used.
        bic: -2 log_likelihood + k log n.
        pos_error_m / orient_error_rad: mean distance between optimised and observed poses.
        has_loop: the graph contains a closed chain.
        projection: PCA matrix P (dof, dof_links) when the DOFs were reduced, else None.
        bic_per_dof: {D: BIC} for every DOF evaluated.
    """

    edges: tuple
    models: dict
    dof: int
    dof_links: int
    log_likelihood: float
    k: int
    n: int
    bic: float
    pos_error_m: float
    orient_error_rad: float
    has_loop: bool
    projection: np.ndarray | None = None
    bic_per_dof: dict = field(default_factory=dict)
    prior_cost: float = 0.0

    @property
    def score(self) -> float:
        """What the search minimises: ``bic + prior_cost`` (``prior_cost``: the term of a
        :class:`~mmlearn.models.articulation.structure_prior.StructurePrior`, BIC units; 0
        without one)."""
        return self.bic + self.prior_cost


@dataclass
class StructureResult:
    """Result of a structure search.

    Attributes:
        best: the selected :class:`GraphEvaluation`.
        tree: evaluation of the minimum spanning tree (the search's start).
        search: "tree", "local" or "exhaustive".
        evaluated: every graph evaluated, in order.
        search_seconds: wall time of the graph search (after the pair models were fitted).
        fit_seconds: wall time to fit the pair models (0 when they were passed in).
        part_names: names of the parts.
        pair_models: {(i, j): LinkSelection}.
        search_cpu_seconds, fit_cpu_seconds: the same as CPU time of this process
            (time.process_time; not inflated by other processes on a shared machine).
    """

    best: GraphEvaluation
    tree: GraphEvaluation
    search: str
    evaluated: list
    search_seconds: float
    fit_seconds: float
    part_names: list
    pair_models: dict
    search_cpu_seconds: float = float("nan")
    fit_cpu_seconds: float = float("nan")
    roles: dict | None = None

    @property
    def seconds(self) -> float:
        return self.search_seconds + self.fit_seconds

    def to_dict(self) -> dict:
        """JSON-friendly summary (the --json schema of apps/fit_structure)."""
        b = self.best
        return {
            "parts": list(self.part_names),
            "edges": [{"a": self.part_names[i], "b": self.part_names[j], "model": b.models[(i, j)],
                       "bic": float(getattr(self.pair_models[(i, j)], "best",
                                            self.pair_models[(i, j)]).bic_)}
                      for i, j in b.edges],
            "dof": int(b.dof),
            "has_loop": bool(b.has_loop),
            "bic": float(b.bic),
            "seconds": float(self.seconds),
            **({} if self.roles is None else
               {"prior_cost": float(b.prior_cost), "score": float(b.score),
                "roles": dict(self.roles)}),
        }


# --------------------------------------------------------------------------- evaluator
class KinematicGraphEvaluator:
    """Evaluates kinematic graphs over fixed part observations and pair models.

    Args:
        part_tracks: (p, T, 7) or list of (T, 7) / (T, 4, 4); NaN rows = unobserved. Only time
            steps at which every part is observed are used (at least 3).
        pair_models: {(i, j): LinkSelection or fitted LinkModel} (part j in the frame of i).
        obs: observation noise Sigma_y (sigma_pos in m, sigma_orient in rad).
        stiffness: weight s of the kinematic constraints relative to the observations.
        max_iters: Gauss-Newton iterations of the pose-graph optimisation.
    """

    def __init__(self, part_tracks, pair_models: dict, *, obs: ObservationModel | None = None,
                 stiffness: float = 30.0, max_iters: int = 10):
        Y = as_part_tracks(part_tracks)
        self.p = Y.shape[0]
        full = np.isfinite(Y).all(axis=2).all(axis=0)
        self.time_index = np.flatnonzero(full)
        if self.time_index.size < 3:
            raise ValueError(f"only {self.time_index.size} time steps observe every part; "
                             "graph evaluation needs at least 3")
        Yf = Y[:, full]
        self.n = int(Yf.shape[1])
        pa = [as_pose_array(Yf[k]) for k in range(self.p)]
        self.Py = np.stack([a.positions for a in pa], axis=1)  # (n, p, 3)
        self.Ry = np.stack([a.rotations.as_matrix() for a in pa], axis=1)  # (n, p, 3, 3)
        self.obs = obs if obs is not None else ObservationModel()
        if not stiffness > 0:
            raise ValueError(f"stiffness must be positive, got {stiffness}")
        self.stiffness = float(stiffness)
        self.max_iters = int(max_iters)
        self.models = {}
        for key, s in pair_models.items():
            i, j = key
            if not (0 <= i < j < self.p):
                raise ValueError(f"pair {key} is not a pair (i, j) with i < j of the {self.p} "
                                 "parts (the model describes part j in the frame of part i)")
            m = getattr(s, "best", s)
            if not m.has_orientation:
                raise ValueError(f"pair {key}: position-only link model; graphs need full poses")
            self.models[(min(i, j), max(i, j))] = m
        self._q = {}
        self._cache = {}
        self.num_evaluations = 0

    # ----- configurations of one edge at the used time steps
    def link_configurations(self, edge) -> np.ndarray:
        e = (min(edge), max(edge))
        if e not in self._q:
            i, j = e
            Ti = np.tile(np.eye(4), (self.n, 1, 1))
            Tj = Ti.copy()
            Ti[:, :3, :3], Ti[:, :3, 3] = self.Ry[:, i], self.Py[:, i]
            Tj[:, :3, :3], Tj[:, :3, 3] = self.Ry[:, j], self.Py[:, j]
            z = np.linalg.inv(Ti) @ Tj
            self._q[e] = self.models[e].inverse(z).reshape(self.n, -1)
        return self._q[e]

    def _predict(self, edges, Q):
        """Predicted relative transforms (n, E, 3) positions and (n, E, 3, 3) rotations."""
        P = np.zeros((self.n, len(edges), 3))
        R = np.zeros((self.n, len(edges), 3, 3))
        k = 0
        for e_i, e in enumerate(edges):
            m = self.models[e]
            d = m.dof
            M = m.forward_matrices(Q[:, k:k + d] if d else np.zeros((self.n, 0)))
            if M.shape[0] == 1 and self.n > 1:
                M = np.repeat(M, self.n, axis=0)
            P[:, e_i], R[:, e_i] = M[:, :3, 3], M[:, :3, :3]
            k += d
        return P, R

    def optimize_poses(self, edges, dP, dR):
        """Batched Gauss-Newton pose-graph optimisation. Returns optimised positions
        (n, p, 3) and rotations (n, p, 3, 3)."""
        n, p = self.n, self.p
        sp, so = self.obs.sigma_pos, self.obs.sigma_orient
        wo = np.array([1 / sp] * 3 + [1 / so] * 3)
        we = self.stiffness * wo
        Px, Rx = self.Py.copy(), self.Ry.copy()
        I_idx = np.array([e[0] for e in edges])
        J_idx = np.array([e[1] for e in edges])
        E = len(edges)
        for _ in range(self.max_iters):
            H = np.zeros((n, 6 * p, 6 * p))
            g = np.zeros((n, 6 * p))
            # observation factors
            ro = np.concatenate([Px - self.Py, _log(np.swapaxes(self.Ry, -1, -2) @ Rx)], axis=-1)
            ro = ro * wo  # (n, p, 6)
            for i in range(p):
                sl = slice(6 * i, 6 * i + 6)
                H[:, sl, sl] += np.diag(wo**2)
                g[:, sl] += ro[:, i] * wo
            # edge factors
            Ri, Rj = Rx[:, I_idx], Rx[:, J_idx]
            RiT = np.swapaxes(Ri, -1, -2)
            r = np.einsum("neab,neb->nea", RiT, Px[:, J_idx] - Px[:, I_idx])
            Qr = RiT @ Rj
            rho = _log(np.swapaxes(dR, -1, -2) @ Qr)
            res = np.concatenate([r - dP, rho], axis=-1) * we  # (n, E, 6)
            Jinv = _jr_inv(rho)
            Ja = np.zeros((n, E, 6, 6))
            Jb = np.zeros((n, E, 6, 6))
            Ja[..., :3, :3] = -RiT
            Ja[..., :3, 3:] = _skew(r)
            Ja[..., 3:, 3:] = -Jinv @ np.swapaxes(Qr, -1, -2)
            Jb[..., :3, :3] = RiT
            Jb[..., 3:, 3:] = Jinv
            Ja *= we[:, None]
            Jb *= we[:, None]
            for e_i, (i, j) in enumerate(edges):
                si, sj = slice(6 * i, 6 * i + 6), slice(6 * j, 6 * j + 6)
                A, B, rr = Ja[:, e_i], Jb[:, e_i], res[:, e_i]
                At = np.swapaxes(A, -1, -2)
                Bt = np.swapaxes(B, -1, -2)
                H[:, si, si] += At @ A
                H[:, sj, sj] += Bt @ B
                H[:, si, sj] += At @ B
                H[:, sj, si] += Bt @ A
                g[:, si] += np.einsum("nab,na->nb", A, rr)
                g[:, sj] += np.einsum("nab,na->nb", B, rr)
            dx = -np.linalg.solve(H, g[..., None])[..., 0].reshape(n, p, 6)
            Px = Px + dx[..., :3]
            Rx = Rx @ _exp(dx[..., 3:])
            if np.max(np.abs(dx)) < 1e-9:
                break
        return Px, Rx

    def _config_prior(self, edges, dof: int) -> float:
        """log p(q) of the object's D = ``dof`` configurations over the n time steps, the
        same configuration prior as link fitting (LinkModel.log_config_prior): n^-D with
        ``config_prior="n"`` (Eq. 4.54 as written), else min(n, c)^-1 per object DOF, with
        c the noise-resolved range of the link DOFs (the D largest when PCA keeps D of
        them)."""
        if dof == 0:
            return 0.0
        if self.obs.config_prior == "n":
            return float(-self.n * dof * np.log(self.n))
        c = np.concatenate([self.models[e].config_resolution() for e in edges])
        c = np.sort(c)[::-1][:dof]
        c = np.pad(c, (0, max(0, dof - c.size)), constant_values=1.0)
        return float(-self.n * np.sum(np.log(distinguishable_configurations(self.n, c))))

    def _score(self, edges, Q, dof, k_extra):
        dP, dR = self._predict(edges, Q)
        Px, Rx = self.optimize_poses(edges, dP, dR)
        ep2 = np.sum((Px - self.Py) ** 2, axis=-1)
        eo = _angle(np.swapaxes(self.Ry, -1, -2) @ Rx)
        ll = float(self.obs.log_inlier(ep2, eo).sum()) + self._config_prior(edges, dof)
        k = int(sum(self.models[e].num_params_ for e in edges)) + int(k_extra)
        bic = -2.0 * ll + k * np.log(self.n)
        return ll, k, bic, float(np.sqrt(ep2).mean()), float(eo.mean())

    def evaluate(self, edges, *, reduce_dofs: bool = False,
                 reduce_tree_dofs: bool = False) -> GraphEvaluation:
        """Global BIC of the graph with the given edges (Eq. 4.47-4.54). With
        ``reduce_dofs``, for a graph with a closed chain every object DOF D = 0..D_links is
        tried by PCA (Eq. 4.55-4.56) and the lowest BIC is kept; a tree keeps D = D_links
        (its links can be actuated independently, Sec. 4.2) unless ``reduce_tree_dofs``.
        Raises ValueError for edges without a pair model or a disconnected graph."""
        import networkx as nx

        edges = tuple(sorted((min(e), max(e)) for e in edges))
        key = (edges, bool(reduce_dofs), bool(reduce_tree_dofs))
        if key in self._cache:
            return self._cache[key]
        for e in edges:
            if e not in self.models:
                raise ValueError(f"no link model for pair {e}")
        G = nx.Graph()
        G.add_nodes_from(range(self.p))
        G.add_edges_from(edges)
        if not nx.is_connected(G):
            raise ValueError(f"graph {edges} does not connect all {self.p} parts")
        self.num_evaluations += 1
        Q = (np.hstack([self.link_configurations(e) for e in edges]) if edges
             else np.zeros((self.n, 0)))
        D_links = Q.shape[1]
        results = {}
        ll, k, bic, ep, eo = self._score(edges, Q, D_links, 0)
        results[D_links] = (ll, k, bic, ep, eo, None)
        loop = len(edges) > self.p - 1
        if reduce_dofs and D_links > 0 and (loop or reduce_tree_dofs):
            for D in range(D_links - 1, -1, -1):
                Qh, P, _, _ = pca_projection(Q, D)
                ll, k, bic, ep, eo = self._score(edges, Qh, D, D * D_links)
                results[D] = (ll, k, bic, ep, eo, P)
        D = min(results, key=lambda d: results[d][2])
        ll, k, bic, ep, eo, P = results[D]
        ev = GraphEvaluation(
            edges=edges, models={e: self.models[e].name for e in edges}, dof=int(D),
            dof_links=int(D_links), log_likelihood=ll, k=k, n=self.n, bic=bic,
            pos_error_m=ep, orient_error_rad=eo, has_loop=len(edges) > self.p - 1,
            projection=P, bic_per_dof={d: r[2] for d, r in sorted(results.items())})
        self._cache[key] = ev
        return ev


# --------------------------------------------------------------------------- search
def _connected(edges, p) -> bool:
    import networkx as nx

    G = nx.Graph()
    G.add_nodes_from(range(p))
    G.add_edges_from(edges)
    return nx.is_connected(G)


def search_structure(evaluator: KinematicGraphEvaluator, tree_edges, *, search: str = "local",
                     reduce_dofs: bool = False, reduce_tree_dofs: bool = False,
                     strategy: str = "first", max_steps: int = 100, prior_cost=None,
                     other_starts=()):
    """Search the graph space from ``tree_edges``. Returns (best, tree evaluation, list of
    evaluated graphs in order). Graphs are compared by their ``score``: the BIC plus
    ``prior_cost(edges)`` when given (a structure prior's term, BIC units). ``other_starts``
    are further trees to start from: the search starts from the best-scoring of them and
    ``tree_edges`` (whose evaluation is still returned as the tree).

    Local search: the neighbours of the current graph (add one edge, the pairs with the
    lowest link BIC first; remove one edge, keeping the graph connected, the highest link
    BIC first) are evaluated in that order; ``strategy="first"`` moves to the first
    neighbour that lowers the BIC, ``"best"`` evaluates all neighbours and moves to the
    best. Stops when no neighbour improves, so the result is never worse than the tree."""
    if strategy not in ("first", "best"):
        raise ValueError(f"unknown local-search strategy {strategy!r}; use 'first' or 'best'")
    if search not in SEARCH_MODES:
        raise ValueError(f"unknown search {search!r}; choose from {', '.join(SEARCH_MODES)}")
    p = evaluator.p
    order = []

    def ev(edges):
        e = evaluator.evaluate(edges, reduce_dofs=reduce_dofs, reduce_tree_dofs=reduce_tree_dofs)
        if prior_cost is not None:
            e.prior_cost = float(prior_cost(e.edges))
        if not any(e is o for o in order):
            order.append(e)
        return e

    tree = ev(tree_edges)
    start = min([tree] + [ev(t) for t in other_starts], key=lambda x: x.score)
    if search == "tree":
        return start, tree, order
    pairs = sorted(evaluator.models)
    if search == "exhaustive":
        best = start
        for m in range(p - 1, len(pairs) + 1):
            for sub in itertools.combinations(pairs, m):
                if not _connected(sub, p):
                    continue
                e = ev(sub)
                if e.score < best.score:
                    best = e
        return best, tree, order
    # neighbours: add one edge (best pair models first) or remove one edge (worst first)
    cost = {e: float(getattr(m, "bic_", np.nan)) for e, m in evaluator.models.items()}
    cur = start
    for _ in range(max_steps):
        cur_set = set(cur.edges)
        cand = [tuple(sorted(cur_set | {e}))
                for e in sorted((e for e in pairs if e not in cur_set), key=cost.get)]
        for e in sorted(cur.edges, key=cost.get, reverse=True):
            rest = tuple(sorted(cur_set - {e}))
            if len(rest) >= p - 1 and _connected(rest, p):
                cand.append(rest)
        if not cand:
            break
        moved = False
        if strategy == "first":
            for c in cand:
                e = ev(c)
                if e.score < cur.score - 1e-9:
                    cur, moved = e, True
                    break
        else:
            nb = min((ev(c) for c in cand), key=lambda x: x.score)
            if nb.score < cur.score - 1e-9:
                cur, moved = nb, True
        if not moved:
            break
    return cur, tree, order


def _tree_from_links(edges, pair_models, p) -> GraphEvaluation:
    """Tree evaluation from the link BICs alone (Eq. 4.39-4.40), used when too few time
    steps observe all parts for a global evaluation."""
    ms = {e: pair_models[e].best for e in edges}
    ll = float(sum(m.log_likelihood_ for m in ms.values()))
    k = int(sum(m.num_params_ for m in ms.values()))
    return GraphEvaluation(
        edges=tuple(edges), models={e: m.name for e, m in ms.items()},
        dof=int(sum(m.dof for m in ms.values())), dof_links=int(sum(m.dof for m in ms.values())),
        log_likelihood=ll, k=k, n=int(max(m.n_train for m in ms.values())),
        bic=float(sum(m.bic_ for m in ms.values())), pos_error_m=float("nan"),
        orient_error_rad=float("nan"), has_loop=False)


def fit_structure(part_tracks, *, part_names=None, search: str = "local",
                  reduce_dofs: bool = False, reduce_tree_dofs: bool = False,
                  models=DEFAULT_CANDIDATES,
                  obs: ObservationModel | None = None, rng=None, min_common: int = 5,
                  n_hypotheses: int = 100, stiffness: float = 30.0,
                  pair_models: dict | None = None, prior=None) -> StructureResult:
    """Learn the kinematic graph of an object from part observations.

    Args:
        part_tracks: (p, T, 7) array or list of p (T, 7) / (T, 4, 4) arrays (NaN =
            unobserved).
        part_names: names of the parts (default part0, part1, ...).
        search: "tree", "local" or "exhaustive".
        reduce_dofs: estimate the DOFs of graphs with closed chains by PCA (Eq. 4.55-4.56).
        reduce_tree_dofs: also try PCA DOF reduction on trees (not in the thesis: a tree with
            PCA-coupled links explains a loop as well as the loop graph, with fewer links).
        models: candidate link models per pair.
        obs: observation noise model (sigma_pos m, sigma_orient rad).
        rng: Generator or seed (MLESAC sampling of the link models).
        pair_models: already fitted {(i, j): LinkSelection} to reuse.
        prior: a :class:`~mmlearn.models.articulation.structure_prior.StructurePrior` (the
            spanning tree and the search then minimise the BIC plus its cost, the search
            also starts from the spanning tree of the plausible edges alone, and graphs may
            couple their DOFs by PCA, trees included; the result's ``roles`` holds the
            parts' roles), or None (the BIC alone).
    """
    if search not in SEARCH_MODES:
        raise ValueError(f"unknown search {search!r}; choose from {', '.join(SEARCH_MODES)}")
    Y = as_part_tracks(part_tracks)
    p = Y.shape[0]
    names = list(part_names) if part_names is not None else [f"part{k}" for k in range(p)]
    if len(names) != p:
        raise ValueError(f"{len(names)} part names for {p} parts")
    obs = obs if obs is not None else ObservationModel()
    t0, c0 = time.perf_counter(), time.process_time()
    if pair_models is None:
        pair_models = fit_pair_models(Y, models=models, obs=obs, rng=rng, min_common=min_common,
                                      n_hypotheses=n_hypotheses)
    t1, c1 = time.perf_counter(), time.process_time()
    n_full = int(np.isfinite(Y).all(axis=2).all(axis=0).sum())
    roles, prior_cost, extra, starts = None, None, None, ()
    if prior is not None:
        roles = prior.resolve_roles(Y, names)
        by_index = [roles[n] for n in names]

        n_prior = max(n_full, 2) if n_full >= 3 else max(
            int(max(getattr(m, "best", m).n_train for m in pair_models.values())), 2)

        def prior_cost(edges):
            return prior.cost(edges, by_index, n_prior)

        extra = {e: prior_cost([e]) for e in pair_models}
        plausible = {e: m for e, m in pair_models.items() if extra[e] == 0.0}
        try:
            starts = (spanning_tree_edges(plausible, p),)
        except ValueError:          # the plausible edges alone do not connect the parts
            starts = ()
        # fronts only ever moved together: a tree of fronts on the carcass with coupled DOFs
        reduce_dofs = reduce_tree_dofs = True
    tree_edges = spanning_tree_edges(pair_models, p, extra_cost=extra)
    if n_full < 3:
        if search != "tree":
            raise ValueError(f"only {n_full} time steps observe every part; the {search!r} "
                             "search evaluates whole graphs and needs at least 3 (use --search "
                             "tree)")
        tree = _tree_from_links(tree_edges, pair_models, p)
        if prior_cost is not None:
            tree.prior_cost = float(prior_cost(tree.edges))
        best, order = tree, [tree]
    else:
        evaluator = KinematicGraphEvaluator(Y, pair_models, obs=obs, stiffness=stiffness)
        best, tree, order = search_structure(evaluator, tree_edges, search=search,
                                             reduce_dofs=reduce_dofs,
                                             reduce_tree_dofs=reduce_tree_dofs,
                                             prior_cost=prior_cost, other_starts=starts)
    t2, c2 = time.perf_counter(), time.process_time()
    return StructureResult(best=best, tree=tree, search=search, evaluated=order,
                           search_seconds=t2 - t1, fit_seconds=t1 - t0, part_names=names,
                           pair_models=pair_models, search_cpu_seconds=c2 - c1,
                           fit_cpu_seconds=c1 - c0, roles=roles)


# --------------------------------------------------------------------------- CSV input
CSV_HEADER = ("t", "part", "x", "y", "z", "qx", "qy", "qz", "qw")


def read_parts_csv(path):
    """Read part observations from CSV with header ``t,part,x,y,z,qx,qy,qz,qw`` (t in
    seconds, one row per observed part per time step; a missing row = not observed).

    Returns (part names in order of first appearance, times (T,), poses (p, T, 7) with NaN
    for unobserved). Raises ValueError naming the file and line on bad input and
    FileNotFoundError for a missing file."""
    import csv
    from pathlib import Path

    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"{p}: file not found")
    with open(p, newline="") as f:
        rows = list(csv.reader(f))
    rows = [(k + 1, r) for k, r in enumerate(rows) if r and any(c.strip() for c in r)]
    if not rows:
        raise ValueError(f"{p}: empty file")
    header = tuple(c.strip().lower() for c in rows[0][1])
    if header != CSV_HEADER:
        raise ValueError(f"{p}:1: bad header {','.join(header)!r}; expected "
                         f"{','.join(CSV_HEADER)!r}")
    names, times, recs = [], [], []
    for line, r in rows[1:]:
        if len(r) != 9:
            raise ValueError(f"{p}:{line}: expected 9 columns, got {len(r)}")
        try:
            t = float(r[0])
            vals = [float(c) for c in r[2:]]
        except ValueError:
            raise ValueError(f"{p}:{line}: non-numeric value in {','.join(r)!r}") from None
        if not (np.isfinite(t) and np.all(np.isfinite(vals))):
            raise ValueError(f"{p}:{line}: NaN or infinite value")
        if sum(v * v for v in vals[3:]) < 1e-12:
            raise ValueError(f"{p}:{line}: zero quaternion")
        if not sum(v * v for v in vals[3:]) < 1e300:
            raise ValueError(f"{p}:{line}: quaternion too long to normalise")
        if max(abs(v) for v in vals[:3]) > MAX_COORDINATE:
            raise ValueError(f"{p}:{line}: position beyond {MAX_COORDINATE:g} m (positions "
                             f"must be in metres)")
        part = r[1].strip()
        if not part:
            raise ValueError(f"{p}:{line}: empty part name")
        if part not in names:
            names.append(part)
        times.append(t)
        recs.append((line, t, part, vals))
    if not recs:
        raise ValueError(f"{p}: no observations")
    tu = np.unique(np.asarray(times))
    Y = np.full((len(names), tu.size, 7), np.nan)
    for line, t, part, vals in recs:
        k, i = names.index(part), int(np.searchsorted(tu, t))
        if np.isfinite(Y[k, i, 0]):
            raise ValueError(f"{p}:{line}: part {part!r} observed twice at t = {t}")
        q = np.asarray(vals[3:])
        Y[k, i] = np.concatenate([vals[:3], q / np.linalg.norm(q)])
    return names, tu, Y


def write_parts_csv(path, part_names, times, poses) -> None:
    """Write (p, T, 7) poses (NaN = unobserved, skipped) in the format of
    :func:`read_parts_csv`, atomically."""
    from mmlearn.models.common.fileio import atomic_write_text

    Y = np.asarray(poses, float)
    lines = [",".join(CSV_HEADER)]
    for i, t in enumerate(np.asarray(times, float)):
        for k, nm in enumerate(part_names):
            if np.all(np.isfinite(Y[k, i])):
                lines.append(f"{t:.6f},{nm}," + ",".join(f"{v:.9g}" for v in Y[k, i]))
    atomic_write_text(path, "\n".join(lines) + "\n")
