import math
import re

import numpy as np
import pytest
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
from pydrake.systems.framework import DiagramBuilder

from mmlearn.sdf import SDF_DIR, add_package, model_path
from mmlearn.sdf import builders


def _load(url_or_text, *, text=False):
    plant, _ = AddMultibodyPlantSceneGraph(DiagramBuilder(), 0.001)
    parser = Parser(plant)
    add_package(parser)
    if text:
        mi = parser.AddModelsFromString(url_or_text, "sdf")[0]
    else:
        mi = parser.AddModels(url=url_or_text)[0]
    plant.Finalize()
    return plant, mi


@pytest.mark.parametrize("fname", sorted(builders.DEFAULT_MODELS))
def test_shipped_model_parses_and_matches_builder(fname):
    plant, mi = _load(f"package://mmlearn/{fname}")
    assert plant.num_bodies() > 1
    # the shipped file is exactly what the builder makes (regenerate with
    # `python -m mmlearn.sdf.builders` after changing a builder)
    assert model_path(fname).read_text() == builders.DEFAULT_MODELS[fname]()


def test_no_remote_packages_referenced():
    for p in SDF_DIR.iterdir():
        if p.suffix in (".sdf", ".yaml", ".urdf", ".xml"):
            assert "drake_models" not in p.read_text(), p


def test_seven_dof_arm_has_the_thesis_parts():
    plant, mi = _load("package://mmlearn/arm_7dof.sdf")
    parts = [f"x{i}" for i in range(1, 11)]
    for p in parts:
        body = plant.GetBodyByName(p, mi)
        assert plant.HasFrameNamed(p + "_marker", mi), p
        assert body is not None
    revolute = [plant.GetJointByName(f"q{i}", mi) for i in range(1, 7)]
    assert all(j.type_name() == "revolute" for j in revolute)
    assert plant.GetJointByName("q7", mi).type_name() == "revolute"
    assert plant.GetJointByName("x1_x2", mi).type_name() == "weld"
    # x2..x8 form a chain on q1..q6; fingers x9, x10 both hang on x8
    chain = [(j.parent_body().name(), j.child_body().name()) for j in revolute]
    assert chain == [(f"x{i}", f"x{i + 1}") for i in range(2, 8)]
    assert plant.GetJointByName("q7_mirror", mi).parent_body().name() == "x8"
    # total length about 1.3 m: highest point of the fingertips at q = 0
    ctx = plant.CreateDefaultContext()
    tip = plant.GetBodyByName("x9", mi).EvalPoseInWorld(ctx).translation()[2] + 0.08
    assert tip == pytest.approx(1.30, abs=0.02)
    assert builders.arm_spec(7).length == pytest.approx(1.30, abs=1e-9)


def test_marker_frame_normal_points_out_of_the_part():
    plant, mi = _load("package://mmlearn/arm_2dof.sdf")
    ctx = plant.CreateDefaultContext()
    for p in ("x2", "x3"):
        X_WB = plant.GetBodyByName(p, mi).EvalPoseInWorld(ctx)
        X_WM = plant.GetFrameByName(p + "_marker", mi).CalcPoseInWorld(ctx)
        n = X_WM.rotation().matrix()[:, 2]
        offset = X_WM.translation() - X_WB.translation()
        assert n @ np.array([1.0, 0, 0]) == pytest.approx(1.0)
        assert offset[0] > 0.02  # on the +x surface of the part


@pytest.mark.parametrize("dof,nq", [(2, 2), (4, 4), (7, 8)])
def test_arm_generator_dofs(dof, nq):
    plant, mi = _load(builders.arm_sdf(dof, tool="gripper" if dof == 7 else "none"), text=True)
    assert plant.num_positions() == nq
    assert plant.num_actuators() == nq  # every joint is actuated


def test_hook_and_mobile_base():
    plant, mi = _load("package://mmlearn/mobile_arm_7dof_hook.sdf")
    for j in ("base_x", "base_y", "base_yaw"):
        assert plant.GetJointByName(j, mi).num_positions() == 1
    hook = plant.GetBodyByName("hook", mi)
    assert len(plant.GetCollisionGeometriesForBody(hook)) == 2  # the two legs of the L
    assert plant.GetJointByName("hook_mount", mi).parent_body().name() == "x8"
    with pytest.raises(ValueError, match="gripper"):
        builders.arm_spec(4, tool="gripper")
    with pytest.raises(ValueError, match="2, 4 or 7"):
        builders.arm_spec(5)


def test_cabinet_joints_behave_like_furniture():
    plant, mi = _load("package://mmlearn/cabinet.sdf")
    for name, kind in (("left_hinge", "revolute"), ("right_hinge", "revolute"),
                       ("drawer_slide", "prismatic")):
        j = plant.GetJointByName(name, mi)
        assert j.type_name() == kind
        assert j.position_lower_limits()[0] == 0.0 and j.position_upper_limits()[0] > 0
        assert j.default_damping_vector()[0] > 0  # damping from the SDF
    # positive opening swings the doors' free edges towards the robot (+x)
    ctx = plant.CreateDefaultContext()
    for side in ("left", "right"):
        frame = plant.GetFrameByName(f"{side}_door_handle", mi)
        x0 = frame.CalcPoseInWorld(ctx).translation()
        plant.GetJointByName(f"{side}_hinge", mi).set_angle(ctx, math.radians(60))
        x1 = frame.CalcPoseInWorld(ctx).translation()
        assert x1[0] > x0[0] + 0.15
    with pytest.raises(ValueError, match="width"):
        builders.CabinetSpec(width=-1)


def test_model_pose_validation():
    with pytest.raises(ValueError, match="6 finite numbers"):
        builders.cabinet_sdf(pose=(0, 0, 0))
    assert re.search(r"<pose>1 2 0 0 0 0.5</pose>",
                     builders.cabinet_sdf(pose=(1, 2, 0, 0, 0, 0.5)))
