"""Structure search for the body schema (thesis Sec. 3.2.2, Algorithm 1).

Layer by layer in the complexity ``k = |Q|``, local models are trained and judged *valid* on
observations they were not trained on (by default leave-one-out: each sample of a pair is
predicted by the GP conditioned on all the pair's other samples; alternatively a fixed held-out
split, every ``test_every``-th sample): a model is valid when its median translational and rotational errors on the
held-out samples are within ``n_sigma`` times the observation noise (``sigma_pos``,
``sigma_orient``). Its quality is ``q(M) = log p(D|M) - k log(eta |D|)`` (Eq. 3.11) with the
data log-likelihood of Eq. 3.10 evaluated on the held-out predictions and scaled to ``|D|``. The search
stops at the first layer whose valid models (of this and lower layers) contain a spanning tree
over all *observed* parts and returns the minimum spanning tree on ``-q``.

"Train only what is needed":
  * at layer k only pairs that lie in *different* components of the valid-model graph of the
    layers below are considered (a higher-k model inside a component never enters the MST:
    a valid lower-k model always has the higher quality, Sec. 3.2.2);
  * each candidate is first screened with a GP of fixed, data-scaled hyper-parameters (one
    batched Cholesky per pair for all subsets Q); only candidates that pass a loose version of
    the validity test get their hyper-parameters optimised and are tested for real.

The MST orders edges by (k, -q): that is the thesis' property that any valid model of lower
complexity has the higher quality, made explicit so that it holds for every eta.
"""


from dataclasses import dataclass, field
from itertools import combinations

import numpy as np
from networkx.utils import UnionFind

from mmlearn.models.common.config import param, validate_fields
from mmlearn.models.common.gp import blas_single_thread
from mmlearn.models.common.se3 import project_to_so3
from mmlearn.models.body_schema.local import (
                                              LocalModel,
                                              log_likelihood,
                                              orthonormalize,
                                              pose_errors,
                                              poses_from_xyzquat,
                                              relative_poses,
                                              se3_inv,
                                              visible_mask,
                                              )

__all__ = ["SearchConfig", "StructureResult", "learn_structure", "spanning_tree",
           "check_data"]


@dataclass
class SearchConfig:
    """Parameters of the structure search and of the validity test.

    Attributes:
        sigma_pos: standard deviation of the translational error of a relative observation
            z_ij (m). Valid: median held-out error <= n_sigma * sigma_pos.
        sigma_orient: same for the rotational error (rad).
        n_sigma: width of the validity test (3 in the thesis).
        eta: factor of the complexity penalty ``k log(eta |D|)`` (> 0).
        test_every: every test_every-th sample of a pair is held out for the validity test.
        min_train, min_test: fewest training / held-out samples a pair needs to be judged.
        max_k: highest layer to evaluate (None: all action signals).
        max_opt: hyper-parameters are optimised on at most this many samples.
        max_screen: the screening GP uses at most this many training samples.
        screen_factor: screening passes at screen_factor times the validity thresholds.
        screen_reg: noise-to-signal ratio of the screening GP.
        screen_top_factor: when no candidate of a pair passes the screening, its best-ranked
            one is still trained and tested if within screen_top_factor times the thresholds.
        screen_ell: length scales of the screening GP, in standard deviations of each action
            signal. 1.5 rather than 1: with 10-12 samples the k = 2 model bridging an
            occluded part (Drake 7-DOF arm, x3-x5 on q2, q3; 10 seeds, sigma 0.01 m)
            screened at a median 2.0 (1.2-5.4) times the thresholds with 1 std -- above
            screen_factor, so only the rescue below could train it, and not above 3 --
            and at a median 1.3 (0.8-4.0) with 1.5 std, still ranked first of its pair; its
            optimised model is valid in most of those cases.
        min_observations: a part seen fewer times than this is not a node (occluded).
        noise_min: lower bound on the GP noise variance (all 12 outputs).
        noise_min_pos, noise_min_rot: further lower bounds for the translation outputs (m^2)
            and the rotation-matrix entries of a local model (set from the known sensor noise
            by the body-schema diagram; 0: only ``noise_min``).
        validation: "loo" (default): every sample of a pair is held out once: the model is
            judged on its leave-one-out predictions (closed form for a GP; each prediction
            comes from the GP conditioned on all *other* samples, with the hyper-parameters
            fitted on the pair's data); "split": a fixed held-out split (every
            test_every-th sample), the model is trained on the rest and refitted on all.
            LOO uses every sample for both and decides the structure with fewer samples.
        refit_ell_starts: the final fit of each tree model (on all of its pair's samples)
            adds per-output optimiser starts at these multiples of the data-scale length
            scales (GaussianProcess.fit ``ell_starts``) if it has k >= 2 action signals;
            () = none.
        refit_max_opt: that final fit optimises the hyper-parameters on at most this many
            samples (the search's fits on at most ``max_opt``).
            Both measured on the Drake 7-DOF arm, x4 occluded, sigma 0.01 m, 50 samples:
            the k = 2 GP x3-x5 on (q2, q3) ended in a local optimum of the marginal
            likelihood that explains q3's effect on a translation output as noise (its
            length scale at the upper bound, the noise above the observations') in most
            seeds: the 12 outputs are optimised jointly, and one output's line searches
            carry another into that basin; and hyper-parameters fitted on a subset of the
            samples often prefer it. Per-output starts at 0.5 x the length scales plus
            hyper-parameters on all samples lowered that GP's test error and the schema's
            prediction error at 50 samples.
        warm_start: reuse the hyper-parameters of an earlier search (``learn_structure``
            ``warm_start``: the cache in ``StructureResult.hyperparameters``, which an online
            learner passes from one search to the next). Per candidate (i, j, Q) the earlier
            search trained: (1) a candidate valid there, whose hyper-parameters were
            optimised on at least 1 / refit_growth as many samples, is first judged with
            them (conditioning only; optimised as usual if it then fails); (2) otherwise
            its optimisation starts from them instead of the data-scale initialisation;
            (3) a k <= 1 candidate that fails the validity test gets the cold retry
            (data-scale and low-noise starts) only if it was valid before or its samples
            grew by refit_growth since its last cold retry (on the Drake 7-DOF arm, sigma
            0.01 m, 50 samples, no retry of a candidate invalid in the previous search
            turned it valid; k >= 2 candidates, e.g. the bridge x3-x5 on (q2, q3), are
            always retried: skipping theirs raised the prediction error); (4) the final fit of a k <= 1 tree model whose hyper-parameters were
            optimised by an earlier final fit on at least 1 / refit_growth as many samples
            conditions on the pair's samples with them (k >= 2: always re-optimised).
            Changes the search's cost (``benchmarks/bench_learner_cost.py``); the optima it
            finds can differ from a cold search (results in ``systems/body_schema/learner.py``).
            No effect without a cache (a batch ``learn_structure`` call).
        refit_growth: growth factor (>= 1) of a pair's samples after which ``warm_start``
            re-optimises / retries cold again (see above); rules (1), (3) and (4) apply
            only while the pair's samples are at least as many as those the cached values
            came from (the relearning on the samples after a change of the robot, Sec. 3.3,
            starts from fewer samples and is optimised and retried as without a cache).
        kernel: covariance of the local models' GPs: "se" (the thesis' squared-exponential
            kernel) or "se+revolute" (default; plus sb2 prod_d (1 + cos(q_d - q'_d)) over
            the model's action signals, in radians: Bayesian linear regression on the
            products of (1, cos q_d, sin q_d), which is exactly what the entries of a
            relative transform across revolute joints are; see :mod:`mmlearn.models.common.gp`).
            A deviation from the thesis, measured on the Drake 7-DOF arm, x4 occluded
            (``learn_body_schema --arm 7dof --occlude x4 --samples 50``): the SE GP of the
            k = 2 bridge x3-x5 reverts to its mean away from its ~40 samples in (q2, q3);
            with the revolute term the mean prediction error at 50 samples is below the
            observation noise (numbers in ``systems/body_schema/learner.py``). Prismatic action
            signals: the term only adds a periodic component the marginal likelihood can
            switch off (sb2 -> its lower bound).
    """

    sigma_pos: float = param(0.05, unit="m", gt=0)
    sigma_orient: float = param(float(np.deg2rad(15.0)), unit="rad", gt=0)
    n_sigma: float = param(3.0, gt=0)
    eta: float = param(1.0, gt=0)
    test_every: int = param(3, integer=True, ge=2)
    min_train: int = param(3, integer=True, ge=1)
    min_test: int = param(2, integer=True, ge=1)
    max_k: int | None = param(None, optional=True, integer=True, ge=0)
    max_opt: int = param(30, integer=True, ge=1)
    max_screen: int = param(60, integer=True, ge=1)
    screen_factor: float = param(1.5, ge=0)
    screen_reg: float = param(1e-2, ge=0)
    screen_top_factor: float = param(3.0, ge=0)
    screen_ell: float = param(1.5, gt=0)
    min_observations: int = param(3, integer=True, ge=1)
    noise_min: float = param(1e-8, ge=0)
    noise_min_pos: float = param(0.0, unit="m^2", ge=0)
    noise_min_rot: float = param(0.0, ge=0)
    validation: str = param("loo", choices=("loo", "split"))
    refit_ell_starts: tuple = param((0.5,), elements=True, gt=0)
    refit_max_opt: int = param(100, integer=True, ge=1)
    warm_start: bool = param(True)
    refit_growth: float = param(1.25, ge=1)
    kernel: str = param("se+revolute", choices=LocalModel.KERNELS)

    def __post_init__(self):
        validate_fields(self)

    @property
    def output_noise_min(self) -> np.ndarray:
        """Per-output noise-variance floor (12,) of a local model's GP (outputs: the rows of
        [R | t], translations at 3, 7, 11)."""
        nm = np.full(12, max(self.noise_min, self.noise_min_rot))
        nm[3::4] = max(self.noise_min, self.noise_min_pos)
        return nm

    @property
    def thresholds(self):
        return self.n_sigma * self.sigma_pos, self.n_sigma * self.sigma_orient


@dataclass
class StructureResult:
    """Outcome of :func:`learn_structure`.

    Attributes:
        tree: local models of the minimum spanning tree (refitted on all samples of their pair).
        complete: True when the tree spans all observed parts.
        nodes: the observed parts (tree nodes).
        valid: every valid model found, with its statistics.
        layers: the complexity layers evaluated.
        n_screened, n_trained: candidates screened / trained with hyper-parameter optimisation.
        stats: per tree model: dict(pos_err, rot_err, loglik, q, n_test).
        hyperparameters: the hyper-parameter cache after this search: {(i, j, Q):
            {"search": hp, "valid": bool, "n_opt": int, "n_cold": int, "refit_hp": hp,
            "refit_n": int}} (hp: GaussianProcess.hyperparameters() dicts) for every
            candidate trained here and those of the ``warm_start`` cache it did not train;
            pass it as the next search's ``warm_start``.
    """

    tree: list
    complete: bool
    nodes: list
    valid: list = field(default_factory=list)
    layers: list = field(default_factory=list)
    n_screened: int = 0
    n_trained: int = 0
    stats: list = field(default_factory=list)
    hyperparameters: dict = field(default_factory=dict)

    def edges(self) -> set:
        """{(i, j, Q)} of the tree (i < j)."""
        return {(m.i, m.j, m.Q) for m in self.tree}


def check_data(actions, poses):
    """Validate and convert (t, m) actions and (t, p, 4, 4) poses (NaN = unobserved); poses
    may also be (t, p, 7) ``x y z qx qy qz qw`` rows."""
    actions = np.asarray(actions, float)
    poses = np.asarray(poses, float)
    if poses.ndim == 3 and poses.shape[2] == 7:
        poses = poses_from_xyzquat(poses)
    if actions.ndim != 2:
        raise ValueError(f"actions must be (t, n_actions), got shape {actions.shape}")
    if poses.ndim != 4 or poses.shape[2:] != (4, 4):
        raise ValueError(f"poses must be (t, n_parts, 4, 4), got shape {poses.shape}")
    if len(actions) != len(poses):
        raise ValueError(f"{len(actions)} action rows but {len(poses)} pose rows")
    if not np.all(np.isfinite(actions)):
        raise ValueError("actions contain NaN or inf (actions must always be known)")
    return actions, poses


def kruskal(nodes, pairs) -> list:
    """Kruskal's greedy forest: the indices of the (i, j) ``pairs``, taken in the given
    order, that join two components of ``nodes`` (pairs touching other nodes are skipped).
    networkx's union-find."""
    uf = UnionFind(nodes)
    members = set(nodes)
    out = []
    for e, (i, j) in enumerate(pairs):
        if i in members and j in members and uf[i] != uf[j]:
            uf.union(i, j)
            out.append(e)
    return out


def spanning_tree(nodes, models, quality):
    """Kruskal's minimum spanning tree over ``nodes`` with edge order (k, -quality).

    Returns (tree models, complete?)."""
    order = sorted(range(len(models)), key=lambda e: (models[e].k, -quality[e]))
    tree = [order[e] for e in kruskal(nodes, [(models[e].i, models[e].j) for e in order])]
    return tree, len(tree) == len(nodes) - 1


def _components(nodes, models):
    uf = UnionFind(nodes)
    for m in models:
        uf.union(m.i, m.j)
    return {x: uf[x] for x in nodes}


def _split(n: int, test_every: int):
    idx = np.arange(n)
    test = idx % test_every == test_every - 1
    return idx[~test], idx[test]


def _screen(Xall_tr, Y_tr, Xall_te, Z_te, Qs, ell, reg):
    """Median held-out errors (nQ, 2) of a fixed-hyper-parameter GP for every subset in Qs.

    Xall_*: full action rows; Y_tr: (n, 12) targets; ell: (m,) length scales."""
    n = len(Y_tr)
    ym = Y_tr.mean(axis=0)
    Yc = Y_tr - ym
    nQ = len(Qs)
    k = len(Qs[0])
    if k == 0:
        pred = np.broadcast_to(ym, (len(Z_te), 12))[None]
    else:
        Qa = np.array(Qs)  # (nQ, k)
        Xtr = Xall_tr[:, Qa] / ell[Qa]  # (n, nQ, k)
        Xte = Xall_te[:, Qa] / ell[Qa]
        Xtr = np.swapaxes(Xtr, 0, 1)  # (nQ, n, k)
        Xte = np.swapaxes(Xte, 0, 1)
        d2 = ((Xtr[:, :, None, :] - Xtr[:, None, :, :]) ** 2).sum(-1)
        K = np.exp(-0.5 * d2) + reg * np.eye(n)
        d2s = ((Xte[:, :, None, :] - Xtr[:, None, :, :]) ** 2).sum(-1)
        Ks = np.exp(-0.5 * d2s)
        alpha = np.linalg.solve(K, np.broadcast_to(Yc, (nQ,) + Yc.shape))
        pred = Ks @ alpha + ym  # (nQ, nt, 12)
    nt = len(Z_te)
    Zp = np.zeros((nQ, nt, 4, 4))
    Zp[..., :3, :4] = pred.reshape(nQ, nt, 3, 4)
    Zp[..., 3, 3] = 1.0
    Zp = orthonormalize(Zp)
    dp, dr = pose_errors(Zp, Z_te[None])
    return np.stack([np.median(dp, axis=1), np.median(dr, axis=1)], axis=1)


def _screen_loo_pairs(actions, items, Qs, ell, reg):
    """Median leave-one-out errors (nQ, 2) of a fixed-hyper-parameter GP for every subset in
    Qs, for each of several pairs at once (one layer of the search).

    actions: (t, m) all action rows; items: per pair (rows (n,) into ``actions``, Y (n, 12)
    targets, Z (n, 4, 4) observed relative poses); ell: (m,) length scales (units of the
    actions); reg: noise-to-signal ratio. Pairs observed on the same rows share one kernel
    matrix inverse per Q (it depends on the actions only), and the rotation blocks of all
    predictions are projected onto SO(3) in one call. Returns a list of (nQ, 2) arrays
    (translational m, rotational rad)."""
    nQ = len(Qs)
    k = len(Qs[0])
    groups = {}
    for e, (rows, _, _) in enumerate(items):
        groups.setdefault((len(rows), rows.tobytes()), []).append(e)
    preds = []  # per group: (P, nQ, n, 3, 4) LOO predictions
    for idx in groups.values():
        rows = items[idx[0]][0]
        n = len(rows)
        Ys = np.stack([items[e][1] for e in idx])  # (P, n, 12)
        if k == 0:
            # constant model: the LOO mean is the mean of the other samples
            pred = ((Ys.sum(axis=1, keepdims=True) - Ys) / (n - 1))[:, None]  # (P, 1, n, 12)
        else:
            Qa = np.array(Qs)
            Xs = np.swapaxes(actions[rows][:, Qa] / ell[Qa], 0, 1)  # (nQ, n, k)
            d2 = ((Xs[:, :, None, :] - Xs[:, None, :, :]) ** 2).sum(-1)
            Kinv = np.linalg.inv(np.exp(-0.5 * d2) + reg * np.eye(n))  # (nQ, n, n)
            alpha = Kinv[None] @ (Ys - Ys.mean(axis=1, keepdims=True))[:, None]
            pred = Ys[:, None] - alpha / np.diagonal(Kinv, axis1=1, axis2=2)[None, :, :, None]
        preds.append(pred.reshape(len(idx), nQ, n, 3, 4))
    # all rotation blocks at once (one vectorised SO(3) projection)
    R = project_to_so3(np.concatenate([p[..., :3].reshape(-1, 3, 3) for p in preds]))
    out, at = [None] * len(items), 0
    for p, idx in zip(preds, groups.values()):
        P, n = len(idx), p.shape[2]
        Rp = R[at:at + p[..., 0, 0].size].reshape(P, nQ, n, 3, 3)
        at += p[..., 0, 0].size
        Z = np.stack([items[e][2] for e in idx])  # (P, n, 4, 4)
        err = np.empty((2, P, nQ, n))
        err[0] = np.linalg.norm(p[..., 3] - Z[:, None, :, :3, 3], axis=-1)
        c = (np.einsum("pqnab,pnab->pqn", Rp, Z[:, :, :3, :3]) - 1.0) / 2.0
        err[1] = np.arccos(np.clip(c, -1.0, 1.0))
        med = np.moveaxis(np.median(err, axis=-1), 0, -1)  # (P, nQ, 2)
        for e, m in zip(idx, med):
            out[e] = m
    return out


def _stats(model, dp, dr, config, n_total):
    ll = log_likelihood(dp, dr, config.sigma_pos, config.sigma_orient)
    thr_p, thr_r = config.thresholds
    mp, mr = float(np.median(dp)), float(np.median(dr))
    valid = mp <= thr_p and mr <= thr_r
    loglik = float(ll.mean()) * n_total
    q = loglik - model.k * np.log(config.eta * n_total)
    return valid, dict(pos_err=mp, rot_err=mr, loglik=loglik, q=q, n_test=len(dp))


def _judge(model, config, rows, te, actions, Z, n_total):
    if config.validation == "loo":
        dp, dr = pose_errors(model.loo_predict(), Z)
        return _stats(model, dp, dr, config, n_total)
    return _evaluate(model, rows[te], actions, Z[te], config, n_total)


def _evaluate(model, rows_te, actions, Z_te, config, n_total):
    dp, dr = model.errors(actions[rows_te], Z_te)
    return _stats(model, dp, dr, config, n_total)


def _grew_less(n: int, n_before: int, config: SearchConfig) -> bool:
    """The pair's data grew from n_before to n samples by less than config.refit_growth (a
    continuation of the data the cached values came from; a smaller data set, e.g. the
    samples after a change of the robot, is not)."""
    return n_before <= n < config.refit_growth * n_before


def _blas_single_thread():
    return blas_single_thread()


def learn_structure(actions, poses, **kwargs) -> "StructureResult":
    """Algorithm 1 (see :func:`_learn_structure` for the arguments); BLAS single-threaded."""
    with _blas_single_thread():
        return _learn_structure(actions, poses, **kwargs)


def _learn_structure(actions, poses, *, config: SearchConfig | None = None,
                    mask: np.ndarray | None = None, seed_models=(),
                    refit: bool = True, warm_start: dict | None = None) -> StructureResult:
    """Algorithm 1: learn the kinematic structure and the local models from data.

    Args:
        actions: (t, m) commanded action vectors.
        poses: (t, p, 4, 4) observed part poses, NaN where a part was not seen.
        config: :class:`SearchConfig`.
        mask: optional (t, p) bool visibility (default: finite poses).
        seed_models: known (e.g. engineered) local models; they count as valid models of
            their layer with the held-out statistics computed on this data.
        refit: refit the tree models on all samples of their pair (with "split": train +
            held-out), re-optimising the hyper-parameters with one extra low-noise start.
        warm_start: hyper-parameter cache of an earlier search (its
            ``StructureResult.hyperparameters``; see ``SearchConfig.warm_start``); not
            changed.
    Returns:
        :class:`StructureResult`.

    Deterministic: no randomness is involved (leave-one-out, or every test_every-th sample
    held out).
    """
    config = config or SearchConfig()
    actions, poses = check_data(actions, poses)
    t, m = actions.shape
    p = poses.shape[1]
    if mask is None:
        mask = visible_mask(poses)
    mask = np.asarray(mask, bool)
    if mask.shape != (t, p):
        raise ValueError(f"mask must be ({t}, {p}), got {mask.shape}")
    if t < config.min_train + config.min_test:
        raise ValueError(f"too few samples for the structure search: {t} < min_train + "
                         f"min_test = {config.min_train + config.min_test}")
    nodes = [i for i in range(p) if mask[:, i].sum() >= config.min_observations]
    if len(nodes) < 2:
        raise ValueError(f"need at least 2 observed parts (seen >= {config.min_observations} "
                         f"times), got {len(nodes)} from {t} samples")
    max_k = m if config.max_k is None else min(config.max_k, m)
    ell = actions.std(axis=0)
    ell = config.screen_ell * np.where(ell > 1e-9, ell, 1.0)

    # per-pair data
    pair = {}
    for i, j in combinations(nodes, 2):
        rows, Z = relative_poses(poses, i, j, mask)
        if config.validation == "loo":
            tr = te = np.arange(len(rows))
            enough = len(rows) >= config.min_train + config.min_test
        else:
            tr, te = _split(len(rows), config.test_every)
            enough = len(tr) >= config.min_train and len(te) >= config.min_test
        if enough:
            pair[(i, j)] = (rows, Z, tr, te)

    valid_models, valid_stats = [], []
    for sm in seed_models:
        key = (min(sm.i, sm.j), max(sm.i, sm.j))
        if key in pair and sm.i in nodes and sm.j in nodes:
            rows, Z, tr, te = pair[key]
            Zs = Z if (sm.i, sm.j) == key else se3_inv(Z)
            ok, st = _evaluate(sm, rows[te], actions, Zs[te], config, t)
            if ok:
                valid_models.append(sm)
                valid_stats.append(st)

    result = StructureResult(tree=[], complete=False, nodes=nodes)
    old_cache = dict(warm_start or {})
    cache = result.hyperparameters
    thr_p, thr_r = config.thresholds
    for k in range(0, max_k + 1):
        result.layers.append(k)
        comp = _components(nodes, valid_models)
        Qs = list(combinations(range(m), k))
        todo = []
        for (i, j), (rows, Z, tr, te) in pair.items():
            if comp[i] == comp[j]:
                continue
            tr_s = tr
            if len(tr_s) > config.max_screen:
                tr_s = tr[np.unique(np.linspace(0, len(tr) - 1, config.max_screen).round()
                                    .astype(int))]
            todo.append(((i, j), tr_s))
        if config.validation == "loo":
            # the whole layer's screening at once (see _screen_loo_pairs)
            meds = _screen_loo_pairs(
                actions, [(pair[ij][0][tr_s], pair[ij][1][tr_s, :3, :4].reshape(-1, 12),
                           pair[ij][1][tr_s]) for ij, tr_s in todo], Qs, ell,
                config.screen_reg) if todo else []
        else:
            meds = [_screen(actions[pair[ij][0][tr_s]],
                            pair[ij][1][tr_s, :3, :4].reshape(-1, 12),
                            actions[pair[ij][0][pair[ij][3]]], pair[ij][1][pair[ij][3]], Qs,
                            ell, config.screen_reg) for ij, tr_s in todo]
        for ((i, j), _), med in zip(todo, meds):
            rows, Z, tr, te = pair[(i, j)]
            result.n_screened += len(Qs)
            score = np.maximum(med[:, 0] / thr_p, med[:, 1] / thr_r)
            passing = np.flatnonzero(score <= config.screen_factor)
            best = int(np.argmin(score))
            if passing.size == 0 and score[best] <= config.screen_top_factor:
                # the screening GP (fixed hyper-parameters) misjudges small samples: the
                # pair's best-ranked candidate gets a real test anyway
                passing = np.array([best])
            for qi in passing:
                model = LocalModel(i, j, Qs[qi], m, kernel=config.kernel)
                prev = old_cache.get(model.key, {}) if config.warm_start else {}
                hp0 = prev.get("search")
                n_opt = min(len(tr), config.max_opt)
                ok = False
                if prev.get("valid") and _grew_less(n_opt, prev["n_opt"], config):
                    # valid before, with hyper-parameters optimised on nearly as many
                    # samples: judged with them first (conditioning only)
                    model.fit(actions[rows[tr]], Z[tr], optimize=False, hyperparameters=hp0,
                              noise_min=config.output_noise_min)
                    ok, st = _judge(model, config, rows, te, actions, Z, t)
                    if ok:
                        n_opt = prev["n_opt"]
                if not ok:
                    model.fit(actions[rows[tr]], Z[tr], max_opt=config.max_opt,
                              noise_min=config.output_noise_min, n_restarts=0,
                              hyperparameters=hp0)
                    result.n_trained += 1
                    ok, st = _judge(model, config, rows, te, actions, Z, t)
                n_cold = prev.get("n_cold", 0)
                if not ok and not (model.k < 2 and prev.get("valid") is False
                                   and _grew_less(len(tr), n_cold, config)):
                    # it passed the screening: a bad local optimum of the hyper-parameters
                    # is the likely cause; retry once with an extra low-noise start. The
                    # retry's first start is the data-scale one; when the fit above began
                    # there too (no cached values), it starts from that fit's optimum
                    # instead (the same L-BFGS-B run: only the low-noise start is new)
                    model.fit(actions[rows[tr]], Z[tr], max_opt=config.max_opt,
                              noise_min=config.output_noise_min, n_restarts=1,
                              hyperparameters=None if hp0 is not None
                              else model.gp.hyperparameters())
                    result.n_trained += 1
                    ok, st = _judge(model, config, rows, te, actions, Z, t)
                    n_cold = len(tr)
                cache[model.key] = {"search": model.gp.hyperparameters(), "valid": ok,
                                    "n_opt": n_opt, "n_cold": n_cold}
                if ok:
                    valid_models.append(model)
                    valid_stats.append(st)
        idx, complete = spanning_tree(nodes, valid_models, [s["q"] for s in valid_stats])
        if complete or k == max_k:
            break

    result.complete = complete
    result.valid = list(zip(valid_models, valid_stats))
    for e in idx:
        model = valid_models[e]
        if refit and isinstance(model, LocalModel):
            # final fit on all samples of the pair; hyper-parameters re-optimised (on up to
            # refit_max_opt samples) from the search optimum plus one low-noise start
            # (escapes the "signal is noise" local optimum on clean data) and, for k >= 2,
            # per-output starts at shorter length scales (escape the "one input is noise"
            # optimum on noisy data), best kept per output
            rows, Z, _, _ = pair[(model.i, model.j)]
            prev = old_cache.get(model.key, {}) if config.warm_start else {}
            if (model.k < 2 and "refit_hp" in prev
                    and _grew_less(len(rows), prev["refit_n"], config)):
                # optimised on nearly as many samples before: condition on the pair's samples
                # with those hyper-parameters (the cheap update of an online learner)
                model.fit(actions[rows], Z, optimize=False, hyperparameters=prev["refit_hp"],
                          noise_min=config.output_noise_min)
                refit_n = prev["refit_n"]
            else:
                model.fit(actions[rows], Z, hyperparameters=model.gp.hyperparameters(),
                          noise_min=config.output_noise_min, n_restarts=1,
                          max_opt=config.refit_max_opt if model.k >= 2 else config.max_opt,
                          ell_starts=tuple(config.refit_ell_starts) if model.k >= 2 else ())
                refit_n = len(rows)
            c = cache.setdefault(model.key, {})
            c["refit_hp"], c["refit_n"] = model.gp.hyperparameters(), refit_n
        result.tree.append(model)
        result.stats.append(valid_stats[e])
    for key, v in old_cache.items():
        if key not in cache:
            cache[key] = v
        elif "refit_hp" in v and "refit_hp" not in cache[key]:
            cache[key]["refit_hp"], cache[key]["refit_n"] = v["refit_hp"], v["refit_n"]
    return result
