import math

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator

from mmlearn.diagrams import MakeSceneDiagram, SceneConfig
from mmlearn.systems import MarkerSensorConfig


def _simulate(cfg, command, t_end):
    scene = MakeSceneDiagram(cfg)
    d = scene.diagram
    sim = Simulator(d)
    ctx = sim.get_mutable_context()
    d.GetInputPort("command").FixValue(ctx, np.asarray(command, float))
    sim.Initialize()
    sim.AdvanceTo(t_end)
    return scene, ctx


@pytest.mark.slow
@pytest.mark.parametrize("arm,cmd", [
    ("2dof", [0.4, -0.6]),
    ("4dof", [0.5, 0.3, -0.4, 0.6]),
    ("7dof", [0.3, 0.4, -0.3, 0.5, 0.2, -0.4, 0.03]),
])
def test_compliant_arm_reaches_a_held_command(arm, cmd):
    scene, ctx = _simulate(SceneConfig(arm=arm), cmd, 1.5)
    x = scene.diagram.GetOutputPort("robot_state").Eval(ctx)
    q = x[: scene.plant.num_positions(scene.robot)]
    # gravity compensated PD: the steady state error is small
    np.testing.assert_allclose(q[: len(cmd)], cmd, atol=0.01)
    stats = scene.diagram.GetOutputPort("marker_stats").Eval(ctx)
    # frames at t = 0, 0.1, ..., 1.4 (10 Hz; Drake handles the event at t = 1.5 at the
    # start of the next step)
    assert stats[0] == 15 and stats[1] == 15 * len(scene.sensor.marker_ids)
    obs = scene.diagram.GetOutputPort("observations").Eval(ctx)
    assert obs.time == pytest.approx(1.4)
    assert obs.marker_ids == scene.sensor.marker_ids


def test_without_gravity_compensation_the_arm_sags():
    cmd = [0.0, 1.0, 0.0, 0.5, 0.0, 0.0, 0.0]
    errs = []
    for gc in (True, False):
        scene, ctx = _simulate(SceneConfig(arm="7dof", gravity_compensation=gc,
                                           cabinet=False), cmd, 1.0)
        q = scene.diagram.GetOutputPort("robot_state").Eval(ctx)[:7]
        errs.append(np.abs(q - cmd).max())
    assert errs[0] < 0.005 < errs[1]


def test_cabinet_joints_have_friction_and_damping():
    scene = MakeSceneDiagram(SceneConfig(arm="2dof"))
    d, plant, cab = scene.diagram, scene.plant, scene.cabinet
    sim = Simulator(d)
    ctx = sim.get_mutable_context()
    d.GetInputPort("command").FixValue(ctx, [0.0, 0.0])
    pctx = plant.GetMyMutableContextFromRoot(ctx)
    hinge = plant.GetJointByName("left_hinge", cab)
    hinge.set_angle(pctx, 0.5)
    hinge.set_angular_rate(pctx, 1.0)  # a push
    slide = plant.GetJointByName("drawer_slide", cab)
    slide.set_translation(pctx, 0.1)
    slide.set_translation_rate(pctx, 0.3)
    sim.AdvanceTo(1.0)
    # the door and the drawer come to rest, inside their limits
    assert abs(hinge.get_angular_rate(pctx)) < 1e-2
    assert abs(slide.get_translation_rate(pctx)) < 1e-2
    assert 0.5 < hinge.get_angle(pctx) < math.radians(110) + 1e-3
    assert 0.1 < slide.get_translation(pctx) < 0.38 + 1e-3


@pytest.mark.slow
def test_mobile_base_with_hook_drives_to_a_commanded_pose():
    cfg = SceneConfig(arm="7dof", tool="hook", mobile_base=True, cabinet=False,
                      sensor=MarkerSensorConfig(cameras=[]))
    scene = MakeSceneDiagram(cfg)
    assert scene.command_names[:3] == ["base_x", "base_y", "base_yaw"]
    assert "hook" in scene.sensor.marker_ids
    cmd = np.zeros(len(scene.command_names))
    cmd[:3] = [0.3, -0.2, 0.4]
    scene, ctx = _simulate(cfg, cmd, 3.0)
    pctx = scene.plant.GetMyContextFromRoot(ctx)
    X = scene.plant.GetBodyByName("mobile_base", scene.robot).EvalPoseInWorld(pctx)
    np.testing.assert_allclose(X.translation()[:2], [0.3, -0.2], atol=0.01)


def test_bad_scene_config():
    with pytest.raises(ValueError, match="tool"):
        MakeSceneDiagram(SceneConfig(tool="spoon"))
    with pytest.raises(ValueError, match="2, 4 or 7"):
        MakeSceneDiagram(SceneConfig(arm="3dof"))
    scene = MakeSceneDiagram(SceneConfig(arm="2dof", cabinet=False))
    with pytest.raises(ValueError, match="command needs 2 values"):
        scene.set_joint_positions(scene.diagram.CreateDefaultContext(), [0.0])
