"""The small systems that show or score a simulation: FinitePointCloud, TrueFrontPose,
SchemaVisualizer and DbnVisualizer, each built alone on fixed inputs."""

import math

import numpy as np
import pytest
from pydrake.math import RigidTransform
from pydrake.perception import BaseField, Fields, PointCloud
from pydrake.systems.analysis import Simulator

from mmlearn.models.perception.motion import FrontJointKinematics
from mmlearn.systems.body_schema.visualizer import SchemaVisualizer
from mmlearn.systems.imitation.dbn_visualizer import DbnVisualizer
from mmlearn.systems.perception.front_pose import TrueFrontPose
from mmlearn.systems.perception.point_cloud_filter import FinitePointCloud


@pytest.fixture(scope="module")
def meshcat():
    from pydrake.geometry import StartMeshcat

    return StartMeshcat()


def test_finite_point_cloud_drops_missing_points_and_keeps_colours():
    xyz = np.array([[0.0, 1.0, np.nan, 3.0, np.inf, 5.0],
                    [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
                    [1.0, 1.0, 1.0, 1.0, 1.0, 1.0]])
    cloud = PointCloud(6, Fields(BaseField.kXYZs | BaseField.kRGBs))
    cloud.mutable_xyzs()[:] = xyz
    cloud.mutable_rgbs()[:] = np.arange(18, dtype=np.uint8).reshape(3, 6)
    for stride, kept in ((1, [0, 1, 3, 5]), (2, [0, 3])):
        f = FinitePointCloud(stride=stride)
        ctx = f.CreateDefaultContext()
        f.get_cloud_input_port().FixValue(ctx, cloud)
        out = f.get_cloud_output_port().Eval(ctx)
        np.testing.assert_array_equal(out.xyzs(), xyz[:, kept])
        np.testing.assert_array_equal(out.rgbs(), cloud.rgbs()[:, kept])
    for bad in (0, 1.5, True):
        with pytest.raises(ValueError, match="stride"):
            FinitePointCloud(stride=bad)


def test_true_front_pose_follows_the_joint():
    X0 = np.eye(4)
    X0[:3, 3] = [1.0, 0.2, 0.6]
    kin = FrontJointKinematics(kind="revolute", axis_W=[0.0, 0.0, 1.0],
                               point_W=[1.0, 0.0, 0.6], X_WR0=X0, width=0.4, height=0.58)
    s = TrueFrontPose(kinematics=kin, position_index=2, num_positions=4)
    ctx = s.CreateDefaultContext()
    q = math.radians(30)
    s.get_positions_input_port().FixValue(ctx, [0.0, 9.0, q, 9.0])
    assert s.get_joint_value_output_port().Eval(ctx)[0] == pytest.approx(q)
    X = s.get_X_WR_output_port().Eval(ctx).GetAsMatrix4()
    np.testing.assert_allclose(X, kin.X_WR(q), atol=1e-12)
    # the centre turned about the hinge: still 0.2 m from it, 30 deg round
    np.testing.assert_allclose(X[:3, 3], [1.0 - 0.2 * math.sin(q), 0.2 * math.cos(q), 0.6],
                               atol=1e-12)
    front = s.get_front_output_port().Eval(ctx)
    assert (front.width, front.height) == (0.4, 0.58)
    np.testing.assert_allclose(front.X_WR, X, atol=1e-12)
    with pytest.raises(ValueError, match="position_index"):
        TrueFrontPose(kinematics=kin, position_index=4, num_positions=4)


def test_schema_visualizer_draws_the_tree_between_seen_parts(meshcat):
    parts = ["x0", "x1", "x2"]
    v = SchemaVisualizer(meshcat=meshcat, parts=parts, prefix="/test_schema")
    ctx = v.CreateDefaultContext()
    v.get_predicted_poses_input_port().FixValue(
        ctx, [RigidTransform([0.0, 0.0, 0.1 * k]) for k in range(2)] + [None])
    v.get_model_validity_input_port().FixValue(ctx, [
        dict(a="x0", b="x1", valid=True, in_tree=True),
        dict(a="x1", b="x2", valid=False, in_tree=True),    # x2 not predicted: no line
        dict(a="x0", b="x2", valid=True, in_tree=False)])   # not in the tree: no line
    Simulator(v, ctx).AdvanceTo(0.15)  # publishes at 0 and 0.1 s
    assert meshcat.HasPath("/test_schema/tree/x0_x1")
    assert not meshcat.HasPath("/test_schema/tree/x1_x2")
    assert not meshcat.HasPath("/test_schema/tree/x0_x2")
    with pytest.raises(ValueError, match="offset"):
        SchemaVisualizer(meshcat=meshcat, parts=parts, offset=(0.0, 1.0))
    with pytest.raises(ValueError, match="rate_hz"):
        SchemaVisualizer(meshcat=meshcat, parts=parts, rate_hz=0.0)


def test_dbn_visualizer_counts_its_dots_in_the_context(meshcat):
    v = DbnVisualizer(meshcat=meshcat, period=0.1, prefix="test_trail")
    ctx = v.CreateDefaultContext()
    v.get_hand_input_port().FixValue(ctx, [0.4, 0.0, 0.5])
    sim = Simulator(v, ctx)
    sim.AdvanceTo(0.55)
    k = int(ctx.get_discrete_state(0).GetAtIndex(0))
    assert k == 6  # updates at 0.0, 0.1, ..., 0.5
    assert meshcat.HasPath(f"test_trail/dot_{k:05d}")
    # a second simulator on a fresh context starts counting again (nothing kept in the system)
    ctx2 = v.CreateDefaultContext()
    v.get_hand_input_port().FixValue(ctx2, [0.4, 0.0, 0.5])
    Simulator(v, ctx2).AdvanceTo(0.15)
    assert int(ctx2.get_discrete_state(0).GetAtIndex(0)) == 2
    with pytest.raises(ValueError, match="period"):
        DbnVisualizer(meshcat=meshcat, period=0.0)
