"""The DBN of constraints (models/imitation/dbn.py, thesis ch. 8): alignment, the per-slice
Gaussians, the incremental product of constraints (the sign test) and obstacle avoidance."""

import warnings

import numpy as np
import pytest
from imitation_tasks import const_model, planar_fk, planar_jacobian, reach_demos

from mmlearn.models.imitation.dbn import (align_demonstrations, constraint_step, derivative,
                                          fill_gaps, learn_task, reproduce_cartesian)
from mmlearn.models.imitation.types import Demonstration, ImitationDataError, Obstacle, TaskModel


def _path(tau):
    return np.stack([0.3 * np.sin(2 * np.pi * tau), 0.5 * tau, 0.1 * np.cos(3 * tau)], axis=1)


def _demo(warp, T, dt=0.2, noise=0.0, rng=None):
    t = np.arange(0.0, T + 1e-9, dt)
    tau = warp(t / T)
    hand = _path(tau)
    if noise:
        hand = hand + noise * rng.standard_normal(hand.shape)
    return Demonstration(t=t, hand=hand, objects={"cup": np.tile([0.5, 0.2, 0.1], (len(t), 1))},
                         gripper=(tau > 0.5).astype(float))


# ------------------------------------------------------------------------------------------
def test_alignment_recovers_known_warp():
    ref = _demo(lambda u: u, T=20.0)
    warp = lambda u: u + 0.06 * np.sin(2 * np.pi * u)          # speed 0.62 .. 1.38, 18 s long
    other = _demo(warp, T=18.0)
    al = align_demonstrations([ref, other], reference=0)
    assert al[1].T == ref.T and np.allclose(al[1].t, ref.t)
    err = np.abs(al[1].hand - ref.hand).mean()
    # without alignment: only the durations scaled
    naive = np.stack([np.interp(ref.t * 18 / 20, other.t, other.hand[:, c]) for c in range(3)], 1)
    err_naive = np.abs(naive - ref.hand).mean()
    assert err < 0.4 * err_naive, (err, err_naive)       # measured 0.0071 m vs 0.0212 m
    # the gripper event is aligned to within one sample
    assert abs(np.argmax(al[1].gripper > 0.5) - np.argmax(ref.gripper > 0.5)) <= 1
    # the thesis' derivative-only features also align (less precisely, see the docstring)
    al_d = align_demonstrations([ref, other], reference=0, features="derivative")
    assert np.abs(al_d[1].hand - ref.hand).mean() < 0.6 * err_naive   # measured 0.0112 m


def test_derivative_estimate_is_keogh_pazzani():
    x = np.array([0.0, 1.0, 4.0, 9.0, 16.0])[:, None]
    d = derivative(x)
    assert d[2, 0] == pytest.approx(((4 - 1) + (9 - 1) / 2) / 2)
    assert d[0, 0] == d[1, 0] and d[-1, 0] == d[-2, 0]


def test_gaps_are_interpolated_and_single_demo_warns():
    d = _demo(lambda u: u, T=4.0)
    d.hand[3:6] = np.nan
    d.hand[0] = np.nan
    f = fill_gaps(d)
    truth = _demo(lambda u: u, T=4.0).hand
    assert not np.isnan(f.hand).any() and f.meta["gap_frames"] == 4
    np.testing.assert_allclose(f.hand[4], truth[2] + (truth[6] - truth[2]) / 2)
    np.testing.assert_allclose(f.hand[0], truth[1])                 # leading gap holds
    with pytest.warns(UserWarning, match="single demonstration"):
        al = align_demonstrations([d])
    assert len(al) == 1 and not np.isnan(al[0].hand).any()
    with pytest.warns(UserWarning, match="single demonstration"):
        m = learn_task([d])
    assert m.S == d.T and np.all(m.var["obj:cup"] > 0)


def test_per_slice_gaussians_equal_hand_computation():
    rng = np.random.default_rng(3)
    t = np.arange(4) * 0.2
    demos = [Demonstration(t=t, hand=rng.normal(size=(4, 2)), objects={"o": rng.normal(size=(4, 2))},
                           joints=rng.normal(size=(4, 3))) for _ in range(3)]
    h = 0.2
    for full in (False, True):
        m = learn_task(demos, h=h, align=False, full_covariance=full, min_var=1e-12)
        for k in range(4):
            w = np.array([[np.exp(-0.5 * ((tp - t[k]) / h) ** 2) for tp in t] for _ in demos])   # Eq. 8.10-8.11
            w /= w.sum()                                                                          # Eq. 8.12
            for c, vals in (("obj:o", [d.objects["o"] - d.hand for d in demos]),
                            ("joints", [d.joints for d in demos])):
                mu = sum(w[g, j] * vals[g][j] for g in range(3) for j in range(4))              # Eq. 8.13/8.15
                cov = sum(w[g, j] * np.outer(vals[g][j] - mu, vals[g][j] - mu)
                          for g in range(3) for j in range(4)) / (1 - np.sum(w ** 2))           # Eq. 8.14/8.16
                np.testing.assert_allclose(m.mean[c][k], mu, atol=1e-12)
                np.testing.assert_allclose(m.var[c][k], cov if full else np.diag(cov), atol=1e-10)


def test_learned_model_roundtrip(tmp_path):
    rng = np.random.default_rng(0)
    demos = [_demo(lambda u, a=a: u ** a, T=10 + rng.normal(), noise=0.005, rng=rng) for a in (1, 1.1, 0.9)]
    m = learn_task(demos)
    assert m.constraints == ["obj:cup", "gripper"] and m.meta["n_demos"] == 3 and m.meta["h"] == 0.2
    back = TaskModel.load(m.save(tmp_path / "task.json"))
    np.testing.assert_allclose(back.var["obj:cup"], m.var["obj:cup"])


# ------------------------------------------------------------------------------------------
def test_sign_single_constraint_hand_converges_to_object_minus_mean():
    """Eq. 8.18 as printed (mu - (x_i - x_E)) would push the hand away; corrected it converges."""
    m = const_model(40, {"obj:a": [0.1, -0.05]}, {"obj:a": [1e-4, 1e-4]})
    x_a = np.array([0.55, 0.35])
    q = np.array([0.3, 0.5, 0.4])
    for k in range(40):
        r = constraint_step(m, k, hand=planar_fk(q), objects={"a": x_a}, J=planar_jacobian(q), use_joints=False)
        q = q + r.dq
    np.testing.assert_allclose(planar_fk(q), x_a - [0.1, -0.05], atol=1e-4)
    np.testing.assert_allclose(r.target_hand, x_a - [0.1, -0.05])


def test_sign_two_constraints_land_at_precision_weighted_combination():
    va, vb = np.array([1e-4, 4e-4]), np.array([4e-4, 1e-4])
    m = const_model(40, {"obj:a": [0.1, 0.0], "obj:b": [0.0, -0.2]}, {"obj:a": va, "obj:b": vb})
    objs = {"a": np.array([0.6, 0.3]), "b": np.array([0.3, 0.1])}
    ta, tb = objs["a"] - [0.1, 0.0], objs["b"] - [0.0, -0.2]
    expect = (ta / va + tb / vb) / (1 / va + 1 / vb)
    # a point hand (J = I) ...
    _, x = reproduce_cartesian(m, [0.0, 0.0], objs, damping=0.1)
    np.testing.assert_allclose(x[-1], expect, atol=1e-6)
    # ... and a redundant planar arm (n = 3 > D = 2)
    q = np.array([0.3, 0.5, 0.4])
    for k in range(40):
        q = q + constraint_step(m, k, hand=planar_fk(q), objects=objs, J=planar_jacobian(q), use_joints=False).dq
    np.testing.assert_allclose(planar_fk(q), expect, atol=1e-4)
    # the same constraints given as full covariances fuse to the same point
    mf = TaskModel(t=m.t, constraints=m.constraints, mean=m.mean,
                   var={c: np.stack([np.diag(v) for v in m.var[c]]) for c in m.constraints}, meta=m.meta)
    rf = constraint_step(mf, 3, hand=[0.0, 0.0], objects=objs, J=np.eye(2), use_joints=False, damping=0.0)
    np.testing.assert_allclose(rf.dq, expect, atol=1e-9)
    # an object not observed this step is skipped, not a crash
    r = constraint_step(m, 0, hand=planar_fk(q), objects={"a": objs["a"], "b": [np.nan, 0.0]}, J=planar_jacobian(q),
                        use_joints=False)
    assert r.info["skipped"] == ["obj:b"] and np.allclose(r.target_hand, ta)


def test_joint_constraint_and_switch():
    mu = np.array([0.2, -0.4, 0.6])
    m = const_model(30, {"joints": mu}, {"joints": [1e-3] * 3})
    q = np.zeros(3)
    for k in range(30):
        q = q + constraint_step(m, k, hand=planar_fk(q), objects={}, J=planar_jacobian(q), q=q).dq
    np.testing.assert_allclose(q, mu, atol=1e-6)
    r = constraint_step(m, 0, hand=planar_fk(q), objects={}, J=planar_jacobian(q), q=q * 0, use_joints=False)
    assert np.all(r.dq == 0)
    with pytest.raises(ImitationDataError, match="pass q or use_joints=False"):
        constraint_step(m, 0, hand=planar_fk(q), objects={}, J=planar_jacobian(q))


def test_obstacle_attractor_keeps_positive_clearance():
    m = learn_task(reach_demos())
    c, s = np.cos(np.pi / 4), np.sin(np.pi / 4)
    box = Obstacle(centre=[0.5, 0.08], half_size=[0.1, 0.1], R=[[c, -s], [s, c]])   # a corner cuts the path
    objs = {"target": np.array([1.0, 0.0])}

    def clearance(x):
        dense = np.concatenate([np.linspace(a, b, 10) for a, b in zip(x[:-1], x[1:])])
        return float(box.signed_distance(dense).min())

    _, plain = reproduce_cartesian(m, [0.0, 0.0], objs, substeps=5, max_step=0.02)
    _, avoid = reproduce_cartesian(m, [0.0, 0.0], objs, substeps=5, max_step=0.02, obstacles=[box],
                                   extra_time=2.0)
    assert clearance(plain) < -0.03
    assert clearance(avoid) > 0.0
    assert np.linalg.norm(avoid[-1] - [1.0, 0.0]) < 0.02     # and still reaches the target (around the corner)


# ------------------------------------------------------------------------------------------
def test_bad_input_is_named():
    d = _demo(lambda u: u, T=4.0)
    with pytest.raises(ImitationDataError, match="no demonstrations"):
        learn_task([])
    d2 = Demonstration(t=d.t, hand=d.hand[:, :2], objects={})
    with pytest.raises(ImitationDataError, match="demonstration 1: hand has 2 dimensions"):
        align_demonstrations([d, d2])
    bad = Demonstration(t=d.t, hand=np.full_like(d.hand, np.nan), objects={})
    with pytest.raises(ImitationDataError, match="demonstration 1: hand: NaN in every frame"):
        learn_task([d, bad])
    with pytest.raises(ImitationDataError, match="h must be a positive"):
        learn_task([d], h=0.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = learn_task([d, _demo(lambda u: u, T=5.0)])          # different lengths are legal
    J = np.eye(3)
    with pytest.raises(ImitationDataError, match="hand must be a finite"):
        constraint_step(m, 0, hand=[np.nan, 0, 0], objects={}, J=J)
    with pytest.raises(ImitationDataError, match=r"J must be a finite \(3, n\)"):
        constraint_step(m, 0, hand=[0, 0, 0], objects={}, J=np.eye(2))
    with pytest.raises(ImitationDataError, match="outside the model's slices"):
        constraint_step(m, m.S, hand=[0, 0, 0], objects={}, J=J)
    with pytest.raises(ImitationDataError, match="features must be"):
        align_demonstrations([d, d], features="speed")
    # objects present in only some demonstrations are dropped with a warning
    d3 = _demo(lambda u: u, T=4.0)
    d3.objects["extra"] = d3.hand + 1
    with pytest.warns(UserWarning, match=r"\['extra'\] are not in every demonstration"):
        al = align_demonstrations([d, d3])
    assert set(al[1].objects) == {"cup"}




def _two_tables(shift_a):
    """Two demonstrations of a hand that goes to table b; table a is elsewhere and moves
    between them by ``shift_a`` (x, y), m."""
    t = np.arange(0.0, 4.0 + 1e-9, 0.2)
    out = []
    for g, sh in enumerate(([0.0, 0.0], shift_a)):
        b = np.array([0.5, -0.3 + 0.01 * g, 0.3])
        a = np.array([0.5, 0.3, 0.3]) + np.r_[sh, 0.0]
        hand = b + np.array([0.0, 0.0, 0.1]) + 0.002 * np.sin(t + g)[:, None]
        out.append(Demonstration(t=t, hand=hand, objects={"table_a": np.tile(a, (len(t), 1)),
                                                          "table_b": np.tile(b, (len(t), 1))}))
    return out


@pytest.mark.parametrize("full", [False, True])
def test_isotropic_prior_pools_an_objects_spread_over_the_directions(full):
    # table a moved 0.6 m along y between the demonstrations but not along x: unpooled,
    # its x relation looks as certain as table b's and steers x; with the prior it does not
    demos = _two_tables([0.0, 0.6])
    plain = learn_task(demos, use_joints=False, align=False, full_covariance=full)
    pooled = learn_task(demos, use_joints=False, align=False, full_covariance=full,
                        isotropic_prior=1.0)
    k = plain.S // 2
    va, vb = plain.covariance("obj:table_a", k), plain.covariance("obj:table_b", k)
    pa = pooled.covariance("obj:table_a", k)
    assert va[0, 0] < 1e-3 < va[1, 1]
    # posterior mean (nu * mean variance * I + G * Sigma) / (nu + G), nu = 1, G = 2
    assert pa[0, 0] == pytest.approx((np.trace(va) / 3 + 2 * va[0, 0]) / 3, rel=1e-9)
    assert np.trace(pa) == pytest.approx(np.trace(va), rel=1e-9)     # the spread is kept
    assert pooled.meta["isotropic_prior"] == 1.0 and plain.meta["isotropic_prior"] == 0.0
    assert np.allclose(plain.mean["obj:table_a"], pooled.mean["obj:table_a"])
    # a new scene: table a 0.06 m further along x than table b. The hand's x target follows
    # table a's x shift by its share of the x precision; the prior shrinks that share
    objs = {"table_a": np.array([0.56, 0.3, 0.3]), "table_b": np.array([0.5, -0.3, 0.3])}
    want = objs["table_b"] - plain.mean["obj:table_b"][k]
    dx = [abs(constraint_step(m, k, hand=want, objects=objs, J=np.eye(3),
                              use_joints=False).target_hand[0] - want[0]) for m in (plain, pooled)]
    assert dx[0] > 0.01 and dx[1] < 0.2 * dx[0], dx
    with pytest.raises(ImitationDataError, match="isotropic_prior"):
        learn_task(demos, use_joints=False, align=False, isotropic_prior=-1.0)
