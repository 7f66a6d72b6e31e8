"""Body schema in Drake: failures in the plant, SchemaLearner, SchemaController, diagram."""

import math

import numpy as np
import pytest
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.analysis import Simulator

from mmlearn.diagrams.body_schema.trials import (babble, control_error, observation_noise,
                                                 prediction_error, sample_test_commands)
from mmlearn.models.body_schema.evaluation import converged_at, is_correct
from mmlearn.diagrams.body_schema.diagram import BodySchemaDiagramConfig, MakeBodySchemaDiagram
from mmlearn.diagrams.common.scene import MakeSceneDiagram, SceneConfig
from mmlearn.sdf.builders import DEFAULT_MODELS, arm_sdf
from mmlearn.systems.body_schema.arm_failures import JointBlocker, PlantFailures
from mmlearn.systems.body_schema.motor_babbling import MotorBabbling
from mmlearn.systems.common.observations import MarkerObservations
from mmlearn.systems.body_schema.controller import SchemaController
from mmlearn.systems.body_schema.learner import SchemaLearner, SchemaLearnerConfig


def _sim(bs):
    sim = Simulator(bs.diagram)
    root = sim.get_mutable_context()
    bs.prepare(root)
    sim.Initialize()
    return sim, root


# ------------------------------------------------------------------------- failures
def test_failure_joints_are_optional_and_default_sdf_unchanged():
    assert arm_sdf(4, tool="none") == DEFAULT_MODELS["arm_4dof.sdf"]()
    s = arm_sdf(4, tool="none", failure_joints=True)
    for name in ("x3_bend", "x3_outer", "tool_length", "tool_angle", "x6_marker"):
        assert name in s


def test_joint_blocker_freezes_entry_at_value_when_blocked():
    jb = JointBlocker(size=3)
    ctx = jb.CreateDefaultContext()
    jb.get_command_input_port().FixValue(ctx, [0.1, 0.2, 0.3])
    jb.block(ctx, 1)
    jb.get_command_input_port().FixValue(ctx, [1.0, 2.0, 3.0])
    assert np.allclose(jb.get_command_output_port().Eval(ctx), [1.0, 0.2, 3.0])
    assert jb.blocked(ctx) == {1: pytest.approx(0.2)}
    jb.unblock(ctx)
    assert np.allclose(jb.get_command_output_port().Eval(ctx), [1.0, 2.0, 3.0])
    with pytest.raises(ValueError):
        JointBlocker(size=0)
    with pytest.raises(ValueError):
        jb.block(ctx, 5)


def test_plant_failures_bend_and_tool_move_only_downstream_markers():
    cfg = BodySchemaDiagramConfig(arm="4dof", noise_pos=0.0, noise_orient=0.0)
    bs = MakeBodySchemaDiagram(cfg)
    sim, root = _sim(bs)
    assert bs.parts == ["x1", "x2", "x3", "x4", "x5", "x6"]
    q = np.array([0.3, 0.4, -0.5, 0.2])
    X0 = bs.true_poses(root, q)
    bs.failures.bend_link(root, math.pi / 4)
    X1 = bs.true_poses(root, q)
    moved = [not np.allclose(X0[i], X1[i], atol=1e-9) for i in range(6)]
    assert moved == [False, False, False, True, True, True]  # x3 is split after its marker
    bs.failures.unbend(root)
    bs.failures.change_tool(root, 0.1, math.pi / 6)
    X2 = bs.true_poses(root, q)
    assert [not np.allclose(X0[i], X2[i], atol=1e-9) for i in range(6)] == [False] * 5 + [True]
    # the locked joints hold their values while simulating
    bs.failures.bend_link(root, math.pi / 4)
    sim.AdvanceTo(0.3)
    st = bs.failures.state(root)
    assert st["x3_bend"] == pytest.approx(math.pi / 4, abs=1e-9)
    assert st["tool_length"] == pytest.approx(0.1, abs=1e-9)
    bs.failures.reset(root)
    assert np.allclose(bs.true_poses(root, q), X0)
    with pytest.raises(ValueError, match="failure joints"):
        scene = MakeSceneDiagram(SceneConfig(arm="2dof", cabinet=False))
        PlantFailures(plant=scene.plant, model_instance=scene.robot)


@pytest.mark.slow
def test_blocked_joint_stops_following_its_command_in_the_plant():
    bs = MakeBodySchemaDiagram(BodySchemaDiagramConfig(arm="2dof"))
    sim, root = _sim(bs)
    sim.AdvanceTo(0.2)
    bs.blocker.block(root, 1)
    frozen = bs.blocker.blocked(root)[1]
    sim.AdvanceTo(3.0)
    plant = bs.scene.plant
    q = plant.GetPositions(plant.GetMyContextFromRoot(root))
    i1 = plant.GetJointByName("q2", bs.scene.robot).position_start()
    cmd = bs.diagram.GetOutputPort("command").Eval(root)  # what the learner sees
    assert q[i1] == pytest.approx(frozen, abs=0.02)
    assert abs(cmd[1] - frozen) > 0.05


def test_babbling_targets_are_accepted_by_the_filter():
    bs = MakeBodySchemaDiagram(BodySchemaDiagramConfig(arm="2dof"))
    acc = bs.babbling._accept
    for k in range(1, 15):
        assert acc(bs.babbling.target(k))
    assert not acc(np.array([2.0, 0.0]))  # the upper arm points into the floor
    with pytest.raises(ValueError):
        MotorBabbling(lower=[0], upper=[1], accept=3)


# ------------------------------------------------------------------------- learner unit
def test_diagram_rejects_babbling_too_fast_for_settling():
    with pytest.raises(ValueError, match="settle"):
        MakeBodySchemaDiagram(BodySchemaDiagramConfig(arm="2dof", babble_period=0.5))


def test_validity_noise_is_that_of_a_relative_pose():
    # z_ij = y_i^-1 y_j combines two markers' noise: sqrt(2) x the marker's RMS error,
    # floored for (nearly) noise-free sensors
    cfg = BodySchemaDiagramConfig(noise_pos=0.044, noise_orient=math.radians(3.0))
    s = cfg.search_config()
    assert s.sigma_pos == pytest.approx(math.sqrt(2) * 0.044)
    assert s.sigma_orient == pytest.approx(math.sqrt(2) * math.radians(3.0))
    s0 = BodySchemaDiagramConfig(noise_pos=0.0, noise_orient=0.0).search_config()
    assert s0.sigma_pos == pytest.approx(0.01) and s0.sigma_orient == pytest.approx(
        math.radians(3.0))


def test_learner_bad_config_raises():
    with pytest.raises(ValueError):
        SchemaLearner(parts=["a"], n_actions=1)
    with pytest.raises(ValueError):
        SchemaLearner(parts=["a", "b"], n_actions=0)
    with pytest.raises(ValueError):
        SchemaLearner(parts=["a", "b"], n_actions=1, end_effector="c")
    with pytest.raises(ValueError, match="settle_time"):
        SchemaLearner(parts=["a", "b"], n_actions=1,
                      config=SchemaLearnerConfig(settle_time=-1))
    with pytest.raises(ValueError):
        SchemaController(part=1, lower=[1.0], upper=[0.0])


def _frame(t, ids, poses, visible):
    return MarkerObservations(time=t, marker_ids=ids, poses=poses,
                              visible=np.asarray(visible, bool),
                              outlier=np.zeros(len(ids), bool))


def test_learner_drops_bad_frames_without_raising():
    lrn = SchemaLearner(parts=["a", "b"], n_actions=1,
                        config=SchemaLearnerConfig(settle_time=0.0))
    ctx = lrn.CreateDefaultContext()
    lrn.get_command_input_port().FixValue(ctx, [0.0])
    nan = RigidTransform()
    nan.set_translation([np.nan, 0, 0])
    bad = [_frame(0.0, ["a", "x"], [RigidTransform()] * 2, [1, 1]),      # unknown marker
           _frame(0.1, ["a", "b"], [RigidTransform(), nan], [1, 1]),      # NaN pose
           _frame(0.2, ["a", "b"], [RigidTransform()] * 2, [1, 0])]       # too few seen
    sim = Simulator(lrn, ctx)
    for k, f in enumerate(bad):
        lrn.get_observations_input_port().FixValue(ctx, AbstractValue.Make(f))
        sim.AdvanceTo(0.1 * k + 0.05)
    st = lrn.get_status_output_port().Eval(ctx)
    assert st[0] == 0 and st[1] == 3
    good = _frame(0.3, ["a", "b"], [RigidTransform(), RigidTransform([0, 0, 1.0])], [1, 1])
    lrn.get_observations_input_port().FixValue(ctx, AbstractValue.Make(good))
    sim.AdvanceTo(0.35)
    assert lrn.get_status_output_port().Eval(ctx)[0] == 1


# ------------------------------------------------------------------------- learning in Drake
@pytest.fixture(scope="module")
def learned_2dof():
    bs = MakeBodySchemaDiagram(BodySchemaDiagramConfig(arm="2dof", noise_pos=0.044,
                                                       noise_orient=0.0,
                                                       babble_fraction=0.6))
    sim, root = _sim(bs)
    history = {}
    for n in (10, 40):
        babble(bs, sim, n - bs.learner.state(root).n_samples, show_progress=False)
        history[n] = bs.learner.state(root)
    return bs, sim, root


@pytest.mark.slow
def test_drake_2dof_structure_within_10_samples_and_beats_noise(learned_2dof):
    bs, sim, root = learned_2dof
    st = bs.learner.state(root)
    sch = st.schema
    n_nodes = len(bs.parts)
    assert is_correct([(m.i, m.j, m.Q) for m in sch.tree], bs.truth, n_nodes)
    at = converged_at(st.history, bs.truth, n_nodes)
    assert at is not None and at <= 12
    Q = sample_test_commands(bs, 60, np.random.default_rng(3))
    pe, _ = prediction_error(bs, root, sch, Q)
    noise = observation_noise(bs, root, Q[:20], 0)
    assert 0.03 < noise < 0.05
    assert pe < noise  # the learned model predicts better than the sensor observes
    assert np.median(st.update_seconds) < 0.05  # far below the 0.1 s of a 10 Hz loop
    # outputs: predicted end-effector pose near the true one for the current command
    q = bs.diagram.GetOutputPort("command").Eval(root)
    X_WE = bs.diagram.GetOutputPort("X_WE").Eval(root)
    assert np.linalg.norm(X_WE.translation() - bs.true_poses(root, q)[-1, :3, 3]) < 0.15
    rows = bs.diagram.GetOutputPort("model_validity").Eval(root)
    assert sum(r["in_tree"] for r in rows) == n_nodes - 1


@pytest.mark.slow
def test_drake_schema_controller_positions_end_effector(learned_2dof):
    bs, sim, root = learned_2dof
    Q = sample_test_commands(bs, 3, np.random.default_rng(11))
    err = control_error(bs, sim, Q, 2.5, show_progress=False)
    assert err < 0.06  # thesis Fig. 3.10: ~0.050 m positioning error


@pytest.mark.slow
def test_drake_tool_change_detected_and_recovered():
    bs = MakeBodySchemaDiagram(BodySchemaDiagramConfig(arm="2dof", noise_pos=0.01,
                                                       noise_orient=0.0,
                                                       babble_fraction=0.6))
    sim, root = _sim(bs)
    babble(bs, sim, 20, show_progress=False)
    assert bs.learner.state(root).schema.valid
    bs.failures.change_tool(root, 0.10, math.radians(30))
    invalid = []
    for _ in range(60):
        babble(bs, sim, 1, show_progress=False)
        invalid.append(not bs.learner.state(root).schema.valid)
    assert any(invalid[:10])           # the failure is noticed
    assert not any(invalid[-5:])       # and a valid schema is back


@pytest.mark.slow
def test_meshcat_draws_learned_frames_and_tree():
    from pydrake.geometry import StartMeshcat

    meshcat = StartMeshcat()
    bs = MakeBodySchemaDiagram(BodySchemaDiagramConfig(arm="2dof", noise_pos=0.01),
                               meshcat=meshcat)
    sim, root = _sim(bs)
    babble(bs, sim, 12, show_progress=False)
    sim.AdvanceTo(root.get_time() + 0.2)
    assert bs.learner.state(root).schema.valid
    for p in bs.parts:
        assert meshcat.HasPath(f"/body_schema/parts/{p}/z")
    assert meshcat.HasPath("/body_schema/tree")
