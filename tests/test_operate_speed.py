"""What keeps the opening trial's simulation cheap: the plant's time step, no unread marker sensor,
the hinge's friction in the plant, the localisation's command offset added and the controller's
command interpolated in C++, live output ports with the wrist sensor reading the forces of the
steps sampled ports would give it (one event a sample), the estimator refitting a long track less
often, the estimator's kernels loaded before the simulation, the garbage collector
left alone during the simulation, the CPU time in the record (diagrams/articulation/operate.py,
trials.py; docs/performance_articulation.md)."""

import gc

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator

from mmlearn.diagrams.articulation.operate import MakeOperateDiagram, OperateConfig
from mmlearn.diagrams.articulation.trials import open_mechanism
from mmlearn.diagrams.common.scene import MakeSceneDiagram, SceneConfig
from mmlearn.systems import JointFriction


def _started(cfg: OperateConfig):
    """The opening trial's diagram for ``cfg``, its simulator and root context, initialised at
    the start command."""
    op = MakeOperateDiagram(cfg)
    sim = Simulator(op.diagram)
    ctx = sim.get_mutable_context()
    op.scene.set_joint_positions(ctx, op.start_command)
    sim.Initialize()
    return op, sim, ctx


def _steps(cfg: OperateConfig, t_end: float) -> tuple[int, object]:
    op, sim, _ = _started(cfg)
    sim.AdvanceTo(t_end)
    return sim.get_num_steps_taken(), op


def test_the_plant_steps_at_the_configured_time_step_and_no_event_falls_between_steps():
    n, op = _steps(OperateConfig(kind="drawer", seed=2), 0.3)
    assert op.scene.plant.time_step() == OperateConfig().time_step == 0.0025
    # the controller (0.1 s), estimator (0.03 s), localisation (0.05 s) and wrist sensor
    # (0.01 s) periods are multiples of the step: one simulator step per plant step
    assert n <= round(0.3 / 0.0025) + 1
    # a step they are not multiples of adds steps of its own
    n4, _ = _steps(OperateConfig(kind="drawer", seed=2, time_step=0.004,
                                 sampled_output_ports=True), 0.3)
    assert n4 > round(0.3 / 0.004) + 1
    # live output ports: the wrist sensor's instants are plant steps
    with pytest.raises(ValueError, match="time_step 0.004 s must divide"):
        OperateConfig(kind="drawer", seed=2, time_step=0.004).validate()


def test_the_dynamics_monitor_samples_on_the_plant_steps():
    from mmlearn.systems.articulation.jam_monitor import DynamicsMonitorConfig

    cfg = OperateConfig(kind="drawer", seed=2, monitor=DynamicsMonitorConfig())
    assert cfg.monitor.period / cfg.time_step == pytest.approx(round(cfg.monitor.period
                                                                     / cfg.time_step))
    n, op = _steps(cfg, 0.3)
    # (a sample time of 0.025 s and the step's multiple may differ in the last bit: a
    # step of a few ulp now and then; a period off the steps would add 12 in 0.3 s)
    assert op.monitor is not None and n <= round(0.3 / cfg.time_step) + 3


def test_operate_config_rejects_a_coarse_time_step():
    cfg = OperateConfig(time_step=0.02)
    with pytest.raises(ValueError, match="time_step"):
        cfg.validate()


def test_the_opening_scene_has_no_marker_sensor_and_a_scene_can_leave_it_out():
    op = MakeOperateDiagram(OperateConfig(kind="left_door", seed=0))
    assert op.scene.sensor is None
    scene = MakeSceneDiagram(SceneConfig(arm="2dof", cabinet=False, marker_sensor=False))
    assert scene.sensor is None
    assert not scene.diagram.HasOutputPort("observations")
    assert not scene.diagram.HasOutputPort("marker_stats")
    assert MakeSceneDiagram(SceneConfig(arm="2dof", cabinet=False)).diagram.HasOutputPort(
        "observations")


def test_a_trial_records_its_cpu_time_and_leaves_the_collector_as_it_was():
    before = gc.get_freeze_count()
    r = open_mechanism(kind="drawer", seed=0, max_time=0.2, show_progress=False)
    assert gc.get_freeze_count() == before
    assert r["sim_seconds"] == pytest.approx(0.2)
    assert 0.0 < r["cpu_seconds"] < 60.0


def test_joint_friction_output_is_the_same_float_values_as_the_formula():
    rng = np.random.default_rng(3)
    joints = {9: 1.3, 4: 0.2, 6: 0.0}
    f = JointFriction(num_positions=10, num_velocities=10, joints=joints, v_stiction=0.02)
    ctx = f.CreateDefaultContext()
    idx, mu = np.array(list(joints)), np.array(list(joints.values()))
    for _ in range(20):
        x = rng.normal(0.0, 0.05, 20)
        f.get_state_input_port().FixValue(ctx, x)
        want = np.zeros(10)
        want[idx] = -mu * np.tanh(x[10:][idx] / 0.02)
        np.testing.assert_array_equal(f.get_generalized_force_output_port().Eval(ctx), want)


def test_the_plants_output_ports_are_live_unless_the_trial_asks_for_sampled_ones():
    from mmlearn.diagrams.articulation.operate import WRIST_NOISE_SAMPLES
    from mmlearn.systems.articulation.jam_monitor import DynamicsMonitorConfig

    live = MakeOperateDiagram(OperateConfig(kind="drawer", seed=0))
    assert not live.scene.plant.has_sampled_output_ports()
    assert live.force_sensor._table.shape[0] == WRIST_NOISE_SAMPLES
    # a trial with the dynamics monitor keeps sampled ports and per-sample noise
    mon = MakeOperateDiagram(OperateConfig(kind="drawer", seed=0,
                                           monitor=DynamicsMonitorConfig()))
    assert mon.scene.plant.has_sampled_output_ports()
    assert mon.force_sensor._table.shape[0] == 0
    assert MakeSceneDiagram(SceneConfig(arm="2dof", cabinet=False)).plant \
        .has_sampled_output_ports()
    sampled = MakeOperateDiagram(OperateConfig(kind="drawer", seed=0,
                                               sampled_output_ports=True))
    assert sampled.scene.plant.has_sampled_output_ports()


def test_the_estimator_refits_a_long_track_less_often_unless_the_trial_has_a_monitor():
    from mmlearn.diagrams.articulation.operate import REFIT_FRACTION
    from mmlearn.systems.articulation.jam_monitor import DynamicsMonitorConfig

    assert 0.0 < REFIT_FRACTION < 1.0
    assert OperateConfig().estimator_refit_fraction() == REFIT_FRACTION
    # the monitor's regression reads the model: its trials keep a refit every 10 samples
    assert OperateConfig(monitor=DynamicsMonitorConfig()).estimator_refit_fraction() == 0.0
    assert OperateConfig(monitor=DynamicsMonitorConfig(),
                         refit_fraction=0.2).estimator_refit_fraction() == 0.2
    with pytest.raises(ValueError, match="refit_fraction"):
        OperateConfig(refit_fraction=1.5).validate()
    est = MakeOperateDiagram(OperateConfig(kind="drawer", seed=0)).estimator
    assert est._refit_interval(10) == 10 and est._refit_interval(300) == 30


def _force_track(sampled: bool, times) -> tuple[np.ndarray, int]:
    op, sim, ctx = _started(OperateConfig(kind="drawer", seed=2, sampled_output_ports=sampled))
    out = []
    for t in times:
        sim.AdvanceTo(t)
        out.append(op.diagram.GetOutputPort("force_W").Eval(ctx).copy())
    return np.array(out), sim.get_num_steps_taken()


def test_with_live_ports_the_wrist_sensor_reads_the_forces_of_the_steps_sampled_ports_give_it():
    # at the sample instants (10 ms apart) the sensor reads the reaction forces of the step
    # that starts there, as with sampled ports, and turns them with the tool's pose at the
    # step's start (sampled ports: its end): to the last bit while the robot rests, within
    # a thousandth of the noise's 0.3 N once it moves; one event a sample, none adding a
    # simulator step
    times = np.arange(1, 31) * 0.01
    (sampled, n_sampled), (live, n_live) = _force_track(True, times), _force_track(False, times)
    assert n_live == n_sampled <= round(0.3 / 0.0025) + 1
    assert np.abs(sampled).max() > 0.1
    rest = times <= 0.1 + 1e-9
    np.testing.assert_array_equal(live[rest], sampled[rest])
    np.testing.assert_allclose(live[~rest], sampled[~rest], atol=3e-4)
    assert not np.array_equal(live[~rest], sampled[~rest])  # the pose of the step's start


def test_the_plant_command_is_the_localisations_to_the_last_bit():
    # the diagram adds the controller's command and the localisation's offset with an
    # Adder: the same floats as the localisation's own plant_command
    op, sim, ctx = _started(OperateConfig(kind="left_door", seed=1))
    loc = op.localization
    for t in (0.1, 0.2375, 0.45):
        sim.AdvanceTo(t)
        lc = loc.GetMyContextFromRoot(ctx)
        assert np.any(loc.error(lc) != 0.0)
        adder = op.diagram.GetSubsystemByName("plant_command")
        got = adder.get_output_port().Eval(adder.GetMyContextFromRoot(ctx))
        np.testing.assert_array_equal(got, loc.get_plant_command_output_port().Eval(lc))


def test_the_plant_command_is_the_controllers_interpolated_in_cpp_to_the_last_bit():
    op, sim, ctx = _started(OperateConfig(kind="left_door", seed=1))
    interp = op.diagram.GetSubsystemByName("command_interpolator")
    epc = op.controller
    moved = 0
    for t in (0.1, 0.2375, 0.45, 0.6125):
        sim.AdvanceTo(t)
        got = interp.get_output_port().Eval(interp.GetMyContextFromRoot(ctx))
        want = epc.get_command_output_port().Eval(epc.GetMyContextFromRoot(ctx))
        np.testing.assert_array_equal(got, want)
        moved += not np.array_equal(got, op.start_command)
    assert moved


def test_the_estimator_warm_up_loads_the_fit_kernels_and_leaves_no_trace():
    from mmlearn.models.articulation import kernels
    from mmlearn.systems.articulation.estimator import ArticulationEstimator

    est = ArticulationEstimator(mode="pose", pose_size=3, models=("rigid", "revolute"))
    ctx = est.CreateDefaultContext()
    before = est.GetOutputPort("stats").Eval(ctx).copy()
    est.warm_up()
    assert kernels.em_gamma_full.signatures
    np.testing.assert_array_equal(est.GetOutputPort("stats").Eval(ctx), before)


def test_a_revolute_mechanisms_friction_is_a_door_hinge_of_the_plant_with_the_same_law():
    from pydrake.multibody.tree import MultibodyForces

    from mmlearn.diagrams.common.scene import HINGE_STICTION_VELOCITY
    from mmlearn.sdf.mechanisms import sample_mechanism

    door = sample_mechanism("left_door", np.random.default_rng(4))
    scene = MakeSceneDiagram(SceneConfig(arm="2dof", cabinet=False, mechanism=door))
    assert not scene.diagram.HasSubsystemNamed("furniture_friction")
    plant = scene.plant
    joint = plant.GetJointByName("mechanism", scene.mechanism)
    ctx = plant.CreateDefaultContext()
    forces = MultibodyForces(plant)
    for v in (-0.3, -0.01, 0.0, 0.004, 0.05, 1.2):
        joint.set_angular_rate(ctx, v)
        forces.SetZero()
        plant.CalcForceElementsContribution(ctx, forces)
        tau = forces.generalized_forces()[joint.velocity_start()]
        # (with the joint's own viscous damping, which the plant adds here too)
        want = (-door.friction * np.tanh(v / HINGE_STICTION_VELOCITY)
                - joint.default_damping() * v)
        assert tau == pytest.approx(want, rel=1e-14, abs=1e-15)
    # a drawer's slide keeps the Python system (Drake has no prismatic friction element)
    drawer = sample_mechanism("drawer", np.random.default_rng(4))
    scene = MakeSceneDiagram(SceneConfig(arm="2dof", cabinet=False, mechanism=drawer))
    assert scene.diagram.HasSubsystemNamed("furniture_friction")
