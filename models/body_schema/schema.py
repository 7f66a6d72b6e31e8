"""Body schema: a tree of local models, prediction, control and life-long adaptation
(thesis ch. 3: Sec. 3.2.3 Eq. 3.17/3.19, Sec. 3.3).

Typical use::

    from mmlearn.models.body_schema.schema import BodySchema, SearchConfig
    schema = BodySchema(n_parts=5, n_actions=2, search=SearchConfig(sigma_pos=0.044))
    schema.fit(actions, poses)                # Algorithm 1 on a batch (t, m), (t, p, 4, 4)
    T = schema.forward_kinematics(q)          # (p, 4, 4) part poses in the root-part frame
    J = schema.jacobian(q, part=4)            # (6, m) learned Jacobian
    q_goal, info = schema.reach(q, part=4, target=p_goal)   # damped least squares
    status = schema.update(q_t, poses_t)      # one new observation: monitor and adapt

Module layout: :mod:`.body_schema_local` (local GP models, SE(3) helpers),
:mod:`.body_schema_search` (Algorithm 1), this module (the schema: prediction, control,
adaptation), :mod:`.body_schema_experiments` (thesis Sec. 3.4 experiments) and
:mod:`.kinematic_sim` (simulated arms).

Poses are homogeneous (4, 4) matrices in metres; actions in the units of the action signals
(rad / m); invisible parts are NaN matrices (or pass ``mask``).

Adaptation (Sec. 3.3): every tracked local model (the current tree, the history of previously
useful models and the models being trained) is tested on each new observation *before* it is
ever trained on it; its last ``window`` errors form its sliding test window and it is valid
while the median errors stay within the thresholds of :class:`SearchConfig`. Each step the
schema takes the minimum spanning tree over the valid tracked models (order (k, -q)), so a
history model that fits again is recalled at once. When no valid spanning tree exists for
``patience`` consecutive steps, a replacement local model is sampled for a pair bridging the
broken tree, ordered by structural proximity (shared Bayesian-network nodes) to the models that
failed, and trained on the recent samples and then on the following ``n_train_new`` samples.
"""


import contextlib
from collections import deque
from dataclasses import dataclass
from itertools import combinations

import numpy as np
from networkx.utils import UnionFind

from mmlearn.models.common.config import param, validate_fields
from mmlearn.models.common.se3 import matrix_to_rotvec
from mmlearn.models.body_schema.local import (
                                              EngineeredModel,
                                              LocalModel,
                                              log_likelihood,
                                              poses_from_xyzquat,
                                              se3_inv,
                                              visible_mask,
                                              )
from mmlearn.models.body_schema.search import (
                                               SearchConfig,
                                               StructureResult,
                                               _blas_single_thread,
                                               kruskal,
                                               check_data,
                                               learn_structure,
                                               )

__all__ = ["BodySchema", "AdaptationConfig", "SearchConfig", "StructureResult", "LocalModel",
           "EngineeredModel", "learn_structure", "rotation_vector"]


@dataclass
class AdaptationConfig:
    """Parameters of life-long adaptation (Sec. 3.3).

    Attributes:
        window: held-out errors kept per tracked model (the sliding test window).
        min_window: fewest held-out errors before the window decides validity.
        patience: steps without a valid spanning tree before a new model is sampled (15).
        n_train_new: samples a new model is trained on (30).
        n_init_test: of the recent samples a new model starts with, this many are held out.
        reoptimize_at: training-set sizes at which a new model re-optimises its
            hyper-parameters (otherwise it re-conditions with fixed ones: cheap).
        max_history: most models kept in the history (oldest dropped).
        max_training: most models trained at the same time.
        buffer: recent observations kept.
        relearn_every: before a first complete tree exists, run the structure search on the
            buffer every this many steps (from 6 samples on; 1: at every step, so that a
            structure found by e.g. 7 samples is used at once).
    """

    window: int = param(10, integer=True, ge=1)
    min_window: int = param(3, integer=True, ge=1)
    patience: int = param(15, integer=True, ge=0)
    n_train_new: int = param(30, integer=True, ge=3)
    n_init_test: int = param(3, integer=True, ge=0)
    reoptimize_at: list[int] = param([8, 15, 30], integer=True, elements=True, factory=True)
    max_history: int = param(50, integer=True, ge=1)
    max_training: int = param(1, integer=True, ge=0)
    buffer: int = param(300, integer=True, ge=1)
    relearn_every: int = param(1, integer=True, ge=1)

    def __post_init__(self):
        self.validate()

    def validate(self) -> None:
        validate_fields(self)
        if self.window < self.min_window:
            raise ValueError(f"AdaptationConfig: need min_window <= window, got min_window "
                             f"{self.min_window} and window {self.window}")


def rotation_vector(R: np.ndarray) -> np.ndarray:
    """Rotation vector (..., 3) of rotation matrices (..., 3, 3) (radians)."""
    return matrix_to_rotvec(R)


def _trained(model) -> bool:
    return not isinstance(model, LocalModel) or model.gp is not None


class _Track:
    """A tracked local model with its sliding test window."""

    def __init__(self, model, status: str, born: int, prior_valid: bool = True,
                 window: int = 10):
        self.model = model
        self.status = status  # "active", "history", "training"
        self.born = born
        self.prior_valid = prior_valid
        self.errors = deque(maxlen=window)
        self.train_rows: list = []  # buffer step indices (training models)
        self.used = 0  # steps spent in a valid tree


class BodySchema:
    """Learned kinematic model of a robot: a spanning tree of local models.

    Args:
        n_parts: number of body parts (markers) p.
        n_actions: number of action signals m.
        search: :class:`SearchConfig` (noise levels, validity test, search options).
        adapt: :class:`AdaptationConfig`.
        root: reference part (default: the lowest-indexed tree node).
    """

    def __init__(self, n_parts: int, n_actions: int, *, search: SearchConfig | None = None,
                 adapt: AdaptationConfig | None = None, root: int | None = None):
        if n_parts < 2 or n_actions < 0:
            raise ValueError(f"need n_parts >= 2 and n_actions >= 0, got {n_parts}, {n_actions}")
        self.n_parts, self.n_actions = int(n_parts), int(n_actions)
        self.search = search or SearchConfig()
        self.adapt = adapt or AdaptationConfig()
        self._root = root
        self.nodes: list = []
        self.tree: list = []
        self.valid = False
        self.steps_invalid = 0
        self.step = 0
        self.tracks: list = []
        self._last_valid_tree: list = []
        self._tried: set = set()
        self._buf_actions = deque(maxlen=self.adapt.buffer)
        self._buf_poses = deque(maxlen=self.adapt.buffer)
        self._buf_step = deque(maxlen=self.adapt.buffer)
        self.events: list = []  # (step, text)
        self.last_search: StructureResult | None = None
        # hyper-parameters of the last structure search's candidates (warm starts of the
        # next search, SearchConfig.warm_start); part of the schema, so it lives wherever
        # the schema does (e.g. in a SchemaLearner's state in the Drake context)
        self.hp_cache: dict = {}

    # ------------------------------------------------------------------ construction
    @property
    def root(self) -> int:
        if self._root is not None:
            return self._root
        return min(self.nodes) if self.nodes else 0

    def fit(self, actions, poses, *, mask=None, seed_models=()) -> StructureResult:
        """Learn the structure and the local models from a batch (Algorithm 1).

        The batch also fills the observation buffer; the tree models become the tracked
        models of life-long adaptation.
        """
        actions = self._check_actions(actions)
        actions, poses = check_data(actions, poses)
        res = learn_structure(actions, poses, config=self.search, mask=mask,
                              seed_models=seed_models, warm_start=self.hp_cache)
        self.hp_cache = res.hyperparameters
        self.last_search = res
        self._set_tree_from_search(res)
        if mask is not None:
            poses = poses.copy()
            poses[~np.asarray(mask, bool)] = np.nan
        for a, y in zip(actions, poses):
            self._push(a, y)
        return res

    def buffer(self):
        """The buffered observations: actions (n, m) and poses (n, p, 4, 4) (NaN = unseen),
        oldest first (at most ``adapt.buffer`` of them)."""
        m = self.n_actions
        A = np.array(self._buf_actions).reshape(-1, m)
        P = np.array(self._buf_poses).reshape(-1, self.n_parts, 4, 4)
        return A, P

    def relearn(self, last: int | None = None) -> StructureResult:
        """Re-run the structure search (Algorithm 1) on the buffered observations (the
        ``last`` ones, default all) and, when it finds a complete tree, make it the current
        tree. Used to refine a schema as data accumulates; the buffer is not changed.

        When the current tree is valid (a refinement on data it is consistent with), the
        search on more data supersedes its models: they are dropped, not kept in the
        history (a model the larger search no longer finds valid, e.g. a rigid link judged
        on a few samples, would otherwise be recalled from the history whenever its sliding
        window happens to pass). Models of an invalid tree go to the history (Sec. 3.3)."""
        A = np.array(self._buf_actions)
        P = np.array(self._buf_poses)
        if last is not None:
            A, P = A[-int(last):], P[-int(last):]
        with _blas_single_thread():
            res = learn_structure(A, P, config=self.search, warm_start=self.hp_cache)
        self.hp_cache = res.hyperparameters
        if res.complete:
            self.last_search = res
            refine = self.valid
            for t in list(self.tracks):
                if t.status == "active":
                    if refine:
                        self.tracks.remove(t)
                    else:
                        t.status = "history"
            self._set_tree_from_search(res)
            self.steps_invalid = 0
        return res

    def _set_tree_from_search(self, res: StructureResult):
        self.nodes = list(res.nodes)
        self.tracks = [t for t in self.tracks if t.status == "history"]
        for m in res.tree:
            self.tracks.append(_Track(m, "active", self.step, True, self.adapt.window))
        self.tree = list(res.tree)
        self.valid = res.complete
        if res.complete:
            self._last_valid_tree = list(res.tree)
        self.events.append((self.step, f"structure search: {len(res.tree)} models, "
                                       f"complete={res.complete}"))

    @classmethod
    def from_models(cls, models, n_parts: int, n_actions: int, **kwargs) -> "BodySchema":
        """A schema seeded with known (e.g. engineered) local models forming a tree."""
        s = cls(n_parts, n_actions, **kwargs)
        s.nodes = sorted({m.i for m in models} | {m.j for m in models})
        for m in models:
            if m.n_actions != n_actions:
                raise ValueError(f"{m!r} has n_actions={m.n_actions}, expected {n_actions}")
        joined = kruskal(s.nodes, [(m.i, m.j) for m in models])
        if len(joined) < len(models):
            cyc = next(e for e in range(len(models)) if e not in joined)
            raise ValueError(f"seed models contain a cycle at {models[cyc]!r}")
        s.tree = list(models)
        s.tracks = [_Track(m, "active", 0, True, s.adapt.window) for m in models]
        s.valid = len(models) == len(s.nodes) - 1
        s._last_valid_tree = list(models)
        return s

    def _check_actions(self, actions) -> np.ndarray:
        a = np.asarray(actions, float)
        if a.ndim == 1:
            a = a[None]
        if a.ndim != 2 or a.shape[1] != self.n_actions:
            raise ValueError(f"actions must be (n, {self.n_actions}), got {np.shape(actions)}")
        if not np.all(np.isfinite(a)):
            raise ValueError("actions contain NaN or inf")
        return a

    # ------------------------------------------------------------------ prediction
    def _paths(self, tree=None):
        """BFS over the tree from the root: list of (parent, child, model, forward?)."""
        tree = self.tree if tree is None else tree
        adj = {}
        for m in tree:
            adj.setdefault(m.i, []).append((m.j, m, True))
            adj.setdefault(m.j, []).append((m.i, m, False))
        order, seen, q = [], {self.root}, deque([self.root])
        while q:
            u = q.popleft()
            for v, m, fwd in adj.get(u, []):
                if v not in seen:
                    seen.add(v)
                    order.append((u, v, m, fwd))
                    q.append(v)
        return order

    def forward_kinematics(self, actions, *, with_jacobian: bool = False):
        """Poses of all parts in the root-part frame by concatenating local-model predictions
        along the tree (Eq. 3.17). Parts not in the tree are NaN.

        Args:
            actions: (m,) or (n, m) commanded actions.
            with_jacobian: also return d pose / d q, (n, p, 4, 4, m) (chain rule through the
                products of the local models' derivatives).
        Returns:
            (p, 4, 4) or (n, p, 4, 4) [and the Jacobian].
        """
        single = np.asarray(actions).ndim == 1
        a = self._check_actions(actions)
        n, m = a.shape
        T = np.full((n, self.n_parts, 4, 4), np.nan)
        T[:, self.root] = np.eye(4)
        dT = None
        if with_jacobian:
            dT = np.full((n, self.n_parts, 4, 4, m), np.nan)
            dT[:, self.root] = 0.0
        with _blas_single_thread() if n > 50 else contextlib.nullcontext():
            for u, v, model, fwd in self._paths():
                Z = model.predict(a)
                if with_jacobian:
                    dZ = model.predict_jacobian(a)
                if not fwd:
                    Zi = se3_inv(Z)
                    if with_jacobian:
                        dZ = -np.einsum("nab,nbcq,ncd->nadq", Zi, dZ, Zi, optimize=True)
                    Z = Zi
                T[:, v] = T[:, u] @ Z
                if with_jacobian:
                    dT[:, v] = (np.einsum("nabq,nbc->nacq", dT[:, u], Z, optimize=True)
                                + np.einsum("nab,nbcq->nacq", T[:, u], dZ, optimize=True))
        if single:
            T = T[0]
            dT = None if dT is None else dT[0]
        return (T, dT) if with_jacobian else T

    def predict_relative(self, actions, i: int, j: int) -> np.ndarray:
        """Predicted x_i^-1 x_j (n, 4, 4) through the tree."""
        T = self.forward_kinematics(self._check_actions(actions))
        return se3_inv(T[:, i]) @ T[:, j]

    def jacobian(self, q, part: int) -> np.ndarray:
        """(6, m) Jacobian of the learned kinematic function at actions q (Eq. 3.19): rows 0-2
        the derivative of the position of ``part`` (m per action unit), rows 3-5 its angular
        velocity (rad per action unit), both in the root-part frame."""
        q = np.asarray(q, float)
        if q.ndim != 1:
            raise ValueError(f"q must be (n_actions,), got {q.shape}")
        T, dT = self.forward_kinematics(q, with_jacobian=True)
        if not np.all(np.isfinite(T[part])):
            raise ValueError(f"part {part} is not in the body-schema tree")
        R = T[part, :3, :3]
        dR = dT[part, :3, :3, :]  # (3, 3, m)
        W = np.einsum("abq,cb->acq", dR, R)  # dR R^T, skew-symmetric
        w = 0.5 * np.stack([W[2, 1] - W[1, 2], W[0, 2] - W[2, 0], W[1, 0] - W[0, 1]])
        return np.concatenate([dT[part, :3, 3, :], w], axis=0)

    # ------------------------------------------------------------------ control
    def _task_error(self, T, target, orient_weight):
        target = np.asarray(target, float)
        if target.shape == (3,):
            return target - T[:3, 3]
        if target.shape != (4, 4):
            raise ValueError(f"target must be a position (3,) or a pose (4, 4), got {target.shape}")
        e_p = target[:3, 3] - T[:3, 3]
        e_r = rotation_vector(target[:3, :3] @ T[:3, :3].T)
        return np.concatenate([e_p, orient_weight * e_r])

    def dls_step(self, q, part: int, target, *, damping: float = 0.05,
                 orient_weight: float = 0.1, max_step: float = 0.3, q_low=None, q_high=None,
                 centering: float = 0.0) -> np.ndarray:
        """One damped-least-squares step ``dq = J^T (J J^T + lambda^2 I)^-1 e`` on the
        *learned* model towards ``target`` (position (3,) m, or pose (4, 4) in the root-part
        frame; orientation error weighted by ``orient_weight`` m/rad). The step is scaled to
        at most ``max_step`` (action units, infinity norm).

        With joint limits ``q_low``/``q_high`` (action units), joints at a limit whose step
        would leave the range are frozen and the step is recomputed without them (clamping);
        ``centering`` > 0 adds a null-space motion towards the middle of the range (useful for
        redundant arms)."""
        q = np.asarray(q, float)
        T = self.forward_kinematics(q)[part]
        e = self._task_error(T, target, orient_weight)
        J = self.jacobian(q, part)
        if e.shape == (3,):
            J = J[:3]
        else:
            J = np.concatenate([J[:3], orient_weight * J[3:]])
        lo = np.full(q.shape, -np.inf) if q_low is None else np.asarray(q_low, float)
        hi = np.full(q.shape, np.inf) if q_high is None else np.asarray(q_high, float)
        free = np.ones(q.shape, bool)
        dq = np.zeros_like(q)
        for _ in range(q.size + 1):
            Jf = J * free
            A = Jf @ Jf.T + damping**2 * np.eye(len(e))
            dq = Jf.T @ np.linalg.solve(A, e)
            if centering > 0 and np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)):
                P = np.diag(free.astype(float)) - Jf.T @ np.linalg.solve(A, Jf)
                dq = dq + centering * P @ (0.5 * (lo + hi) - q)
            push_out = free & (((q <= lo + 1e-9) & (dq < 0)) | ((q >= hi - 1e-9) & (dq > 0)))
            if not np.any(push_out):
                break
            free &= ~push_out
        mx = np.max(np.abs(dq)) if dq.size else 0.0
        if mx > max_step:
            dq *= max_step / mx
        return dq

    def reach(self, q0, part: int, target, *, damping: float = 0.05,
              orient_weight: float = 0.1, max_iter: int = 100, tol: float = 1e-3,
              max_step: float = 0.3, q_low=None, q_high=None, centering: float = 0.0):
        """Iterate :meth:`dls_step` from ``q0`` until the predicted error of ``part`` is below
        ``tol`` (m; for poses the weighted 6-D error norm) or ``max_iter`` steps; the
        actions stay within ``q_low``/``q_high``.

        Returns (q, info) with info = dict(iterations, error, converged)."""
        q = self._check_actions(q0)[0].copy()
        lo = -np.inf if q_low is None else np.asarray(q_low, float)
        hi = np.inf if q_high is None else np.asarray(q_high, float)
        q = np.clip(q, lo, hi)
        err = np.inf
        it = 0
        for it in range(1, max_iter + 1):
            T = self.forward_kinematics(q)[part]
            err = float(np.linalg.norm(self._task_error(T, target, orient_weight)))
            if err < tol:
                it -= 1
                break
            q = np.clip(q + self.dls_step(q, part, target, damping=damping,
                                          orient_weight=orient_weight, max_step=max_step,
                                          q_low=q_low, q_high=q_high, centering=centering),
                        lo, hi)
        else:
            T = self.forward_kinematics(q)[part]
            err = float(np.linalg.norm(self._task_error(T, target, orient_weight)))
        return q, dict(iterations=it, error=err, converged=err < tol)

    # ------------------------------------------------------------------ adaptation
    def _push(self, action, poses):
        self._buf_actions.append(np.asarray(action, float))
        self._buf_poses.append(np.asarray(poses, float))
        self._buf_step.append(self.step)
        self.step += 1

    def _track_valid(self, tr: _Track):
        thr_p, thr_r = self.search.thresholds
        if len(tr.errors) < self.adapt.min_window:
            return tr.prior_valid
        e = np.array(tr.errors)
        return bool(np.median(e[:, 0]) <= thr_p and np.median(e[:, 1]) <= thr_r)

    def _track_quality(self, tr: _Track):
        if not tr.errors:
            return 0.0
        e = np.array(tr.errors)
        ll = log_likelihood(e[:, 0], e[:, 1], self.search.sigma_pos, self.search.sigma_orient)
        n = self.adapt.window
        return float(ll.mean()) * n - tr.model.k * np.log(self.search.eta * n)

    def _best_tree(self, valid_only: bool):
        cands = [t for t in self.tracks if _trained(t.model)
                 and (t.status != "training" or self._track_valid(t))]
        key = []
        for t in cands:
            v = self._track_valid(t)
            if valid_only and not v:
                continue
            key.append(((not v), t.model.k, -self._track_quality(t), -t.born, id(t), t))
        key.sort(key=lambda x: x[:5])
        ts = [x[-1] for x in key]
        tree = [ts[e] for e in kruskal(self.nodes, [(t.model.i, t.model.j) for t in ts])]
        return tree, len(tree) == len(self.nodes) - 1

    def update(self, action, poses, *, mask=None) -> dict:
        """Process one new observation: test every tracked model on it, then adapt.

        Args:
            action: (m,) commanded action vector.
            poses: (p, 4, 4) observed part poses (NaN where unseen), or (p, 7) rows
                ``x y z qx qy qz qw``.
            mask: optional (p,) visibility.
        Returns:
            dict(valid, steps_invalid, tree (list of model reprs), event or None).
        """
        with _blas_single_thread():
            return self._update(action, poses, mask)

    def _update(self, action, poses, mask):
        a = self._check_actions(action)[0]
        y = np.asarray(poses, float)
        if y.shape == (self.n_parts, 7):
            y = poses_from_xyzquat(y)
        if y.shape != (self.n_parts, 4, 4):
            raise ValueError(f"poses must be ({self.n_parts}, 4, 4), got {y.shape}")
        if mask is not None:
            y = y.copy()
            y[~np.asarray(mask, bool)] = np.nan
        seen = visible_mask(y[None])[0]
        event = None
        # 1. test-then-train on the new sample
        for tr in self.tracks:
            m = tr.model
            if seen[m.i] and seen[m.j] and _trained(m):
                z = se3_inv(y[m.i]) @ y[m.j]
                dp, dr = m.errors(a[None], z[None])
                tr.errors.append((float(dp[0]), float(dr[0])))
        cur = self.step
        self._push(a, y)
        for tr in [t for t in self.tracks if t.status == "training"]:
            m = tr.model
            if seen[m.i] and seen[m.j] and len(tr.train_rows) < self.adapt.n_train_new:
                tr.train_rows.append(cur)
                self._train(tr)
        # 2. before a first structure exists: learn it from the buffer
        if not self.nodes or (not self.valid and not self._last_valid_tree):
            if len(self._buf_actions) >= 6 and self.step % self.adapt.relearn_every == 0:
                try:
                    res = learn_structure(np.array(self._buf_actions),
                                          np.array(self._buf_poses), config=self.search,
                                          warm_start=self.hp_cache)
                    self.hp_cache = res.hyperparameters
                    self.last_search = res
                    self._set_tree_from_search(res)
                    event = "structure search"
                except ValueError:
                    pass
            return self._status(event)
        # 3. drop training models that proved invalid
        for tr in [t for t in self.tracks if t.status == "training"]:
            done = len(tr.train_rows) >= self.adapt.n_train_new
            judged = len(tr.errors) >= self.adapt.min_window and len(tr.train_rows) >= 8
            if (done or judged) and not self._track_valid(tr):
                self.tracks.remove(tr)
                event = f"dropped {tr.model!r}"
                self.events.append((cur, event))
            elif done:
                tr.status = "history"
        # 4. minimum spanning tree over the valid tracked models
        tree, complete = self._best_tree(valid_only=True)
        if complete:
            self.valid = True
            self.steps_invalid = 0
            self._tried.clear()
            chosen = {id(t) for t in tree}
            for t in self.tracks:
                if id(t) in chosen:
                    t.used += 1
                    if t.status != "training":
                        t.status = "active"
                elif t.status == "active":
                    t.status = "history"
            self.tree = [t.model for t in tree]
            self._last_valid_tree = list(self.tree)
        else:
            self.valid = False
            self.steps_invalid += 1
            tree, _ = self._best_tree(valid_only=False)  # best available (combined) model
            self.tree = [t.model for t in tree]
            n_training = sum(t.status == "training" for t in self.tracks)
            if self.steps_invalid >= self.adapt.patience and \
                    n_training < self.adapt.max_training:
                ev = self._sample_new_model()
                if ev:
                    event = ev
        self._trim_history()
        return self._status(event)

    def _status(self, event):
        return dict(valid=self.valid, steps_invalid=self.steps_invalid,
                    tree=[repr(m) for m in self.tree], event=event)

    def _trim_history(self):
        hist = [t for t in self.tracks if t.status == "history"]
        if len(hist) > self.adapt.max_history:
            hist.sort(key=lambda t: (t.used, t.born))
            for t in hist[: len(hist) - self.adapt.max_history]:
                self.tracks.remove(t)

    def candidate_models(self):
        """Keys (i, j, Q) for a replacement model, best first: pairs bridging the components
        of the currently valid models, ordered by structural proximity to the failed models
        (then by complexity)."""
        valid = [t for t in self.tracks if self._track_valid(t) and t.status != "training"]
        uf = UnionFind(self.nodes)
        for t in valid:
            uf.union(t.model.i, t.model.j)
        valid_ids = {id(t.model) for t in valid}
        failed = [m for m in self._last_valid_tree if id(m) not in valid_ids] or \
            list(self._last_valid_tree)
        kmax = max([m.k for m in failed] + [0]) + 1
        kmax = min(kmax, self.n_actions)
        tracked = {t.model.key for t in self.tracks if t.status == "training"}
        out = []
        for i, j in combinations(sorted(self.nodes), 2):
            if uf[i] == uf[j]:
                continue
            for k in range(kmax + 1):
                for Q in combinations(range(self.n_actions), k):
                    key = (i, j, Q)
                    if key in self._tried or key in tracked:
                        continue
                    probe = LocalModel(i, j, Q, self.n_actions, kernel=self.search.kernel)
                    prox = max((probe.proximity(f) for f in failed), default=0.0)
                    out.append((-prox, k, key))
        out.sort()
        return [(key, -p) for p, _, key in out]

    def _sample_new_model(self):
        cands = self.candidate_models()
        if not cands:
            return None
        (i, j, Q), prox = cands[0]
        self._tried.add((i, j, Q))
        model = LocalModel(i, j, Q, self.n_actions, kernel=self.search.kernel)
        tr = _Track(model, "training", self.step, prior_valid=False, window=self.adapt.window)
        # recent samples since the tree became invalid, pair visible
        steps = list(self._buf_step)[-max(self.steps_invalid, 1):]
        base = self._buf_step[0]
        rows = [s for s in steps if np.all(np.isfinite(self._buf_poses[s - base][[i, j]]))]
        n_test = min(self.adapt.n_init_test, max(len(rows) - 3, 0))
        init_train, init_test = rows[: len(rows) - n_test], rows[len(rows) - n_test:]
        tr.train_rows = list(init_train)
        if len(tr.train_rows) >= 2:
            self._train(tr, force_opt=True)
            for s in init_test:
                yy = self._buf_poses[s - base]
                z = se3_inv(yy[i]) @ yy[j]
                dp, dr = model.errors(self._buf_actions[s - base][None], z[None])
                tr.errors.append((float(dp[0]), float(dr[0])))
            tr.train_rows += init_test
            self._train(tr)
        else:
            tr.train_rows += init_test
        self.tracks.append(tr)
        ev = f"sampled {model!r} (proximity {prox:.2f}, {len(rows)} recent samples)"
        self.events.append((self.step, ev))
        return ev

    def _train(self, tr: _Track, force_opt: bool = False):
        base = self._buf_step[0]
        rows = [s for s in tr.train_rows if s >= base]
        tr.train_rows = rows
        if len(rows) < 2:
            return
        A = np.array([self._buf_actions[s - base] for s in rows])
        P = np.array([self._buf_poses[s - base] for s in rows])
        m = tr.model
        Z = se3_inv(P[:, m.i]) @ P[:, m.j]
        opt = force_opt or m.gp is None or len(rows) in self.adapt.reoptimize_at
        hp = None if (opt or m.gp is None) else m.gp.hyperparameters()
        m.fit(A, Z, optimize=opt, hyperparameters=hp, max_opt=self.search.max_opt,
              noise_min=self.search.output_noise_min)

    # ------------------------------------------------------------------ I/O
    def to_dict(self) -> dict:
        """JSON-able dict of the learned tree (engineered models are not serialisable)."""
        return {"type": "BodySchema", "version": 1, "n_parts": self.n_parts,
                "n_actions": self.n_actions, "root": self.root, "nodes": list(self.nodes),
                "tree": [m.to_dict() for m in self.tree if isinstance(m, LocalModel)]}

    @classmethod
    def from_dict(cls, d: dict, **kwargs) -> "BodySchema":
        models = [LocalModel.from_dict(x) for x in d["tree"]]
        s = cls.from_models(models, d["n_parts"], d["n_actions"], root=d.get("root"), **kwargs)
        s.nodes = list(d.get("nodes", s.nodes))
        return s
