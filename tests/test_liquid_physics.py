"""Liquid detection physics (thesis Sec. 7.3): the smooth wrist roll and the sloshing model."""

import numpy as np
import pytest

from mmlearn.diagrams.tactile.liquid_roll import (LiquidRollConfig, make_instance, roll_trajectory,
                                                  sine_roll_angle)
from mmlearn.models.tactile.liquid import first_slosh_mode


def test_sine_roll_is_smooth_and_matches_its_trajectory():
    c = LiquidRollConfig(roll_profile="sine")
    t = np.arange(0.0, c.duration, 1e-3)
    q, qd, qdd = sine_roll_angle(c, t)
    assert np.abs(q).max() == pytest.approx(c.roll_amplitude, rel=1e-3)
    assert np.all(q[t < c.t_roll] == 0) and np.all(q[t > c.t_roll + 2 / c.roll_hz] == 0)
    # continuous angle, rate and acceleration: no step anywhere (the triangle's reversals
    # flip the rate by 2 * 3.4 rad/s within one step)
    for x in (q, qd, qdd):
        assert np.abs(np.diff(x)).max() < 0.05 * max(np.abs(x).max(), 1.0)
    # the rate and acceleration are the angle's derivatives
    np.testing.assert_allclose(np.gradient(q, t)[5:-5], qd[5:-5], atol=2e-3)
    np.testing.assert_allclose(np.gradient(qd, t)[5:-5], qdd[5:-5], atol=0.05)
    tr = roll_trajectory(c)
    ts = t[::37]
    np.testing.assert_allclose([tr.value(x)[0, 0] for x in ts], q[::37], atol=1e-6)
    np.testing.assert_allclose([tr.EvalDerivative(x, 1)[0, 0] for x in ts], qd[::37],
                               atol=1e-3)
    tri = roll_trajectory(LiquidRollConfig(roll_profile="triangle", reversal_time=0.0))
    rate = np.array([tri.EvalDerivative(x, 1)[0, 0] for x in t])
    assert np.abs(np.diff(rate)).max() > 1.0  # the old profile: abrupt reversals
    with pytest.raises(ValueError, match="roll_profile"):
        LiquidRollConfig(roll_profile="square")


def test_first_slosh_mode_numbers():
    # half-full Odwalla-like cylinder: R = 36 mm, 450 ml
    R, V = 0.036, 0.45e-3
    H = V / (np.pi * R**2)
    half = first_slosh_mode(radius=R, depth=H / 2, liquid_mass=1000 * V / 2,
                            container_height=H)
    w2 = 9.81 * 1.841 / R * np.tanh(1.841 * H / 2 / R)
    assert half.omega == pytest.approx(np.sqrt(w2))
    assert half.omega / (2 * np.pi) == pytest.approx(3.55, abs=0.01)
    assert half.mass / (1000 * V / 2) == pytest.approx(0.294, abs=0.002)
    assert half.zeta == pytest.approx(0.0056, abs=3e-4)  # water, boundary-layer damping
    assert half.stiffness == pytest.approx(half.mass * half.omega**2)
    assert half.damping == pytest.approx(2 * half.zeta * half.mass * half.omega)
    assert half.length == pytest.approx(9.81 / half.omega**2)
    # a 0.7 rad tilt moves the pendulum by L1 sin(0.7): inside the barrier when half full,
    # beyond it when nearly full (the liquid hits the cap)
    full = first_slosh_mode(radius=R, depth=0.93 * H, liquid_mass=930 * V,
                            container_height=H)
    assert half.length * np.sin(0.7) < half.barrier
    assert full.length * np.sin(0.7) > full.barrier
    assert full.mass < half.mass * 1.1  # the nearly full liquid mostly moves as a body
    thick = first_slosh_mode(radius=R, depth=H / 2, liquid_mass=0.225, container_height=H,
                             viscosity=4e-6)
    assert thick.zeta == pytest.approx(2 * half.zeta)  # zeta ~ sqrt(viscosity)
    for kw in ({"depth": 0.0}, {"depth": H}, {"viscosity": float("nan")}):
        args = dict(radius=R, depth=H / 2, liquid_mass=0.2, container_height=H) | kw
        with pytest.raises(ValueError):
            first_slosh_mode(**args)


def test_instances_use_the_slosh_mode():
    inst = make_instance("odwalla_half", np.random.default_rng(0))
    assert np.sqrt(inst.slosh_k / inst.slosh_mass) / (2 * np.pi) == pytest.approx(3.55,
                                                                                  abs=0.05)
    assert 0 < inst.slosh_travel <= inst.radius
    assert make_instance("dummy", np.random.default_rng(0)).slosh_mass == 0
    assert make_instance("odwalla_empty", np.random.default_rng(0)).slosh_mass == 0


@pytest.mark.parametrize("tau", [0.1, 0.25])
def test_sweep_roll_reaches_the_amplitude_with_continuous_acceleration(tau):
    from mmlearn.diagrams.tactile.liquid_roll import sweep_roll_angle

    c = LiquidRollConfig(roll_profile="sweep", reversal_time=tau)
    t = np.arange(0.0, c.duration, 5e-4)
    q, qd, qdd = sweep_roll_angle(c, t)
    assert q.max() == pytest.approx(c.roll_amplitude, abs=1e-4)
    assert q.min() == pytest.approx(-c.roll_amplitude, abs=1e-4)
    assert abs(q[-1]) < 1e-9 and abs(q[t > c.t_roll + c.roll_duration - 1e-3]).max() < 1e-4
    w = 2 * c.roll_amplitude / (1 / c.roll_hz / 2 - tau + 2 * tau / np.pi)
    assert np.abs(qd).max() == pytest.approx(w, rel=1e-6)
    assert np.abs(qdd).max() == pytest.approx(np.pi * w / tau, rel=1e-3)
    # continuous: the largest step between 0.5 ms samples is one jerk-limited increment
    assert np.abs(np.diff(qdd)).max() < np.pi**2 * w / tau**2 * 5e-4 * 1.01
    np.testing.assert_allclose(np.gradient(q, t)[3:-3], qd[3:-3], atol=2e-3)
    # (central differences across a jump of the jerk err by up to one jerk x step)
    np.testing.assert_allclose(np.gradient(qd, t)[3:-3], qdd[3:-3],
                               atol=np.pi**2 * w / tau**2 * 5e-4)
    tr = roll_trajectory(c)
    np.testing.assert_allclose([tr.value(x)[0, 0] for x in t[::97]], q[::97], atol=1e-6)
    with pytest.raises(ValueError, match="reversal_time"):
        LiquidRollConfig(roll_profile="sweep", reversal_time=0.0)


def _roll_run(label, **cfg):
    """One simulated roll at seed 4: (times in the roll window, s; taxels there; config)."""
    from mmlearn.diagrams.tactile.liquid_roll import simulate_roll

    inst = make_instance(label, np.random.default_rng([4, 17]))
    c = LiquidRollConfig(grasp_height=inst.height / 2, seed=4, **cfg)
    r = simulate_roll(c, container=inst)
    m = (r["t"] >= r["roll_window"][0]) & (r["t"] <= r["roll_window"][1])
    return r["t"][m], r["taxels"][m], c


def _roll(label, **cfg):
    return _roll_run(label, **cfg)[1]


@pytest.fixture(scope="module")
def sweep_runs():
    """The default roll (sweep, 0.25 s reversals) of three containers at one seed."""
    return {k: _roll_run(k) for k in ("dummy", "odwalla_half", "odwalla_empty")}


@pytest.fixture(scope="module")
def sweeps(sweep_runs):
    return {k: v[1] for k, v in sweep_runs.items()}


@pytest.mark.slow
def test_abrupt_reversals_made_the_rigid_dummy_respond(sweeps):
    """The earlier roll (constant rate, reversals within one PD response) jerks the held
    rigid dummy: its high-passed taxels spike at every reversal. The smooth sweep (0.25 s
    reversals, continuous acceleration) removes most of that response."""
    from mmlearn.models.tactile.liquid import liquid_feature

    abrupt = liquid_feature(_roll("dummy", roll_profile="triangle", reversal_time=0.0))
    smooth = liquid_feature(sweeps["dummy"])
    assert smooth < 0.25 * abrupt, (smooth, abrupt)


def _slosh_band_power(taxels, lo=3.0, hi=4.2):
    """Power of the pad-load difference (left - right taxel sums) in ``lo``-``hi`` Hz, around
    the first sloshing mode (3.5 Hz)."""
    from scipy import signal

    d = taxels[:, :15].sum(1) - taxels[:, 15:].sum(1)
    f, p = signal.periodogram(d - d.mean(), fs=24.0)
    return float(p[(f >= lo) & (f <= hi)].sum())


@pytest.mark.slow
def test_the_liquid_rings_at_its_sloshing_mode(sweeps):
    """Each reversal of the sweep excites the liquid's first sloshing mode: the load on the
    pads oscillates near 3.5 Hz between the reversals. Neither the rigid dummy nor the empty
    bottle has such a mode (measured on seeds 12-13: liquids >= 4.9e-5, dummy <= 3.4e-5,
    empties <= 4.6e-6)."""
    b = {k: _slosh_band_power(v) for k, v in sweeps.items()}
    assert b["odwalla_half"] > 2 * b["dummy"], b
    assert b["odwalla_half"] > 10 * b["odwalla_empty"], b


def test_roll_change_windows_are_where_the_commanded_rate_changes():
    from mmlearn.diagrams.tactile.liquid_roll import roll_change_windows, sweep_roll_angle

    for cycles in (1.0, 2.0):
        c = LiquidRollConfig(roll_cycles=cycles)
        w = roll_change_windows(c)
        assert w.shape == (int(2 * cycles) + 2, 2)
        t = np.linspace(c.t_roll - 0.1, c.t_roll + c.roll_duration + 0.1, 40001)
        _, qd, qdd = sweep_roll_angle(c, t)
        busy = ((t[:, None] >= w[None, :, 0]) & (t[:, None] <= w[None, :, 1])).any(axis=1)
        roll = (t > c.t_roll) & (t < c.t_roll + c.roll_duration)
        # outside the windows the commanded rate is constant (+-w), inside it changes
        assert np.all(qdd[~busy] == 0.0)
        assert np.mean(np.abs(qdd[busy & roll]) > 0) > 0.99  # 0 only at the windows' edges
        np.testing.assert_allclose(np.abs(qd[roll & ~busy]), np.abs(qd[roll & ~busy]).max())
    with pytest.raises(ValueError, match="sine"):
        roll_change_windows(LiquidRollConfig(roll_profile="sine"))


@pytest.mark.slow
def test_coast_feature_rigid_dummy_well_below_liquid(sweep_runs):
    """The robot knows its roll command: over the coast phases (constant commanded roll
    rate, from ``COAST_DELAY`` s after each reversal) the rigid dummy's and the empty
    bottle's high-passed taxel norm follows a slow trend (gravity shifting the load between
    the pads), while the half-full bottle's liquid keeps ringing about it. (Over the whole
    roll the dummy's rigid response during the reversals is as large as the liquid's: see
    docs/tactile.md, deviations.)"""
    from mmlearn.models.tactile.evaluation import COAST_DELAY
    from mmlearn.diagrams.tactile.liquid_roll import roll_change_windows
    from mmlearn.models.tactile.liquid import coast_feature, coast_mask

    f = {}
    for k, (t, x, c) in sweep_runs.items():
        m = coast_mask(t, roll_change_windows(c), start=c.t_roll,
                       end=c.t_roll + c.roll_duration, delay=COAST_DELAY)
        assert 30 < m.sum() < len(t)
        f[k] = coast_feature(x, m)
    assert f["dummy"] < 0.25 * f["odwalla_half"], f  # seed 4: 0.00012 vs 0.00096
    assert f["odwalla_empty"] < 0.25 * f["odwalla_half"], f  # 0.00009
