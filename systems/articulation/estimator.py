"""ArticulationEstimator: learns the kinematic model of an articulated object online.

Wraps models/articulation*.py (thesis Sec. 4.1) in a LeafSystem.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, LeafSystem, ValueProducer

from mmlearn.models.articulation.link import ObservationModel
from mmlearn.models.articulation.structure import (DEFAULT_CANDIDATES, ArticulatedObject,
                                                   LinkEdge, fit_kinematic_tree,
                                                   select_link_model)

from mmlearn.systems.common.observations import MarkerObservations

__all__ = ["ArticulationEstimator", "ArticulationEstimatorState"]


def _checked_models(models) -> tuple:
    """The candidate link model names as a tuple; ValueError naming an unknown one."""
    from mmlearn.models.articulation.link import make_model

    names = (models,) if isinstance(models, str) else models
    try:
        names = tuple(names)
    except TypeError:
        raise ValueError(f"models must be a list of link model names, got {models!r}") from None
    if not names:
        raise ValueError("models: give at least one link model name")
    for n in names:
        if not isinstance(n, str):
            raise ValueError(f"models: expected link model names, got {n!r}")
        make_model(n)  # raises ValueError("unknown link model ...; choose from ...")
    return names


@dataclass(frozen=True)
class ArticulationEstimatorState:
    """Abstract state of the estimator (replaced, never mutated, on every update).

    Immutable (read-only arrays; the model is replaced by a refit, never changed), so
    Drake's copies of it, on every update and context clone, share it.

    Attributes:
        poses: (k, p, 7) buffered observations x y z qx qy qz qw (NaN = part not seen); in
            pose mode with 3 entries, (k, 2, 3).
        times: (k,) observation times, seconds.
        num_dropped: observations rejected as invalid (NaN, wrong size, bad quaternion, wrong
            type).
        num_fit_failures: refits that raised (model kept).
        model: the current ArticulatedObject or None.
        last_fit_count: ``total`` at the last refit.
        total: number of observations stored so far (including those pushed out).
    """

    poses: np.ndarray
    times: np.ndarray = field(default_factory=lambda: np.zeros(0))
    num_dropped: int = 0
    num_fit_failures: int = 0
    model: ArticulatedObject | None = None
    last_fit_count: int = 0
    total: int = 0

    def __post_init__(self):
        for a in (self.poses, self.times):
            a.setflags(write=False)

    def __deepcopy__(self, memo):
        return self


class ArticulationEstimator(LeafSystem):
    """Periodically re-estimates the kinematic model of an articulated object from a stream of
    pose observations of its parts (thesis Sec. 4.1: candidate link models, BIC selection,
    minimum spanning tree).

    Two input modes (keyword ``mode``):

    - ``"markers"``: abstract input ``observations`` carrying
      :class:`~mmlearn.systems.common.observations.MarkerObservations`; ``part_ids`` (>= 2 marker ids)
      name the object parts; invisible parts are missing observations of that part.
    - ``"pose"``: vector input ``pose`` of size ``pose_size`` = 3 (x y z) or 7 (x y z qx qy qz
      qw), e.g. the end-effector pose of a robot holding the handle, in a fixed frame. The
      object then has two parts, ``"fixed"`` (identity) and ``"moving"``.

    Every ``period`` seconds the input is sampled and stored (at most ``max_observations``,
    oldest dropped); every ``refit_every`` stored observations (once ``min_observations`` are
    there) the model is re-fitted. With ``refit_fraction`` > 0 the interval grows with the
    buffer: a refit waits for ``max(refit_every, ceil(refit_fraction * n))`` new observations
    (n stored at the last refit), so a long track, whose refit costs most and whose model a
    few samples change least, is refitted at a rate that falls with its length; the model is
    then also refitted when the track ends (``refit_every`` periods without an observation
    after observations it has not seen), so it holds the whole track (0, the default: every
    ``refit_every``, nothing at the track's end). A bad observation (NaN / inf, wrong size,
    zero quaternion, wrong type) never raises: it is dropped and counted.

    .. pydrake_system::

        name: ArticulationEstimator
        input_ports:
        - observations (markers mode) | pose (pose mode)
        output_ports:
        - object_model
        - selected_models
        - configuration
        - jacobian
        - stats

    Outputs:
        object_model: abstract, the current ArticulatedObject (None before the first fit).
        selected_models: abstract dict "parent->child" -> model name ("rigid", "prismatic",
            "revolute", "gp"...).
        configuration: vector (max_dof,), the configuration estimate of the latest complete
            observation (metres / radians, per tree link in edge order), zero-padded; NaN where
            unknown.
        jacobian: abstract ndarray (6 * num_links, dof): block-diagonal Jacobian of each link's
            relative pose w.r.t. its configuration at the estimate (see
            ArticulatedObject.jacobian).
        stats: vector [num_observations, num_dropped, dof, total_bic, num_fit_failures].
    """

    def __init__(self, *, mode: str = "markers", part_ids=None, pose_size: int = 7,
                 period: float = 0.05, refit_every: int = 20, min_observations: int = 10,
                 max_observations: int = 500, max_dof: int | None = None,
                 obs: ObservationModel | None = None, models=DEFAULT_CANDIDATES,
                 seed: int = 0, refit_fraction: float = 0.0):
        super().__init__()
        if mode not in ("markers", "pose"):
            raise ValueError(f"mode must be 'markers' or 'pose', got {mode!r}")
        if (not isinstance(period, (int, float, np.integer, np.floating))
                or isinstance(period, bool) or not (np.isfinite(period) and period > 0)):
            raise ValueError(f"period must be a finite number > 0 s, got {period!r}")
        if not all(isinstance(v, (int, np.integer)) and not isinstance(v, bool)
                   for v in (refit_every, min_observations, max_observations)):
            raise ValueError("refit_every, min_observations and max_observations must be "
                             "integers")
        if refit_every < 1 or min_observations < 3 or max_observations < min_observations:
            raise ValueError("need refit_every >= 1, min_observations >= 3 and "
                             "max_observations >= min_observations")
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
            raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
        if (isinstance(refit_fraction, bool)
                or not isinstance(refit_fraction, (int, float, np.integer, np.floating))
                or not 0.0 <= refit_fraction <= 1.0):
            raise ValueError(f"refit_fraction must be a number in [0, 1], got "
                             f"{refit_fraction!r}")
        models = _checked_models(models)
        self._mode = mode
        if mode == "markers":
            if part_ids is None or len(part_ids) < 2:
                raise ValueError("markers mode needs part_ids with at least 2 marker ids")
            self._part_ids = [str(p) for p in part_ids]
            self._width = 7
            self._in = self.DeclareAbstractInputPort("observations",
                                                     AbstractValue.Make(MarkerObservations()))
        else:
            if pose_size not in (3, 7):
                raise ValueError(f"pose_size must be 3 or 7, got {pose_size}")
            self._part_ids = ["fixed", "moving"]
            self._width = int(pose_size)
            self._in = self.DeclareVectorInputPort("pose", BasicVector(self._width))
        p = len(self._part_ids)
        self._max_dof = int(max_dof) if max_dof is not None else max(1, p - 1)
        self._obs = obs if obs is not None else ObservationModel()
        self._models = models
        self._seed = int(seed)
        self._refit_every = int(refit_every)
        self._refit_fraction = float(refit_fraction)
        self._period = float(period)
        self._min_obs = int(min_observations)
        self._max_obs = int(max_observations)
        init = ArticulationEstimatorState(poses=np.zeros((0, p, self._width)))
        self._state_index = self.DeclareAbstractState(AbstractValue.Make(init))
        self.DeclarePeriodicUnrestrictedUpdateEvent(period, 0.0, self._update)
        # every output is a function of the state alone (not of the input, which changes
        # every plant step); the configuration estimate is computed once per state
        st = {self.abstract_state_ticket(self._state_index)}
        self._estimate_cache = self.DeclareCacheEntry(
            "estimate", ValueProducer(allocate=lambda: AbstractValue.Make(None),
                                      calc=lambda c, v: v.set_value(self._estimate(c))), st)
        est = {self._estimate_cache.ticket()}
        self._out_model = self.DeclareAbstractOutputPort(
            "object_model", lambda: AbstractValue.Make(None), self._calc_model, st)
        self._out_sel = self.DeclareAbstractOutputPort(
            "selected_models", lambda: AbstractValue.Make(dict()), self._calc_selected, st)
        self._out_q = self.DeclareVectorOutputPort(
            "configuration", self._max_dof, self._calc_q, prerequisites_of_calc=est)
        self._out_J = self.DeclareAbstractOutputPort(
            "jacobian", lambda: AbstractValue.Make(np.zeros((0, 0))), self._calc_J, est)
        self._out_stats = self.DeclareVectorOutputPort("stats", 5, self._calc_stats,
                                                       prerequisites_of_calc=st)

    # ------------------------------------------------------------------ ports
    # the same pattern as the other systems (MarkerSensor's get_observations_output_port):
    # get_<port name>_input_port / get_<port name>_output_port
    def get_observations_input_port(self):
        """The ``observations`` input (markers mode: MarkerObservations)."""
        if self._mode != "markers":
            raise RuntimeError("this ArticulationEstimator is in pose mode: its input port "
                               "is 'pose' (get_pose_input_port())")
        return self._in

    def get_pose_input_port(self):
        """The ``pose`` input (pose mode: x y z [qx qy qz qw], m)."""
        if self._mode != "pose":
            raise RuntimeError("this ArticulationEstimator is in markers mode: its input "
                               "port is 'observations' (get_observations_input_port())")
        return self._in

    def get_object_model_output_port(self):
        """The current ArticulatedObject (None before the first fit)."""
        return self._out_model

    def get_selected_models_output_port(self):
        """dict "parent->child" -> selected model name."""
        return self._out_sel

    def get_configuration_output_port(self):
        """Configuration estimate (max_dof,), m / rad, NaN where unknown."""
        return self._out_q

    def get_jacobian_output_port(self):
        """Block-diagonal Jacobian (6 * num_links, dof) at the estimate."""
        return self._out_J

    def get_stats_output_port(self):
        """[num_observations, num_dropped, dof, total_bic, num_fit_failures]."""
        return self._out_stats

    def get_input_port_observations(self):
        """Deprecated: use get_observations_input_port() (markers mode) or
        get_pose_input_port() (pose mode). Returns the one input port in either mode."""
        warnings.warn("ArticulationEstimator.get_input_port_observations() is deprecated; "
                      "use get_observations_input_port() (markers mode) or "
                      "get_pose_input_port() (pose mode)", DeprecationWarning, stacklevel=2)
        return self._in

    def part_ids(self) -> list[str]:
        return list(self._part_ids)

    # ------------------------------------------------------------------ helpers
    def _state(self, context) -> ArticulationEstimatorState:
        return context.get_abstract_state(self._state_index).get_value()

    def _read(self, context):
        """One observation row (p, width) or None if invalid (to be counted as dropped);
        returns (row, time, is_new)."""
        p = len(self._part_ids)
        if self._mode == "pose":
            v = np.asarray(self._in.Eval(context), float).reshape(-1)
            if v.shape != (self._width,) or not np.all(np.isfinite(v)):
                return None, context.get_time()
            row = np.zeros((2, self._width))
            if self._width == 7:
                nq = np.linalg.norm(v[3:])
                if nq < 1e-6:
                    return None, context.get_time()
                row[0] = [0, 0, 0, 0, 0, 0, 1]
                v = v.copy()
                v[3:] /= nq
            row[1] = v
            return row, context.get_time()
        try:
            obs = self._in.Eval(context)
        except Exception:  # noqa: BLE001 - a bad input must not stop the simulation
            return None, context.get_time()
        if not isinstance(obs, MarkerObservations):
            return None, context.get_time()
        row = np.full((p, 7), np.nan)
        try:
            vis = np.asarray(obs.visible, bool).reshape(-1)
            ids = list(obs.marker_ids)
            for k, pid in enumerate(self._part_ids):
                if pid not in ids:
                    continue
                i = ids.index(pid)
                if i >= vis.shape[0] or not vis[i]:
                    continue
                X = obs.poses[i]
                t = np.asarray(X.translation(), float)
                qq = X.rotation().ToQuaternion()
                q = np.array([qq.x(), qq.y(), qq.z(), qq.w()])
                if not (np.all(np.isfinite(t)) and np.all(np.isfinite(q))):
                    return None, float(obs.time)
                row[k, :3] = t
                row[k, 3:] = q
        except Exception:  # noqa: BLE001
            return None, context.get_time()
        return row, float(obs.time)

    def _fit(self, poses: np.ndarray, rng) -> ArticulatedObject:
        if self._mode == "pose":
            sel = select_link_model(poses[:, 1], models=self._models, obs=self._obs, rng=rng)
            return ArticulatedObject(self._part_ids, 0,
                                     [LinkEdge(0, 1, sel.best, dict(sel.bic))])
        return fit_kinematic_tree([poses[:, k] for k in range(poses.shape[1])],
                                  part_names=self._part_ids, models=self._models,
                                  obs=self._obs, rng=rng, min_common=self._min_obs)

    def warm_up(self) -> None:
        """Fit the candidate models once to a short synthetic track (an arc of 24 points),
        outside any simulation: the first refit of a simulation then does not pay the
        one-time costs of the process (loading the compiled kernels of the fits from
        numba's cache, the modules the fits import: about 1 s of CPU). Touches no context
        and no random stream of the estimator; the result is thrown away."""
        a = np.linspace(0.0, 1.2, 24)
        P = np.stack([0.5 * np.cos(a), 0.5 * np.sin(a), 0.01 * a], axis=1)
        if self._width == 7:
            P = np.concatenate([P, np.tile([0.0, 0.0, 0.0, 1.0], (a.size, 1))], axis=1)
        rng = np.random.default_rng(0)
        P = P + np.pad(rng.normal(0.0, 0.002, (a.size, 3)), ((0, 0), (0, P.shape[1] - 3)))
        try:
            select_link_model(P, models=self._models, obs=self._obs, rng=rng)
        except (ValueError, np.linalg.LinAlgError):
            pass  # a candidate set that cannot fit this arc: its first refit loads them

    def _update(self, context, state):
        s = self._state(context)
        row, t = self._read(context)
        if row is None:
            model, fails, last = self._refit_at_track_end(s, t)
            new = ArticulationEstimatorState(s.poses, s.times, s.num_dropped + 1, fails, model,
                                             last, s.total)
            state.get_mutable_abstract_state(self._state_index).set_value(new)
            return
        if s.times.size and self._mode == "markers" and t == s.times[-1]:
            return  # the same frame again: not an observation, not an error
        if np.all(np.isnan(row[:, 0])):  # nothing seen: not an observation, not an error
            model, fails, last = self._refit_at_track_end(s, t)
            if last != s.last_fit_count:
                state.get_mutable_abstract_state(self._state_index).set_value(
                    ArticulationEstimatorState(s.poses, s.times, s.num_dropped, fails, model,
                                               last, s.total))
            return
        poses = np.concatenate([s.poses, row[None]], axis=0)[-self._max_obs:]
        times = np.concatenate([s.times, [t]])[-self._max_obs:]
        model, fails, last = s.model, s.num_fit_failures, s.last_fit_count
        total = s.total + 1
        if poses.shape[0] >= self._min_obs and (
                (model is None and total - last >= min(self._refit_every, 5))
                or total - last >= self._refit_interval(poses.shape[0] - (total - last))):
            model, fails, last = self._refit(poses, model, fails, total)
        new = ArticulationEstimatorState(poses, times, s.num_dropped, fails, model, last, total)
        state.get_mutable_abstract_state(self._state_index).set_value(new)

    def _refit(self, poses, model, fails: int, total: int):
        """The model fitted to ``poses`` (the old ``model`` kept when the fit fails), the
        failure count and the new last-fit count (``total``)."""
        rng = np.random.default_rng(self._seed + total)
        try:
            model = self._fit(poses, rng)
        except Exception as e:  # noqa: BLE001 - never stop the simulation; keep the old model
            fails += 1
            warnings.warn(f"ArticulationEstimator: the fit at observation {total} failed "
                          f"({type(e).__name__}: {e}); keeping the previous model",
                          RuntimeWarning, stacklevel=3)
        return model, fails, total

    def _refit_at_track_end(self, s: ArticulationEstimatorState, t: float):
        """With ``refit_fraction`` > 0: the refit of a track that has ended, once no
        observation came for ``refit_every`` periods after some the model has not seen
        (a growing interval would otherwise leave up to that fraction of the track's end
        out of its model). Returns (model, failures, last-fit count), unchanged otherwise."""
        if (self._refit_fraction > 0.0 and s.total > s.last_fit_count
                and s.poses.shape[0] >= self._min_obs
                and t - s.times[-1] >= self._refit_every * self._period - 1e-9):
            return self._refit(s.poses, s.model, s.num_fit_failures, s.total)
        return s.model, s.num_fit_failures, s.last_fit_count

    def _refit_interval(self, n_fitted: int) -> int:
        """New observations a refit waits for after one on ``n_fitted`` observations."""
        if self._refit_fraction <= 0.0:
            return self._refit_every
        return max(self._refit_every, math.ceil(self._refit_fraction * n_fitted))

    def _estimate(self, context):
        s = self._state(context)
        if s.model is None or s.poses.shape[0] == 0:
            return s, None
        try:
            q = s.model.configuration(s.poses[-1])
        except Exception:  # noqa: BLE001
            q = np.full(s.model.dof, np.nan)
        return s, q

    # ------------------------------------------------------------------ outputs
    def _calc_model(self, context, out):
        out.set_value(self._state(context).model)

    def _calc_selected(self, context, out):
        m = self._state(context).model
        sel = {}
        if m is not None:
            for e in m.edges:
                sel[f"{m.part_names[e.parent]}->{m.part_names[e.child]}"] = e.model.name
        out.set_value(sel)

    def _calc_q(self, context, out):
        v = np.zeros(self._max_dof)
        _, q = self._estimate_cache.Eval(context)
        if q is not None:
            k = min(q.size, self._max_dof)
            v[:k] = q[:k]
        out.SetFromVector(v)

    def _calc_J(self, context, out):
        s, q = self._estimate_cache.Eval(context)
        if q is None:
            out.set_value(np.zeros((0, 0)))
            return
        qq = np.where(np.isfinite(q), q, 0.0)
        try:
            out.set_value(s.model.jacobian(qq))
        except ValueError:
            out.set_value(np.zeros((6 * len(s.model.edges), s.model.dof)))

    def _calc_stats(self, context, out):
        s = self._state(context)
        dof = s.model.dof if s.model is not None else 0
        bic = s.model.total_bic if s.model is not None else np.nan
        out.SetFromVector([s.poses.shape[0], s.num_dropped, dof, bic, s.num_fit_failures])
