"""The teacher and its recorded demonstrations: minimum-jerk paths, task plans, the playback
diagram observed by the MarkerSensor, the record_demos app."""

import dataclasses
import json

import numpy as np
import pytest

from conftest import bad_usage, run_main
from mmlearn.apps.record_demos import main
from mmlearn.diagrams.imitation.demonstrations import (MakeTeacherDiagram, TeacherConfig,
                                                       default_sensor_config, record_demonstration,
                                                       record_demonstrations)
from mmlearn.models.imitation.types import load_demonstrations
from mmlearn.models.imitation.min_jerk import MinJerkTrajectory, min_jerk_segment
from mmlearn.models.imitation.teacher import TASKS, TeacherStyle, plan_demonstration, task_scene

FAST = TeacherStyle(speed=0.6, dwell=0.5, gripper_time=0.3)  # short demonstrations


# ----------------------------------------------------------------------------- min jerk
def test_two_points_is_the_classic_profile_and_stops_rest():
    t = np.linspace(-0.5, 2.5, 61)
    tr = MinJerkTrajectory([0.0, 2.0], [[0.0, 1.0], [1.0, -1.0]])
    np.testing.assert_allclose(tr.value(t), min_jerk_segment([0, 1], [1, -1], 2.0, t),
                               atol=1e-12)
    np.testing.assert_allclose(tr.value([1.0])[0], [0.5, 0.0], atol=1e-12)  # symmetric
    np.testing.assert_allclose(tr.value([0.0, 2.0], 1), 0.0, atol=1e-12)


def test_via_points_are_passed_and_the_hand_rests_at_stops():
    P = np.array([[0, 0, 0], [0.3, 0.1, 0.2], [0.5, -0.2, 0.1], [0.6, 0.0, 0.0],
                  [0.2, 0.3, 0.1]], float)
    tr = MinJerkTrajectory([0, 1.0, 1.6, 2.5, 3.5], P, stops=[0, 0, 0, 1, 0],
                           dwell=[0, 0, 0, 0.4, 0], optimize_times=True)
    np.testing.assert_allclose(tr.value(tr.via_times), P, atol=1e-9)
    assert tr.duration == pytest.approx(3.9)
    stop_t = tr.via_times[3]
    for tt in (stop_t, stop_t + 0.2, stop_t + 0.4):  # at rest through the dwell
        np.testing.assert_allclose(tr.value([tt])[0], P[3], atol=1e-9)
        np.testing.assert_allclose(tr.value([tt], 1)[0], 0.0, atol=1e-9)
        np.testing.assert_allclose(tr.value([tt], 2)[0], 0.0, atol=1e-7)
    # C2 through the via points (a minimum-jerk path has no velocity or acceleration jumps)
    for tv in tr.via_times[1:3]:
        for nu in (1, 2):
            a, b = tr.value([tv - 1e-7], nu)[0], tr.value([tv + 1e-7], nu)[0]
            np.testing.assert_allclose(a, b, atol=1e-4)


def _jerk(tr, t0, t1):
    g = np.linspace(t0, t1, 4001)
    j = tr.value(g, 3)
    return float(np.trapezoid(np.sum(j * j, axis=1), g))


def test_optimised_via_times_have_less_jerk_and_no_overshoot():
    # uneven given times: a long and a very short move into a stop
    P = np.array([[0.0, 0.0], [0.4, 0.0], [0.45, 0.0]])
    given = MinJerkTrajectory([0, 1.9, 2.2], P)
    best = MinJerkTrajectory([0, 1.9, 2.2], P, optimize_times=True)
    assert _jerk(best, 0, 2.2) < 0.9 * _jerk(given, 0, 2.2)
    x = best.value(np.linspace(0, 2.2, 500))[:, 0]
    assert x.max() < 0.45 + 0.005 and x.min() > -0.005


@pytest.mark.parametrize("kw, msg", [
    (dict(times=[0, 1], points=[[0.0]]), "must match"),
    (dict(times=[0, 0], points=[[0.0], [1.0]]), "increasing"),
    (dict(times=[0, 1], points=[[0.0], [np.nan]]), "finite"),
    (dict(times=[0], points=[[0.0]]), "at least 2"),
    (dict(times=[0, 1], points=[[0.0], [1.0]], dwell=[-1, 0]), "dwell"),
])
def test_bad_trajectory_input_is_named(kw, msg):
    with pytest.raises(ValueError, match=msg):
        MinJerkTrajectory(kw.pop("times"), kw.pop("points"), **kw)


# ----------------------------------------------------------------------------- plans
@pytest.mark.slow
def test_plans_are_seeded_and_vary():
    for task in TASKS:
        a, b = plan_demonstration(task, seed=5), plan_demonstration(task, seed=5)
        c = plan_demonstration(task, seed=6)
        t = a.times(5.0)
        np.testing.assert_array_equal(a.hand_position(t), b.hand_position(t))
        assert a.duration != c.duration
        assert not np.allclose(a.hand.points, c.hand.points)


@pytest.mark.slow
def test_pick_place_carries_the_cup_to_the_place_spot():
    for seed in range(3):
        p = plan_demonstration("pick_place", seed=seed,
                               scene=task_scene("pick_place", swap_tables=True))
        t = np.linspace(0, p.duration, 400)
        cup, g = p.cup_position(t), p.opening(t)
        np.testing.assert_allclose(cup[0], p.scene.cup_start())
        assert g[0] == 1.0 and g[-1] == 1.0 and g.min() == 0.0
        held = g < 0.5
        np.testing.assert_allclose(cup[held], p.hand_position(t[held]) + p.grasp_offset)
        end = cup[-1]
        assert end[2] == pytest.approx(p.scene.table_height)
        # grasp and put-down points each jitter by up to contact_jitter per axis
        j = TeacherStyle().contact_jitter
        assert np.linalg.norm(end[:2] - p.scene.place_spot()[:2]) <= 2 * np.sqrt(2) * j
        assert p.scene.cup_start()[1] < 0 < end[1]  # swapped: from the right to the left
        # the hand never dips below the rim while over the cup
        over = np.linalg.norm(p.hand_position(t)[:, :2] - p.scene.cup_start()[:2], axis=1) < 0.03
        rim = p.scene.cup_start()[2] + p.scene.cup_height
        assert np.all(p.hand_position(t)[over & (t < t[held][0]), 2] > rim)


def test_whiteboard_wipes_inside_the_corner_markers_of_any_scale():
    for scale in (0.7, 1.0, 1.4):
        p = plan_demonstration("whiteboard", seed=2,
                               scene=task_scene("whiteboard", board_scale=scale))
        C = p.scene.board_corners()
        x = p.hand_position(np.linspace(0, p.duration, 2000))
        on = x[:, 0] > C[0, 0] - 0.02  # touching the board (standoff 0.01 m)
        assert on.sum() > 100
        y, z = x[on, 1], x[on, 2]
        assert y.max() <= C[0, 1] + 1e-6 and y.min() >= C[1, 1] - 1e-6
        assert z.min() >= C[0, 2] - 1e-6 and z.max() <= C[3, 2] + 1e-6
        width = C[0, 1] - C[1, 1]
        assert y.max() - y.min() > 0.7 * width  # covers the area, which scales


def test_bad_task_and_style_are_named():
    with pytest.raises(ValueError, match="unknown task"):
        plan_demonstration("juggle", seed=0)
    with pytest.raises(ValueError, match="strokes"):
        plan_demonstration("whiteboard", seed=0, style=TeacherStyle(strokes=3))
    with pytest.raises(ValueError, match="needs a scene with board"):
        plan_demonstration("whiteboard", seed=0, scene=task_scene("pick_place"))


# ----------------------------------------------------------------------------- recording
def _cfg(task="pick_place", seed=1, **sensor):
    s = dataclasses.replace(default_sensor_config(), **sensor)
    return TeacherConfig(task=task, seed=seed, style=FAST, sensor=s)


@pytest.mark.slow
def test_demonstration_is_what_the_sensor_saw():
    cfg = _cfg(sigma_pos=0.0, dropout=0.0)
    td = MakeTeacherDiagram(cfg)
    d = record_demonstration(cfg)
    assert d.D == 3 and d.T == td.frame_times.size and d.joints is None
    np.testing.assert_allclose(d.t, td.frame_times)
    assert set(d.objects) == {"cup", "table_a", "table_b"}
    seen = np.isfinite(d.hand).all(axis=1)
    assert seen.mean() > 0.8
    # noise-free: the observed hand is the planned tool centre point (IK tolerance 2 mm)
    err = np.linalg.norm(d.hand[seen] - td.plan.hand_position(d.t[seen]), axis=1)
    assert err.max() < 0.0036
    g = td.plan.opening(d.t)
    ok = np.isfinite(d.gripper)
    np.testing.assert_allclose(d.gripper[ok], g[ok], atol=0.02)
    # with the default 5 mm noise the same frames scatter around it
    noisy = record_demonstration(dataclasses.replace(cfg, sensor=default_sensor_config()))
    both = seen & np.isfinite(noisy.hand).all(axis=1)
    res = (noisy.hand - d.hand)[both]
    assert 0.0035 < res.std() < 0.0065


def test_gaps_are_nan_rows_and_the_demonstration_stays_valid():
    d = record_demonstration(_cfg(task="obstacle", dropout=0.3))
    miss = ~np.isfinite(d.hand).all(axis=1)
    assert 0.1 < miss.mean() < 0.5
    assert np.all(np.isnan(d.hand[miss]))  # a whole row, never a partial one
    tgt_miss = ~np.isfinite(d.objects["target"]).all(axis=1)
    assert tgt_miss.any() and not tgt_miss.all()
    assert np.isnan(d.gripper).any()
    d.validate()


@pytest.mark.slow
def test_same_seed_same_demonstrations_and_file_round_trip(tmp_path):
    a = record_demonstrations("whiteboard", 2, seed=4, style=FAST)
    b = record_demonstrations("whiteboard", 2, seed=4, style=FAST)
    c = record_demonstrations("whiteboard", 1, seed=5, style=FAST)
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x.hand, y.hand)
        for k in x.objects:
            np.testing.assert_array_equal(x.objects[k], y.objects[k])
    assert a[0].T != a[1].T or not np.allclose(a[0].hand, a[1].hand, equal_nan=True)
    assert c[0].T != a[0].T or not np.allclose(c[0].hand, a[0].hand, equal_nan=True)
    assert {f"board_c{k}" for k in range(4)} <= set(a[0].objects)


def test_app_records_saves_and_reports(tmp_path, capsys):
    out = tmp_path / "demos.json"
    rc, text, err = run_main(main, ["--task", "u_obstacle", "--demos", "2", "--seed", "3",
                                    "--out", str(out), "--json"], capsys)
    assert rc == 0, err
    r = json.loads(text)
    assert r["task"] == "u_obstacle" and len(r["demonstrations"]) == 2
    assert r["record_seconds"] > 0 and r["out"] == str(out)
    demos = load_demonstrations(out)
    assert len(demos) == 2 and "target" in demos[0].objects
    assert "obstacle" not in demos[0].objects  # the thesis demonstrated without it
    assert demos[0].meta["task"] == "u_obstacle"
    assert r["demonstrations"][0]["frames"] == demos[0].T


def test_app_help_and_bad_arguments(tmp_path, capsys):
    rc, text, _ = run_main(main, ["--help"], capsys)
    assert rc == 0 and "--board-scale" in text and "--swap-tables" in text
    bad_usage(main, ["--task", "juggle"], capsys, "--task")
    bad_usage(main, ["--demos", "0"], capsys, "--demos")
    bad_usage(main, ["--seed", "-1"], capsys, "--seed")
    bad_usage(main, ["--board-scale", "nan"], capsys, "--board-scale")
    bad_usage(main, ["--out", str(tmp_path / "missing" / "d.json")], capsys, "--out")
    bad_usage(main, ["--task", "whiteboard", "--board-scale", "3", "--demos", "1"], capsys,
              "does not fit")


def test_kinematic_body_poses_system():
    from pydrake.multibody.plant import MultibodyPlant

    from mmlearn.models.imitation.scene import ImitationSceneSpec
    from mmlearn.sdf.imitation import add_imitation_scene, add_teacher
    from mmlearn.systems import KinematicBodyPoses

    plant = MultibodyPlant(0.0)
    add_teacher(plant)
    add_imitation_scene(plant, ImitationSceneSpec())
    plant.Finalize()
    sys_ = KinematicBodyPoses(plant=plant)
    ctx = sys_.CreateDefaultContext()
    pctx = plant.CreateDefaultContext()
    rng = np.random.default_rng(0)
    q = plant.GetPositions(pctx)
    q[:8] = rng.uniform(-1, 1, 8)
    cup = plant.GetBodyByName("cup")
    s = cup.floating_positions_start()
    q[s:s + 4] = [2.0, 0.0, 0.0, 2.0]  # not unit: normalised by the system
    sys_.get_positions_input_port().FixValue(ctx, q)
    poses = sys_.get_body_poses_output_port().Eval(ctx)
    q[s:s + 4] /= np.linalg.norm(q[s:s + 4])
    plant.SetPositions(pctx, q)
    assert len(poses) == plant.num_bodies()
    for name in ("hand", "x4", "cup", "table_b"):
        b = plant.GetBodyByName(name)
        np.testing.assert_allclose(poses[int(b.index())].GetAsMatrix4(),
                                   plant.EvalBodyPoseInWorld(pctx, b).GetAsMatrix4(),
                                   atol=1e-12)
    q[0] = np.nan  # a bad sample: identity poses, no exception
    sys_.get_positions_input_port().FixValue(ctx, q)
    poses = sys_.get_body_poses_output_port().Eval(ctx)
    assert all(p.IsExactlyIdentity() for p in poses)
    with pytest.raises(ValueError, match="finalized"):
        KinematicBodyPoses(plant=MultibodyPlant(0.0))


def test_teacher_config_loads_from_yaml_and_rejects_misspelled_keys():
    from pydrake.common.yaml import yaml_load_typed

    c = yaml_load_typed(schema=TeacherConfig, data=(
        "task: whiteboard\nstyle: {speed: 0.3}\n"
        "scene: {board: true, tables: false, cup: false, board_scale: 1.2}\n"))
    assert c.validate().scene_spec().board_scale == 1.2 and c.style.speed == 0.3
    with pytest.raises(RuntimeError, match="tsk"):
        yaml_load_typed(schema=TeacherConfig, data="tsk: whiteboard")
    with pytest.raises(ValueError, match="multiple"):
        TeacherConfig(playback_rate_hz=7.0).validate()


@pytest.mark.slow
def test_stratified_table_shifts_spread_the_tables_apart():
    from mmlearn.models.imitation.scene import stratified_table_shifts

    for n in (2, 4, 7):
        s = stratified_table_shifts(n, 3)
        assert s.shape == (n, 4) and np.all(np.abs(s) <= 1)
        for c in range(4):  # one demonstration per bin of every coordinate
            assert sorted(np.floor((s[:, c] + 1) / 2 * n).astype(int)) == list(range(n))
        # table B takes the mirrored bin: the tables' offset spans the range
        d = s[:, 1] - s[:, 3]
        assert d.max() - d.min() > 2.0 * (n - 1) / n * 0.9
    np.testing.assert_array_equal(stratified_table_shifts(4, 9), stratified_table_shifts(4, 9))
    demos = record_demonstrations("pick_place", 2, seed=1, style=FAST)
    ya, yb = (np.array([d.meta["scene"][k][1] for d in demos]) for k in ("table_a", "table_b"))
    # the two demonstrations' tables sit in opposite halves of the y range
    assert abs((ya - yb)[0] - (ya - yb)[1]) > 0.15


def test_teacher_tilts_its_hand_only_where_it_must_and_names_unreachable_points():
    from mmlearn.diagrams.imitation.demonstrations import TeacherIKError, _teacher_path
    from mmlearn.models.imitation.teacher import DemoPlan

    def plan_at(p):
        p = np.asarray(p, float)
        return DemoPlan(task="obstacle", scene=task_scene("obstacle"),
                        hand=MinJerkTrajectory([0, 1], [p, p + [0, 0, 0.001]]),
                        gripper=MinJerkTrajectory([0, 1], [[1.0], [1.0]]),
                        hand_axis=np.array([0, 0, -1.0]), grasp_offset=None)

    def tilt(p, tol):
        plant, Q = _teacher_path(plan_at(p), np.array([0.0]),
                                 TeacherConfig(ik_angle_tolerance=tol))
        ctx = plant.CreateDefaultContext()
        plant.SetPositions(ctx, Q[0])
        R = plant.CalcRelativeTransform(ctx, plant.world_frame(),
                                        plant.GetFrameByName("x8")).rotation().matrix()
        return float(np.arccos(-R[2, 2]))

    assert tilt([0.55, 0.0, 0.40], 0.2) <= 0.2 + 1e-6  # within reach: hand straight down
    assert 0.2 < tilt([0.80, 0.0, 0.40], 0.2) <= 0.5 + 1e-6  # far: tilted, within 2.5 x
    with pytest.raises(TeacherIKError, match=r"cannot reach the hand position \[0.95"):
        tilt([0.95, 0.0, 0.40], 0.2)


def test_observation_conversion_rejects_bad_input():
    from mmlearn.diagrams.imitation.demonstrations import observations_to_demonstration
    from mmlearn.systems.common.observations import MarkerObservations

    with pytest.raises(ValueError, match="no frames"):
        observations_to_demonstration([], objects=[], gripper_calibration=(0.09, 0.14))
    f = MarkerObservations(time=0.0, marker_ids=["hand", "x9", "x10"])
    with pytest.raises(ValueError, match="gripper_calibration"):
        observations_to_demonstration([f], objects=[], gripper_calibration=(0.14, 0.09))


def test_app_writes_the_meshcat_recording(tmp_path, capsys):
    html = tmp_path / "demos.html"
    rc, text, err = run_main(main, ["--task", "obstacle", "--demos", "1", "--seed", "2",
                                    "--html-out", str(html)], capsys)
    assert rc == 0, err
    page = html.read_text()
    assert page.startswith("<!DOCTYPE html>") and len(page) > 100_000  # scene + animation
    assert "1 demonstration(s) of obstacle" in text and f"written to {html}" in text


@pytest.mark.slow
def test_whiteboard_teacher_varies_the_marked_area_and_the_learner_scales_the_zigzag():
    """The teacher marks areas of different sizes (board_scale_jitter); learned from 5 Hz
    samples of such plans, the corner constraints' relative precisions stretch the
    reproduced zig-zag over a 1.25 times larger area, which a same-size teacher's does not."""
    from mmlearn.diagrams.imitation.trials import PARZEN_H
    from mmlearn.models.imitation.dbn import learn_task, reproduce_cartesian
    from mmlearn.models.imitation.evaluation import SPONGE_RADIUS, coverage, densify
    from mmlearn.models.imitation.types import Demonstration

    scales = [plan_demonstration("whiteboard", seed=s).scene.board_scale for s in range(6)]
    j = TeacherStyle().board_scale_jitter
    assert all(1 - j <= s <= 1 + j for s in scales) and np.ptp(scales) > 0.1
    assert plan_demonstration("whiteboard", seed=0, style=TeacherStyle(
        board_scale_jitter=0)).scene.board_scale == 1.0
    with pytest.raises(ValueError, match="board_scale_jitter"):
        TeacherStyle(board_scale_jitter=1.0).validate()
    assert SPONGE_RADIUS > 0

    def learned(jitter):
        demos = []
        for s in range(4):
            p = plan_demonstration("whiteboard", seed=10 + s,
                                   style=TeacherStyle(board_scale_jitter=jitter))
            t = np.arange(0.0, p.duration, 0.2)  # the sensor's 5 Hz
            C = p.scene.board_corners()
            objs = {f"board_c{k}": np.tile(C[k], (t.size, 1)) for k in range(4)}
            demos.append(Demonstration(t=t, hand=p.hand_position(t), objects=objs))
        return learn_task(demos, use_joints=False, h=PARZEN_H["whiteboard"])

    sc = task_scene("whiteboard", board_scale=1.25).sampled(7).resolved()
    C = sc.board_corners()
    objs = {f"board_c{k}": C[k] for k in range(4)}
    cov = {}
    for jitter in (0.0, 0.25):
        m = learned(jitter)
        _, x = reproduce_cartesian(m, np.asarray(TeacherStyle().home), objs)
        cov[jitter] = coverage(densify(x), C, plane_tol=0.03)
    assert cov[0.25] > cov[0.0] + 0.05, cov
