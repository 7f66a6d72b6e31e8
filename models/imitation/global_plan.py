"""Global reproduction of a learned task (thesis Eq. 8.27-8.28): the configuration sequence
minimising the summed per-slice Mahalanobis cost, found by A* on a time-expanded roadmap
(:func:`plan_global`).

**Eq. 8.28 cost.** The per-slice cost is the Mahalanobis distance of the configuration to every
constraint's Gaussian at that slice (``sum_i (x_i - fk(q) - mu_i)^T Sigma_i^-1 (..) + (q -
mu~)^T Sigma~^-1 (q - mu~)``), i.e. -2 log of the slice's factors of Eq. 8.2 up to a constant:
the exact form of the Mahalanobis distance to the combined Gaussian of Eq. 8.23-8.24 (which
linearises ``fk``). The sum over slices is Eq. 8.27's negative log-likelihood; obstacles are
hard constraints of the roadmap (nodes and edges in collision are removed).

Plain numpy/scipy/networkx; the robot's kinematics enter through ``fk`` / ``jacobian``
callables given by the caller.
"""

from __future__ import annotations

import time
from typing import Callable, Sequence

import numpy as np
from scipy.spatial import cKDTree

from mmlearn.models.imitation.types import ImitationDataError, Obstacle, TaskModel

__all__ = ["plan_global"]


def _slice_costs(model: TaskModel, hands: np.ndarray, qs: np.ndarray, objects: dict, *,
                 use_joints: bool, carried_mask: dict) -> np.ndarray:
    """``(S, N)`` Mahalanobis cost of every roadmap configuration at every slice (Eq. 8.28,
    exact form): Cartesian constraints ``(x_i - fk(q) - mu_i)^T Sigma_i^-1 (...)`` plus the
    joint constraint."""
    S, N = model.S, hands.shape[0]
    C = np.zeros((S, N))
    for name in model.objects:
        x = objects.get(name)
        if x is None or not np.all(np.isfinite(x)):
            continue
        c = f"obj:{name}"
        R = (np.asarray(x, float)[None, None, :] - hands[None, :, :]) - model.mean[c][:, None, :]  # (S, N, D)
        v = model.var[c]
        if v.ndim == 2:
            cost = np.einsum("snd,sd->sn", R * R, 1.0 / v)
        else:
            P = np.linalg.inv(v)
            cost = np.einsum("snd,sde,sne->sn", R, P, R)
        m = carried_mask.get(name)
        if m is not None:
            cost[m] = 0.0
        C += cost
    if use_joints and "joints" in model.constraints:
        R = qs[None, :, :] - model.mean["joints"][:, None, :]
        v = model.var["joints"]
        if v.ndim == 2:
            C += np.einsum("snd,sd->sn", R * R, 1.0 / v)
        else:
            C += np.einsum("snd,sde,sne->sn", R, np.linalg.inv(v), R)
    return C


def _ik(x_target, q_seed, fk, jacobian, *, iters=40, damping=0.02, tol=1e-4, lower=None, upper=None):
    q = np.array(q_seed, dtype=float)
    for _ in range(iters):
        e = x_target - fk(q)
        if np.linalg.norm(e) < tol:
            break
        Jq = jacobian(q)
        q = q + Jq.T @ np.linalg.solve(Jq @ Jq.T + damping ** 2 * np.eye(len(e)), e)
        if lower is not None:
            q = np.clip(q, lower, upper)
    return q


def _fk_rows(Q, fk, fk_batch):
    """Forward kinematics of every row of ``Q`` (vectorised with ``fk_batch`` when given)."""
    if fk_batch is not None:
        return np.asarray(fk_batch(Q), float)
    return np.array([fk(q) for q in Q])


def _collides(Q, H, *, obstacles, clearance, body_points, D) -> np.ndarray:
    """Per configuration of ``Q`` (hands ``H``): the hand or a body point closer than
    ``clearance`` to an obstacle."""
    if not obstacles:
        return np.zeros(len(Q), bool)
    bad = np.zeros(len(Q), bool)
    for ob in obstacles:
        bad |= ob.signed_distance(H) < clearance
    if body_points is not None:
        for i, q in enumerate(Q):
            if not bad[i]:
                P = np.asarray(body_points(q), float).reshape(-1, D)
                bad[i] = any(np.any(ob.signed_distance(P) < clearance) for ob in obstacles)
    return bad


def _carried_objects(model: TaskModel, carry_radius: float) -> dict:
    """Object name -> slices (S,) bool at which it is held in the hand: the gripper closed
    (< 0.5) and the object within ``carry_radius`` of the hand."""
    carried = {}
    if "gripper" in model.constraints:
        closed = model.mean["gripper"][:, 0] < 0.5
        for name in model.objects:
            m = closed & (np.linalg.norm(model.mean[f"obj:{name}"], axis=1) < carry_radius)
            if m.any():
                carried[name] = m
    return carried


def _mean_configurations(model: TaskModel, objs: dict, carried: dict, *, q0, h0, fk, jacobian,
                         lower, upper):
    """Roadmap step 1: every slice's precision-weighted hand target ``x_i - mu_i`` (S, D) and
    its inverse kinematics (S, n), damped least squares from the previous slice's."""
    S, D = model.S, h0.shape[0]
    targets = np.zeros((S, D))
    for k in range(S):
        P_sum = np.zeros((D, D))
        b = np.zeros(D)
        for name in model.objects:
            if name not in objs or (name in carried and carried[name][k]):
                continue
            P = np.linalg.inv(model.covariance(f"obj:{name}", k))
            P_sum += P
            b += P @ (objs[name] - model.mean[f"obj:{name}"][k])
        targets[k] = np.linalg.solve(P_sum, b) if np.any(P_sum) else (targets[k - 1] if k else h0)
    mean_q = np.zeros((S, q0.shape[0]))
    q = q0.copy()
    for k in range(S):
        q = _ik(targets[k], q, fk, jacobian, lower=lower, upper=upper)
        mean_q[k] = q
    return targets, mean_q


def _sampled_configurations(targets, mean_q, *, h0, obstacles, margin, n_samples, rng, fk,
                            jacobian, lower, upper):
    """Roadmap step 2: ``n_samples`` random hand positions, uniform in the bounding box of
    the targets, the start and the obstacles grown by ``margin``, solved by IK from the
    nearest mean configuration."""
    D = h0.shape[0]
    pts = np.concatenate([targets, h0[None]] + [np.stack([ob.centre - ob.half_size.max() * np.sqrt(D),
                                                          ob.centre + ob.half_size.max() * np.sqrt(D)])
                                                for ob in obstacles])
    lo, hi = pts.min(axis=0) - margin, pts.max(axis=0) + margin
    X = rng.uniform(lo, hi, size=(n_samples, D))
    _, near = cKDTree(targets).query(X)
    if not n_samples:
        return np.zeros((0, mean_q.shape[1]))
    return np.array([_ik(X[i], mean_q[near[i]], fk, jacobian, lower=lower, upper=upper)
                     for i in range(n_samples)])


def _free_nodes(Q, H, *, obstacles, clearance, body_points):
    """The configurations whose hand and body points keep ``clearance`` (the start always
    kept): (their indices, their checked points (N, m + 1, D), their smallest signed
    distance to an obstacle (N,))."""
    D = H.shape[1]
    Pn = H[:, None, :]
    if body_points is not None and obstacles:
        Pn = np.concatenate([Pn, np.array([np.asarray(body_points(q), float).reshape(-1, D) for q in Q])], axis=1)
    if obstacles:
        sd_node = np.min([ob.signed_distance(Pn).min(axis=1) for ob in obstacles], axis=0)
    else:
        sd_node = np.full(len(Q), np.inf)
    ok = sd_node >= clearance
    ok[0] = True                                           # the start is where the robot is
    idx = np.flatnonzero(ok)
    return idx, Pn[idx], sd_node[idx]


def _roadmap_edges(Q, orig, *, n_neighbors: int, S: int) -> np.ndarray:
    """Undirected roadmap edges (E, 2): each configuration to its ``n_neighbors`` nearest in
    joint space, and the chain q0 -> mean 0 -> mean 1 ... (``orig``: each node's index before
    the collision check; the mean configuration of slice k had index k + 1)."""
    N = len(Q)
    _, nb = cKDTree(Q).query(Q, k=min(n_neighbors + 1, N))
    nb = np.atleast_2d(nb)
    pairs = {(min(i, j), max(i, j)) for i in range(N) for j in nb[i][1:] if j < N}
    pos_of = {o: i for i, o in enumerate(orig)}
    for k in range(S):
        a, b = pos_of.get(k), pos_of.get(k + 1)
        if a is not None and b is not None and a != b:
            pairs.add((min(a, b), max(a, b)))
    return np.array(sorted(pairs), dtype=int).reshape(-1, 2)


def _collision_free_edges(pairs, Q, Pn, sd_node, *, collides, clearance, edge_checks,
                          check_resolution, fk_rows):
    """The edges whose interpolated configurations are collision free, and the number of
    configurations checked. The hand-space length of each edge decides how many interior
    points are checked; an edge whose endpoints are both farther from every obstacle than its
    hand length (plus the clearance) is kept unchecked (exact for a point hand, a heuristic
    for an arm)."""
    n = Q.shape[1]
    Le = np.linalg.norm(Pn[pairs[:, 0]] - Pn[pairs[:, 1]], axis=2).max(axis=1)
    need = np.minimum(sd_node[pairs[:, 0]], sd_node[pairs[:, 1]]) - clearance <= Le
    n_e = np.clip(np.ceil(Le / check_resolution), edge_checks, 16).astype(int)
    bad = np.zeros(len(pairs), bool)
    n_checked = 0
    for m_ in np.unique(n_e[need]):
        sel = np.flatnonzero(need & (n_e == m_))
        s_ = np.linspace(0, 1, m_ + 2)[1:-1]
        Qi = (Q[pairs[sel, 0], None, :] * (1 - s_[None, :, None])
              + Q[pairs[sel, 1], None, :] * s_[None, :, None]).reshape(-1, n)
        bad[sel] = collides(Qi, fk_rows(Qi)).reshape(len(sel), -1).any(axis=1)
        n_checked += len(Qi)
    return pairs[~bad], n_checked


def _search_networkx(C, a_src, a_dst, a_mot, rest):
    """A* (networkx) on the time-expanded graph: (configuration per slice or None, edges)."""
    import networkx as nx

    S, N = C.shape
    G = nx.DiGraph()
    goal = "goal"
    first = a_src == 0
    G.add_weighted_edges_from(zip(map(tuple, np.stack([np.zeros(first.sum(), int), a_src[first]], 1)),
                                  map(tuple, np.stack([np.ones(first.sum(), int), a_dst[first]], 1)),
                                  (C[1, a_dst[first]] + a_mot[first]).tolist()))
    for k in range(1, S - 1):
        w = (C[k + 1, a_dst] + a_mot).tolist()
        G.add_weighted_edges_from(zip(((k, int(a)) for a in a_src), ((k + 1, int(b)) for b in a_dst), w))
    G.add_weighted_edges_from(((S - 1, b), goal, 0.0) for b in range(N))
    n_edges = G.number_of_edges()
    try:
        path = nx.astar_path(G, (0, 0), goal, weight="weight",
                             heuristic=lambda u, v: 0.0 if u == goal else float(rest[u[0]]))
    except (nx.NetworkXNoPath, nx.NodeNotFound):
        path = None
    return (None if path is None else [node[1] for node in path[:-1]]), n_edges


def _search_scipy(C, a_src, a_dst, a_mot, hmin):
    """A* with the slice-wise heuristic h(k) as Dijkstra (scipy) on the reduced costs
    w'(u, v) = w(u, v) + h(v) - h(u) = C[k+1, b] - min_j C[k+1, j] + motion >= 0:
    (configuration per slice or None, edges)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import dijkstra

    S, N = C.shape
    first = a_src == 0
    src_l = [a_src[first]]
    dst_l = [N + a_dst[first]]
    w_l = [C[1, a_dst[first]] - hmin[1] + a_mot[first]]
    for k in range(1, S - 1):
        src_l.append(k * N + a_src)
        dst_l.append((k + 1) * N + a_dst)
        w_l.append(C[k + 1, a_dst] - hmin[k + 1] + a_mot)
    goal = S * N
    src_l.append((S - 1) * N + np.arange(N))
    dst_l.append(np.full(N, goal))
    w_l.append(np.zeros(N))
    w = np.concatenate(w_l) + 1e-12                    # explicit zeros would not be edges
    Gs = coo_matrix((w, (np.concatenate(src_l), np.concatenate(dst_l))), shape=(goal + 1, goal + 1)).tocsr()
    dist, pred = dijkstra(Gs, directed=True, indices=0, return_predecessors=True)
    if not np.isfinite(dist[goal]):
        return None, len(w)
    node, rev = pred[goal], []
    while node >= 0:
        rev.append(int(node) % N)
        node = pred[node]
    return rev[::-1], len(w)


def plan_global(model: TaskModel, *, q0, objects: dict, fk: Callable, jacobian: Callable,
                obstacles: Sequence[Obstacle] = (), use_joints: bool = True, n_samples: int = 300,
                n_neighbors: int = 12, clearance: float = 0.02, edge_checks: int = 2,
                check_resolution: float = 0.02,
                margin: float = 0.15, motion_weight: float = 0.0, rng=None, seed: int | None = 0,
                q_lower=None, q_upper=None, body_points: Callable | None = None,
                fk_batch: Callable | None = None, carry_radius: float = 0.05,
                return_info: bool = False, search: str = "scipy"):
    """Global reproduction (Eq. 8.27-8.28): the configuration sequence ``q^{1:S}`` minimising the
    summed per-slice Mahalanobis cost, found by A* on a time-expanded roadmap.

    Roadmap: (1) "mean" configurations: inverse kinematics (damped least squares from the
    previous one) of every slice's precision-weighted hand target ``x_i - mu_i``; (2)
    ``n_samples`` random hand positions, uniform in the bounding box of those targets and the
    obstacles grown by ``margin``, solved by IK from the nearest mean configuration;
    configurations whose hand (and ``body_points``) lies within ``clearance`` of an obstacle
    are dropped. Roadmap edges join each configuration to its ``n_neighbors`` nearest in joint
    space and consecutive mean configurations; an edge is kept when the points interpolated
    along it (in joint space) are collision free. The time-expanded graph has a node (k, j)
    per slice k and configuration j and edges (k, j) -> (k+1, j') along roadmap edges (and
    j' = j: wait), of cost ``C[k+1, j'] + motion_weight * |q_j' - q_j|^2`` with ``C`` the slice
    cost (Eq. 8.28, see the module docstring). A* uses the admissible (and consistent)
    heuristic ``h(k) = sum_{k' > k} min_j C[k', j]``.

    Search: ``"scipy"`` (default) runs ``scipy.sparse.csgraph.dijkstra`` on the reduced costs
    ``w + h(v) - h(u)``, which is exactly A* with ``h`` and builds the graph with numpy;
    ``"networkx"`` runs ``networkx.astar_path`` on the same graph (the same optimum, far
    slower: on the pick-and-place benchmark building the networkx graph alone takes seconds).

    Objects held in the hand (the model's gripper closed, < 0.5, and ``|mu_i| < carry_radius``
    at that slice) have their constraint skipped: they move with the hand.

    Args:
        model: the learned task.
        q0: ``(n,)`` start configuration (slice 0 is fixed to it), rad.
        objects: name -> ``(D,)`` object positions at the start, m.
        fk: ``q -> (D,)`` hand position, m. jacobian: ``q -> (D, n)``, m/rad.
        obstacles: :class:`Obstacle` boxes (hard constraints).
        use_joints: include the joint constraint in the cost.
        n_samples: random roadmap samples. n_neighbors: roadmap degree.
        clearance: minimum signed distance of hand/body points to obstacles, m.
        edge_checks, check_resolution: interpolated points checked per roadmap edge: at least
            ``edge_checks``, and one per ``check_resolution`` (m) of the largest straight-line
            displacement of the hand or a body point between the edge's ends, at most 16.
            Edges whose two ends are both farther than that displacement (plus
            ``clearance``) from every obstacle are not checked (exact for a point hand; for an
            arm, interpolating in joint space may bow the points' paths a little more).
        margin: growth of the sampling box, m.
        motion_weight: weight of the squared joint step (1/rad^2), 0 = pure Eq. 8.27.
        rng / seed: randomness (a ``numpy.random.Generator`` or a seed).
        q_lower, q_upper: joint limits, rad (IK results are clipped).
        body_points: optional ``q -> (m, D)`` extra points on the robot checked for collision.
        fk_batch: optional vectorised ``(N, n) -> (N, D)`` forward kinematics (speed only).
        carry_radius: see above, m.
        return_info: also return a dict (cost, roadmap size, edges, seconds).
        search: ``"scipy"`` or ``"networkx"`` (see above).
    Returns:
        ``(S, n)`` configurations (row 0 = q0), or ``(path, info)`` with ``return_info``.
    Raises:
        ImitationDataError: bad inputs; RuntimeError when no collision-free sequence exists on
            the roadmap (more samples may help).
    """
    t_start = time.perf_counter()
    if search not in ("scipy", "networkx"):
        raise ImitationDataError(f"search must be 'scipy' or 'networkx', got {search!r}")
    rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(seed if rng is None else rng)
    q0 = np.asarray(q0, dtype=float)
    if q0.ndim != 1 or not np.all(np.isfinite(q0)):
        raise ImitationDataError(f"q0 must be a finite (n,) configuration, got {q0!r}")
    n = q0.shape[0]
    S = model.S
    h0 = np.asarray(fk(q0), dtype=float)
    D = h0.shape[0]
    lower = None if q_lower is None else np.asarray(q_lower, float)
    upper = None if q_upper is None else np.asarray(q_upper, float)
    objs = {k: np.asarray(v, float) for k, v in objects.items()}
    ik = dict(fk=fk, jacobian=jacobian, lower=lower, upper=upper)

    def fk_rows(Q):
        return _fk_rows(Q, fk, fk_batch)

    carried = _carried_objects(model, carry_radius)
    targets, mean_q = _mean_configurations(model, objs, carried, q0=q0, h0=h0, **ik)
    rand_q = _sampled_configurations(targets, mean_q, h0=h0, obstacles=obstacles, margin=margin,
                                     n_samples=n_samples, rng=rng, **ik)
    Q = np.concatenate([q0[None], mean_q, rand_q])
    H = fk_rows(Q)
    orig, Pn, sd_node = _free_nodes(Q, H, obstacles=obstacles, clearance=clearance,
                                    body_points=body_points)
    Q, H = Q[orig], H[orig]
    N = len(Q)
    pairs = _roadmap_edges(Q, orig, n_neighbors=n_neighbors, S=S)
    n_checked = 0
    if len(pairs) and obstacles:
        def collides(Qi, Hi):
            return _collides(Qi, Hi, obstacles=obstacles, clearance=clearance,
                             body_points=body_points, D=D)

        pairs, n_checked = _collision_free_edges(
            pairs, Q, Pn, sd_node, collides=collides, clearance=clearance,
            edge_checks=edge_checks, check_resolution=check_resolution, fk_rows=fk_rows)
    C = _slice_costs(model, H, Q, objs, use_joints=use_joints and "joints" in model.constraints
                     and model.mean["joints"].shape[1] == n, carried_mask=carried)
    # directed roadmap arcs, waiting (j -> j) always allowed
    a_src = np.concatenate([np.arange(N), pairs[:, 0], pairs[:, 1]])
    a_dst = np.concatenate([np.arange(N), pairs[:, 1], pairs[:, 0]])
    a_mot = motion_weight * np.sum((Q[a_dst] - Q[a_src]) ** 2, axis=1) if motion_weight else np.zeros(len(a_src))
    hmin = C.min(axis=1)
    rest = np.concatenate([np.cumsum(hmin[::-1])[::-1][1:], [0.0]])  # h(k) = sum_{k'>k} min_j C[k', j]
    if search == "networkx":
        seq, n_edges = _search_networkx(C, a_src, a_dst, a_mot, rest)
    else:
        seq, n_edges = _search_scipy(C, a_src, a_dst, a_mot, hmin)
    if seq is None:
        raise RuntimeError("plan_global: no collision-free sequence on the roadmap "
                           "(increase n_samples or margin, or reduce clearance)")
    out = Q[seq]
    if not return_info:
        return out
    cost = float(sum(C[k, j] for k, j in enumerate(seq) if k > 0)
                 + sum(motion_weight * np.sum((Q[b] - Q[a]) ** 2) for a, b in zip(seq[:-1], seq[1:])))
    return out, {"cost": cost, "roadmap_nodes": N, "roadmap_edges": int(len(pairs)),
                 "graph_edges": int(n_edges), "edge_check_points": int(n_checked),
                 "seconds": time.perf_counter() - t_start, "hand": H[seq]}
