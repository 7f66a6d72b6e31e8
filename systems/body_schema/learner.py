"""SchemaLearner: learns a body schema (thesis ch. 3) online from commanded joint positions
and marker observations, and adapts it life-long (Sec. 3.3).

The learning itself is :class:`mmlearn.models.body_schema.schema.BodySchema`; this system decides
*when* a sample is taken (once per babbling target, after the command has stayed constant
for ``settle_time``, so that the arm is at rest and the commanded action signals are the
joint values) and feeds it to :meth:`BodySchema.update` (structure search until a first
valid spanning tree exists, then test-then-train monitoring and model replacement).
:func:`learn_sample` is that per-sample step without Drake (replays recorded data).

When the structure search runs online (the thesis gives Algorithm 1 as a batch method and
says nothing about when to run it):

* before a first complete tree, on the whole buffer at *every* sample from 6 samples on
  (``AdaptationConfig.relearn_every = 1``; with every 5th sample a tree first found with 11
  samples was only used at 15);
* while the tree rests on 10-20 samples (``refit_every_until``), again at every sample on
  all the samples it is consistent with, including those the search found it from: a
  structure found on few samples is often wrong (a rigid finger or link whose joint barely
  moved yet) and the next samples correct it; then at ``refit_at`` (20, 30, 40, 50, ...).
  A refinement replaces the tree models instead of keeping them in the history, from where a
  rigid model that passed on a few samples would be recalled whenever its sliding window
  happened to pass.

With these rules the 7-DOF arm with x4 occluded (``learn_body_schema --arm 7dof --occlude
x4``, 10 seeds) has the right structure within 12 samples in 9 of 10 runs at sigma 0.01 m
and at 0.044 m. The misses: a gripper finger whose q7 has barely moved yet is judged rigid,
and a bridge model still invalid on 12 samples.

Model fitting (deviations in the optimiser and the kernel; the model is the thesis'):

* The search's final fit of each k >= 2 tree model adds per-output optimiser starts at
  0.5 x the length scales and fits the hyper-parameters on all the pair's samples
  (``SearchConfig.refit_ell_starts``, ``refit_max_opt``): from a single start the GP that
  bridges the occluded part (x3-x5 on (q2, q3)) ended in a local optimum that explains q3's
  effect as noise (a fitted noise well above the markers' own).
* The local GPs' kernel has the term ``sb2 prod_d (1 + cos(q_d - q'_d))`` besides the
  squared exponential (``SearchConfig.kernel``): it spans the relative transforms of
  revolute chains, so the bridge GP no longer reverts to its mean away from its samples
  (its prediction error is the lower for it).
* Consecutive searches reuse each candidate's hyper-parameters (``warm_start``,
  ``refit_growth``; kept in the schema, i.e. in this system's state).

Cost: the structure search's arithmetic (none of its decisions) is vectorised: the k = 0 GPs
get their marginal-likelihood optimum in closed form, the screening of a layer runs once for
all pairs, SO(3) projections use the Newton polar iteration. The learner's share of the 7-DOF
simulation's CPU time is measured by ``benchmarks/bench_learner_cost.py`` (``learner_share``;
docs/body_schema.md gives it from the speed results).
"""

from __future__ import annotations

import copy
import time
from dataclasses import dataclass, replace

import numpy as np

from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.systems.framework import BasicVector, EventStatus, LeafSystem, ValueProducer

from mmlearn.models.body_schema.schema import AdaptationConfig, BodySchema, SearchConfig
from mmlearn.models.common.config import param, validate_fields
from mmlearn.models.common.se3 import project_to_so3

from mmlearn.systems.common.observations import MarkerObservations

__all__ = ["SchemaLearner", "SchemaLearnerConfig", "SchemaLearnerState", "learn_sample"]


@dataclass
class SchemaLearnerConfig:
    """Configuration of a :class:`SchemaLearner` (load with ``yaml_load_typed``).

    Attributes:
        rate_hz: rate of the periodic update, Hz (> 0).
        settle_time: the command must have been constant this long (s) before the
            observation that is used was taken.
        settle_tol: largest change of any command entry (rad or m) still counted as constant.
        one_per_target: take a single sample per constant command (else one per frame).
        min_visible: fewest visible markers for a frame to be used (>= 2).
        refit_at: numbers of samples since the tree was last invalid at which the structure
            search is re-run on those samples (refines the local models as data
            accumulates; between refits the models are fixed and only monitored); while
            the tree is invalid, also at these numbers of consecutive invalid samples, on
            those samples (a structure search on data after the change, alongside the
            model replacement of Sec. 3.3).
        refit_every_until: while a valid tree is consistent with at most this many samples
            (and at least min(refit_at), or it was found by a structure search on them), the
            structure search is re-run on them at *every* sample (a search on 10-20
            samples is cheap, and the structure found on the first few samples is often
            still wrong, e.g. a joint barely moved so far).
        search: noise levels and options of the structure search (SearchConfig).
        adapt: life-long adaptation parameters (AdaptationConfig).
    """

    rate_hz: float = param(10.0, unit="Hz", gt=0)
    settle_time: float = param(0.5, unit="s", ge=0)
    settle_tol: float = param(1e-4, unit="rad or m", ge=0)
    one_per_target: bool = param(True)
    min_visible: int = param(2, integer=True, ge=2)
    refit_at: list[int] = param([10, 15, 20, 30, 40, 50, 70, 100, 150, 200, 300], integer=True,
                                ge=1, elements=True, factory=True)
    refit_every_until: int = param(20, integer=True, ge=0)
    search: SearchConfig = param(default_factory=SearchConfig, nested=SearchConfig)
    adapt: AdaptationConfig = param(default_factory=AdaptationConfig, nested=AdaptationConfig)

    def validate(self) -> None:
        validate_fields(self)


#: entries kept in the learner's logs (``history``, ``update_seconds``, ``refit_seconds``,
#: ``command_log`` keeps 64) and in its schema's ``events``
LOG_SIZE = 1000


@dataclass(frozen=True)
class SchemaLearnerState:
    """The learner's abstract state: immutable, replaced by every update that changes it.

    Drake copies abstract state values (``copy.deepcopy``) whenever it clones a context
    and twice around every unrestricted update. This value is immutable, so a copy is the
    value itself: the (large) schema is shared, never copied, between the state before
    and after an update, and between clones of a context. The contract that makes this
    safe: nobody mutates ``schema`` or the arrays in here (they are read-only). The learner
    learns each new sample on a private copy of the schema and stores that copy in a new
    state; to change a schema yourself, ``copy.deepcopy(state.schema)`` first.

    Attributes:
        schema: the current BodySchema (treat as read-only).
        n_samples: observations fed to the schema.
        n_dropped: frames that were unusable (wrong markers, non-finite poses, too few
            visible markers, a failed update).
        last_command, stable_since: settling detector (command, s).
        sampled_since: ``stable_since`` of the last constant command that was sampled.
        last_frame_time: time of the last frame used (s).
        command_log: the last 64 (time, command, stable_since), one per update.
        X_WR: estimate of the root part's world pose (4, 4) (mean of its observations).
        n_root: observations averaged into X_WR.
        history: per sample (n, valid, tree keys ((a, b, actions), ...)), the last
            ``LOG_SIZE``.
        update_seconds: wall time of the schema updates, per sample, the last ``LOG_SIZE``.
        clean_since: sample count from which on the current tree is consistent with the
            data: the last invalid sample, or the start of the samples the tree was
            learned from by a structure search.
        clean_searched: the samples since ``clean_since`` are those a structure search
            learned the current tree from.
        refit_seconds: wall time of each structure re-search, the last ``LOG_SIZE``.
        last_event: last adaptation event text.
    """

    schema: BodySchema
    n_samples: int = 0
    n_dropped: int = 0
    last_command: np.ndarray | None = None
    stable_since: float = 0.0
    sampled_since: float | None = None
    last_frame_time: float | None = None
    clean_since: int = 0
    clean_searched: bool = False
    refit_seconds: tuple = ()
    command_log: tuple = ()
    X_WR: np.ndarray | None = None
    n_root: int = 0
    history: tuple = ()
    update_seconds: tuple = ()
    last_event: str | None = None

    def __copy__(self):
        return self

    def __deepcopy__(self, memo):
        return self  # immutable (see the class docstring)


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.array(a, float)
    a.setflags(write=False)
    return a


def learn_sample(cfg: SchemaLearnerConfig, s: SchemaLearnerState, u, Y):
    """Feed one sample (commanded actions ``u`` (m,), part poses ``Y`` (p, 4, 4), NaN =
    unseen) to the learner: :meth:`BodySchema.update`, the re-searches of ``cfg.refit_at`` /
    ``cfg.refit_every_until``, the root-pose estimate and the logs. What the system does per
    sample once it has decided to take one; usable without a Drake context (e.g. to replay
    recorded data). ``s`` is not changed (its schema may be shared with Drake's copies of
    the state): the update works on a private copy of the schema, once per sample.

    Returns (the new state, accepted); accepted is False when the schema rejected the sample
    (counted as dropped)."""
    schema = copy.deepcopy(s.schema)
    t0 = time.perf_counter()
    try:
        st = schema.update(u, Y)
    except (ValueError, np.linalg.LinAlgError, FloatingPointError) as e:
        # the copy the failed update worked on is kept
        return replace(s, schema=schema, n_dropped=s.n_dropped + 1,
                       last_event=f"dropped sample: {e}"), False
    update_seconds = (s.update_seconds + (time.perf_counter() - t0,))[-LOG_SIZE:]
    n_samples = s.n_samples + 1
    clean_since, clean_searched = s.clean_since, s.clean_searched
    last_event, refit_seconds = s.last_event, s.refit_seconds
    searched = st.get("event") == "structure search"
    if not schema.valid:
        clean_since, clean_searched = n_samples, False
    elif searched:
        # a first tree found by the search on the whole buffer: all buffered samples are
        # consistent with it (refits use them all, not only those after it)
        clean_since, clean_searched = n_samples - len(schema.buffer()[0]), True
    n_clean = n_samples - clean_since
    # refine a valid tree on the samples since it became valid; re-search a tree that stays
    # invalid on the samples since it became invalid (all after any change)
    n_relearn = n_clean if schema.valid else schema.steps_invalid
    refit = n_relearn in cfg.refit_at or (
        schema.valid and not searched and n_relearn <= cfg.refit_every_until
        and (clean_searched or n_relearn >= min(cfg.refit_at, default=0)))
    if schema.nodes and refit and n_relearn <= schema.adapt.buffer:
        was_valid = schema.valid
        t1 = time.perf_counter()
        try:
            res = schema.relearn(last=n_relearn)
            last_event = f"relearned on {n_relearn} samples (complete={res.complete})"
        except (ValueError, np.linalg.LinAlgError) as e:
            last_event = f"relearn failed: {e}"
        refit_seconds = (refit_seconds + (time.perf_counter() - t1,))[-LOG_SIZE:]
        if not schema.valid:
            clean_since, clean_searched = n_samples, False
        elif not was_valid:  # the tree is learned from those samples
            clean_since, clean_searched = n_samples - n_relearn, True
    if st.get("event"):
        last_event = st["event"]
    if len(schema.events) > LOG_SIZE:  # our private copy: cap its event log
        del schema.events[:-LOG_SIZE]
    X_WR, n_root = s.X_WR, s.n_root
    r = schema.root
    if np.all(np.isfinite(Y[r])):
        X_WR, n_root = _frozen(_mean_pose(X_WR, n_root, Y[r])), n_root + 1
    keys = tuple(sorted((m.i, m.j, tuple(m.Q)) for m in schema.tree))
    history = (s.history + ((n_samples, bool(schema.valid), keys),))[-LOG_SIZE:]
    return replace(s, schema=schema, n_samples=n_samples, clean_since=clean_since,
                   clean_searched=clean_searched, refit_seconds=refit_seconds, X_WR=X_WR,
                   n_root=n_root, history=history, update_seconds=update_seconds,
                   last_event=last_event), True


def _mean_pose(X_old: np.ndarray | None, n: int, X_new: np.ndarray) -> np.ndarray:
    """Running mean of poses: arithmetic mean of positions, rotation mean projected on SO(3)."""
    if X_old is None or n == 0:
        return X_new.copy()
    M = (X_old * n + X_new) / (n + 1)
    out = np.eye(4)
    out[:3, :3], out[:3, 3] = project_to_so3(M[:3, :3]), M[:3, 3]
    return out


class SchemaLearner(LeafSystem):
    """Learns the body schema of a robot from its commanded actions and marker frames.

    .. pydrake_system::

        name: SchemaLearner
        input_ports:
        - command
        - observations
        output_ports:
        - schema
        - X_WE
        - X_WR
        - predicted_poses
        - model_validity
        - status

    Inputs: ``command`` the commanded joint positions (action signals, the learner is never
    told the real joint values); ``observations`` :class:`MarkerObservations` frames whose
    ``marker_ids`` are ``parts``.

    Outputs: ``schema`` (abstract :class:`BodySchema`, the current learned model);
    ``X_WE`` (RigidTransform) the predicted world pose of the end-effector part for the
    current command (identity until the part is in the tree); ``X_WR`` the estimated world
    pose of the root part; ``predicted_poses`` (list of RigidTransform or None per part,
    world frame); ``model_validity`` (list of dicts ``a``, ``b``, ``actions``, ``valid``,
    ``status``, ``in_tree`` for every tracked local model); ``status`` vector
    [samples, dropped frames, tree valid (0/1), steps invalid, tree size,
    last update time (ms)].

    Args:
        parts: marker ids (part names) in the order the schema indexes them.
        n_actions: length of the command.
        config: :class:`SchemaLearnerConfig`.
        end_effector: the part whose pose ``X_WE`` predicts (default: the last part).
    """

    def __init__(self, *, parts, n_actions: int, config: SchemaLearnerConfig | None = None,
                 end_effector: str | None = None):
        super().__init__()
        cfg = config or SchemaLearnerConfig()
        cfg.validate()
        parts = [str(p) for p in parts]
        if len(parts) < 2 or len(set(parts)) != len(parts):
            raise ValueError(f"SchemaLearner: need >= 2 distinct parts, got {parts}")
        if int(n_actions) < 1:
            raise ValueError(f"SchemaLearner: n_actions must be >= 1, got {n_actions}")
        ee = parts[-1] if end_effector is None else end_effector
        if ee not in parts:
            raise ValueError(f"SchemaLearner: end_effector {ee!r} is not one of {parts}")
        self._cfg, self._parts, self._m = cfg, parts, int(n_actions)
        self._ee = parts.index(ee)
        init = SchemaLearnerState(schema=self._new_schema())
        self._cmd = self.DeclareVectorInputPort("command", self._m)
        self._obs = self.DeclareAbstractInputPort(
            "observations", AbstractValue.Make(MarkerObservations()))
        self._s = self.DeclareAbstractState(AbstractValue.Make(init))
        self.DeclarePeriodicUnrestrictedUpdateEvent(1.0 / cfg.rate_hz, 0.0, self._update)
        st = {self.abstract_state_ticket(self._s)}
        st_cmd = {self.abstract_state_ticket(self._s), self._cmd.ticket()}
        self._schema_out = self.DeclareAbstractOutputPort(
            "schema", lambda: AbstractValue.Make(self._new_schema()),
            lambda c, o: o.set_value(self._get(c).schema), st)
        # the world poses of all parts for the current command, shared by two outputs
        self._world_cache = self.DeclareCacheEntry(
            "world_poses", ValueProducer(allocate=lambda: AbstractValue.Make(None),
                                         calc=self._calc_world_poses), st_cmd)
        self._ee_out = self.DeclareAbstractOutputPort(
            "X_WE", lambda: AbstractValue.Make(RigidTransform()), self._calc_ee,
            {self._world_cache.ticket()})
        self._root_out = self.DeclareAbstractOutputPort(
            "X_WR", lambda: AbstractValue.Make(RigidTransform()), self._calc_root, st)
        self._pred_out = self.DeclareAbstractOutputPort(
            "predicted_poses", lambda: AbstractValue.Make([None] * len(parts)),
            self._calc_pred, {self._world_cache.ticket()})
        self._valid_out = self.DeclareAbstractOutputPort(
            "model_validity", lambda: AbstractValue.Make([]), self._calc_validity, st)
        self._status_out = self.DeclareVectorOutputPort(
            "status", BasicVector(6), self._calc_status, st)

    def _new_schema(self) -> BodySchema:
        return BodySchema(len(self._parts), self._m, search=self._cfg.search,
                          adapt=self._cfg.adapt)

    # -- ports ---------------------------------------------------------------------------
    def get_command_input_port(self):
        return self._cmd

    def get_observations_input_port(self):
        return self._obs

    def get_schema_output_port(self):
        return self._schema_out

    def get_X_WE_output_port(self):
        return self._ee_out

    def get_X_WR_output_port(self):
        return self._root_out

    def get_predicted_poses_output_port(self):
        return self._pred_out

    def get_model_validity_output_port(self):
        return self._valid_out

    def get_status_output_port(self):
        return self._status_out

    @property
    def parts(self) -> list[str]:
        return list(self._parts)

    @property
    def end_effector(self) -> int:
        return self._ee

    def state(self, context) -> SchemaLearnerState:
        """The learner state in ``context`` (this system's or the root context)."""
        try:
            context = self.GetMyContextFromRoot(context)
        except (RuntimeError, ValueError):
            pass
        return self._get(context)

    def _get(self, context) -> SchemaLearnerState:
        return context.get_abstract_state(self._s).get_value()

    # -- update --------------------------------------------------------------------------
    def _frame(self, obs) -> np.ndarray | None:
        """(p, 4, 4) poses in the schema's part order (NaN = unseen), or None if unusable."""
        if not isinstance(obs, MarkerObservations) or len(obs) == 0:
            return None
        try:
            Y = obs.as_matrices()
            idx = [obs.marker_ids.index(p) for p in self._parts]
        except (ValueError, AttributeError, TypeError, IndexError):
            return None
        Y = Y[idx]
        seen = np.all(np.isfinite(Y.reshape(len(idx), -1)), axis=1)
        vis = np.asarray(obs.visible, bool)[idx]
        if np.any(vis & ~seen):
            return None  # a visible marker with a non-finite pose: corrupt frame
        if seen.sum() < self._cfg.min_visible:
            return None
        return Y

    def _update(self, context, state):
        new = self._next_state(context, self._get(context))
        state.get_mutable_abstract_state(self._s).set_value(new)
        return EventStatus.Succeeded()

    def _next_state(self, context, s: SchemaLearnerState) -> SchemaLearnerState:
        """The state after one periodic update (``s`` itself is not changed)."""
        cfg = self._cfg
        t = context.get_time()
        u = np.asarray(self._cmd.Eval(context), float)
        if not np.all(np.isfinite(u)):
            return replace(s, n_dropped=s.n_dropped + 1)
        last_command, stable_since = s.last_command, s.stable_since
        if last_command is None or np.max(np.abs(u - last_command)) > cfg.settle_tol:
            last_command, stable_since = _frozen(u), t
        # the command log pairs a frame with the command at the frame's time
        s = replace(s, last_command=last_command, stable_since=stable_since,
                    command_log=(s.command_log + ((t, _frozen(u), stable_since),))[-64:])
        if not self._obs.HasValue(context):
            return s
        obs = self._obs.Eval(context)
        t_obs = getattr(obs, "time", None)
        entry = next((e for e in reversed(s.command_log)
                      if t_obs is not None and abs(e[0] - t_obs) < 1e-6), None)
        if entry is None:
            return s  # no command known for that frame's time
        _, u, since = entry
        if t_obs < since + cfg.settle_time - 1e-9:
            return s  # the arm has not settled yet
        if cfg.one_per_target and s.sampled_since == since:
            return s  # this target was sampled already
        if s.last_frame_time == t_obs:
            return s  # frame used already
        s = replace(s, last_frame_time=t_obs)
        Y = self._frame(obs)
        if Y is None:
            return replace(s, n_dropped=s.n_dropped + 1)
        s, accepted = learn_sample(cfg, s, u, Y)
        return replace(s, sampled_since=since) if accepted else s

    # -- outputs -------------------------------------------------------------------------
    def _calc_world_poses(self, context, value):
        value.set_value(self._world_poses(context))

    def _world_poses(self, context):
        s = self._get(context)
        if s.X_WR is None or not s.schema.tree:
            return None
        q = np.asarray(self._cmd.Eval(context), float)
        if not np.all(np.isfinite(q)):
            return None
        try:
            T = s.schema.forward_kinematics(q)
        except (ValueError, np.linalg.LinAlgError):
            return None
        return s.X_WR @ T

    def _calc_ee(self, context, output):
        W = self._world_cache.Eval(context)
        X = RigidTransform()
        if W is not None and np.all(np.isfinite(W[self._ee])):
            X = RigidTransform(_rotation(W[self._ee, :3, :3]), W[self._ee, :3, 3])
        output.set_value(X)

    def _calc_root(self, context, output):
        s = self._get(context)
        X = RigidTransform() if s.X_WR is None else RigidTransform(
            _rotation(s.X_WR[:3, :3]), s.X_WR[:3, 3])
        output.set_value(X)

    def _calc_pred(self, context, output):
        W = self._world_cache.Eval(context)
        out = [None] * len(self._parts)
        if W is not None:
            for i in range(len(self._parts)):
                if np.all(np.isfinite(W[i])):
                    out[i] = RigidTransform(_rotation(W[i, :3, :3]), W[i, :3, 3])
        output.set_value(out)

    def _calc_validity(self, context, output):
        s = self._get(context)
        sch = s.schema
        in_tree = {id(m) for m in sch.tree}
        rows = []
        for tr in sch.tracks:
            m = tr.model
            rows.append(dict(a=self._parts[m.i], b=self._parts[m.j], actions=list(m.Q),
                             valid=bool(sch._track_valid(tr)), status=tr.status,
                             in_tree=id(m) in in_tree))
        output.set_value(rows)

    def _calc_status(self, context, output):
        s = self._get(context)
        ms = 1000 * s.update_seconds[-1] if s.update_seconds else 0.0
        output.SetFromVector([s.n_samples, s.n_dropped, float(s.schema.valid),
                              s.schema.steps_invalid, len(s.schema.tree), ms])


def _rotation(R: np.ndarray) -> RotationMatrix:
    return RotationMatrix(project_to_so3(R))
