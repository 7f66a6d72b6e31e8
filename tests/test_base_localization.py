import math

import numpy as np
import pytest

from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import BasicVector, DiagramBuilder, LeafSystem
from pydrake.systems.primitives import ConstantVectorSource

from mmlearn.systems.articulation.base_localization import (BaseLocalization, BaseLocalizationConfig,
                                                            believed_from_true, initial_error)


class _Ramp(LeafSystem):
    """A robot state whose base drives along x at ``speed`` m/s (positions x, y, yaw, q)."""

    def __init__(self, speed):
        super().__init__()
        self._v = speed
        self.DeclareVectorOutputPort("y", BasicVector(8), self._calc)

    def _calc(self, context, out):
        out.SetFromVector([self._v * context.get_time(), 0, 0, 0.3, 0, 0, 0, 0])


def _errors(cfg, times, speed=0.0, frame="map"):
    """The error (x, y, yaw) at the given times, the base standing or driving."""
    b = DiagramBuilder()
    loc = b.AddSystem(BaseLocalization(config=cfg, state_size=8, frame=frame,
                                       base_position_indices=[0, 1, 2], num_commands=4))
    src = b.AddSystem(_Ramp(speed) if speed else ConstantVectorSource(np.r_[1.0, 2.0, 0.5,
                                                                           np.zeros(5)]))
    b.Connect(src.get_output_port(0), loc.get_robot_state_input_port())
    sim = Simulator(b.Build())
    ctx = sim.get_mutable_context()
    lc = loc.GetMyContextFromRoot(ctx)
    loc.get_command_input_port().FixValue(lc, np.zeros(4))
    loc.get_force_input_port().FixValue(lc, np.zeros(3))
    sim.Initialize()
    out = []
    for t in times:
        sim.AdvanceTo(t)
        out.append(loc.error(lc).copy())
    return np.array(out), loc, lc


def test_seeded_reproducible_and_seed_dependent():
    times = np.arange(0.0, 5.01, 0.5)
    a, _, _ = _errors(BaseLocalizationConfig(seed=3), times)
    b, _, _ = _errors(BaseLocalizationConfig(seed=3), times)
    c, _, _ = _errors(BaseLocalizationConfig(seed=4), times)
    np.testing.assert_array_equal(a, b)
    assert np.abs(a - c).max() > 1e-3
    # the initial error is the documented deterministic draw
    np.testing.assert_array_equal(initial_error(BaseLocalizationConfig(seed=3)),
                                  initial_error(BaseLocalizationConfig(seed=3)))


def test_stationary_magnitude_matches_sigma():
    # a short time constant so that 200 s hold many independent samples; the process is
    # the same Ornstein-Uhlenbeck recursion as with the default 30 s
    cfg = BaseLocalizationConfig(time_constant=1.0, seed=1)
    e, _, _ = _errors(cfg, np.arange(1.0, 200.0, 0.5))
    std_xy = e[:, :2].std(axis=0)
    assert np.all((0.8 * cfg.sigma_xy < std_xy) & (std_xy < 1.2 * cfg.sigma_xy)), std_xy
    assert 0.8 * cfg.sigma_yaw < e[:, 2].std() < 1.2 * cfg.sigma_yaw
    # RMS horizontal error of the default: ~0.05 m
    assert math.hypot(cfg.sigma_xy, cfg.sigma_xy) == pytest.approx(0.05, abs=0.001)


def test_the_default_drifts_slowly():
    # over one control period (0.1 s) and over 1 s, the error barely changes (RMS over 8
    # seeds), while over a 30 s trial it changes by about 0.9 sigma
    d01, d1, d30 = [], [], []
    for seed in range(8):
        e, _, _ = _errors(BaseLocalizationConfig(seed=seed), [1.0, 1.1, 2.0, 31.0])
        d01.append(e[1, :2] - e[0, :2])
        d1.append(e[2, :2] - e[0, :2])
        d30.append(e[3, :2] - e[0, :2])
    rms = [float(np.sqrt(np.mean(np.square(d)))) for d in (d01, d1, d30)]
    sigma = BaseLocalizationConfig().sigma_xy
    assert rms[0] < 0.15 * sigma and rms[1] < 0.4 * sigma, rms
    assert 0.4 * sigma < rms[2] < 2.0 * sigma, rms


def test_odometry_error_grows_only_while_the_base_moves():
    cfg = BaseLocalizationConfig(sigma_xy=0.0, sigma_yaw=0.0, seed=2)
    standing, _, _ = _errors(cfg, [5.0])
    np.testing.assert_array_equal(standing, 0.0)
    ends = np.array([_errors(BaseLocalizationConfig(sigma_xy=0.0, sigma_yaw=0.0, seed=s,
                                                    time_constant=1e6), [2.0, 4.0],
                             speed=0.5)[0] for s in range(12)])
    # 2 m driven straight ahead: a scale error of std 0.03 m/m along the heading, so the
    # error is 2 x 0.03 m RMS along x, none across and in yaw, and it grows with distance
    rms = float(np.sqrt(np.mean(ends[:, 1, 0] ** 2)))
    assert 0.03 < rms < 0.1, rms
    np.testing.assert_allclose(ends[:, 1, 0], 2.0 * ends[:, 0, 0], rtol=0.03)
    np.testing.assert_allclose(ends[:, :, 1:], 0.0, atol=1e-12)


def test_odometry_frame_drifts_only_with_the_base_motion():
    cfg = BaseLocalizationConfig(seed=6)
    # standing: the localisation drifts, the dead reckoning keeps its initial error
    e, loc, lc = _errors(cfg, [0.0, 20.0], frame="odometry")
    np.testing.assert_allclose(loc.odometry_error(lc), initial_error(cfg), atol=1e-15)
    assert np.linalg.norm(loc.error(lc)[:2] - initial_error(cfg)[:2]) > 1e-3
    np.testing.assert_allclose(loc.get_error_output_port().Eval(lc), initial_error(cfg))
    np.testing.assert_allclose(loc.get_believed_robot_state_output_port().Eval(lc)[:3],
                               np.r_[1.0, 2.0, 0.5] + initial_error(cfg))
    # driving 2 m straight ahead: the odometry's scale error along the heading, never
    # pulled back (a time constant that pulls the map frame's part back within seconds)
    quick = BaseLocalizationConfig(sigma_xy=0.0, sigma_yaw=0.0, seed=2, time_constant=0.5)
    _, loc, lc = _errors(quick, [4.0], speed=0.5, frame="odometry")
    odo = loc.odometry_error(lc)
    assert abs(odo[0]) > 0.01 and abs(loc.error(lc)[0]) < 0.2 * abs(odo[0])
    with pytest.raises(ValueError, match="frame"):
        BaseLocalization(state_size=8, base_position_indices=[0, 1, 2], num_commands=4,
                         frame="world")


def test_ports_apply_the_error_consistently():
    e_traj, loc, lc = _errors(BaseLocalizationConfig(seed=5), [2.0])
    e = e_traj[0]
    x_true = np.r_[1.0, 2.0, 0.5, np.zeros(5)]
    np.testing.assert_allclose(loc.get_believed_robot_state_output_port().Eval(lc),
                               x_true + np.r_[e, np.zeros(5)])
    loc.get_command_input_port().FixValue(lc, np.array([1.0, 2.0, 0.5, 0.7]))
    np.testing.assert_allclose(loc.get_plant_command_output_port().Eval(lc),
                               [1.0 - e[0], 2.0 - e[1], 0.5 - e[2], 0.7])
    loc.get_force_input_port().FixValue(lc, np.array([1.0, 0.0, 2.0]))
    np.testing.assert_allclose(loc.get_believed_force_output_port().Eval(lc),
                               [math.cos(e[2]), math.sin(e[2]), 2.0])
    np.testing.assert_allclose(loc.get_error_output_port().Eval(lc), e)
    # a point keeps its pose relative to the base
    p = believed_from_true([2.0, 2.0, 1.0], [1.0, 2.0, 0.5], e)
    b_hat = np.array([1.0 + e[0], 2.0 + e[1], 0.0])
    assert np.linalg.norm(p[:2] - b_hat[:2]) == pytest.approx(1.0)
    assert p[2] == 1.0


def test_zero_scale_is_exact_and_bad_config_rejected():
    cfg = BaseLocalizationConfig(seed=1).scaled(0.0)
    assert cfg.exact
    e, _, _ = _errors(cfg, [0.0, 3.0])
    np.testing.assert_array_equal(e, 0.0)
    with pytest.raises(ValueError, match="sigma_xy"):
        BaseLocalizationConfig(sigma_xy=-1.0).validate()
    with pytest.raises(ValueError, match="scale"):
        BaseLocalizationConfig().scaled(-1)
    with pytest.raises(ValueError, match="base_position_indices"):
        BaseLocalization(state_size=4, base_position_indices=[0, 1], num_commands=3)


def test_operate_diagram_sees_the_hook_in_the_believed_frame():
    """The hook position the estimator gets is the true one moved with the base error."""
    from mmlearn.diagrams.articulation.operate import MakeOperateDiagram, OperateConfig
    from mmlearn.systems.articulation.epc_controller import P_HOOK_GRIP

    op = MakeOperateDiagram(OperateConfig(kind="left_door", seed=4, base_noise=3.0))
    sim = Simulator(op.diagram)
    ctx = sim.get_mutable_context()
    op.scene.set_joint_positions(ctx, op.start_command)
    sim.Initialize()
    sim.AdvanceTo(0.5)
    plant = op.scene.plant
    pc = plant.GetMyContextFromRoot(ctx)
    e = op.diagram.GetOutputPort("base_error").Eval(ctx)
    assert np.linalg.norm(e[:2]) > 1e-3
    X = plant.CalcRelativeTransform(pc, plant.world_frame(),
                                    plant.GetBodyByName("hook", op.scene.robot).body_frame())
    G_true = X @ P_HOOK_GRIP
    xb = [plant.GetJointByName(n, op.scene.robot).GetOnePosition(pc)
          for n in ("base_x", "base_y", "base_yaw")]
    ctrl = op.controller
    G_believed = ctrl.measured_grip_pose(ctrl.GetMyContextFromRoot(ctx)).translation()
    np.testing.assert_allclose(G_believed, believed_from_true(G_true, xb, e), atol=1e-9)
    # the task the robot is told is the true one seen through its belief at time 0
    assert np.linalg.norm(op.task.handle - op.true_task.handle) > 1e-3


def _update_reference(loc, cfg, x, base):
    """One update of the documented recursion in numpy arrays: the error's AR(1) step, the
    odometry's scale errors on the base's motion since the last update."""
    x = np.array(x, float)
    k = int(x[9]) + 1
    w = np.random.default_rng([cfg.seed, k]).normal(size=3)
    prev = x[6:9].copy()
    d = base[:2] - prev[:2]
    turn = math.remainder(float(base[2] - prev[2]), 2 * math.pi)
    c, s = math.cos(base[2]), math.sin(base[2])
    along, across = c * d[0] + s * d[1], -s * d[0] + c * d[1]
    odo_scale = loc._odo
    ea, ec = odo_scale[0] * along, odo_scale[1] * across
    odo = np.array([c * ea - s * ec, s * ea + c * ec, odo_scale[2] * turn])
    x[0:3] = loc._a * x[0:3] + loc._b * w
    x[3:6] = loc._a * x[3:6] + odo
    x[10:13] = x[10:13] + odo
    x[6:9] = base
    x[9] = k
    return x


def test_the_update_is_the_recursion_to_the_last_bit():
    """The periodic update (scalar arithmetic) gives the array recursion's floats exactly,
    on a base that drives and turns."""
    cfg = BaseLocalizationConfig(seed=5).scaled(2.0)
    loc = BaseLocalization(config=cfg, state_size=8, base_position_indices=[0, 1, 2],
                           num_commands=4)
    ctx = loc.CreateDefaultContext()
    loc.get_command_input_port().FixValue(ctx, np.zeros(4))
    loc.get_force_input_port().FixValue(ctx, np.zeros(3))
    rng = np.random.default_rng(0)
    base = np.array([1.0, 2.0, 3.1])
    x = ctx.get_discrete_state(0).value().copy()
    for i in range(30):
        base = base + rng.normal(0.0, 0.05, 3)  # the yaw wraps past pi
        loc.get_robot_state_input_port().FixValue(ctx, np.r_[base, np.zeros(5)])
        ctx.SetTime(0.05 * (i + 1))
        x_new = loc.EvalUniquePeriodicDiscreteUpdate(ctx).get_vector(0).value()
        np.testing.assert_array_equal(x_new, _update_reference(loc, cfg, x, base))
        ctx.SetDiscreteState(0, x_new)
        x = x_new.copy()
    assert abs(x[12]) > 0 and x[9] == 30
