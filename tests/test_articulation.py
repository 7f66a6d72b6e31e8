"""Tests of the articulation link models, selection, trees, persistence and SDF export."""

import os

os.environ.setdefault("DRAKE_ALLOW_NETWORK", "meshcat")

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mmlearn.models.articulation.link import (GPModel, ObservationModel, PrismaticModel,
                                              RevoluteModel, RigidModel, make_model)
from mmlearn.models.articulation.io import load_model, save_model, to_sdf
from mmlearn.models.articulation.sim import _BASE_R, simulate_link, true_pose
from mmlearn.models.articulation.structure import fit_kinematic_tree, select_link_model
from mmlearn.models.common.se3 import as_pose_array, relative_poses, rotation_distance

OBS = ObservationModel(sigma_pos=0.002, sigma_orient=np.deg2rad(2.0))
AXIS_Z = _BASE_R.apply([0, 0, 1.0])


def _angle(a, b):
    c = abs(np.dot(a, b)) / np.linalg.norm(a) / np.linalg.norm(b)
    return np.degrees(np.arccos(min(1.0, c)))


# ------------------------------------------------------------------ se3
def test_se3_roundtrip_and_relative():
    rng = np.random.default_rng(0)
    q = Rotation.random(5, random_state=1).as_quat()
    p7 = np.hstack([rng.normal(size=(5, 3)), q])
    T = as_pose_array(p7).as_matrices()
    back = as_pose_array(T).as_array()
    assert np.allclose(back[:, :3], p7[:, :3])
    assert np.all(rotation_distance(Rotation.from_quat(back[:, 3:]), Rotation.from_quat(q)) < 1e-9)
    z = relative_poses(p7, p7[::-1])
    Tz = z.as_matrices()
    assert np.allclose(Tz, np.linalg.inv(T) @ T[::-1], atol=1e-12)
    with pytest.raises(ValueError, match="NaN"):
        as_pose_array(np.full((3, 7), np.nan))
    with pytest.raises(ValueError, match="shape"):
        as_pose_array(np.zeros((4, 5)))


# ------------------------------------------------------------------ single models
def test_revolute_recovers_radius_axis_center():
    tr = simulate_link("microwave", 60, rng=1)
    sel = select_link_model(tr.Z, obs=OBS, rng=0)
    assert sel.selected == "revolute"
    m = sel.best
    assert abs(m.radius - 0.3) < 0.005
    assert _angle(m.axis, AXIS_Z) < 2.0
    true_center = true_pose("microwave", [0.0])[0, :3] - _BASE_R.apply([0.3, 0, 0])
    assert np.linalg.norm(m.center - true_center) < 0.01
    assert m.q_max[0] - m.q_min[0] == pytest.approx(np.ptp(tr.q), abs=0.05)
    assert m.avg_pos_error_ < 2.5 * OBS.sigma_pos
    assert set(sel.bic) == {"rigid", "prismatic", "revolute", "gp"}
    assert sel.bic["revolute"] == min(sel.bic.values())


def test_prismatic_recovers_axis_and_range():
    tr = simulate_link("drawer", 40, rng=2)
    sel = select_link_model(tr.Z, obs=OBS, rng=0)
    assert sel.selected == "prismatic"
    e_true = _BASE_R.apply(np.array([1.0, 0.2, 0.1]) / np.linalg.norm([1.0, 0.2, 0.1]))
    assert _angle(sel.best.axis, e_true) < 1.0
    assert sel.best.q_max[0] - sel.best.q_min[0] == pytest.approx(np.ptp(tr.q), abs=0.01)


def test_rigid_and_gp_selection():
    tr = simulate_link("rigid", 30, rng=3)
    assert select_link_model(tr.Z, obs=OBS, rng=0).selected == "rigid"
    roll = simulate_link("rollup", 60, sigma_pos=0.01, rng=4)
    sel = select_link_model(roll.Z, obs=ObservationModel(0.01, np.deg2rad(2)), rng=0)
    assert sel.selected == "gp", sel.bic
    assert sel.best.avg_pos_error_ < 0.02


@pytest.mark.parametrize("kind,model,gamma", [("rigid", "rigid", 0.9),
                                              ("drawer", "prismatic", 0.75),
                                              ("microwave", "revolute", 0.6)])
def test_outlier_robustness_and_gamma(kind, model, gamma):
    sp = 0.01
    obs = ObservationModel(sp, np.deg2rad(3))
    tr = simulate_link(kind, 100, sigma_pos=sp, sigma_orient=np.deg2rad(3), gamma=gamma, rng=7)
    m = make_model(model, obs=obs).fit(tr.Z, rng=1)
    ep, _ = m.residuals(tr.Z_true)
    assert ep.mean() < sp  # below the noise level
    assert abs(m.gamma - tr.outlier.mean()) < 0.05


def test_rigid_at_95_percent_outliers_finds_exactly_the_inliers():
    # Fig. 4.21 at gamma = 0.95: whenever the data hold more inliers than a minimal sample
    # (k >= 2), the rigid MLESAC estimate is the mean of exactly the true inliers; runs with
    # k <= 1 are unidentifiable (any single outlier explains the data as well).
    sp, so = 0.01, np.deg2rad(3)
    rng = np.random.default_rng(11)
    errs, few = [], 0
    for _ in range(60):
        tr = simulate_link("rigid", 100, sigma_pos=sp, sigma_orient=so, gamma=0.95, rng=rng)
        inl = ~tr.outlier
        if inl.sum() <= 1:
            few += 1
            continue
        m = RigidModel(obs=ObservationModel(sp, so)).fit(tr.Z, rng=rng)
        assert np.array_equal(m.inliers_, inl)
        assert np.allclose(m.theta[:3], tr.Z[inl, :3].mean(axis=0), atol=1e-6)
        assert abs(m.gamma - tr.outlier.mean()) < 0.02
        errs.append(np.linalg.norm(m.theta[:3] - tr.Z_true[0, :3]))
    assert few < 10 and np.mean(errs) < sp  # below the noise level on identifiable runs


def test_exact_outlier_ratio_rigid_below_noise_at_95_percent():
    # Fig. 4.21 with sequences of exactly round(gamma n) outliers: the rigid MLESAC estimate
    # stays below the noise level at gamma = 0.95 in every run (5 inliers of 100).
    sp, so = 0.01, np.deg2rad(3)
    rng = np.random.default_rng(3)
    errs = []
    for _ in range(20):
        tr = simulate_link("rigid", 100, sigma_pos=sp, sigma_orient=so, gamma=0.95, rng=rng,
                           exact_ratio=True)
        assert int(tr.outlier.sum()) == 95
        m = RigidModel(obs=ObservationModel(sp, so)).fit(tr.Z, rng=rng)
        assert np.array_equal(m.inliers_, ~tr.outlier)
        errs.append(np.linalg.norm(m.theta[:3] - tr.Z_true[0, :3]))
    assert np.mean(errs) < sp  # the mean of 5 noisy inliers: ~0.007 m


def test_position_only_track():
    tr = simulate_link("microwave", 50, rng=5)
    m = RevoluteModel(obs=OBS).fit(tr.Z[:, :3], rng=0)
    assert not m.has_orientation
    assert abs(m.radius - 0.3) < 0.01
    assert m.avg_orient_error_ is None
    assert m.num_params_ == 9
    assert m.forward([[0.1]]).shape == (1, 3)
    assert m.jacobian([[0.1]]).shape == (1, 3, 1)
    e_pos, e_ori = m.prediction_errors(tr.Z[:, :3])
    assert e_ori is None and e_pos < 0.005


@pytest.mark.parametrize("name", ["rigid", "prismatic", "revolute", "gp"])
def test_forward_inverse_jacobian_consistency(name):
    kind = {"rigid": "rigid", "prismatic": "drawer", "revolute": "microwave",
            "gp": "rollup"}[name]
    tr = simulate_link(kind, 40, sigma_pos=0.001, sigma_orient=np.deg2rad(1), rng=6)
    m = make_model(name, obs=ObservationModel(0.001, np.deg2rad(1))).fit(tr.Z, rng=0)
    q = m.inverse(tr.Z_true)
    assert q.shape == (40, m.dof)
    P = m.forward(q)
    assert np.mean(np.linalg.norm(P[:, :3] - tr.Z_true[:, :3], axis=1)) < 0.01
    if m.dof:
        q0 = (0.5 * (m.q_min + m.q_max))[None]
        J = m.jacobian(q0)[0]
        h = 1e-6 * max(1.0, float(np.ptp(q)))
        fp, fm = m.forward(q0 + h), m.forward(q0 - h)
        assert np.allclose(J[:3, 0], (fp[0, :3] - fm[0, :3]) / (2 * h), atol=1e-4)
        w = (Rotation.from_quat(fp[0, 3:]) * Rotation.from_quat(fm[0, 3:]).inv()).as_rotvec()
        assert np.allclose(J[3:, 0], w / (2 * h), atol=1e-3)
        # the configuration increases along the training track's motion
        assert m.q_max[0] > 0 and m.q_min[0] <= 1e-9


def test_bad_input_raises():
    with pytest.raises(ValueError, match="too short"):
        RevoluteModel(obs=OBS).fit(np.zeros((2, 7)) + [0, 0, 0, 0, 0, 0, 1])
    bad = simulate_link("microwave", 10, rng=0).Z
    bad[3, 1] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        select_link_model(bad, obs=OBS)
    with pytest.raises(ValueError, match="degenerate"):
        RevoluteModel(obs=OBS).fit(np.tile([0.1, 0.2, 0.3], (10, 1)), rng=0)
    with pytest.raises(ValueError, match="unknown link model"):
        make_model("screw")
    with pytest.raises(ValueError, match="sigma_pos"):
        ObservationModel(sigma_pos=-1)


# ------------------------------------------------------------------ persistence
@pytest.mark.parametrize("ext", ["json", "yaml"])
def test_save_load_identical_predictions(tmp_path, ext):
    tr = simulate_link("microwave", 30, rng=8)
    for name in ["rigid", "prismatic", "revolute", "gp"]:
        m = make_model(name, obs=OBS).fit(tr.Z, rng=0)
        path = tmp_path / f"{name}.{ext}"
        save_model(m, path)
        m2 = load_model(path)
        assert type(m2) is type(m) and m2.name == m.name
        q = m.inverse(tr.Z)
        assert np.array_equal(m2.inverse(tr.Z), q)
        assert np.array_equal(m2.forward(q), m.forward(q))
        assert np.array_equal(m2.jacobian(q), m.jacobian(q))
        assert m2.bic(tr.Z) == m.bic(tr.Z)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        f"{n}.{ext}" for n in ["rigid", "prismatic", "revolute", "gp"])  # no temp files left
    with pytest.raises(ValueError, match="extension"):
        save_model(m, tmp_path / "x.txt")


# ------------------------------------------------------------------ trees + SDF
def _cabinet(T=60, seed=0):
    """Cabinet (part 0) with a drawer (part 1) and a door (part 2); drawer unseen at some
    steps."""
    rng = np.random.default_rng(seed)
    Rb = Rotation.from_euler("z", 0.4)
    pb = np.array([1.0, 0.5, 0.3])
    q1 = np.linspace(0, 0.3, T)
    q2 = np.linspace(0, 1.2, T)

    def noisy(P, R):
        return np.hstack([P + rng.normal(0, 0.002, P.shape),
                          (Rotation.from_rotvec(rng.normal(0, 0.003, (T, 3))) * R).as_quat()])

    Rbs = Rotation.from_quat(np.tile(Rb.as_quat(), (T, 1)))
    Y0 = noisy(np.tile(pb, (T, 1)), Rbs)
    Y1 = noisy(pb + Rb.apply(np.array([0.1, 0, 0]) + q1[:, None] * [1.0, 0, 0]), Rbs)
    Rd = Rbs * Rotation.from_rotvec(q2[:, None] * [0, 0, 1.0])
    Y2 = noisy(pb + Rb.apply([0, 0.5, 0]) + Rd.apply([0.4, 0, 0]), Rd)
    Y1[::7] = np.nan
    return [Y0, Y1, Y2], q1, q2


@pytest.mark.slow
def test_kinematic_tree_and_sdf_export(tmp_path):
    (Y0, Y1, Y2), q1, q2 = _cabinet()
    obs = ObservationModel(0.003, 0.005)
    obj = fit_kinematic_tree([Y0, Y1, Y2], part_names=["cabinet", "drawer", "door"], obs=obs,
                             rng=0)
    kinds = {(obj.part_names[e.parent], obj.part_names[e.child]): e.model.name
             for e in obj.edges}
    assert kinds == {("cabinet", "drawer"): "prismatic", ("cabinet", "door"): "revolute"}
    assert obj.dof == 2
    assert np.isfinite(obj.total_bic)
    door = [e.model for e in obj.edges if e.model.name == "revolute"][0]
    assert abs(door.radius - 0.4) < 0.01
    q = obj.configuration(np.stack([Y0[20], Y1[20], Y2[20]]))
    order = [e.model.name for e in obj.edges]
    assert q[order.index("prismatic")] == pytest.approx(q1[20] - q1[1], abs=0.01)
    J = obj.jacobian(q)
    assert J.shape == (12, 2)

    save_model(obj, tmp_path / "obj.yaml")
    obj2 = load_model(tmp_path / "obj.yaml")
    assert np.array_equal(obj2.forward(q), obj.forward(q))

    sdf = to_sdf(obj, model_name="cabinet_learned")
    from pydrake.multibody.parsing import Parser
    from pydrake.multibody.plant import MultibodyPlant
    from pydrake.multibody.tree import JointIndex

    plant = MultibodyPlant(0.0)
    old = os.environ.get("DRAKE_ALLOW_NETWORK")
    # the Parser registers the (remote) drake_models package in its constructor
    os.environ["DRAKE_ALLOW_NETWORK"] = "meshcat:package_map"
    try:
        parser = Parser(plant)
    finally:
        if old is None:
            os.environ.pop("DRAKE_ALLOW_NETWORK")
        else:
            os.environ["DRAKE_ALLOW_NETWORK"] = old
    parser.AddModels(file_contents=sdf, file_type="sdf")
    plant.Finalize()
    joints = {plant.get_joint(JointIndex(i)).name(): plant.get_joint(JointIndex(i))
              for i in range(plant.num_joints())}
    assert joints["cabinet__drawer"].type_name() == "prismatic"
    assert joints["cabinet__door"].type_name() == "revolute"
    assert joints["cabinet__door"].position_upper_limits()[0] == pytest.approx(
        door.q_max[0], abs=1e-6)
    ctx = plant.CreateDefaultContext()
    qd = np.zeros(plant.num_positions())
    for e, qi in zip(obj.edges, q):
        j = joints[f"{obj.part_names[e.parent]}__{obj.part_names[e.child]}"]
        qd[j.position_start()] = qi
    plant.SetPositions(ctx, qd)
    T = obj.forward(q)
    for k, name in enumerate(obj.part_names):
        X = plant.EvalBodyPoseInWorld(ctx, plant.GetBodyByName(name))
        assert np.allclose(X.GetAsMatrix4(), T[k], atol=1e-6), name


def test_tree_rejects_disconnected():
    (Y0, Y1, Y2), _, _ = _cabinet(T=20)
    Y2[:] = np.nan
    with pytest.raises(ValueError, match="cannot be connected"):
        fit_kinematic_tree([Y0, Y1, Y2], obs=OBS, rng=0)


# ------------------------------------------------------------------ real data
DATA = Path(__file__).parent / "data" / "articulation_logs"


def test_real_tracks_select_expected_models():
    from mmlearn.models.common.track_io import read_track

    obs = ObservationModel(0.01, np.deg2rad(5))
    res = {}
    for f in ["drawer_001.log", "left_door_001.log", "dishwasher_005.log"]:
        t = read_track(DATA / f)
        res[f] = select_link_model(t.poses, obs=obs, rng=0, models="rigid,prismatic,revolute")
    assert res["drawer_001.log"].selected == "prismatic"
    assert res["left_door_001.log"].selected == "revolute"
    assert 0.3 < res["left_door_001.log"].best.radius < 0.4
    assert res["dishwasher_005.log"].selected == "revolute"
    assert 0.3 < res["dishwasher_005.log"].best.radius < 0.7
    for s in res.values():
        assert s.best.avg_pos_error_ < 0.01  # near the noise level


@pytest.mark.slow
def test_matrix_input_and_gp_variants():
    tr = simulate_link("microwave", 40, rng=9)
    T = as_pose_array(tr.Z).as_matrices()
    a = RevoluteModel(obs=OBS).fit(tr.Z, rng=0)
    b = RevoluteModel(obs=OBS).fit(T, rng=0)
    assert b.radius == pytest.approx(a.radius, abs=1e-6)
    assert np.allclose(b.inverse(T), a.inverse(tr.Z), atol=1e-9)
    roll = simulate_link("rollup", 50, sigma_pos=0.005, rng=1)
    obs = ObservationModel(0.005, np.deg2rad(2))
    for name, dof in [("gp2", 2), ("gp-lle", 1)]:
        m = make_model(name, obs=obs).fit(roll.Z, rng=0)
        assert m.dof == dof and m.num_params_ == 1 + dof + 6 * 50
        assert m.avg_pos_error_ < 0.02
        assert m.jacobian(m.q_min[None]).shape == (1, 6, dof)


# ------------------------------------------------------------------ refinement
@pytest.mark.parametrize("kind,model", [("rigid", "rigid"), ("drawer", "prismatic"),
                                        ("microwave", "revolute")])
def test_fast_refinement_matches_quasi_newton(kind, model):
    """EM (rigid, prismatic) and Levenberg-Marquardt (revolute) reach at least the optimum of
    the generic L-BFGS refinement of the same objective (clean and outlier-laden tracks, full
    poses and position-only), and the final likelihood matches a recomputation."""
    obs = ObservationModel(0.01, np.deg2rad(3.0))
    worse = []
    for seed, gamma in [(0, 0.0), (1, 0.3), (2, 0.6)]:
        tr = simulate_link(kind, 60, sigma_pos=0.01, sigma_orient=np.deg2rad(3), gamma=gamma,
                           rng=seed)
        for Z in (tr.Z, tr.Z[:, :3]):
            fast = make_model(model, obs=obs).fit(Z, rng=seed)
            slow = make_model(model, obs=obs)
            slow.refinement = "lbfgs"
            slow.fit(Z, rng=seed)
            worse.append(slow.log_likelihood_ - fast.log_likelihood_)
            assert fast.log_likelihood(Z) == pytest.approx(fast.log_likelihood_, abs=1e-6)
            assert abs(fast.gamma - tr.outlier.mean()) < 0.1
    assert max(worse) < 0.5, worse


def test_rotation_helpers_agree():
    from mmlearn.models.articulation.link import _log_rot, _m2rv, _rv2m

    rng = np.random.default_rng(0)
    rv = rng.normal(size=(50, 3))
    rv *= (rng.uniform(0, np.pi - 1e-3, 50) / np.linalg.norm(rv, axis=1))[:, None]
    rv[0] = 0.0
    rv[1] = [1e-9, 0, 0]
    R = Rotation.from_rotvec(rv).as_matrix()
    assert np.allclose(_rv2m(rv), R, atol=1e-12)
    assert np.allclose(_m2rv(R), rv, atol=1e-9)
    assert np.allclose(_log_rot(R), rv, atol=1e-9)
    assert _rv2m(rv.reshape(5, 10, 3)).shape == (5, 10, 3, 3)
    assert _m2rv(R.reshape(5, 10, 3, 3)).shape == (5, 10, 3)
    # one vector / matrix (the scalar path) and angles within 1e-4 of pi, where the axis
    # comes from the symmetric part: the same as scipy's to ~1e-15
    for k in range(5):
        assert np.allclose(_rv2m(rv[k]), R[k], atol=1e-14)
        assert np.allclose(_m2rv(R[k]), rv[k], atol=1e-12)
    axis = rng.normal(size=(20, 3))
    near_pi = axis / np.linalg.norm(axis, axis=1)[:, None] * (
        np.pi - rng.uniform(0, 1e-4, 20))[:, None]
    Rp = Rotation.from_rotvec(near_pi).as_matrix()
    assert np.allclose(_m2rv(Rp), near_pi, atol=1e-12)
    assert np.allclose(_rv2m(near_pi), Rp, atol=1e-14)


def test_each_model_declares_its_refinement_and_evaluation_leaves_it_unchanged():
    """One refinement per model class, stated (no detection of overridden methods), and a
    fitted model assigns no members while it is evaluated."""
    import copy

    from mmlearn.models.articulation.refine import REFINEMENTS

    expected = {"rigid": "em", "prismatic": "em", "revolute": "lm", "gp": None}
    tr = simulate_link("microwave", 40, rng=3)
    for name, ref in expected.items():
        m = make_model(name, obs=OBS)
        assert m.refinement == ref
        assert ref is None or ref in REFINEMENTS
        m.fit(tr.Z, rng=0)
        before = copy.deepcopy({k: v for k, v in vars(m).items() if k not in ("gp", "_lle")})
        m.log_likelihood(tr.Z), m.residuals(tr.Z), m.inverse(tr.Z), m.bic(tr.Z)
        m.prediction_errors(tr.Z, inliers_only=True), m.log_likelihood_of_visits([tr.Z[:20], tr.Z[20:]])
        after = {k: v for k, v in vars(m).items() if k not in ("gp", "_lle")}
        assert after.keys() == before.keys(), name
        for k, v in before.items():
            same = (np.array_equal(after[k], v) if isinstance(v, np.ndarray)
                    else after[k] == v)
            assert same, (name, k)
    bad = make_model("revolute", obs=OBS)
    bad.refinement = "bfgs"
    with pytest.raises(ValueError, match="refinement"):
        bad.fit(tr.Z, rng=0)


def test_link_models_share_the_base_interface():
    from mmlearn.models.articulation.base import LinkModel, distinguishable_configurations
    from mmlearn.models.articulation.link import make_model

    tr = simulate_link("drawer", 30, rng=0)
    for name in ("rigid", "prismatic", "revolute", "gp"):
        m = make_model(name)
        assert isinstance(m, LinkModel)
        assert m.fit(tr.Z, rng=0) is m and np.isfinite(m.bic_)
    # at most n configurations, at least one, the noise-resolved count between
    np.testing.assert_array_equal(distinguishable_configurations(10, np.array([0.5, 5.0, 50.0])),
                                  [1.0, 5.0, 10.0])
