"""DynamicsMonitor: learns the mechanism's dynamics while the robot pulls and stops the pull
when the mechanism no longer follows the model (jammed or locked; thesis outlook, Sec. 9.1).

Every ``period`` it stores the hook position and the wrist force (while the controller
reports the hook on the handle), refits the dynamics along the current learned model
(:func:`mmlearn.models.articulation.dynamics.fit_dynamics`) and watches for a block: over
the last ``window`` seconds the hook advanced less than ``min_progress`` along the pull
(the model's tangent; before there is one, the given pulling direction of a prismatic
mechanism or the hook's recent track on a door) while the force pulling along it rose by
``min_rise`` (within ``rise_window``), on two samples, to more than the learned dynamics
predict (the prediction at the pulling rate seen so far, plus ``sigma_margin`` of its
deviations and ``force_margin``, at most ``block_force``; before any dynamics are learned,
or against a mechanism that has not moved, ``locked_force``); or the force stayed beyond
``block_force`` over ``fast_window`` without the hook advancing. It then tells the
controller to stop: halt code 1 (jammed: the hook had advanced by ``locked_travel`` or
more) or 2 (locked), and keeps where the block began (``blocked_at``: the opening from
where the hook began to move the mechanism to where the force rose). For a prismatic
mechanism the regression's force is the mean of every wrist-sensor sample over the period
(``prismatic_force_period``; the block tests keep the force at the sample instant). The pulling
speed is modulated so that the rate varies and damping can be told from friction: for a
door sinusoidally (``speed`` x (1 + ``excitation`` sin(2 pi t / ``excitation_period``)) of the
step), for a drawer alternating between two speeds, each held for a while and joined by
half-cosine ramps (the ``prismatic_`` fields; :func:`speed_modulation`).

Its ports are listed on :class:`DynamicsMonitor`. :class:`HaltGate` relaxes the arm at once when the monitor halts (the controller reacts only
at its next period): for ``hold`` seconds it commands the robot's measured joint positions,
so its joint springs stop pulling.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, EventStatus, LeafSystem

from mmlearn.models.articulation.dynamics import (MechanismDynamics, fit_dynamics,
                                                  generalized_samples, path_opening)
from mmlearn.models.common.config import param, validate_fields
from mmlearn.systems.common.plant_helpers import STICTION_VELOCITY

__all__ = ["DynamicsMonitorConfig", "DynamicsMonitorState", "DynamicsMonitor", "HaltGate", "GO",
           "RegressionSamples",
           "JAMMED", "LOCKED", "HALT_NAMES", "estimate_dynamics", "speed_modulation"]

GO, JAMMED, LOCKED = 0, 1, 2
HALT_NAMES = {GO: "", JAMMED: "jammed", LOCKED: "locked"}


@dataclass
class DynamicsMonitorConfig:
    """Parameters of :class:`DynamicsMonitor`.

    Attributes:
        period: sampling and decision period, s.
        force_period: for a mechanism that is not prismatic (``joint``), the wrist force
            is also read every this many seconds and averaged over each ``period`` for the
            regression (0, the default: the regression uses the force read at the sample
            instant, as the block tests do). Off for doors: with the mean of every sensor
            sample, 5 of 15 doors' damping read 25-47 % high where the instants' force gave
            them within 21 % (docs/mechanism_dynamics.md). s.
        prismatic_force_period: the same for a prismatic mechanism, 0.01 s: the wrist
            sensor's sample period, so every sensor sample is read once and the regression's
            force noise is the sensor's over the square root of the 2.5 samples averaged
            (a drawer's damping force is a few tenths of a newton beside it); the block
            tests keep the force read at the sample instant. The readings fall on this
            period's multiples, the sensor's own sample instants, and read the sample held
            until then (no simulator step of their own).
        refit_every: the dynamics are refitted after this many new samples (count).
        min_samples: samples before the first fit (count).
        speed: the pulling speed relative to the controller's step (its mean over the
            modulation), dimensionless: a slower pull meets a block with less force.
        excitation: relative amplitude of the pulling speed's modulation (0: constant):
            the pull alternates between ``speed`` x (1 - ``excitation``) and
            ``speed`` x (1 + ``excitation``).
        excitation_period: period of that modulation (one slow and one fast part), s.
        excitation_ramp: each change between the two speeds is a half-cosine ramp of this
            duration, s, at most half the period (:func:`speed_modulation`). Half the
            period is a sinusoidal modulation, which runs from the pull's first sample; a
            shorter ramp dwells at both speeds (a wider spread of rates for the regression)
            and starts, at the slow speed, where the hook has travelled ``start_travel``.
        prismatic_speed, prismatic_excitation, prismatic_excitation_period,
            prismatic_excitation_ramp: the same for a prismatic mechanism (``joint``): a
            drawer dwells at two speeds 1:3.4 apart (3.4 and 11.6 cm/s at the controller's
            default step; the hook follows at about 3.5 and 9.5 cm/s), where a drawer's
            small damping force is told from its friction and from the wrist sensor's
            noise; a door keeps the sinusoid (with two speeds, even with the force lag and
            the across term below, a light door's damping was no more often within 25 %,
            and heavier doors' less often: docs/mechanism_dynamics.md).
        start_travel: the first this far of the pull (the hook taking up the slack, the
            mechanism breaking free) go at the modulation's slowest speed, m.
        settle: the block test begins this long after the pull's first sample (the hook
            seating on the bar pushes it sideways), s.
        window: the block test looks at the last this many seconds, s.
        min_progress: the hook advancing less than this along the model in ``window``
            counts as not moving, m.
        min_rise: ... while the pulling force rose by at least this, N ...
        rise_window: ... over the last this many seconds, s.
        force_margin: the force must exceed the learned prediction by this much, N ...
        sigma_margin: ... plus this many of the prediction's standard deviations.
        block_force: a force above this without motion is a block whatever the learned
            dynamics predict (their prediction is loose after a short pull), N: below the
            controller's ``stop_force``. Held above it over ``fast_window`` while the hook
            advances less than ``min_progress`` is a block at once (a hook that takes up its
            slack and hits a stop raises the force by tens of N within one period).
        fast_window: the fast block test looks at the last this many seconds, s.
        onset_margin: the block began after the last sample whose pulling force was at
            most this above the free pull's level (see ``_block_span``), N: ``jammed_at``
            is the opening from where the hook began to move the mechanism to there (after
            a mechanism stops, the hook may slide on its handle by centimetres before the
            force rises).
        locked_force: without learned dynamics (or a mechanism that has not moved) a
            force above this, not moving, is a block, N.
        locked_travel: a block before the hook travelled this far from its first sample
            (along the pull where its direction is known) is a locked mechanism rather than
            a jammed one (the hook takes up ~3 cm of
            slack between its seat and the bar before it pulls), m.
        joint: the kind of mechanism the robot was sent to open ("revolute",
            "prismatic"; "" = not known): the unit of the opening at a block and the
            pulling speed's modulation (:meth:`modulation`).
        pull: the direction the robot was told to pull in (world; zero = not known): for
            a prismatic mechanism, progress and force are measured along it until the
            learned model gives its own direction.
        track_length: for a revolute mechanism before its model is revolute, progress and
            force are measured along the hook's track over its last this many metres (the
            arm's force across the door, which holds the hook on the bar, is not a block), m.
        open_enough: a block beyond this opening (rad or m; 0 = none) is the end of the
            mechanism's range, not a jam: the monitor lets the controller's own end-of-range
            test end the pull. Not for a door whose model is not yet revolute: the opening
            guessed from the hook's track is too loose to let the arm pull on.
        force_lag_period: for a revolute mechanism (``joint``), the wrist sensor's sample
            period, s: a force reading describes the force at the sensor's last sample
            before the monitor's sample, so the regression pairs it with the door's opening,
            rate and acceleration that long before (from the local fits of the hook's track);
            0 (the default): at the sample instant. A door swings against the compliant arm at a few hertz
            and its inertia force in that swing is several times a light door's damping
            force: a force read late by a fraction of that period reads partly as damping.
        regression_period: for a revolute mechanism (``joint``), the hook position and the
            wrist force are also read every this many seconds, at the wrist sensor's own
            sample instants (its multiples), and the dynamics are fitted to these readings
            instead of the monitor's ``period`` samples (the block tests keep those); 0 (the
            default): the monitor's samples. At 0.01 s every sensor sample is one regression
            sample (2.5 times as many as at ``period``); give ``force_lag_period`` the same
            value, as each reading then describes the force one sensor sample before its
            hook position. s.
        rate_window, prismatic_rate_window: the half-width of the local quadratic fits that
            give the regression its rates and accelerations from the hook's track, for a
            revolute (or not known) and for a prismatic mechanism, s.
        across_term: for a revolute mechanism, the force across the door (along the learned
            radius) times the learned radius is a further regressor of unknown size
            (:func:`~mmlearn.models.articulation.dynamics.fit_dynamics`' ``nuisance``): the
            arm holds the hook on the bar with several newtons across the door, and a
            learned tangent a little off the door's leaks part of it into the torque (off by
            default).
        friction_velocity: the Coulomb friction's regularisation speed the dynamics are
            fitted with (:func:`~mmlearn.models.articulation.dynamics.friction_shape`:
            tanh(qdot / v); 0: ideal Coulomb friction), rad/s or m/s: the simulated
            joints' friction builds up over its first few 0.02 (``JointFriction``), and at
            a drawer's few cm/s an ideal Coulomb term would read that growth as damping.
    """

    period: float = param(0.025, unit="s", gt=0)
    force_period: float = param(0.0, unit="s", ge=0)
    prismatic_force_period: float = param(0.01, unit="s", ge=0)
    refit_every: int = param(20, integer=True, ge=1)
    min_samples: int = param(40, integer=True, ge=10)
    speed: float = param(0.65, gt=0, le=3)
    excitation: float = param(0.5, ge=0, lt=1)
    excitation_period: float = param(2.0, unit="s", gt=0)
    excitation_ramp: float = param(1.0, unit="s", gt=0)
    prismatic_speed: float = param(0.75, gt=0, le=3)
    prismatic_excitation: float = param(0.55, ge=0, lt=1)
    prismatic_excitation_period: float = param(4.0, unit="s", gt=0)
    prismatic_excitation_ramp: float = param(1.0, unit="s", gt=0)
    start_travel: float = param(0.04, unit="m", ge=0)
    settle: float = param(0.3, unit="s", ge=0)
    window: float = param(0.1, unit="s", gt=0)
    min_progress: float = param(0.002, unit="m", gt=0)
    min_rise: float = param(2.0, unit="N", ge=0)
    rise_window: float = param(0.5, unit="s", gt=0)
    force_margin: float = param(4.0, unit="N", ge=0)
    sigma_margin: float = param(4.0, ge=0)
    block_force: float = param(25.0, unit="N", gt=0)
    fast_window: float = param(0.025, unit="s", gt=0)
    onset_margin: float = param(1.0, unit="N", ge=0)
    track_length: float = param(0.03, unit="m", gt=0)
    locked_force: float = param(15.0, unit="N", gt=0)
    locked_travel: float = param(0.045, unit="m", gt=0)
    joint: str = param("", choices=("", "revolute", "prismatic"))
    pull: list[float] = param([0.0, 0.0, 0.0], unit="world direction", length=3,
                              elements=True, factory=True)
    open_enough: float = param(0.0, unit="rad or m", ge=0)
    force_lag_period: float = param(0.0, unit="s", ge=0)
    regression_period: float = param(0.0, unit="s", ge=0)
    across_term: bool = param(False)
    rate_window: float = param(0.2, unit="s", gt=0)
    prismatic_rate_window: float = param(0.2, unit="s", gt=0)
    friction_velocity: float = param(STICTION_VELOCITY, unit="rad/s or m/s", ge=0)

    def __post_init__(self):
        validate_fields(self)
        for pre in ("", "prismatic_"):
            value = getattr(self, pre + "force_period")
            if value > self.period:
                raise ValueError(f"DynamicsMonitorConfig.{pre}force_period must be at most "
                                 f"period ({self.period:g} s), got {value:g} s")
        if self.regression_period > self.period:
            raise ValueError(f"DynamicsMonitorConfig.regression_period must be at most period "
                             f"({self.period:g} s), got {self.regression_period:g} s")
        for pre in ("", "prismatic_"):
            period, ramp = getattr(self, pre + "excitation_period"), \
                getattr(self, pre + "excitation_ramp")
            if ramp > 0.5 * period + 1e-12:
                raise ValueError(f"DynamicsMonitorConfig.{pre}excitation_ramp must be at most "
                                 f"half of {pre}excitation_period ({0.5 * period:g} s), got "
                                 f"{ramp:g} s")

    def averaging_period(self) -> float:
        """The period the wrist force is read at for the regression's mean, by ``joint``
        (``prismatic_force_period`` for a prismatic mechanism, else ``force_period``;
        0: no mean), s."""
        return float(self.prismatic_force_period if self.joint == "prismatic"
                     else self.force_period)

    def own_regression_samples(self) -> bool:
        """Whether the dynamics are fitted to samples of their own
        (``regression_period``, a revolute mechanism) rather than the monitor's."""
        return self.regression_period > 0 and self.joint == "revolute"

    def force_lags(self, t) -> np.ndarray:
        """How much older the force read at each of the times ``t`` (s) is than the hook
        position read with it, s: the age of the wrist sensor's last sample before ``t``
        (``force_lag_period``, sampling from time 0) for a revolute mechanism, else 0."""
        t = np.asarray(t, float)
        p = self.force_lag_period
        if p <= 0 or self.joint != "revolute":
            return np.zeros(t.shape)
        return t - p * (np.ceil(t / p - 1e-6) - 1.0)

    def regression_samples(self, link, t, G, F) -> dict | None:
        """The samples the dynamics are fitted to
        (:func:`~mmlearn.models.articulation.dynamics.generalized_samples` with this
        configuration's force lag and window of the local fits)."""
        window = self.prismatic_rate_window if self.joint == "prismatic" else self.rate_window
        return generalized_samples(link, t, G, F, force_lag=self.force_lags(t),
                                   half_window=window)

    def fit(self, g: dict | None) -> MechanismDynamics | None:
        """The dynamics fitted to :meth:`regression_samples`' output (None for None), with
        the force across a revolute mechanism as a nuisance term when ``across_term``."""
        if g is None:
            return None
        across = g.get("across") if self.across_term and self.joint == "revolute" else None
        return fit_dynamics(g["q"], g["qdot"], g["tau"], g["qddot"], joint=g["joint"],
                            radius=g["radius"], q_offset=g["q_offset"], q_sign=g["q_sign"],
                            friction_velocity=self.friction_velocity,
                            nuisance=None if across is None else across[:, None])

    def modulation(self) -> tuple[float, float, float, float]:
        """The pulling speed's modulation for this ``joint``: (speed, excitation, period,
        ramp), the ``prismatic_`` fields for a prismatic mechanism, else the plain ones."""
        pre = "prismatic_" if self.joint == "prismatic" else ""
        return tuple(float(getattr(self, pre + k)) for k in
                     ("speed", "excitation", "excitation_period", "excitation_ramp"))


def speed_modulation(t, period: float, ramp: float) -> float:
    """The pulling speed's modulation at time ``t`` (s) after it started, between -1 (the
    slow speed) and 1 (the fast one): it starts slow, rises over ``ramp`` seconds (a
    half-cosine), stays fast until half the ``period``, falls over ``ramp`` and stays slow
    until the period's end. With ``ramp`` = ``period`` / 2 it is -cos(2 pi t / period)."""
    x = math.fmod(max(float(t), 0.0), period)
    half = 0.5 * period
    if x < ramp:
        return -math.cos(math.pi * x / ramp)
    if x < half:
        return 1.0
    if x < half + ramp:
        return math.cos(math.pi * (x - half) / ramp)
    return -1.0


@dataclass(frozen=True)
class DynamicsMonitorState:
    """The monitor's abstract state (replaced on every update, never changed in place).

    Attributes:
        t, G, F: stored sample times (s), hook positions and wrist forces (world, m, N).
        F_mean: the wrist force averaged over each sample's period (world, N; ``F`` when
            the force is read only at the sample instants): what the regression uses.
        force_sum: the wrist-force readings' running sum and count at the last sample
            (N, N, N, count).
        t_start: time of the first sample (the pull's start; NaN before), s.
        t_excite: time the hook had travelled ``start_travel`` from its first sample: the
            speed's modulation starts there (NaN before), s.
        dynamics: the latest fit (None before one).
        last_fit: number of samples at the last fit.
        halt: GO, JAMMED or LOCKED.
        t_halt: time of the halt (NaN: none), s.
        blocked_at: the opening by the learned model where the block began (rad or m;
            NaN: no model or no block).
        t_onset: time the block began (the force rose from the free pull's level), s.
        travel: the hook's distance from its first sample at the block, m.
        peak_force: largest wrist force sample while the hook held the handle, N.
    """

    def held_peak_force(self, hold: float = 0.1, since: float = -math.inf,
                        until: float = math.inf) -> float:
        """The largest wrist force held for ``hold`` seconds (the largest over windows of
        that length of the smallest force in the window), N: the force the robot pulled
        with, without the few-millisecond spike of an impact; over the samples from
        ``since`` to ``until`` (s; default: all)."""
        inside = (self.t >= since - 1e-9) & (self.t <= until + 1e-9)
        t, F = self.t[inside], self.F[inside]
        if t.size == 0:
            return 0.0
        f = np.linalg.norm(F, axis=1)
        best = 0.0
        for i, t0 in enumerate(t):
            m = (t >= t0) & (t <= t0 + hold + 1e-9)
            if t[m][-1] - t0 >= hold - 1e-9:
                best = max(best, float(f[m].min()))
        return best

    t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    G: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    F: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    F_mean: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    force_sum: np.ndarray = field(default_factory=lambda: np.zeros(4))
    t_start: float = float("nan")
    t_excite: float = float("nan")
    dynamics: MechanismDynamics | None = None
    last_fit: int = 0
    halt: int = GO
    t_halt: float = float("nan")
    blocked_at: float = float("nan")
    t_onset: float = float("nan")
    travel: float = 0.0
    peak_force: float = 0.0

    def __post_init__(self):
        for k in ("t", "G", "F", "F_mean", "force_sum"):
            getattr(self, k).setflags(write=False)

    def __deepcopy__(self, memo):
        return self


@dataclass(frozen=True)
class RegressionSamples:
    """The readings the dynamics are fitted to when they have their own sampling
    (:attr:`DynamicsMonitorConfig.regression_period`; the monitor's second abstract state,
    replaced on every reading).

    Attributes:
        t, G, F: reading times (s), hook positions and wrist forces (world, m, N), while
            the hook held the handle.
    """

    t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    G: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    F: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))

    def __post_init__(self):
        for k in ("t", "G", "F"):
            getattr(self, k).setflags(write=False)

    def __deepcopy__(self, memo):
        return self


def _link(obj):
    if obj is None or not getattr(obj, "edges", None):
        return None
    return obj.edges[0].model


class DynamicsMonitor(LeafSystem):
    """Learns the mechanism's dynamics during the pull and halts a blocked pull (see the
    module docstring).

    .. pydrake_system::

        name: DynamicsMonitor
        input_ports:
        - hook_position
        - force_W
        - object_model
        output_ports:
        - supervisor
        - halted_since
        - dynamics

    ``hook_position``: the grip point (world, m; NaN while the hook is not on the handle,
    as the controller reports it); ``force_W``: the wrist force (force of the mechanism on
    the hook, world, N); ``object_model``: the learned model. ``supervisor``: [step scale,
    halt code] for :class:`~mmlearn.systems.articulation.epc_controller.EpcController`;
    ``halted_since``: the time of the halt (NaN: none), s; ``dynamics``: the latest
    :class:`MechanismDynamics` (or None).
    """

    def __init__(self, config: DynamicsMonitorConfig | None = None):
        super().__init__()
        self._cfg = cfg = config or DynamicsMonitorConfig()
        validate_fields(cfg)
        self._in_G = self.DeclareVectorInputPort("hook_position", 3)
        self._in_F = self.DeclareVectorInputPort("force_W", 3)
        self._in_model = self.DeclareAbstractInputPort("object_model",
                                                       AbstractValue.Make(None))
        self._s = self.DeclareAbstractState(AbstractValue.Make(DynamicsMonitorState()))
        # the wrist force's running sum and count (N, N, N, count)
        self._sum = self.DeclareDiscreteState(4)
        every = cfg.averaging_period()
        if every > 0:
            self.DeclarePeriodicDiscreteUpdateEvent(every, 0.0, self._accumulate)
        self.DeclarePeriodicUnrestrictedUpdateEvent(cfg.period, 0.0, self._update)
        # the regression's own readings (a second abstract state: the two updates may fall
        # on the same instant, and each replaces only its own state)
        self._reg = self.DeclareAbstractState(AbstractValue.Make(RegressionSamples()))
        if cfg.own_regression_samples():
            self.DeclarePeriodicUnrestrictedUpdateEvent(cfg.regression_period, 0.0,
                                                        self._read_regression)
        deps = {self.abstract_state_ticket(self._s), self.time_ticket()}
        self._out_sup = self.DeclareVectorOutputPort("supervisor", BasicVector(2),
                                                     self._calc_supervisor,
                                                     prerequisites_of_calc=deps)
        self._out_halt = self.DeclareVectorOutputPort(
            "halted_since", BasicVector(1),
            lambda context, out: out.SetFromVector([self.state(context).t_halt]),
            prerequisites_of_calc={self.abstract_state_ticket(self._s)})
        self._out_dyn = self.DeclareAbstractOutputPort(
            "dynamics", lambda: AbstractValue.Make(None), self._calc_dynamics,
            prerequisites_of_calc={self.abstract_state_ticket(self._s)})

    @property
    def config(self) -> DynamicsMonitorConfig:
        """A copy of the monitor's parameters."""
        return replace(self._cfg)

    # ------------------------------------------------------------------ ports
    def get_hook_position_input_port(self):
        return self._in_G

    def get_force_input_port(self):
        return self._in_F

    def get_object_model_input_port(self):
        return self._in_model

    def get_supervisor_output_port(self):
        return self._out_sup

    def get_dynamics_output_port(self):
        return self._out_dyn

    def get_halted_since_output_port(self):
        return self._out_halt

    def state(self, context) -> DynamicsMonitorState:
        return context.get_abstract_state(self._s).get_value()

    def regression_input(self, context, s: DynamicsMonitorState | None = None
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The times, hook positions and wrist forces the dynamics are fitted to: the
        readings of their own (:class:`RegressionSamples`) when
        :meth:`DynamicsMonitorConfig.own_regression_samples`, else the monitor's samples with
        the force the regression uses (``F_mean``), of ``s`` if given (a state an update is
        building, with its newest sample), else of the context's state."""
        if self._cfg.own_regression_samples():
            r = context.get_abstract_state(self._reg).get_value()
            return r.t, r.G, r.F
        s = self.state(context) if s is None else s
        return s.t, s.G, s.F_mean

    # ------------------------------------------------------------------ outputs
    def _calc_supervisor(self, context, output):
        s, cfg = self.state(context), self._cfg
        speed, excitation, period, ramp = cfg.modulation()
        scale = speed * (1.0 - excitation)
        if ramp >= 0.5 * period:
            # the sinusoid, from the pull's first sample once the hook is past start_travel
            if math.isfinite(s.t_start) and \
                    np.linalg.norm(s.G[-1] - s.G[0]) >= cfg.start_travel:
                phase = 2 * math.pi * (context.get_time() - s.t_start) / period
                scale = speed * (1.0 + excitation * math.sin(phase))
        elif math.isfinite(s.t_excite):
            # two speeds, from the slow one where the hook passed start_travel
            scale = speed * (1.0 + excitation * speed_modulation(
                context.get_time() - s.t_excite, period, ramp))
        output.SetFromVector([scale, float(s.halt)])

    def _calc_dynamics(self, context, value):
        value.set_value(self.state(context).dynamics)

    # ------------------------------------------------------------------ update
    def _accumulate(self, context, discrete_state):
        F = np.asarray(self._in_F.Eval(context), float)
        if not np.all(np.isfinite(F)):
            return EventStatus.DidNothing()
        total = np.asarray(context.get_discrete_state(self._sum).value(), float)
        discrete_state.get_mutable_vector(self._sum).SetFromVector(
            total + np.append(F, 1.0))
        return EventStatus.Succeeded()

    def _read_regression(self, context, state):
        G = np.asarray(self._in_G.Eval(context), float)
        F = np.asarray(self._in_F.Eval(context), float)
        if not (np.all(np.isfinite(G)) and np.all(np.isfinite(F))) or \
                self.state(context).halt != GO:
            return EventStatus.DidNothing()
        r = context.get_abstract_state(self._reg).get_value()
        state.get_mutable_abstract_state(self._reg).set_value(RegressionSamples(
            t=np.append(r.t, context.get_time()), G=np.vstack([r.G, G]),
            F=np.vstack([r.F, F])))
        return EventStatus.Succeeded()

    def _update(self, context, state):
        s = self.state(context)
        G = np.asarray(self._in_G.Eval(context), float)
        F = np.asarray(self._in_F.Eval(context), float)
        total = np.array(context.get_discrete_state(self._sum).value(), float)
        new = total - s.force_sum
        F_mean = new[:3] / new[3] if new[3] > 0.5 else F
        s = replace(s, force_sum=total)  # the next mean starts here, whatever this sample
        if not (np.all(np.isfinite(G)) and np.all(np.isfinite(F))):
            state.get_mutable_abstract_state(self._s).set_value(s)
            return EventStatus.Succeeded()
        t = context.get_time()
        # after a halt the samples go on (the force while the hook lets go), unused
        s = replace(s, t=np.append(s.t, t), G=np.vstack([s.G, G]), F=np.vstack([s.F, F]),
                    F_mean=np.vstack([s.F_mean, F_mean]),
                    t_start=t if not math.isfinite(s.t_start) else s.t_start,
                    peak_force=max(s.peak_force, float(np.linalg.norm(F))))
        if not math.isfinite(s.t_excite) and \
                np.linalg.norm(s.G[-1] - s.G[0]) >= self._cfg.start_travel:
            s = replace(s, t_excite=t)
        if s.halt != GO:
            state.get_mutable_abstract_state(self._s).set_value(s)
            return EventStatus.Succeeded()
        obj = self._in_model.Eval(context) if self._in_model.HasValue(context) else None
        s = self._refit(s, _link(obj), self.regression_input(context, s))
        s = self._check_block(s, _link(obj))
        state.get_mutable_abstract_state(self._s).set_value(s)
        return EventStatus.Succeeded()

    def _refit(self, s: DynamicsMonitorState, link, data) -> DynamicsMonitorState:
        """Refit every ``refit_every`` of the monitor's samples; ``data``: the regression's
        (t, G, F) (:meth:`regression_input`)."""
        cfg = self._cfg
        n = s.t.size
        if n < cfg.min_samples or n - s.last_fit < cfg.refit_every:
            return s
        return replace(s, dynamics=cfg.fit(cfg.regression_samples(link, *data)), last_fit=n)

    def _check_block(self, s: DynamicsMonitorState, link) -> DynamicsMonitorState:
        """Halt when the hook has stopped advancing along the model while the force
        pulling along it rose beyond what the learned dynamics predict, or at once when the
        wrist force (in any direction) stayed beyond ``block_force`` over ``fast_window``
        without the hook advancing."""
        cfg = self._cfg
        t_now = s.t[-1]
        recent = s.t >= t_now - cfg.window - 1e-9
        if s.t[0] > t_now - max(cfg.window, cfg.settle) + 0.5 * cfg.period \
                or recent.sum() < 3:
            return s
        d = self._direction(link, s.G)
        # without a direction: any motion counts, and the force is the one the robot
        # pulls with
        pulls_all = np.linalg.norm(s.F, axis=1) if d is None else -s.F @ d

        def progress(since):
            step = s.G[-1] - s.G[since][0]
            return float(np.linalg.norm(step)) if d is None else float(step @ d)

        rising = s.t >= t_now - cfg.rise_window - 1e-9
        pulls = pulls_all[rising]
        rise = float(pulls[-1] - pulls.min())
        fast = s.t >= t_now - cfg.fast_window - 1e-9
        # a door's hook is also held on the bar across the door (radial surges of the
        # arm's force are not a block): its fast test takes the force along the door
        door = cfg.joint == "revolute" and d is not None
        held = pulls_all[fast] if door else np.linalg.norm(s.F[fast], axis=1)
        fast_block = (fast.sum() >= 2 and bool(np.all(held > cfg.block_force))
                      and progress(fast) < cfg.min_progress)
        if not fast_block and (progress(recent) >= cfg.min_progress or rise < cfg.min_rise):
            return s
        # how far the hook got: along the pull where it is known (a hook that slides
        # sideways on a latched handle has not opened it), else anywhere
        travel = (max(float(np.max((s.G - s.G[0]) @ d)), 0.0)
                  if d is not None and cfg.joint == "prismatic"
                  else float(np.linalg.norm(s.G[-1] - s.G[0])))
        limit = cfg.locked_force
        if s.dynamics is not None and travel >= cfg.locked_travel:
            limit = min(self._expected_force(s, link, s.G[-1]), cfg.block_force)
        if not fast_block and min(pulls[-2:]) <= limit:
            return s  # (two samples: not one spike of the hook knocking on something)
        halt = JAMMED if travel >= cfg.locked_travel else LOCKED
        engage, onset = self._block_span(s, pulls_all)
        at = self.opening(link, s.G[engage:onset + 1])
        # the end of its range, unless a door's opening is only the hook track's guess
        guessed = cfg.joint == "revolute" and getattr(link, "name", "") != "revolute"
        if halt == JAMMED and cfg.open_enough > 0 and at >= cfg.open_enough and not guessed:
            return s
        return replace(s, halt=halt, t_halt=float(t_now), travel=travel, blocked_at=at,
                       t_onset=float(s.t[onset]))

    def _direction(self, link, G) -> np.ndarray | None:
        """Unit direction of the pull at the hook's last position: the learned model's
        tangent (oriented along the hook's track so far), else for a prismatic mechanism
        the pulling direction the robot was given (``pull``), for a revolute one the
        direction of the hook's track over its last ``track_length`` (turned to have a
        positive component along ``pull``); None otherwise."""
        d = _tangent(link, G[-1])
        if d is not None:
            return -d if float(d @ (G[-1] - G[0])) < 0 else d
        cfg = self._cfg
        pull = np.asarray(cfg.pull, float)
        if cfg.joint == "prismatic" and np.linalg.norm(pull) > 0:
            return pull / np.linalg.norm(pull)
        if cfg.joint == "revolute":
            # the direction of the hook's track over its last ``track_length``, turned to
            # open the door (a hook that lost the bar and moves back is not opening it)
            far = np.flatnonzero(np.linalg.norm(G - G[-1], axis=1) >= cfg.track_length)
            if far.size:
                step = G[-1] - G[far[-1]]
                if float(step @ pull) < 0:
                    step = -step
                return step / np.linalg.norm(step)
        return None

    def _block_span(self, s: DynamicsMonitorState, pulls: np.ndarray) -> tuple[int, int]:
        """Indices of the samples where the hook began to move the mechanism and where
        the block began. The free pull is the one after ``settle`` and before the last
        ``rise_window``; its level is the median of the pulling force (3-sample mean) and
        its spread the scaled median absolute deviation. The block began after the last
        sample before the halt at most ``onset_margin`` (or two spreads, when larger) above
        that level; the hook began to move the mechanism at the first sample that reached
        half the level (before it the hook takes up its slack on the handle)."""
        cfg = self._cfg
        n = pulls.size
        f = np.convolve(pulls, np.ones(3) / 3, mode="same") if n >= 3 else pulls.copy()
        f[-1] = pulls[-1]
        free = (s.t >= s.t[0] + cfg.settle) & (s.t < s.t[-1] - cfg.rise_window)
        if free.sum() < 5:
            return 0, n - 1
        level = float(np.median(f[free]))
        spread = 1.4826 * float(np.median(np.abs(f[free] - level)))
        low = np.flatnonzero(f[:n - 1] <= level + max(cfg.onset_margin, 2 * spread))
        onset = int(low[-1]) if low.size else n - 1
        up = np.flatnonzero(f[:onset] >= 0.5 * level) if level > 0 else np.zeros(0, int)
        return (int(up[0]) if up.size else 0), onset

    def opening(self, link, G) -> float:
        """The opening along the hook's track G (rad or m): by the learned model when it
        is the kind the robot was sent to open (or any revolute / prismatic model when
        that is not known), else from the track itself
        (:func:`~mmlearn.models.articulation.dynamics.path_opening`)."""
        joint = self._cfg.joint
        name = getattr(link, "name", "")
        if (name == joint) or (not joint and name in ("revolute", "prismatic")):
            return _opening(link, G[0], G[-1])
        if joint:
            return path_opening(G, joint)
        return float("nan")

    def _expected_force(self, s, link, G) -> float:
        """The pulling force (N, at the handle) the learned dynamics predict here at the
        rate of the pull so far, plus the margins."""
        cfg, dyn = self._cfg, s.dynamics
        q = _opening(link, s.G[0], G)
        rate = _typical_rate(dyn, link, s)
        if not math.isfinite(q) or rate is None:
            return cfg.locked_force
        m, sd = dyn.predict(q, rate)
        scale = dyn._handle_scale()
        return float(m[0] * scale + cfg.sigma_margin * sd[0] * scale + cfg.force_margin)


def estimate_dynamics(link, t, G, F, friction_velocity: float = 0.0) -> MechanismDynamics | None:
    """The dynamics along ``link`` from hook positions and wrist forces (None when the
    model is not revolute or prismatic, or too few samples moved); ``friction_velocity``:
    see :func:`~mmlearn.models.articulation.dynamics.fit_dynamics`. The monitor's fit at
    its default settings (:meth:`DynamicsMonitorConfig.fit`)."""
    return DynamicsMonitorConfig(friction_velocity=friction_velocity).fit(
        generalized_samples(link, t, G, F))


def _tangent(link, G) -> np.ndarray | None:
    """Unit tangent of a revolute or prismatic model at the hook position G."""
    if link is None or link.name not in ("revolute", "prismatic"):
        return None
    q = np.asarray(link.inverse(np.asarray(G, float)[None]), float)
    J = np.asarray(link.jacobian(q), float)[0, :3, 0]
    n = np.linalg.norm(J)
    return J / n if n > 1e-9 else None


def _opening(link, G0, G1) -> float:
    """The opening from G0 to G1 by the model (rad or m; NaN without a model)."""
    if link is None or link.name not in ("revolute", "prismatic"):
        return float("nan")
    q = np.asarray(link.inverse(np.stack([G0, G1])), float)[:, 0]
    dq = q[1] - q[0]
    if link.name == "revolute":
        dq = math.remainder(dq, 2 * math.pi)
    return abs(float(dq))


def _typical_rate(dyn, link, s) -> float | None:
    """The median opening rate while the mechanism moved (rad/s or m/s)."""
    g = generalized_samples(link, s.t, s.G, s.F)
    if g is None:
        return None
    qd = g["qdot"][np.isfinite(g["qdot"])]
    qd = qd[qd > 0]
    return float(np.median(qd)) if qd.size else None


class HaltGate(LeafSystem):
    """Passes the robot's joint commands through, except for ``hold`` seconds after a halt
    (``halted_since`` finite): then it commands the robot's measured joint positions, so the
    arm's joint springs stop pulling at once rather than at the controller's next period.

    .. pydrake_system::

        name: HaltGate
        input_ports:
        - command
        - robot_state
        - halted_since
        output_ports:
        - command

    ``command_positions``: index of each command in the robot instance's position vector;
    ``state_size``: size of ``robot_state`` (positions and velocities).
    """

    def __init__(self, *, command_positions, state_size: int, hold: float = 0.25):
        super().__init__()
        if not hold > 0:
            raise ValueError(f"HaltGate: hold must be > 0 s, got {hold}")
        self._idx = np.asarray(command_positions, int)
        self._hold = float(hold)
        n = self._idx.size
        self._in_cmd = self.DeclareVectorInputPort("command", n)
        self._in_state = self.DeclareVectorInputPort("robot_state", state_size)
        self._in_halt = self.DeclareVectorInputPort("halted_since", 1)
        self.DeclareVectorOutputPort("command", BasicVector(n), self._calc)

    def get_command_input_port(self):
        return self._in_cmd

    def get_robot_state_input_port(self):
        return self._in_state

    def get_halted_since_input_port(self):
        return self._in_halt

    def _calc(self, context, output):
        t_halt = float(self._in_halt.Eval(context)[0])
        t = context.get_time()
        if math.isfinite(t_halt) and t_halt <= t < t_halt + self._hold:
            output.SetFromVector(np.asarray(self._in_state.Eval(context))[self._idx])
        else:
            output.SetFromVector(self._in_cmd.Eval(context))
