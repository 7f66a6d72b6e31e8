import numpy as np
import pytest
from pydrake.multibody.math import SpatialForce
from pydrake.multibody.plant import ExternallyAppliedSpatialForce
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from mmlearn.diagrams import MakeSceneDiagram, SceneConfig
from mmlearn.systems import MarkerSensorConfig, WristForceSensor


def _rig(push=None, sigma=0.0):
    scene = MakeSceneDiagram(SceneConfig(arm="7dof", tool="hook", mobile_base=True,
                                         cabinet=False,
                                         sensor=MarkerSensorConfig(cameras=[])))
    plant = scene.plant
    b = DiagramBuilder()
    sd = b.AddSystem(scene.diagram)
    sensor = b.AddSystem(WristForceSensor(
        plant=plant, mount_joint=plant.GetJointByName("hook_mount", scene.robot),
        sigma_force=sigma, seed=3))
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
    sim = Simulator(d, ctx)
    sim.AdvanceTo(1.5)
    return sensor.get_force_output_port().Eval(sensor.GetMyContextFromRoot(ctx))


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
