"""PriorModelSelector: use prior models learned from earlier objects while operating a new
one (thesis Sec. 4.2, Algorithm 2 and Eq. 4.46)."""

from dataclasses import dataclass, field, replace

import numpy as np

from pydrake.common.value import AbstractValue
from pydrake.systems.framework import EventStatus, LeafSystem

from mmlearn.models.articulation.priors import PriorDatabase
from mmlearn.models.articulation.structure import ArticulatedObject, LinkEdge


class ShiftedLinkModel:
    """A link model fitted to trajectories aligned at their first observation, moved back
    to where the current trajectory started: positions p = f(q) + origin. Orientation,
    axes and configurations are unchanged. Offers what the controller and the drawing
    use (name, dof, n_train, q_min/q_max, forward, inverse, jacobian, axis, center,
    radius)."""

    def __init__(self, model, origin):
        self.model = model
        self.origin = np.asarray(origin, float).reshape(3)
        self.name = model.name
        self.dof = model.dof
        self.n_train = getattr(model, "n_train", 0)
        self.q_min = getattr(model, "q_min", None)
        self.q_max = getattr(model, "q_max", None)

    def _shift_in(self, Z):
        Z = np.array(Z, float, copy=True)
        Z[..., :3] -= self.origin
        return Z

    def inverse(self, Z):
        return self.model.inverse(self._shift_in(Z))

    def forward(self, q):
        P = np.array(self.model.forward(q), float, copy=True)
        P[..., :3] += self.origin
        return P

    def jacobian(self, q):
        return self.model.jacobian(q)

    @property
    def axis(self):
        return self.model.axis

    @property
    def center(self):
        return self.model.center + self.origin

    @property
    def radius(self):
        return self.model.radius


@dataclass(frozen=True)
class _PriorState:
    """Immutable (Drake's copies share it): replaced by every update."""

    track: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    cluster: int | None = None
    model: object = None
    tests: int = 0

    def __post_init__(self):
        self.track.setflags(write=False)

    def __deepcopy__(self, memo):
        return self


class PriorModelSelector(LeafSystem):
    """Chooses between the model learned from scratch and a prior model.

    Every ``period`` it stores the hook position (NaN = no observation); every ``every``
    new observations it repeats the merge test of Algorithm 2 of the trajectory so far
    against the prior database. While the trajectory merges into a known cluster, the
    output is that cluster's joint model (moved to the current trajectory's start);
    otherwise it passes the estimator's model through.

    .. pydrake_system::

        name: PriorModelSelector
        input_ports:
        - hook_position
        - object_model
        output_ports:
        - object_model
        - prior_cluster

    ``prior_cluster`` is the index of the cluster in use, or -1.
    """

    def __init__(self, *, db: PriorDatabase, period: float = 0.03, every: int = 10,
                 min_observations: int = 5, seed: int = 0):
        super().__init__()
        if not period > 0 or every < 1 or min_observations < 3:
            raise ValueError("PriorModelSelector: need period > 0, every >= 1, "
                             "min_observations >= 3")
        if not isinstance(db, PriorDatabase) or not db.clusters:
            raise ValueError("PriorModelSelector: needs a PriorDatabase with clusters")
        self._db, self._every, self._min, self._seed = db, int(every), int(min_observations), seed
        self._in_p = self.DeclareVectorInputPort("hook_position", 3)
        self._in_model = self.DeclareAbstractInputPort("object_model", AbstractValue.Make(None))
        self._s = self.DeclareAbstractState(AbstractValue.Make(_PriorState()))
        self.DeclarePeriodicUnrestrictedUpdateEvent(period, 0.0, self._update)
        self._out = self.DeclareAbstractOutputPort(
            "object_model", lambda: AbstractValue.Make(None), self._calc,
            prerequisites_of_calc={self.abstract_state_ticket(self._s),
                                   self._in_model.ticket()})
        self._out_c = self.DeclareVectorOutputPort(
            "prior_cluster", 1, self._calc_cluster,
            prerequisites_of_calc={self.abstract_state_ticket(self._s)})

    def get_hook_position_input_port(self):
        return self._in_p

    def get_object_model_input_port(self):
        return self._in_model

    def _update(self, context, state):
        s = context.get_abstract_state(self._s).get_value()
        p = np.asarray(self._in_p.Eval(context), float)
        if not np.all(np.isfinite(p)):
            return EventStatus.DidNothing()
        new = _PriorState(np.vstack([s.track, p[None]]), s.cluster, s.model, s.tests)
        n = new.track.shape[0]
        if n >= self._min and (n - self._min) % self._every == 0:
            try:
                d = self._db.merge_test(new.track,
                                        rng=np.random.default_rng([self._seed, n]))
                new = replace(new, cluster=d.cluster, tests=new.tests + 1,
                              model=(None if d.cluster is None
                                     else ShiftedLinkModel(d.model, new.track[0])))
            except (ValueError, np.linalg.LinAlgError, FloatingPointError):
                pass  # keep the previous decision
        state.get_mutable_abstract_state(self._s).set_value(new)
        return EventStatus.Succeeded()

    def _calc(self, context, output):
        s = context.get_abstract_state(self._s).get_value()
        if s.model is None:
            output.set_value(self._in_model.Eval(context))
            return
        output.set_value(ArticulatedObject(["fixed", "moving"], 0,
                                           [LinkEdge(0, 1, s.model, {})]))

    def _calc_cluster(self, context, output):
        c = context.get_abstract_state(self._s).get_value().cluster
        output.SetFromVector([-1.0 if c is None else float(c)])
