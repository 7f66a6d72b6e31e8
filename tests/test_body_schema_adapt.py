"""Life-long adaptation of the body schema (thesis Sec. 3.3, Table 3.1)."""

import numpy as np
import pytest

from mmlearn.models.body_schema.schema import AdaptationConfig, BodySchema, SearchConfig
from mmlearn.models.body_schema.evaluation import recovery_experiment, structure_correct
from mmlearn.models.body_schema.local import EngineeredModel, se3_inv
from mmlearn.models.body_schema.kinematic_sim import make_arm_2dof, make_arm_7dof

CFG = SearchConfig(sigma_pos=0.02, sigma_orient=np.deg2rad(5.0))


def test_engineered_seed_is_exact_and_stays_valid():
    arm = make_arm_7dof()
    models = arm.engineered_models()
    assert all(isinstance(m, EngineeredModel) for m in models)
    s = BodySchema.from_models(models, arm.n_parts, arm.n_actions, search=CFG)
    assert s.valid and len(s.tree) == 9
    rng = np.random.default_rng(0)
    A = arm.sample_actions(20, rng)
    Y, X = arm.observe(A, rng, sigma_pos=0.01, sigma_orient=np.deg2rad(2), visibility=0.9)
    for a, y in zip(A, Y):
        st = s.update(a, y)
        assert st["valid"] and st["event"] is None
    T = s.forward_kinematics(A)
    np.testing.assert_allclose(T, se3_inv(X[:, :1]) @ X, atol=1e-9)
    # the engineered Jacobian (finite differences) through the tree
    J = s.jacobian(A[0], 9)
    assert J.shape == (6, 7) and np.all(np.isfinite(J))


@pytest.mark.slow
def test_blocked_joint_recovery_restore_and_recall():
    """Table 3.1, joint stuck: first occurrence bounded by patience + a few steps,
    restore and second occurrence (history recall) within a few steps."""
    r = recovery_experiment(make_arm_7dof, "joint", seed=3, n_block=60, visibility=0.92,
                            search=CFG)
    assert r["steps_invalid"][0] == 0
    assert r["first"] <= 16.5 + 4, r  # thesis 16.50 +- 1.20
    assert r["restore"] <= 3, r        # thesis 0.45
    assert r["second"] <= 3, r         # thesis 0.65
    assert any("sampled" in e for _, e in r["events"])
    # the stale model is noticed within the sliding window (~half of it must be bad)
    assert r["steps_stale"][2] <= 10 and r["steps_stale"][3] <= 10, r


@pytest.mark.slow
def test_tool_exchange_recovery():
    r = recovery_experiment(make_arm_7dof, "tool", seed=4, n_block=60, visibility=0.79,
                            search=CFG)
    assert r["first"] <= 20.2 + 4, r   # thesis 20.20
    assert r["restore"] <= 11.1, r
    assert r["second"] <= 12.1, r


def test_learning_from_scratch_with_updates_then_detects_change():
    arm = make_arm_2dof()
    rng = np.random.default_rng(5)
    s = BodySchema(arm.n_parts, arm.n_actions,
                   search=SearchConfig(sigma_pos=0.03, sigma_orient=np.deg2rad(5)),
                   adapt=AdaptationConfig(relearn_every=5))
    A = arm.sample_actions(120, rng)
    Y, _ = arm.observe(A, rng, sigma_pos=0.01, sigma_orient=np.deg2rad(2))
    for t in range(40):
        st = s.update(A[t], Y[t])
    assert st["valid"] and structure_correct(arm, s.tree, s.nodes)
    before = {id(m) for m in s.tree}
    # block q2: the x3-x4 model must be replaced by one trained on the new data
    arm.block_joint(1, 0.8)
    Y2, _ = arm.observe(A[40:], rng, sigma_pos=0.01, sigma_orient=np.deg2rad(2))
    n_invalid = 0
    for t in range(80):
        st = s.update(A[40 + t], Y2[t])
        n_invalid += not st["valid"]
    assert st["valid"]
    assert 5 <= n_invalid <= 25
    replaced = [m for m in s.tree if id(m) not in before]
    assert replaced and all(m.n_train >= 20 for m in replaced)
    assert {(m.i, m.j) for m in replaced} <= {(2, 3), (1, 3), (2, 4), (1, 2), (0, 3), (3, 4)}
    X = arm.forward(A[-10:])
    T = s.forward_kinematics(A[-10:])
    err = np.linalg.norm(T[:, 4, :3, 3] - (se3_inv(X[:, 0]) @ X[:, 4])[:, :3, 3], axis=1)
    assert err.mean() < 0.03


def test_candidate_order_prefers_structural_proximity():
    arm = make_arm_2dof()
    s = BodySchema.from_models(arm.engineered_models(), arm.n_parts, arm.n_actions,
                               search=CFG)
    failed = [m for m in s.tree if (m.i, m.j) == (2, 3)][0]
    # pretend x3-x4 failed: drop its track
    s.tracks = [t for t in s.tracks if t.model is not failed]
    cands = s.candidate_models()
    (i, j, Q), prox = cands[0]
    assert (i, j, Q) == (2, 3, (1,)) and prox == 1.0
    # all candidates bridge the two components {x1, x2, x3} and {x4, x5}
    for (i, j, _), _ in cands:
        assert (i <= 2) != (j <= 2)
    proxs = [p for _, p in cands]
    assert proxs == sorted(proxs, reverse=True)


def test_update_rejects_bad_shapes():
    s = BodySchema(5, 2)
    with pytest.raises(ValueError, match="poses"):
        s.update(np.zeros(2), np.zeros((4, 4, 4)))
    with pytest.raises(ValueError, match="actions"):
        s.update(np.zeros(3), np.zeros((5, 4, 4)))


@pytest.mark.slow
def test_engineered_models_seed_the_structure_search():
    arm = make_arm_7dof()
    rng = np.random.default_rng(6)
    A = arm.sample_actions(30, rng)
    Y, _ = arm.observe(A, rng, sigma_pos=0.01, sigma_orient=np.deg2rad(1))
    seeds = [m for m in arm.engineered_models() if (m.i, m.j) in ((3, 4), (4, 5))]
    from mmlearn.models.body_schema.search import learn_structure
    res = learn_structure(A, Y, config=CFG, seed_models=seeds)
    assert res.complete and structure_correct(arm, res.tree, res.nodes)
    used = [m for m in res.tree if isinstance(m, EngineeredModel)]
    assert len(used) == 2  # exact models beat the learned ones of the same complexity
    # an engineered model that does not fit (wrong geometry) is not valid and not used
    bent = make_arm_7dof()
    bent.bend_link(4, np.pi / 4)
    wrong = [m for m in bent.engineered_models() if (m.i, m.j) == (3, 4)]
    res = learn_structure(A, Y, config=CFG, seed_models=wrong)
    assert not any(isinstance(m, EngineeredModel) for m in res.tree)


@pytest.mark.slow
def test_bent_link_control_static_vs_adaptive_small():
    """Table 3.2 in a small setting: a 45 deg bend ruins control with the static model; the
    adapted model controls nearly as well as before."""
    from mmlearn.models.body_schema.evaluation import control_experiment
    from mmlearn.models.body_schema.kinematic_sim import make_arm_4dof

    r = control_experiment(make_arm_4dof, seed=0, n_learn=60, n_waypoints=6, n_adapt=70)
    assert r["intact_static"][0] < 0.02, r
    assert r["bent_static"][0] > 0.08, r
    assert r["bent_adaptive"][0] < 0.03, r
    assert r["valid"]


@pytest.mark.slow
def test_online_learner_finds_7dof_structure_within_12_samples():
    # the SchemaLearner's per-sample step (search at every sample before a first tree,
    # re-search at every sample while the tree rests on few samples) on the numpy 7-DOF
    # arm with x4 occluded, marker noise 0.01 m, 10% drop-outs: seeds 0-4, not chosen
    from mmlearn.systems.body_schema.learner import (
                                                     SchemaLearnerConfig,
                                                     SchemaLearnerState,
                                                     learn_sample,
                                                     )

    arm = make_arm_7dof()
    noise = 0.01
    cfg = SchemaLearnerConfig(search=SearchConfig(
        sigma_pos=np.sqrt(2) * noise, sigma_orient=np.deg2rad(3.0),
        noise_min_pos=0.25 * 2 * noise**2 / 3))
    correct = []
    for seed in range(5):
        rng = np.random.default_rng(seed)
        A = arm.sample_actions(12, rng)
        Y, _ = arm.observe(A, rng, sigma_pos=noise, visibility=0.9, occluded=[3])
        s = SchemaLearnerState(schema=BodySchema(arm.n_parts, arm.n_actions,
                                                 search=cfg.search, adapt=cfg.adapt))
        for a, y in zip(A, Y):
            s, accepted = learn_sample(cfg, s, a, y)
            assert accepted
        assert s.n_samples == 12 and len(s.history) == 12
        correct.append(s.schema.valid and structure_correct(arm, s.schema.tree, s.schema.nodes))
    assert sum(correct) >= 4, correct


def test_refinement_replaces_the_tree_models_an_invalid_tree_keeps_them():
    arm = make_arm_2dof()
    rng = np.random.default_rng(2)
    A = arm.sample_actions(30, rng)
    Y, _ = arm.observe(A, rng, sigma_pos=0.01, sigma_orient=np.deg2rad(2))
    s = BodySchema(arm.n_parts, arm.n_actions, search=CFG)
    s.fit(A[:15], Y[:15])
    for t in range(15, 30):
        s.update(A[t], Y[t])
    assert s.valid
    old = {id(m) for m in s.tree}
    assert s.relearn().complete
    tracked = {id(t.model) for t in s.tracks}
    assert not old & tracked  # superseded by the search on more data, not archived
    assert {id(m) for m in s.tree} <= tracked and s.valid
    s.valid = False  # an invalid tree's models go to the history (Sec. 3.3)
    old = {id(m) for m in s.tree}
    assert s.relearn().complete
    assert old <= {id(t.model) for t in s.tracks if t.status == "history"}
