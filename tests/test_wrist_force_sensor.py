import numpy as np
import pytest
from pydrake.multibody.math import SpatialForce
from pydrake.multibody.plant import ExternallyAppliedSpatialForce
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from mmlearn.diagrams import MakeSceneDiagram, SceneConfig
from mmlearn.systems import MarkerSensorConfig, WristForceSensor


def _pushed_hook(push=None, *, live=False, dt=0.0025, **sensor_kw):
    """A hook arm (plant step ``dt``) with the wrist sensor, held at one command and pushed by
    ``push`` (N, world frame; None: not pushed); ``live``: the plant's output ports live
    instead of sampled. Returns (sensor, simulator)."""
    scene = MakeSceneDiagram(SceneConfig(arm="7dof", tool="hook", mobile_base=True,
                                         cabinet=False, time_step=dt,
                                         sampled_output_ports=not live,
                                         sensor=MarkerSensorConfig(cameras=[])))
    plant = scene.plant
    b = DiagramBuilder()
    sd = b.AddSystem(scene.diagram)
    sensor = b.AddSystem(WristForceSensor(
        plant=plant, mount_joint=plant.GetJointByName("hook_mount", scene.robot), **sensor_kw))
    b.Connect(sd.GetOutputPort("reaction_forces"), sensor.get_reaction_forces_input_port())
    b.Connect(sd.GetOutputPort("body_poses"), sensor.get_body_poses_input_port())
    d = b.Build()
    ctx = d.CreateDefaultContext()
    cmd = np.zeros(len(scene.command_names))
    cmd[3:] = [0.0, 0.5, 0.0, 1.2, 0.0, 0.4]
    sd.GetInputPort("command").FixValue(sd.GetMyMutableContextFromRoot(ctx), cmd)
    scene.set_joint_positions(ctx, cmd)
    forces = []
    if push is not None:
        f = ExternallyAppliedSpatialForce()
        f.body_index = plant.GetBodyByName("hook", scene.robot).index()
        f.p_BoBq_B = np.zeros(3)
        f.F_Bq_W = SpatialForce(np.zeros(3), np.asarray(push, float))
        forces = [f]
    sd.GetInputPort("applied_spatial_force").FixValue(sd.GetMyMutableContextFromRoot(ctx),
                                                       forces)
    return sensor, Simulator(d, ctx)


def _rig(push=None, sigma=0.0, *, live=False, times=(1.5,)):
    """The sensor's output at ``times`` on a hook pushed by ``push`` (N, world frame; None:
    not pushed); ``live``: the plant's output ports live and the sensor given its step
    (plant_time_step), else sampled ports (Drake's default)."""
    dt = 0.0025
    sensor, sim = _pushed_hook(push, live=live, dt=dt, sigma_force=sigma, seed=3,
                               plant_time_step=dt if live else 0.0)
    ctx = sim.get_context()
    out = []
    for t in times:
        sim.AdvanceTo(t)
        out.append(sensor.get_force_output_port().Eval(sensor.GetMyContextFromRoot(ctx)).copy())
    return out[0] if len(times) == 1 else (np.array(out), sim.get_num_steps_taken())


def test_free_hook_reads_no_force():
    np.testing.assert_allclose(_rig(), 0.0, atol=0.3)


def test_a_push_on_the_hook_is_measured_in_the_world_frame():
    f = _rig(push=[8.0, -5.0, 3.0])
    np.testing.assert_allclose(f, [8.0, -5.0, 3.0], atol=0.5)


@pytest.mark.slow
def test_noise_and_bad_config():
    f1, f2 = _rig(sigma=1.0), _rig(sigma=1.0)
    np.testing.assert_array_equal(f1, f2)  # seeded
    assert np.linalg.norm(f1) > 0.05
    with pytest.raises(ValueError, match="sigma_force"):
        WristForceSensor(plant=None, mount_joint=None, sigma_force=-1.0)


def _sensor(**kw):
    scene = MakeSceneDiagram(SceneConfig(arm="7dof", tool="hook", mobile_base=True,
                                         cabinet=False, marker_sensor=False))
    return WristForceSensor(plant=scene.plant,
                            mount_joint=scene.plant.GetJointByName("hook_mount", scene.robot),
                            **kw)


def test_the_noise_is_a_function_of_seed_and_sample_and_a_table_serves_the_first_samples():
    a = _sensor(sigma_force=0.5, seed=4, noise_samples=2000)
    b = _sensor(sigma_force=0.5, seed=4, noise_samples=2000)
    c = _sensor(sigma_force=0.5, seed=5, noise_samples=2000)
    per_sample = _sensor(sigma_force=0.5, seed=4)
    first = np.array([a.noise(k) for k in range(2000)])
    np.testing.assert_array_equal(first, [b.noise(k) for k in range(2000)])
    assert not np.allclose(first[:10], [c.noise(k) for k in range(10)])
    assert abs(first.std() - 0.5) < 0.03 and abs(first.mean()) < 0.03
    # beyond the table, and without one: a generator seeded by (seed, sample index)
    for k in (0, 7, 2000, 2345):
        want = np.random.default_rng([4, k]).normal(0.0, 0.5, 3)
        np.testing.assert_array_equal(per_sample.noise(k), want)
        if k >= 2000:
            np.testing.assert_array_equal(a.noise(k), want)
    assert not np.allclose(a.noise(7), per_sample.noise(7))


def test_bad_plant_time_step_and_noise_samples():
    for dt in (0.003, 0.01, -0.001, float("nan")):
        with pytest.raises(ValueError, match="plant_time_step"):
            _sensor(plant_time_step=dt)
    with pytest.raises(ValueError, match="noise_samples"):
        _sensor(noise_samples=-1)
    with pytest.raises(ValueError, match="noise_samples"):
        _sensor(noise_samples=2.5)
    _sensor(plant_time_step=0.005)  # two steps a sample


def test_with_live_ports_and_its_step_the_sensor_gives_the_samples_of_sampled_ports():
    # plant_time_step: the reaction forces read at each sample instant, turned with the
    # tool's pose a plant step later: the samples of sampled ports, to the last bit, with
    # no simulator step of its own
    times = np.arange(1, 41) * 0.01
    sampled, n_sampled = _rig(push=[8.0, -5.0, 3.0], sigma=0.5, times=times)
    live, n_live = _rig(push=[8.0, -5.0, 3.0], sigma=0.5, live=True, times=times)
    assert np.abs(sampled).max() > 1.0
    np.testing.assert_array_equal(live, sampled)
    assert n_live == n_sampled <= round(0.4 / 0.0025) + 1


def test_a_sample_is_the_true_force_plus_its_noise_to_the_last_bit():
    """One event per sample (live ports, no plant_time_step): the sample at instant k is
    true_force (the reaction force turned into the world frame, the tool's weight taken
    off) plus noise(k), the same floats, on a pushed hook."""
    sensor, sim = _pushed_hook([8.0, -5.0, 3.0], live=True, sigma_force=0.5, seed=3,
                               noise_samples=50)
    sc = sensor.GetMyContextFromRoot(sim.get_context())
    for k in (20, 49, 60):  # a table's noise and a generator's
        sim.AdvanceTo(k * 0.01)
        sample = sensor.EvalUniquePeriodicDiscreteUpdate(sc).get_vector(0).value()
        assert np.abs(sample).max() > 1.0
        np.testing.assert_array_equal(sample, sensor.true_force(sc) + sensor.noise(k))
