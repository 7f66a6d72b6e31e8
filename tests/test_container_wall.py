"""The squeeze-volume wall model of the ch. 7 containers (models/tactile/containers.py) and its Drake
system (systems/tactile/container_wall.py)."""

import dataclasses

import numpy as np
import pytest

from mmlearn.models.tactile.containers import (P0, RHO_WATER, G, sample_container, squeeze_pressure,
                                               squeeze_volume, wall_forces)


def test_ovalisation_volume_and_its_derivative():
    d = np.array([0.0, 0.01, 0.02, -0.003])
    dV, dVd = squeeze_volume(d, squeeze_length=0.1)
    # ellipse of semi-axes R - d/2, R + d/2 over L: area lost pi d^2 / 4
    assert np.allclose(dV, [0.0, np.pi * 0.1 * 1e-4 / 4, np.pi * 0.1 * 4e-4 / 4, 0.0])
    h = 1e-7
    num = (squeeze_volume(0.012 + h, squeeze_length=0.1)[0]
           - squeeze_volume(0.012 - h, squeeze_length=0.1)[0]) / (2 * h)
    assert np.isclose(squeeze_volume(0.012, squeeze_length=0.1)[1], num, rtol=1e-6)


def test_boyle_value_at_a_known_squeeze():
    # 50 ml of gas, rigid rest of the shell, 10 ml squeezed out: p = p0 * 50 / 40
    L = 0.1
    d = np.sqrt(4 * 10e-6 / (np.pi * L))
    dp = squeeze_pressure(d, closed=True, full=True, gas_volume=50e-6, shell_compliance=0.0,
                          squeeze_length=L)
    assert np.isclose(dp, P0 * 0.25, rtol=1e-9)
    # a bulging shell: the root satisfies p0 Vg = (p0 + dp)(Vg - dV + C dp) and is lower
    C = 2e-9
    dpc = squeeze_pressure(d, closed=True, full=True, gas_volume=50e-6, shell_compliance=C,
                           squeeze_length=L)
    assert 0 < dpc < dp
    assert np.isclose((P0 + dpc) * (50e-6 - 10e-6 + C * dpc), P0 * 50e-6, rtol=1e-9)
    # open: the liquid's head in the neck, or nothing
    assert np.isclose(squeeze_pressure(d, closed=False, full=True, gas_volume=50e-6,
                                       shell_compliance=C, squeeze_length=L, neck_area=4e-4),
                      RHO_WATER * G * 10e-6 / 4e-4)
    # ... until the headspace is full and the liquid spills over the rim
    assert np.isclose(squeeze_pressure(d, closed=False, full=True, gas_volume=5e-6,
                                       shell_compliance=C, squeeze_length=L, neck_area=4e-4),
                      RHO_WATER * G * 5e-6 / 4e-4)
    assert squeeze_pressure(d, closed=False, full=False, gas_volume=1.0, shell_compliance=C,
                            squeeze_length=L) == 0.0


def _static_curve(inst, forces):
    """Inward travel of each wall (m) at which shell + content balance a finger force (N)."""
    from scipy.optimize import brentq

    def net(x, F):
        return inst.k_parts["shell"] * x - wall_forces(inst, [x, x], [0.0, 0.0])[0] - F
    return np.array([brentq(net, 0.0, 0.05, args=(F,)) for F in forces])


def test_closed_container_stiffens_open_one_does_not():
    rng = np.random.default_rng(0)
    F = np.array([5.0, 10.0, 15.0, 20.0, 25.0])
    insts = {s: sample_container("odwalla", s, rng) for s in
             ("full_closed", "empty_closed", "empty_open")}
    x = {s: _static_curve(i, F) for s, i in insts.items()}
    k_inc = {s: np.diff(F) / np.diff(v) for s, v in x.items()}  # incremental stiffness N/m
    # the open empty bottle is its shell: linear
    assert np.allclose(k_inc["empty_open"], insts["empty_open"].k_parts["shell"], rtol=1e-6)
    for s in ("full_closed", "empty_closed"):
        assert np.all(np.diff(k_inc[s]) > 0), s                       # stiffening
        assert k_inc[s][-1] > 1.3 * insts[s].k_parts["shell"], s
    # the content separates the states more at a harder probe (thesis Table 7.2)
    gap = x["empty_open"] - x["empty_closed"]
    assert np.all(np.diff(gap) > 0) and np.all(np.diff(gap / F) > 0)
    assert np.all(x["full_closed"] < x["empty_closed"])


def test_liquid_resists_the_volume_flow_only_when_full():
    rng = np.random.default_rng(1)
    full = sample_container("odwalla", "full_open", rng)
    empty = sample_container("odwalla", "empty_open", rng)
    q = np.array([[0.006, 0.006], [0.0, 0.0]])
    v = np.full((2, 2), 0.01)
    tf = wall_forces(full, q, v) - wall_forces(full, q, np.zeros_like(v))
    assert np.all(tf[0] < 0) and np.allclose(tf[1], 0.0)  # no flow lever at d = 0
    assert np.allclose(wall_forces(empty, q, v), 0.0)
    # at the lever dV' = A the flow damping is the linearised c_liq
    A = full.squeeze_length * np.pi * 0.012 / 2
    assert np.isclose(-tf[0, 0] / (2 * 0.01),
                      full.liquid_resistance * A**2, rtol=1e-9)


def test_bad_inputs_are_named():
    inst = sample_container("odwalla", "empty_closed", np.random.default_rng(2))
    with pytest.raises(ValueError, match="shape"):
        wall_forces(inst, np.zeros(3), np.zeros(3))
    with pytest.raises(ValueError, match="squeeze_length"):
        squeeze_volume(0.01, squeeze_length=0.0)
    with pytest.raises(ValueError, match="gas_volume"):
        squeeze_pressure(0.01, closed=True, full=False, gas_volume=-1.0,
                         shell_compliance=0.0, squeeze_length=0.1)
    with pytest.raises(ValueError, match="shell_compliance"):
        squeeze_pressure(0.01, closed=True, full=False, gas_volume=1e-4,
                         shell_compliance=float("nan"), squeeze_length=0.1)
    with pytest.raises(ValueError, match="squeeze_length"):
        wall_forces(dataclasses.replace(inst, squeeze_length=-1.0), np.zeros(2), np.zeros(2))
    # the gas squeezed out of a rigid closed shell has no finite pressure: inf, not NaN
    assert np.isinf(squeeze_pressure(1.0, closed=True, full=True, gas_volume=1e-6,
                                     shell_compliance=0.0, squeeze_length=0.1))


def test_system_puts_the_model_forces_on_the_wall_joints():
    from mmlearn.diagrams.tactile.grasp import MakeTactileGraspDiagram, TactileGraspConfig
    from mmlearn.systems.tactile.container_wall import ContainerWallForce

    inst = sample_container("odwalla", "full_closed", np.random.default_rng(3))
    d, parts = MakeTactileGraspDiagram(TactileGraspConfig(), container=inst)
    plant, sys_ = parts["plant"], parts["container_wall_force"]
    ctx = d.CreateDefaultContext()
    pc = plant.GetMyMutableContextFromRoot(ctx)
    joints = [plant.GetJointByName(f"wall_{s}_slide", parts["container"]) for s in "lr"]
    joints[0].set_translation(pc, 0.007)
    joints[1].set_translation(pc, 0.005)
    joints[0].set_translation_rate(pc, 0.01)
    tau = sys_.get_generalized_force_output_port().Eval(sys_.GetMyContextFromRoot(ctx))
    want = wall_forces(inst, [0.007, 0.005], [0.01, 0.0])
    iv = [j.velocity_start() for j in joints]
    assert np.allclose(tau[iv], want) and want[0] < -1.0
    assert np.count_nonzero(tau) == 2
    with pytest.raises(ValueError, match="indices"):
        ContainerWallForce(container=inst, num_positions=3, num_velocities=3, q_index=[0, 5],
                           v_index=[0, 1])
    with pytest.raises(TypeError, match="ContainerInstance"):
        ContainerWallForce(container="odwalla", num_positions=3, num_velocities=3,
                           q_index=[0, 1], v_index=[0, 1])
    with pytest.raises(ValueError, match="wall_model"):
        MakeTactileGraspDiagram(TactileGraspConfig(wall_model="gas"), container=inst)
    # the linear model has no such system
    _, parts = MakeTactileGraspDiagram(TactileGraspConfig(wall_model="linear"), container=inst)
    assert parts["container_wall_force"] is None


@pytest.mark.slow
def test_simulated_grasp_closed_full_resists_open_empty_yields():
    """Two grasps at 20 N: the squeeze the fingers make (p_first - p_steady) of a closed full
    bottle is well below that of an open empty one, and the grasp settles (no SAP blow-up)."""
    from mmlearn.diagrams.tactile.trials import container_grasp_trial
    from mmlearn.models.tactile.evaluation import grasp_from_record
    from mmlearn.models.tactile.state import extract_grasp_features

    squeeze = {}
    for st in ("full_closed", "empty_open"):
        g = grasp_from_record(container_grasp_trial(seed=1, container="odwalla", state=st,
                                                    grasp_variation="none"))
        ft = extract_grasp_features(g, contact_force=1.0, rest_velocity=0.002)
        assert ft.contact and ft.steady
        p_first, p_steady, f_steady = ft.values[:3]
        squeeze[st] = p_first - p_steady
        # both fingers at 20 N when the fingers come to rest
        assert np.all(np.isfinite(g.p)) and abs(f_steady - 40.0) < 3.0, ft.values
    assert squeeze["full_closed"] < 0.6 * squeeze["empty_open"]
    assert 0.004 < squeeze["full_closed"] and squeeze["empty_open"] < 0.03


def _sim_specs(*args):
    from mmlearn.apps.common.sweep import TrialSpec
    from mmlearn.diagrams.tactile.trials import container_grasp_plan

    return [TrialSpec(**d) for d in container_grasp_plan(*args)]


def test_grasp_plan_names_the_wall_model_and_the_variation_and_defaults_are_the_apps():
    """Every grasp spec names its wall model and grasp variation (so results of different
    models never share a key), and the trial function's and the plan's defaults are the
    app's."""
    import inspect

    from mmlearn.apps.tactile_state import TactileStateConfig
    from mmlearn.diagrams.tactile.trials import container_grasp_plan, container_grasp_trial

    pres = _sim_specs(["odwalla"], 20.0, 2, 5, "pressure")
    lin = _sim_specs(["odwalla"], 20.0, 2, 5, "linear")
    assert all(p.params["wall_model"] == "pressure" for p in pres)
    assert all(s.params["wall_model"] == "linear" for s in lin)
    assert not {p.key for p in pres} & {s.key for s in lin}
    app = TactileStateConfig()
    for fn in (container_grasp_trial, container_grasp_plan):
        ps = inspect.signature(fn).parameters
        assert ps["wall_model"].default == app.wall_model == "pressure"
        assert ps["grasp_variation"].default == app.grasp_variation == "wall"
    assert [s.key for s in _sim_specs(["odwalla"], 20.0, 2, 5)] == \
        [s.key for s in _sim_specs(["odwalla"], 20.0, 2, 5, "pressure", "wall")]


def test_grasp_variation_draws_the_shell_per_grasp_with_the_measured_spread():
    from mmlearn.models.tactile.containers import (CONTAINER_CLASSES, ICUB_SPREAD_CAN,
                                                   ICUB_SPREAD_PLASTIC_BOTTLE, vary_grasp)

    inst = sample_container("odwalla", "full_closed", np.random.default_rng(4))
    a = vary_grasp(inst, np.random.default_rng([7, 29]), mode="shell")
    b = vary_grasp(inst, np.random.default_rng([7, 29]), mode="shell")
    c = vary_grasp(inst, np.random.default_rng([8, 29]), mode="shell")
    assert a == b and a.grasp_factor != c.grasp_factor       # seeded, one draw per grasp
    # only the shell changes: k follows it, the content and the labels stay
    m = a.grasp_factor
    assert np.isclose(a.k_parts["shell"], m * inst.k_parts["shell"])
    assert np.isclose(a.k, inst.k + (m - 1) * inst.k_parts["shell"])
    for key in ("gas", "hydrostatic"):
        assert a.k_parts[key] == inst.k_parts[key]
    assert (a.name, a.state, a.gas_volume, a.fill, a.liquid_resistance) == \
        (inst.name, inst.state, inst.gas_volume, inst.fill, inst.liquid_resistance)
    assert np.allclose(wall_forces(a, [0.004, 0.005], [0.01, 0.0]),
                       wall_forces(inst, [0.004, 0.005], [0.01, 0.0]))
    # the log-normal spread is the class' measured one (plastic bottles / can)
    rng = np.random.default_rng(5)
    for name, want in (("odwalla", ICUB_SPREAD_PLASTIC_BOTTLE), ("can", ICUB_SPREAD_CAN)):
        i0 = sample_container(name, "empty_open", rng)
        logs = np.log([vary_grasp(i0, rng).grasp_factor for _ in range(3000)])
        assert CONTAINER_CLASSES[name].grasp_spread == want
        assert abs(logs.std() - want) < 0.06 * want and abs(logs.mean()) < 0.02
    # "none": the instance as drawn, nothing drawn from the stream
    r = np.random.default_rng(9)
    assert vary_grasp(inst, r, mode="none") is inst
    assert r.normal() == np.random.default_rng(9).normal()


def test_wall_variation_scales_the_whole_static_response():
    """"wall": one factor m on the shell and, through sqrt(m) on the ovalised length, on the
    content's force: exactly for an open full bottle's head and the flow, to first order for
    the gas law; the squeeze at a given force then scales by ~1/m in every state."""
    from mmlearn.models.tactile.containers import vary_grasp

    rng = np.random.default_rng(11)
    inst = sample_container("odwalla", "full_open", rng)
    w = vary_grasp(inst, np.random.default_rng([3, 29]))          # the default mode
    m = w.grasp_factor
    assert m != 1.0 and np.isclose(w.squeeze_length, inst.squeeze_length * np.sqrt(m))
    assert np.isclose(w.k, m * inst.k) and np.isclose(w.k_parts["shell"],
                                                      m * inst.k_parts["shell"])
    q, v = np.array([0.003, 0.003]), np.array([0.02, 0.02])   # below the spill
    assert np.allclose(wall_forces(w, q, v), m * wall_forces(inst, q, v), rtol=1e-9)
    F = np.array([10.0, 20.0])
    for st in ("full_closed", "empty_closed", "empty_open"):
        i0 = sample_container("odwalla", st, rng)
        i1 = vary_grasp(i0, rng)
        x0, x1 = _static_curve(i0, F), _static_curve(i1, F)
        assert np.allclose(x1 * i1.grasp_factor, x0, rtol=0.05), st


def test_grasp_variation_bad_inputs_are_named():
    from mmlearn.apps.tactile_state import TactileStateConfig, run_simulation
    from mmlearn.models.tactile.containers import vary_grasp

    inst = sample_container("can", "full_open", np.random.default_rng(6))
    with pytest.raises(ValueError, match="grasp_variation"):
        vary_grasp(inst, np.random.default_rng(0), mode="shel")
    with pytest.raises(ValueError, match="already carries"):
        vary_grasp(vary_grasp(inst, np.random.default_rng(0)), np.random.default_rng(1))
    with pytest.raises(TypeError, match="ContainerInstance"):
        vary_grasp({"name": "can"}, np.random.default_rng(0))
    with pytest.raises(ValueError, match="grasp_variation"):
        run_simulation(TactileStateConfig(f_target=20.0, trials=2, grasp_variation="rotate"))


@pytest.mark.slow
def test_grasp_variation_keeps_the_instance_placement_and_noise_of_the_grasp_without_it():
    """Specs with and without the variation differ; "wall" changes only the wall's response
    of the "none" grasp of the same seed (same instance, placement and noise), and the
    default is "wall"."""
    from mmlearn.diagrams.tactile.trials import container_grasp_trial

    shell = _sim_specs(["odwalla"], 20.0, 2, 5, "pressure", "wall")
    none = _sim_specs(["odwalla"], 20.0, 2, 5, "pressure", "none")
    assert all(s.params["grasp_variation"] == "wall" for s in shell)
    assert all(s.params["grasp_variation"] == "none" for s in none)
    assert not {s.key for s in shell} & {s.key for s in none}
    kw = dict(seed=3, container="odwalla", state="empty_open")
    default = container_grasp_trial(**kw)
    off = container_grasp_trial(**kw, grasp_variation="none")
    on = container_grasp_trial(**kw, grasp_variation="wall")
    assert default["p"] == on["p"] and default["instance"] == on["instance"]
    assert default["wall_model"] == "pressure"
    assert off["instance"]["grasp_factor"] == 1.0
    m = on["instance"]["grasp_factor"]
    assert m != 1.0 and on["offset"] == off["offset"]
    assert np.isclose(on["instance"]["k_parts"]["shell"], m * off["instance"]["k_parts"]["shell"])
    # an open empty bottle is its shell: a stiffer shell squeezes less (and vice versa)
    sq = {k: r["p"][0] - min(r["p"]) for k, r in (("off", off), ("on", on))}
    assert (sq["on"] < sq["off"]) == (m > 1.0) and abs(sq["on"] - sq["off"]) > 1e-4
