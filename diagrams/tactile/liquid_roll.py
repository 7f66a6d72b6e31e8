"""The liquid-detection scene (thesis Sec. 7.3): grasp a container, lift it, roll it.

``MakeLiquidRollDiagram(config, *, container)`` builds a discrete MultibodyPlant (2 ms,
hydroelastic contact) with

* a table (a box, top at z = 0) and a **free** container of :mod:`mmlearn.models.tactile.containers`
  standing on it (its base gets six point-contact feet on the rim of its bottom; the walls on springs and
  the sloshing liquid -- the first sloshing mode's mass on a prismatic spring-damper in the
  base, its travel limited by the cap, :func:`mmlearn.models.tactile.liquid.first_slosh_mode` --
  come from :func:`mmlearn.sdf.tactile.container_sdf`);
* the parallel gripper of :func:`mmlearn.sdf.tactile.gripper_sdf` (PR2-like pads of 5 x 3
  taxels each, 24 Hz as the PR2's arrays) welded to a two-joint wrist: a PD-driven lift
  joint (prismatic along z, m) and a PD-driven roll joint (revolute about y, rad) whose axis
  lies ``roll_axis_height`` m above the pad centres. The roll axis is perpendicular to the
  fingers' closing direction x, so rolling tilts the container towards one finger: gravity
  and the accelerations of the roll load the pads along their normals as on the PR2, whose
  wrist rolls a bottle held upright towards one fingertip;
* the switching grasp controller of Eq. 7.8
  (:class:`~mmlearn.systems.tactile.grasp_controller.TactileGraspController`) followed by a
  :class:`~mmlearn.systems.tactile.finger_hold.FingerPositionHold` that latches the finger
  positions once the grasp has settled (a gripper's position hold): the sloshing liquid's
  reaction then shifts pressure between the pads instead of moving the force-controlled
  fingers along with the container;
* the taxel pads (:class:`~mmlearn.systems.tactile.sensor.TactileSensor`) and the wrist
  force sensor (:class:`~mmlearn.systems.common.wrist_force_sensor.WristForceSensor`) between the
  roll link and the palm.

Timeline (:class:`LiquidRollConfig`): close and squeeze, latch at ``t_latch``, lift by
``lift`` m over ``[t_lift, t_lift + lift_time]``, then roll +-``roll_amplitude`` rad at
``roll_hz`` for ``roll_cycles`` cycles from ``t_roll``. The grasp must have settled by
``t_latch``. Roll profiles (``roll_profile``): "sweep" (default: side to side at a constant
rate with smooth 0.25 s reversals, continuous acceleration, peak 23 rad/s^2 -- a wrist's
acceleration-limited motion), "sine" (a pure sinusoid faded in and out) and "triangle"
(constant rate, reversals abrupt or blended with constant deceleration: acceleration steps).

Findings (docs/tactile.md): the "triangle" roll's reversals flip the roll rate
within one PD response; the resulting jerk made every held body, the rigid dummy included,
spike in the high-passed taxels (dummy feature 0.0109 vs 0.0086 for a half-full bottle).
With continuous acceleration those spikes are gone. Under the "sine" roll the liquid's first
sloshing mode (3.5 Hz, damping ratio ~0.006) is hardly excited and every container's feature
is the 0.6 Hz load shift that leaks through the first-order high-pass (~10 % at 0.6 Hz), in
proportion to its weight; under the "sweep" each reversal excites that mode and the liquid
rings at 3.5 Hz (passed at ~50 %) between the reversals, which the rigid dummy and the empty
containers cannot do. :func:`roll_change_windows` gives where the commanded rate changes, so
that the feature can be taken over the constant-rate (coast) phases only
(:func:`mmlearn.models.tactile.liquid.coast_feature`).

:func:`mmlearn.diagrams.tactile.trials.liquid_roll_trial` runs one trial for the sweep runner
and returns only what the sensors recorded (taxels at 24 Hz, the wrist force) plus the labels.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from pydrake.geometry import (Box, Sphere, ProximityProperties, SceneGraphConfig,
                              AddContactMaterial)
from pydrake.math import RigidTransform
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import (AddMultibodyPlant, CoulombFriction,
                                     MultibodyPlantConfig)
from pydrake.multibody.tree import (PdControllerGains, PrismaticJoint, PrismaticSpring,
                                    RevoluteJoint, SpatialInertia)
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from mmlearn.models.common.config import param, validate_fields
from mmlearn.models.tactile.containers import (CONTAINER_CLASSES, RHO_WATER, ContainerInstance,
                                               sample_container)
from mmlearn.models.tactile.liquid import first_slosh_mode
from mmlearn.models.tactile.pad import PAD_PR2
from mmlearn.sdf.tactile import GripperGeometry, container_sdf, gripper_sdf, pad_z_of
from mmlearn.systems.tactile.finger_hold import FingerPositionHold
from mmlearn.systems.tactile.grasp_controller import TactileGraspController
from mmlearn.systems.common.wrist_force_sensor import WristForceSensor

from mmlearn.diagrams.tactile.grasp import AddTactileSensor

__all__ = ["LiquidRollConfig", "MakeLiquidRollDiagram", "simulate_roll", "LIQUID_CONTAINERS",
           "LIQUID_VISCOSITY", "dummy_instance", "make_instance", "roll_change_windows",
           "roll_trajectory"]


@dataclass
class LiquidRollConfig:
    """One liquid-detection trial.

    Attributes:
        f_target: grasp force per finger before the hold, N.
        v_target: closing speed of the finger distance, m/s.
        grasp_height: height of the pad centres above the container's bottom, m.
        offset: lateral offset of the container from the gripper centre along x, m.
        t_latch: time the finger positions are latched, s.
        t_lift: start of the lift, s. lift: lift height, m. lift_time: its duration, s.
        t_roll: start of the roll, s.
        roll_amplitude: roll angle amplitude, rad.
        roll_hz: roll frequency, Hz (thesis: about 0.6 Hz).
        roll_cycles: number of roll cycles.
        roll_profile: "sweep" (default: side to side at a constant rate with smooth
            reversals of ``reversal_time`` s whose rate turns as a cosine: continuous
            acceleration, bounded jerk, see :func:`sweep_roll_angle`), "sine" (``A sin(2 pi f
            t)`` with its amplitude faded in and out over ``ramp_time``) or "triangle"
            (constant rate, reversals abrupt or blended over ``reversal_time`` with a constant
            deceleration, i.e. acceleration steps: the earlier roll, kept to show where its
            spikes came from).
        ramp_time: "sine" only: fade-in and fade-out of the amplitude (quintic smoothstep), s.
        reversal_time: duration of each reversal, s ("sweep": 0 < tau < half a period,
            default 0.25 s, peak acceleration pi w / tau = 23 rad/s^2; "triangle": 0 =
            abrupt, the roll rate flips within one PD response).
        roll_axis_height: height of the roll axis above the pad centres, m.
        roll_kp, roll_kd: roll joint PD gains, N m/rad and N m s/rad.
        lift_kp, lift_kd: lift joint PD gains, N/m and N s/m.
        time_step: plant time step, s (2 ms: twice as fast as 1 ms, with the feature of a
            half-full bottle's trial close to 1 ms's under the sine roll and further off
            under the sweep; 4 ms changed it more).
        sensor_rate: taxel sampling rate, Hz (PR2: 24 Hz).
        taxel_noise: taxel noise, fraction of saturation (1e-4 = 1.4 mN per cell: the
            high-passed noise alone then gives a feature of ~0.001 N, the floor of the empty
            containers in the thesis' Table 7.4, 0.000-0.008 N; the grasp experiments'
            0.003 gives 0.027 N, above the thesis' half-full Odwalla response, 0.011 N).
        wrist_noise: wrist force noise per axis, N.
        seed: noise seed.
        gripper: gripper dimensions.
    """

    f_target: float = param(20.0, unit="N", gt=0)
    v_target: float = param(0.04, unit="m/s", gt=0)
    grasp_height: float = param(0.07, unit="m", gt=0)
    offset: float = param(0.0, unit="m")
    t_latch: float = param(1.1, unit="s", gt=0)
    t_lift: float = param(1.2, unit="s", gt=0)
    lift: float = param(0.03, unit="m", ge=0)
    lift_time: float = param(0.4, unit="s", gt=0)
    t_roll: float = param(1.9, unit="s", gt=0)
    roll_amplitude: float = param(0.7, unit="rad", ge=0)
    roll_hz: float = param(0.6, unit="Hz", gt=0)
    roll_cycles: float = param(2.0, gt=0)
    roll_profile: str = param("sweep", choices=("sine", "sweep", "triangle"))
    ramp_time: float = param(0.6, unit="s", ge=0)
    reversal_time: float = param(0.25, unit="s", ge=0)
    roll_axis_height: float = param(0.12, unit="m", ge=0)
    roll_kp: float = param(200.0, unit="N m/rad", gt=0)
    roll_kd: float = param(2.0, unit="N m s/rad", ge=0)
    lift_kp: float = param(2.0e4, unit="N/m", gt=0)
    lift_kd: float = param(300.0, unit="N s/m", ge=0)
    time_step: float = param(2e-3, unit="s", gt=0)
    sensor_rate: float = param(24.0, unit="Hz", gt=0)
    taxel_noise: float = param(1e-4, ge=0)
    wrist_noise: float = param(0.05, unit="N", ge=0)
    seed: int = param(0, integer=True)
    gripper: GripperGeometry = param(default_factory=GripperGeometry)

    def __post_init__(self):
        validate_fields(self)
        if self.roll_profile == "sweep" and not (
                0 < self.reversal_time < 0.5 / self.roll_hz):
            raise ValueError(f"LiquidRollConfig: reversal_time: the sweep needs 0 < reversal "
                             f"time < half a roll period ({0.5 / self.roll_hz:g} s), got "
                             f"{self.reversal_time!r}")
        if not self.t_latch <= self.t_lift <= self.t_lift + self.lift_time <= self.t_roll:
            raise ValueError("LiquidRollConfig: expected t_latch <= t_lift <= t_lift + "
                             f"lift_time <= t_roll (s), got {self.t_latch}, {self.t_lift}, "
                             f"{self.t_lift} + {self.lift_time}, {self.t_roll}")
        if self.sensor_rate <= 2 * 5.0:
            raise ValueError(f"LiquidRollConfig: sensor_rate must exceed 10 Hz for the 5 Hz "
                             f"high-pass, got {self.sensor_rate!r}")

    @property
    def roll_duration(self) -> float:
        """Duration of the roll, s (the sweep's start and stop add ``reversal_time``)."""
        extra = self.reversal_time if self.roll_profile == "sweep" else 0.0
        return self.roll_cycles / self.roll_hz + extra

    @property
    def duration(self) -> float:
        """Simulated time, s: the end of the roll plus 0.1 s."""
        return self.t_roll + self.roll_duration + 0.1


def roll_trajectory(c: LiquidRollConfig) -> PiecewisePolynomial:
    """The roll angle (rad) over time for ``c.roll_profile`` (:func:`sine_roll_trajectory`
    or :func:`triangle_roll_trajectory`)."""
    if c.roll_profile == "sine":
        return sine_roll_trajectory(c)
    if c.roll_profile == "sweep":
        return sweep_roll_trajectory(c)
    return triangle_roll_trajectory(c)


def _smoothstep5(u):
    """Quintic smoothstep on [0, 1] and its first two derivatives (0 and 1 at the ends with
    zero first and second derivatives)."""
    u = np.clip(u, 0.0, 1.0)
    return (u**3 * (10 - 15 * u + 6 * u**2), 30 * u**2 * (1 - u)**2,
            60 * u * (1 - u) * (1 - 2 * u))


def sine_roll_angle(c: LiquidRollConfig, t):
    """The smooth roll (rad, rad/s, rad/s^2) at times ``t`` (s): ``A e(t) sin(2 pi f (t -
    t_roll))`` during the roll, 0 outside it, with the envelope ``e`` rising from 0 to 1 over
    the first ``ramp_time`` s and falling back over the last (quintic smoothstep), so angle,
    rate and acceleration are continuous everywhere (a wrist's motion, no jerk impulse)."""
    t = np.asarray(t, float)
    T = c.roll_cycles / c.roll_hz
    tau = t - c.t_roll
    w = 2 * np.pi * c.roll_hz
    r = max(min(c.ramp_time, T / 2), 1e-9)
    a0, a1, a2 = _smoothstep5(tau / r)
    b0, b1, b2 = _smoothstep5((T - tau) / r)
    e, de, dde = a0 * b0, a1 * b0 / r - a0 * b1 / r, (a2 * b0 - 2 * a1 * b1 + a0 * b2) / r**2
    inside = (tau >= 0) & (tau <= T)
    sn, cs = np.sin(w * tau), np.cos(w * tau)
    q = c.roll_amplitude * e * sn
    qd = c.roll_amplitude * (de * sn + e * w * cs)
    qdd = c.roll_amplitude * (dde * sn + 2 * de * w * cs - e * w * w * sn)
    return q * inside, qd * inside, qdd * inside


def sweep_roll_angle(c: LiquidRollConfig, t):
    """The "sweep" roll (rad, rad/s, rad/s^2) at times ``t`` (s): side to side at a constant
    rate ``w`` (rad/s) with smooth reversals: the rate turns from +w to -w as ``w cos(pi s /
    tau)`` over ``tau = reversal_time`` s (acceleration continuous, peak ``pi w / tau``),
    starts from and returns to rest as ``w (1 - cos(pi s / tau)) / 2``; the reversals peak
    at +-``roll_amplitude``, half a roll period apart, so ``w = 2 A / (T / 2 - tau + 2 tau /
    pi)`` with ``T = 1 / roll_hz``. The roll lasts ``roll_cycles T + tau``."""
    t = np.asarray(t, float)
    tau = c.reversal_time
    w, centres, end = _sweep_timing(c)
    n_rev = len(centres)
    s = t - c.t_roll
    rate = sweep_roll_angle_rate(c, s, w=w, centres=centres, end=end)
    acc = np.zeros_like(s)
    if tau > 0:
        for k, tc in enumerate(centres):
            u = s - (tc - tau / 2)
            m = (u >= 0) & (u <= tau)
            acc = np.where(m, -(-1.0) ** k * w * np.pi / tau * np.sin(np.pi * u / tau), acc)
        m = (s >= 0) & (s <= tau)
        acc = np.where(m, w * np.pi / (2 * tau) * np.sin(np.pi * s / tau), acc)
        u = s - (end - tau)
        m = (u >= 0) & (u <= tau)
        acc = np.where(m, -(-1.0) ** n_rev * w * np.pi / (2 * tau) * np.sin(np.pi * u / tau),
                       acc)
    # the angle: the rate integrated (trapezoid) on a 0.2 ms grid
    grid = np.linspace(0.0, end, int(np.ceil(end / 2e-4)) + 1)
    g_rate = sweep_roll_angle_rate(c, grid, w=w, centres=centres, end=end)
    g_q = np.concatenate([[0.0], np.cumsum((g_rate[1:] + g_rate[:-1]) / 2 * np.diff(grid))])
    q = np.interp(s, grid, g_q, left=0.0, right=0.0)
    done = (s < 0) | (s >= end)
    return (np.where(done, 0.0, q), np.where(done, 0.0, rate), np.where(done, 0.0, acc))


def _sweep_timing(c: LiquidRollConfig):
    """The sweep's constant rate ``w`` (rad/s), the centres of its reversals (s after
    ``t_roll``; reversal k turns +-w into -+w) and its end (s after ``t_roll``), see
    :func:`sweep_roll_angle`."""
    T, tau = 1.0 / c.roll_hz, c.reversal_time
    w = 2 * c.roll_amplitude / (T / 2 - tau + 2 * tau / np.pi)
    centres = T / 4 + tau / 2 + np.arange(int(round(2 * c.roll_cycles))) * T / 2
    return w, centres, c.roll_cycles * T + tau


def sweep_roll_angle_rate(c: LiquidRollConfig, s, *, w, centres, end):
    """The sweep's rate (rad/s) at times ``s`` after ``t_roll`` (helper of
    :func:`sweep_roll_angle`)."""
    tau = c.reversal_time
    sign = np.ones_like(s)
    for k, tc in enumerate(centres):
        sign = np.where(s >= tc, (-1.0) ** (k + 1), sign)
    rate = np.where((s >= 0) & (s <= end), sign * w, 0.0)
    if tau <= 0:
        return rate
    for k, tc in enumerate(centres):
        u = s - (tc - tau / 2)
        m = (u >= 0) & (u <= tau)
        rate = np.where(m, (-1.0) ** k * w * np.cos(np.pi * u / tau), rate)
    m = (s >= 0) & (s <= tau)
    rate = np.where(m, w * (1 - np.cos(np.pi * s / tau)) / 2, rate)
    last = (-1.0) ** len(centres)
    u = s - (end - tau)
    m = (u >= 0) & (u <= tau)
    rate = np.where(m, last * w * (1 + np.cos(np.pi * u / tau)) / 2, rate)
    return np.where((s < 0) | (s >= end), 0.0, rate)


def roll_change_windows(c: LiquidRollConfig) -> np.ndarray:
    """Where the commanded roll rate changes, ``(k, 2)`` absolute times (s): the start from
    rest, every reversal and the stop. Outside these (and inside the roll) the wrist turns at
    a constant commanded rate -- the coast phases of
    :func:`mmlearn.models.tactile.liquid.coast_mask`. "sweep": the start and stop ramps and the
    reversals, ``reversal_time`` s each (centred half a roll period apart); "triangle": the
    reversals (``reversal_time`` s, 0 = abrupt: zero-width windows) and the start and stop
    instants; "sine": the rate never stays constant, so a ``ValueError``."""
    if c.roll_profile == "sine":
        raise ValueError("roll_change_windows: the sine roll has no constant-rate phase")
    tau = c.reversal_time
    if c.roll_profile == "sweep":
        _, centres, end = _sweep_timing(c)
        w = [(0.0, tau)] + [(tc - tau / 2, tc + tau / 2) for tc in centres] + [(end - tau, end)]
        return c.t_roll + np.asarray(w, float)
    quarter = 0.25 / c.roll_hz
    n = int(round(4 * c.roll_cycles))
    tau = min(tau, quarter)
    rev = [quarter * (k + 1) for k in range(n) if k % 2 == 0 and k != n - 1]
    w = ([(-tau / 2, tau / 2)] + [(tk - tau / 2, tk + tau / 2) for tk in rev]
         + [(quarter * n, quarter * n)])
    return c.t_roll + np.asarray(w, float)


def _quintic_trajectory(c: LiquidRollConfig, fn, *, knot_dt: float = 0.005
                        ) -> PiecewisePolynomial:
    """The roll ``fn(c, t) -> (q, qd, qdd)`` as a piecewise quintic through knots every
    ``knot_dt`` s (exact angle, rate and acceleration at the knots: continuous
    acceleration)."""
    from pydrake.polynomial import Polynomial

    T = c.roll_duration
    n = max(int(np.ceil(T / knot_dt)), 4)
    ts = np.concatenate([[0.0], c.t_roll + np.linspace(0.0, T, n + 1), [c.duration + 1.0]])
    q, qd, qdd = fn(c, ts)
    polys = []
    for k in range(len(ts) - 1):
        h = ts[k + 1] - ts[k]
        p0, v0, a0 = q[k], qd[k], qdd[k]
        p1, v1, a1 = q[k + 1], qd[k + 1], qdd[k + 1]
        M = np.array([[h**3, h**4, h**5], [3 * h**2, 4 * h**3, 5 * h**4],
                      [6 * h, 12 * h**2, 20 * h**3]])
        rhs = np.array([p1 - p0 - v0 * h - a0 * h**2 / 2, v1 - v0 - a0 * h, a1 - a0])
        c3, c4, c5 = np.linalg.solve(M, rhs)
        polys.append([Polynomial([p0, v0, a0 / 2, c3, c4, c5])])
    return PiecewisePolynomial(polys, list(ts))


def sine_roll_trajectory(c: LiquidRollConfig, *, knot_dt: float = 0.005) -> PiecewisePolynomial:
    """:func:`sine_roll_angle` as a piecewise quintic (continuous acceleration)."""
    return _quintic_trajectory(c, sine_roll_angle, knot_dt=knot_dt)


def sweep_roll_trajectory(c: LiquidRollConfig, *, knot_dt: float = 0.005
                          ) -> PiecewisePolynomial:
    """:func:`sweep_roll_angle` as a piecewise quintic (continuous acceleration)."""
    return _quintic_trajectory(c, sweep_roll_angle, knot_dt=knot_dt)


def triangle_roll_trajectory(c: LiquidRollConfig) -> PiecewisePolynomial:
    """The roll angle (rad) over time: 0 until ``t_roll``, then a triangle wave of
    amplitude ``roll_amplitude`` and frequency ``roll_hz`` (starting towards +angle; constant
    roll rate, each reversal a constant deceleration over ``reversal_time`` s peaking at the
    amplitude, 0: abrupt), back to 0 at the end."""
    quarter = 0.25 / c.roll_hz
    n = int(round(4 * c.roll_cycles))
    tau = min(c.reversal_time, quarter)
    w = c.roll_amplitude / (quarter - tau / 4)  # roll rate between reversals, rad/s
    pattern = (1.0, 0.0, -1.0, 0.0)
    ts, qs, vs = [0.0, c.t_roll], [0.0, 0.0], [0.0, 0.0]
    if tau > 0:  # blend into the first ramp
        ts[-1] = c.t_roll - tau / 2
        ts.append(c.t_roll + tau / 2)
        qs.append(w * tau / 2)
        vs.append(w)
    else:
        vs[-1] = w
    sign = 1.0
    for k in range(n):
        tk = c.t_roll + quarter * (k + 1)
        qk = c.roll_amplitude * pattern[k % 4]
        if pattern[k % 4] == 0.0 or k == n - 1:  # a zero crossing (or the end): keep going
            last = k == n - 1
            ts.append(tk)
            qs.append(qk)
            vs.append(0.0 if last else sign * w)
            continue
        if tau > 0:  # a reversal: parabolic blend over tau
            ts += [tk - tau / 2, tk, tk + tau / 2]
            qs += [qk - sign * w * tau / 4, qk, qk - sign * w * tau / 4]
            vs += [sign * w, 0.0, -sign * w]
        else:
            ts.append(tk)
            qs.append(qk)
            vs.append(0.0)
        sign = -sign
    ts.append(ts[-1] + 1.0)
    qs.append(qs[-1])
    vs.append(0.0)
    if tau > 0:
        return PiecewisePolynomial.CubicHermite(np.array(ts), np.array(qs)[None, :],
                                                np.array(vs)[None, :])
    return PiecewisePolynomial.FirstOrderHold(np.array(ts), np.array(qs)[None, :])


def lift_trajectory(c: LiquidRollConfig, z0: float) -> PiecewisePolynomial:
    """The lift joint's position (m): ``z0`` until ``t_lift``, then a cubic rise by ``lift``
    (zero end velocities) over ``lift_time``."""
    t = np.array([0.0, c.t_lift, c.t_lift + c.lift_time, c.duration + 1.0])
    z = np.array([[z0, z0, z0 + c.lift, z0 + c.lift]])
    return PiecewisePolynomial.CubicShapePreserving(t, z, zero_end_point_derivatives=True)


def _point_contact(mu: float) -> ProximityProperties:
    p = ProximityProperties()
    AddContactMaterial(friction=CoulombFriction(mu, mu), properties=p)
    return p


def MakeLiquidRollDiagram(config: LiquidRollConfig, *, container: ContainerInstance,
                          meshcat=None):
    """Build the scene (see the module docstring); returns (diagram, parts) with parts =
    {"plant", "scene_graph", "sensor", "controller", "hold", "wrist_force_sensor",
    "taxel_log", "force_log", "wrist_log", "roll_log", "gripper", "container"}."""
    c = config
    if not isinstance(container, ContainerInstance):
        raise TypeError(f"container: expected a ContainerInstance, got {type(container).__name__}")
    layout, g = PAD_PR2, c.gripper
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlant(
        MultibodyPlantConfig(time_step=c.time_step, contact_model="hydroelastic_with_fallback",
                             discrete_contact_approximation="sap"),
        SceneGraphConfig(), builder)
    parser = Parser(plant)
    # table
    table = _point_contact(0.6)
    X_table = RigidTransform([0.0, 0.0, -0.01])
    plant.RegisterCollisionGeometry(plant.world_body(), X_table, Box(0.3, 0.3, 0.02), "table",
                                    table)
    plant.RegisterVisualGeometry(plant.world_body(), X_table, Box(0.3, 0.3, 0.02),
                                 "table_visual", np.array([0.6, 0.5, 0.4, 1.0]))
    # container, free, standing on the table
    cont = parser.AddModelsFromString(container_sdf(container), "sdf")[0]
    base = plant.GetBodyByName("base", cont)
    for k, a in enumerate(np.linspace(0.0, 2 * np.pi, 6, endpoint=False)):
        # six small feet on the rim of the bottom (robust point contact with the table)
        plant.RegisterCollisionGeometry(
            base, RigidTransform([0.8 * container.radius * np.cos(a),
                                  0.8 * container.radius * np.sin(a), 0.002]),
            Sphere(0.002), f"foot_{k}", _point_contact(0.8))
    plant.SetDefaultFloatingBaseBodyPose(base, RigidTransform([c.offset, 0.0, 0.0]))
    for side in ("l", "r"):
        plant.AddForceElement(PrismaticSpring(
            plant.GetJointByName(f"wall_{side}_slide", cont), 0.0, container.k))
    if container.slosh_mass > 0:
        plant.AddForceElement(PrismaticSpring(plant.GetJointByName("slosh", cont), 0.0,
                                              container.slosh_k))
    # wrist: world -> lift (prismatic z) -> roll (revolute y) -> palm (weld)
    pad_z = pad_z_of(layout, g)
    z0 = c.grasp_height + c.roll_axis_height
    links = {}
    for name in ("wrist_lift", "wrist_roll"):
        inst = plant.AddModelInstance(name)
        links[name] = plant.AddRigidBody(f"{name}_link", inst,
                                         SpatialInertia.SolidBoxWithMass(0.2, 0.04, 0.04, 0.04))
    lift = plant.AddJoint(PrismaticJoint("lift", plant.world_frame(),
                                         links["wrist_lift"].body_frame(), [0.0, 0.0, 1.0],
                                         -1.0, 1.0, 0.0))
    lift.set_default_translation(z0)
    roll = plant.AddJoint(RevoluteJoint("roll", links["wrist_lift"].body_frame(),
                                        links["wrist_roll"].body_frame(), [0.0, 1.0, 0.0], 0.0))
    for j, kp, kd, eff in ((lift, c.lift_kp, c.lift_kd, 500.0), (roll, c.roll_kp, c.roll_kd,
                                                                   50.0)):
        act = plant.AddJointActuator(f"{j.name()}_motor", j, eff)
        act.set_controller_gains(PdControllerGains(p=kp, d=kd))
    gripper = parser.AddModelsFromString(gripper_sdf(layout, g), "sdf")[0]
    mount = plant.WeldFrames(links["wrist_roll"].body_frame(),
                             plant.GetFrameByName("palm", gripper),
                             RigidTransform([0.0, 0.0, pad_z - c.roll_axis_height]))
    for side in ("left", "right"):
        plant.GetJointActuatorByName(f"{side}_slide", gripper).set_controller_gains(
            PdControllerGains(p=2000.0, d=100.0))
    plant.Finalize()
    sensor = AddTactileSensor(builder, plant, scene_graph, gripper, layout, pad_z,
                              rate_hz=c.sensor_rate, noise=c.taxel_noise, seed=c.seed)
    ctrl = builder.AddNamedSystem("grasp_controller", TactileGraspController(
        f_target=c.f_target, v_target=c.v_target, contact_force=1.0, kp=2000.0, kd=100.0,
        hold_time=1e6, open_gap=g.open_gap, stroke=g.stroke, mode="switching",
        force_rate=40.0, period=c.time_step))
    hold = builder.AddNamedSystem("finger_hold", FingerPositionHold(
        num_fingers=2, t_latch=c.t_latch, period=c.time_step))
    builder.Connect(plant.get_state_output_port(gripper), ctrl.get_gripper_state_input_port())
    builder.Connect(sensor.get_pad_force_output_port(), ctrl.get_pad_force_input_port())
    builder.Connect(ctrl.get_desired_state_output_port(), hold.get_input_port_desired())
    builder.Connect(hold.get_output_port_desired(), plant.get_desired_state_input_port(gripper))
    src_roll = builder.AddNamedSystem("roll_trajectory", TrajectorySource(
        roll_trajectory(c), output_derivative_order=1))
    src_lift = builder.AddNamedSystem("lift_trajectory", TrajectorySource(
        lift_trajectory(c, z0), output_derivative_order=1))
    builder.Connect(src_roll.get_output_port(), plant.get_desired_state_input_port(
        plant.GetModelInstanceByName("wrist_roll")))
    builder.Connect(src_lift.get_output_port(), plant.get_desired_state_input_port(
        plant.GetModelInstanceByName("wrist_lift")))
    wrist = builder.AddNamedSystem("wrist_force_sensor", WristForceSensor(
        plant=plant, mount_joint=mount, sigma_force=c.wrist_noise, rate_hz=c.sensor_rate,
        seed=c.seed))
    builder.Connect(plant.get_reaction_forces_output_port(),
                    wrist.get_reaction_forces_input_port())
    builder.Connect(plant.get_body_poses_output_port(), wrist.get_body_poses_input_port())
    period = 1.0 / c.sensor_rate
    taxel_log = LogVectorOutput(sensor.get_taxels_output_port(), builder, period)
    force_log = LogVectorOutput(sensor.get_pad_force_output_port(), builder, period)
    wrist_log = LogVectorOutput(wrist.get_force_output_port(), builder, period)
    roll_log = LogVectorOutput(plant.get_state_output_port(
        plant.GetModelInstanceByName("wrist_roll")), builder, period)
    if meshcat is not None:
        from pydrake.geometry import MeshcatVisualizer

        MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat)
    diagram = builder.Build()
    return diagram, {"plant": plant, "scene_graph": scene_graph, "sensor": sensor,
                     "controller": ctrl, "hold": hold, "wrist_force_sensor": wrist,
                     "taxel_log": taxel_log, "force_log": force_log, "wrist_log": wrist_log,
                     "roll_log": roll_log, "gripper": gripper, "container": cont}


def simulate_roll(config: LiquidRollConfig, *, container: ContainerInstance,
                  meshcat=None) -> dict:
    """Run one trial; returns the sensor records: ``t`` (s), ``taxels`` (T, 30) normalised
    pressures, ``pad_force`` (T, 2) N, ``wrist_force`` (T, 3) N (world frame, force of the
    held load on the palm), ``roll`` (T,) measured roll angle (rad, the arm's encoder), and
    ``roll_window`` (start, end) s and ``weight_window`` (start, end) s."""
    diagram, parts = MakeLiquidRollDiagram(config, container=container, meshcat=meshcat)
    sim = Simulator(diagram)
    sim.Initialize()
    sim.AdvanceTo(config.duration)
    ctx = sim.get_context()
    logs = [parts[k].FindLog(ctx) for k in ("taxel_log", "force_log", "wrist_log", "roll_log")]
    n = min(lg.num_samples() for lg in logs)
    t = logs[0].sample_times()[:n]
    c = config
    return {"t": t, "taxels": logs[0].data()[:, :n].T, "pad_force": logs[1].data()[:, :n].T,
            "wrist_force": logs[2].data()[:, :n].T, "roll": logs[3].data()[0, :n],
            "roll_window": (c.t_roll, c.t_roll + c.roll_duration),
            "weight_window": (c.t_lift + c.lift_time + 0.1, c.t_roll)}


#: Liquid-detection containers: label -> (class of :mod:`mmlearn.models.tactile.containers`, liquid
#: fill fraction or None for empty). Half full mostly, as in the thesis; the Odwalla bottle
#: also full and empty, the water bottle also a quarter full.
LIQUID_CONTAINERS = {
    "odwalla_half": ("odwalla", 0.5),
    "odwalla_empty": ("odwalla", None),
    "water_half": ("water", 0.5),
    "water_empty": ("water", None),
    "naked_half": ("naked", 0.5),
    "naked_empty": ("naked", None),
    "odwalla_full": ("odwalla", 0.93),
    "can_half": ("can", 0.5),
    "can_empty": ("can", None),
    "water_quarter": ("water", 0.25),
    "naked_quarter": ("naked", 0.25),
}


#: Kinematic viscosity of the liquid in each container class, m^2/s (water and soda 1e-6,
#: orange juice ~2e-6, smoothie ~5e-6 at room temperature).
LIQUID_VISCOSITY = {"odwalla": 2.0e-6, "naked": 5.0e-6, "water": 1.0e-6, "can": 1.0e-6}


def dummy_instance(rng: np.random.Generator, *, mass: float | None = None) -> ContainerInstance:
    """The heavy rigid dummy: an Odwalla-sized rigid cylinder (stiff walls, nothing inside)
    of ``mass`` kg (default: drawn uniformly in 0.2-0.3 kg, about a half-full container)."""
    inst = sample_container("odwalla", "full_closed", rng, fill=0.5)
    if mass is None:
        mass = float(rng.uniform(0.2, 0.3))
    return replace(inst, name="dummy", state="rigid", fill=0.0, mass=float(mass),
                   wall_mass=CONTAINER_CLASSES["odwalla"].wall_mass, slosh_mass=0.0,
                   slosh_k=0.0, slosh_c=0.0)


def make_instance(label: str, rng: np.random.Generator) -> ContainerInstance:
    """A random instance of liquid-detection container ``label`` (a key of
    :data:`LIQUID_CONTAINERS` or "dummy"), closed (cans: open -- they cannot be closed)."""
    if label == "dummy":
        return dummy_instance(rng)
    if label not in LIQUID_CONTAINERS:
        raise ValueError(f"container: unknown {label!r}; choose from "
                         f"{', '.join(list(LIQUID_CONTAINERS) + ['dummy'])}")
    cls, fill = LIQUID_CONTAINERS[label]
    closed = cls != "can"
    state = ("full_" if fill else "empty_") + ("closed" if closed else "open")
    inst = sample_container(cls, state, rng, fill=fill)
    # The squeeze model lumps the liquid's added mass (the column pushed into the neck)
    # into each wall; for rolling, the walls carry only their own mass, so the bodies of the
    # plant add up to the container's true mass (shell + liquid).
    inst = replace(inst, wall_mass=CONTAINER_CLASSES[cls].wall_mass)
    if fill is None:
        return inst
    # the liquid's first sloshing mode with its viscous damping and the cap as a barrier
    # (mmlearn.models.tactile.liquid.first_slosh_mode)
    vol = CONTAINER_CLASSES[cls].volume
    h_eq = vol / (np.pi * inst.radius**2)
    mode = first_slosh_mode(radius=inst.radius, depth=inst.fill * h_eq,
                            liquid_mass=RHO_WATER * inst.fill * vol, container_height=h_eq,
                            viscosity=LIQUID_VISCOSITY[cls])
    return replace(inst, slosh_mass=mode.mass, slosh_k=mode.stiffness, slosh_c=mode.damping,
                   slosh_travel=mode.barrier)
