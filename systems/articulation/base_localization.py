"""BaseLocalization: what a mobile robot believes about its base pose (thesis 4.3/4.4.2).

The thesis' robot senses its hook through its arm's forward kinematics, but expresses the
hook's trajectory in a world frame through its base localisation; that is where its
sigma_pos = 0.05 m comes from. This system puts that error between the plant and the
robot's software: the robot believes its planar base pose is

    (x, y, yaw)_believed = (x, y, yaw)_true + e(t),

e = e_loc + e_odo, where

- e_loc, the localisation error, is a stationary Ornstein-Uhlenbeck process per axis
  (standard deviations ``sigma_xy`` and ``sigma_yaw``, correlation time
  ``time_constant``): it drifts slowly, it does not jitter;
- e_odo, the odometry error, grows only while the base moves: the odometry's scale is
  off by a random factor per trial (standard deviation ``odometry_xy`` along and across
  the base's heading, ``odometry_yaw`` in yaw), so each displacement of the base adds that
  fraction of itself to the error (systematic errors dominate wheel odometry; jitter back
  and forth cancels); the localisation pulls it back with the same time constant.

Everything the robot's software reads in the world frame goes through the belief: the robot
state (its base pose), the wrist force (rotated by the yaw error), and its base commands
are realised by a base controller that closes the loop on the believed pose, so the plant
receives ``command - e``. The robot is thus self-consistent in its believed frame, and the
world (handle, mechanism) appears to drift in it by e(t).

The robot's software may work in either of two frames (``frame``):

- ``"map"``: its belief is the localisation's, e = e_loc + e_odo as above;
- ``"odometry"``: its belief is its dead reckoning since the start, anchored at the
  localisation's belief at time 0: e = e(0) + the odometry error accumulated since (the
  same scale errors, never pulled back, no localisation drift). Over the pull of one door
  it changes only by the odometry's few percent of the base's motion, where the
  localisation's error drifts by centimetres. The thesis' robot, too, moved its
  equilibrium point "in a fixed world frame, attached to the initial location of the
  handle" (Sec. 4.3) and sensed its hook through its arm's forward kinematics.

All randomness is a deterministic function of (seed, update index); the error lives in the
Context's discrete state.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from pydrake.systems.framework import BasicVector, EventStatus, LeafSystem

from mmlearn.models.common.config import param, validate_fields

__all__ = ["BaseLocalization", "BaseLocalizationConfig", "FRAMES"]

#: the frames the robot's software can work in (see the module docstring)
FRAMES = ("map", "odometry")


@dataclass
class BaseLocalizationConfig:
    """Error model of :class:`BaseLocalization` (load with ``yaml_load_typed``).

    Attributes:
        sigma_xy: stationary standard deviation of the localisation error per horizontal
            axis, m. The default 0.035 m gives an RMS horizontal error of 0.05 m.
        sigma_yaw: stationary standard deviation of the heading error, rad (0.02 rad =
            1.1 deg; at the hook, ~0.8 m from the base, about 0.016 m).
        time_constant: correlation time of the localisation error, s: over a 30 s trial it
            drifts by about 0.9 of its standard deviation per axis (0.031 m).
        odometry_xy: standard deviation of the odometry's scale error along and across the
            base's heading, m per m travelled (0.03: 1.5 cm after a 0.5 m drive).
        odometry_yaw: standard deviation of the odometry's heading scale error, rad per
            rad turned.
        period: update period of the error, s.
        seed: seed of the error's random draws.
    """

    sigma_xy: float = param(0.035, unit="m", ge=0)
    sigma_yaw: float = param(0.02, unit="rad", ge=0)
    time_constant: float = param(60.0, unit="s", gt=0)
    odometry_xy: float = param(0.03, unit="m per m", ge=0)
    odometry_yaw: float = param(0.03, unit="rad per rad", ge=0)
    period: float = param(0.05, unit="s", gt=0)
    seed: int = param(0, integer=True, ge=0)

    def validate(self) -> None:
        validate_fields(self)

    def scaled(self, scale: float) -> "BaseLocalizationConfig":
        """A copy with all error magnitudes multiplied by ``scale`` (0 = exact base pose)."""
        if not (math.isfinite(scale) and scale >= 0):
            raise ValueError(f"base noise scale must be >= 0, got {scale}")
        return replace(self, sigma_xy=self.sigma_xy * scale, sigma_yaw=self.sigma_yaw * scale,
                       odometry_xy=self.odometry_xy * scale,
                       odometry_yaw=self.odometry_yaw * scale)

    @property
    def exact(self) -> bool:
        return max(self.sigma_xy, self.sigma_yaw, self.odometry_xy, self.odometry_yaw) == 0


# discrete state layout: localisation error, its odometry part (pulled back), previous true
# base pose, update count, odometry error accumulated since the start (never pulled back)
_LOC, _ODO, _PREV, _K, _RAW = slice(0, 3), slice(3, 6), slice(6, 9), 9, slice(10, 13)


def initial_error(config: BaseLocalizationConfig) -> np.ndarray:
    """The localisation error at time 0, (x, y, yaw) (m, m, rad): a draw from the
    stationary distribution, a deterministic function of ``config.seed``."""
    w = np.random.default_rng([config.seed, 0]).normal(size=3)
    return w * np.array([config.sigma_xy, config.sigma_xy, config.sigma_yaw])


def odometry_scale_errors(config: BaseLocalizationConfig) -> np.ndarray:
    """The trial's odometry scale errors (along, across the heading, yaw), a
    deterministic function of ``config.seed``."""
    w = np.random.default_rng([config.seed, 0, 1]).normal(size=3)
    return w * np.array([config.odometry_xy, config.odometry_xy, config.odometry_yaw])


def believed_from_true(point, base_true, error) -> np.ndarray:
    """A world point as the robot sees it when its base (x, y, yaw) is believed off by
    ``error``: the point keeps its pose relative to the base."""
    p = np.asarray(point, float)
    b = np.array([base_true[0], base_true[1], 0.0])
    c, s = math.cos(error[2]), math.sin(error[2])
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    return b + np.array([error[0], error[1], 0.0]) + R @ (p - b)


def rotate_yaw(v, yaw) -> np.ndarray:
    """Rotate a world vector about z by ``yaw``."""
    c, s = math.cos(yaw), math.sin(yaw)
    v = np.asarray(v, float)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]])


class BaseLocalization(LeafSystem):
    """The robot's belief of its base pose: a slowly drifting localisation error plus
    odometry error (see the module docstring).

    .. pydrake_system::

        name: BaseLocalization
        input_ports:
        - robot_state
        - command
        - force_W
        output_ports:
        - believed_robot_state
        - plant_command
        - believed_force_W
        - error
        - command_offset

    ``robot_state``: the plant's (true) state of the robot instance; ``believed_robot_state``
    the same with the base's x, y, yaw positions offset by the error. ``command``: the
    controller's command (base x, y, yaw first, in the believed frame); ``plant_command``:
    the same with the error taken off the base's entries, what the base controller makes
    the plant do. ``force_W`` / ``believed_force_W``: the wrist force in the true / believed
    world frame (rotated by the yaw error), N. ``error``: e = believed - true (m, m, rad).
    ``command_offset``: what the base controller adds to ``command`` (-e on the base's
    entries, 0 elsewhere): ``command + command_offset`` is ``plant_command`` to the last
    bit, and a diagram that adds them with Drake's ``Adder`` evaluates no Python at every
    plant step for it (this output changes only with the error's updates).

    ``frame``: "map" (the outputs are the localisation's belief, :meth:`error`) or
    "odometry" (the robot's dead reckoning since the start, :meth:`odometry_error`; see the
    module docstring); the ``error`` output is the error of the belief the outputs use.
    """

    def __init__(self, *, config: BaseLocalizationConfig | None = None, state_size: int,
                 base_position_indices, num_commands: int, frame: str = "map"):
        super().__init__()
        cfg = config or BaseLocalizationConfig()
        cfg.validate()
        if frame not in FRAMES:
            raise ValueError(f"frame must be one of {', '.join(FRAMES)}, got {frame!r}")
        self._frame = frame
        self._e0 = initial_error(cfg)
        self._cfg = cfg
        idx = np.asarray(base_position_indices, int).reshape(-1)
        if idx.shape != (3,) or np.any(idx < 0) or np.any(idx >= state_size):
            raise ValueError("base_position_indices must be 3 indices (x, y, yaw) into "
                             f"robot_state of size {state_size}, got {base_position_indices}")
        if num_commands < 3:
            raise ValueError("num_commands must be >= 3 (base x, y, yaw first)")
        self._idx = idx
        a = math.exp(-cfg.period / cfg.time_constant)
        self._a = a
        self._b = math.sqrt(1.0 - a * a) * np.array([cfg.sigma_xy, cfg.sigma_xy, cfg.sigma_yaw])
        self._odo = odometry_scale_errors(cfg)
        # the same numbers as Python floats, for the update's scalar arithmetic
        self._b_f = tuple(float(v) for v in self._b)
        self._odo_f = tuple(float(v) for v in self._odo)
        self._in_state = self.DeclareVectorInputPort("robot_state", state_size)
        self._in_cmd = self.DeclareVectorInputPort("command", num_commands)
        self._in_force = self.DeclareVectorInputPort("force_W", 3)
        x0 = np.zeros(13)
        x0[_LOC] = self._e0
        self._x = self.DeclareDiscreteState(x0)
        self.DeclareInitializationDiscreteUpdateEvent(self._initialize)
        self.DeclarePeriodicDiscreteUpdateEvent(cfg.period, 0.0, self._update)
        st = {self.discrete_state_ticket(self._x)}
        self._out_state = self.DeclareVectorOutputPort(
            "believed_robot_state", state_size, self._calc_state,
            prerequisites_of_calc=st | {self._in_state.ticket()})
        self._out_cmd = self.DeclareVectorOutputPort(
            "plant_command", num_commands, self._calc_cmd,
            prerequisites_of_calc=st | {self._in_cmd.ticket()})
        self._out_force = self.DeclareVectorOutputPort(
            "believed_force_W", 3, self._calc_force,
            prerequisites_of_calc=st | {self._in_force.ticket()})
        self._out_err = self.DeclareVectorOutputPort("error", BasicVector(3), self._calc_err,
                                                     prerequisites_of_calc=st)
        self._out_offset = self.DeclareVectorOutputPort(
            "command_offset", num_commands, self._calc_offset, prerequisites_of_calc=st)

    # ------------------------------------------------------------------ ports
    def get_robot_state_input_port(self):
        return self._in_state

    def get_command_input_port(self):
        return self._in_cmd

    def get_force_input_port(self):
        return self._in_force

    def get_believed_robot_state_output_port(self):
        return self._out_state

    def get_plant_command_output_port(self):
        return self._out_cmd

    def get_believed_force_output_port(self):
        return self._out_force

    def get_error_output_port(self):
        return self._out_err

    def get_command_offset_output_port(self):
        return self._out_offset

    def config(self) -> BaseLocalizationConfig:
        return replace(self._cfg)

    def frame(self) -> str:
        """The frame of the belief the outputs use ("map" or "odometry")."""
        return self._frame

    def error(self, context) -> np.ndarray:
        """e = believed - true base pose (x, y, yaw) of the localisation (map frame) in
        this context."""
        x = context.get_discrete_state(self._x).value()
        return x[_LOC] + x[_ODO]

    def odometry_error(self, context) -> np.ndarray:
        """e = believed - true base pose (x, y, yaw) of the dead reckoning since the start
        (odometry frame, anchored at the localisation's belief at time 0)."""
        return self._e0 + context.get_discrete_state(self._x).value()[_RAW]

    def belief_error(self, context) -> np.ndarray:
        """The error of the belief the outputs use (:meth:`error` or
        :meth:`odometry_error`, by ``frame``)."""
        return self.error(context) if self._frame == "map" else self.odometry_error(context)

    # ------------------------------------------------------------------ events
    def _true_base(self, context) -> np.ndarray:
        return np.asarray(self._in_state.Eval(context), float)[self._idx]

    def _initialize(self, context, discrete_state):
        x = np.array(context.get_discrete_state(self._x).value())
        x[_PREV] = self._true_base(context)
        discrete_state.set_value(self._x, x)
        return EventStatus.Succeeded()

    def _update(self, context, discrete_state):
        # in Python floats (the same IEEE operations as the arrays': one period's few
        # scalars cost less than the arrays' calls)
        x = context.get_discrete_state(self._x).value().tolist()
        k = int(x[_K]) + 1
        w0, w1, w2 = np.random.default_rng([self._cfg.seed, k]).normal(size=3).tolist()
        px, py, pyaw = x[_PREV]
        bx, by, byaw = np.asarray(self._in_state.Eval(context), float)[self._idx].tolist()
        if not (math.isfinite(bx) and math.isfinite(by) and math.isfinite(byaw)):
            bx, by, byaw = px, py, pyaw
        d0, d1 = bx - px, by - py
        turn = math.remainder(byaw - pyaw, 2 * math.pi)
        c, s = math.cos(byaw), math.sin(byaw)
        along, across = c * d0 + s * d1, -s * d0 + c * d1
        o0, o1, o2 = self._odo_f
        ea, ec = o0 * along, o1 * across
        odo = (c * ea - s * ec, s * ea + c * ec, o2 * turn)
        a = self._a
        b0, b1, b2 = self._b_f
        loc, od, raw = x[_LOC], x[_ODO], x[_RAW]
        x[_LOC] = [a * loc[0] + b0 * w0, a * loc[1] + b1 * w1, a * loc[2] + b2 * w2]
        x[_ODO] = [a * od[0] + odo[0], a * od[1] + odo[1], a * od[2] + odo[2]]
        x[_RAW] = [raw[0] + odo[0], raw[1] + odo[1], raw[2] + odo[2]]
        x[_PREV] = [bx, by, byaw]
        x[_K] = k
        discrete_state.set_value(self._x, np.array(x))
        return EventStatus.Succeeded()

    # ------------------------------------------------------------------ outputs
    def _calc_state(self, context, output):
        v = np.array(self._in_state.Eval(context), float)
        v[self._idx] += self.belief_error(context)
        output.SetFromVector(v)

    def _calc_cmd(self, context, output):
        v = np.array(self._in_cmd.Eval(context), float)
        v[:3] -= self.belief_error(context)
        output.SetFromVector(v)

    def _calc_force(self, context, output):
        output.SetFromVector(rotate_yaw(self._in_force.Eval(context),
                                       self.belief_error(context)[2]))

    def _calc_offset(self, context, output):
        # c + (-e) is c - e exactly, and c + (-0.0) is c: the Adder gives plant_command's
        # floats
        v = output.get_mutable_value()
        v[:] = -0.0
        v[:3] = -self.belief_error(context)

    def _calc_err(self, context, output):
        output.SetFromVector(self.belief_error(context))
