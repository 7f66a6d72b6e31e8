"""The reproducer system, the grasp model, the imitation diagram and its apps."""

import json

import numpy as np
import pytest
from pydrake.math import RigidTransform
from pydrake.multibody.math import SpatialVelocity
from pydrake.systems.analysis import Simulator

from conftest import bad_usage, run_main
from mmlearn.diagrams.imitation.diagram import ImitationConfig, MakeImitationDiagram, object_positions
from mmlearn.models.imitation.types import Demonstration, TaskModel, save_demonstrations
from mmlearn.models.imitation.scene import ImitationSceneSpec
from mmlearn.systems.imitation.dbn_reproducer import DbnReproducerConfig
from mmlearn.systems.common.observations import MarkerObservations

# the hand the model asks for: 0.10 m in front of (-x) and 0.15 m above the target marker
OFFSET = np.array([0.10, 0.0, -0.15])  # mu = target - hand


def _reach_model(S=12, dt=0.2):
    mean = {"obj:target": np.tile(OFFSET, (S, 1))}
    var = {"obj:target": np.full((S, 3), 1e-4)}
    return TaskModel(t=np.arange(S) * dt, constraints=["obj:target"], mean=mean,
                     var=var).validate()


def _reach(**kw):
    spec = ImitationSceneSpec(tables=False, cup=False, target=True,
                              target_position=[0.5, -0.2, 0.35])
    cfg = ImitationConfig(task="obstacle", seed=3, scene=spec,
                          reproducer=DbnReproducerConfig(settle_steps=5, **kw))
    return MakeImitationDiagram(cfg, model=_reach_model())


@pytest.mark.slow
def test_reproducer_moves_the_hand_to_the_learned_relation():
    im = _reach()
    ctx = im.diagram.CreateDefaultContext()
    im.set_start(ctx)
    sim = Simulator(im.diagram, ctx)
    status = im.diagram.GetOutputPort("status")
    t = 0.0
    while status.Eval(ctx)[5] == 0 and t < 3 * im.reproducer.duration:
        t += 0.5
        sim.AdvanceTo(t)
    hand = im.diagram.GetOutputPort("hand").Eval(ctx)
    target = object_positions(im.plant, ctx, ["target"])["target"]
    # the hand satisfies r = target - hand = mu (marker noise 5 mm at 10 Hz)
    assert np.linalg.norm(hand - (target - OFFSET)) < 0.02
    st = status.Eval(ctx)
    assert st[0] >= 10 and st[2] == 0 and st[5] == 1


def _snap(im, ctx):
    d = im.diagram
    return (np.array(d.GetOutputPort("robot_state").Eval(ctx)),
            np.array(d.GetOutputPort("command").Eval(ctx)),
            np.array(d.GetOutputPort("status").Eval(ctx)))


def test_two_simulators_interleaved_match_one_alone():
    im = _reach()
    times = [0.3, 0.6, 0.9]
    ctx = im.diagram.CreateDefaultContext()
    im.set_start(ctx)
    sim = Simulator(im.diagram, ctx)
    alone = []
    for t in times:
        sim.AdvanceTo(t)
        alone.append(_snap(im, ctx))
    ca = im.diagram.CreateDefaultContext()
    im.set_start(ca)
    cb = ca.Clone()
    sa, sb = Simulator(im.diagram, ca), Simulator(im.diagram, cb)
    for k, t in enumerate(times):
        sa.AdvanceTo(t)
        sb.AdvanceTo(t)
        for got in (_snap(im, ca), _snap(im, cb)):
            for a, b in zip(got, alone[k]):
                np.testing.assert_array_equal(a, b)
    assert not np.allclose(alone[0][1], alone[-1][1])  # it moved


def _standalone(im):
    rep = im.reproducer
    ctx = rep.CreateDefaultContext()
    nx = im.plant.num_positions(im.robot) + im.plant.num_velocities(im.robot)
    x = np.zeros(nx)
    x[:6] = im.start_command[:6]
    rep.get_robot_state_input_port().FixValue(ctx, x)
    rep.set_initial_command(ctx, im.start_command)
    return rep, ctx


def _obs(p, visible=True):
    return MarkerObservations(time=0.0, marker_ids=["target"], poses=[RigidTransform(p)],
                              visible=np.array([visible]), outlier=np.array([False]))


def test_bad_observations_hold_the_last_good_position_and_never_raise():
    im = _reach()
    rep, ctx = _standalone(im)
    port = rep.get_observations_input_port()
    # never seen: the model waits, the arm holds
    port.FixValue(ctx, _obs([0.5, -0.2, 0.35], visible=False))
    sim = Simulator(rep, ctx)
    sim.AdvanceTo(0.5)
    st = rep.get_status_output_port().Eval(ctx)
    assert st[0] == 0 and st[1] >= 2
    np.testing.assert_allclose(rep.get_command_output_port().Eval(ctx), im.start_command)
    # seen once, then NaN, unseen, and an empty frame: the last good position is kept
    port.FixValue(ctx, _obs([0.5, -0.2, 0.35]))
    sim.AdvanceTo(0.7)
    held = ctx.get_discrete_state(3).get_value()[:3].copy()
    np.testing.assert_allclose(held, [0.5, -0.2, 0.35])
    for bad in (_obs([np.nan, 0.0, 0.3]), _obs([9.0, 9.0, 9.0], visible=False),
                MarkerObservations()):
        port.FixValue(ctx, bad)
        sim.AdvanceTo(sim.get_context().get_time() + 0.4)
        np.testing.assert_allclose(ctx.get_discrete_state(3).get_value()[:3], held)
    st = rep.get_status_output_port().Eval(ctx)
    assert st[0] >= 5 and st[2] == 0
    assert np.all(np.isfinite(rep.get_command_output_port().Eval(ctx)))


def test_reproducer_config_errors_name_the_field():
    with pytest.raises(ValueError, match="mode"):
        DbnReproducerConfig(mode="fast").validate()
    with pytest.raises(ValueError, match="damping"):
        DbnReproducerConfig(damping=float("nan")).validate()
    with pytest.raises(ValueError, match="task"):
        ImitationConfig(task="juggle").validate()
    with pytest.raises(ValueError, match="robot_start"):
        ImitationConfig(robot_start=[0.0] * 5).validate()


def test_grasp_captures_holds_and_releases():
    from mmlearn.systems.imitation.grasp_attachment import GraspAttachment

    spec = ImitationSceneSpec()
    im = MakeImitationDiagram(ImitationConfig(task="pick_place", variation=0.0, scene=spec),
                              model=_reach_model())
    plant = im.plant
    g = GraspAttachment(plant=plant, hand_body=plant.GetBodyByName("x8", im.robot),
                        p_tcp=(0, 0, 0.12), object_body="cup", p_object=(0, 0, 0.1),
                        capture_radius=0.05, closed_below=0.3, period=0.01)
    ctx = g.CreateDefaultContext()
    X = [RigidTransform()] * plant.num_bodies()
    hand_i = int(plant.GetBodyByName("x8", im.robot).index())
    cup_i = int(plant.GetBodyByName("cup").index())
    X[hand_i] = RigidTransform([0.5, 0.3, 0.4])           # TCP at z = 0.52
    X[cup_i] = RigidTransform([0.5, 0.3, 0.40])           # rim centre at z = 0.50
    g.get_body_poses_input_port().FixValue(ctx, X)
    g.get_body_spatial_velocities_input_port().FixValue(
        ctx, [SpatialVelocity(np.zeros(3), np.zeros(3))] * plant.num_bodies())
    g.get_gripper_angle_input_port().FixValue(ctx, [0.6])  # open: nothing happens
    sim = Simulator(g, ctx)
    sim.AdvanceTo(0.05)
    assert g.get_attached_output_port().Eval(ctx)[0] == 0
    assert g.get_spatial_forces_output_port().Eval(ctx) == []
    g.get_gripper_angle_input_port().FixValue(ctx, [0.0])  # closed within the radius
    sim.AdvanceTo(0.1)
    assert g.get_attached_output_port().Eval(ctx)[0] == 1
    # the hand moves up 1 cm: the spring pulls the cup up (plus its weight), the hand down
    X[hand_i] = RigidTransform([0.5, 0.3, 0.41])
    g.get_body_poses_input_port().FixValue(ctx, X)
    f_cup, f_hand = g.get_spatial_forces_output_port().Eval(ctx)
    m = plant.GetBodyByName("cup").default_mass()
    np.testing.assert_allclose(f_cup.F_Bq_W.translational(), [0, 0, 400 * 0.01 + m * 9.81],
                               atol=1e-6)
    np.testing.assert_allclose(f_hand.F_Bq_W.translational(), -f_cup.F_Bq_W.translational())
    g.get_gripper_angle_input_port().FixValue(ctx, [0.6])  # opens: released
    sim.AdvanceTo(0.15)
    assert g.get_attached_output_port().Eval(ctx)[0] == 0
    # closing far from the cup captures nothing
    X[hand_i] = RigidTransform([0.5, 0.3, 0.6])
    g.get_body_poses_input_port().FixValue(ctx, X)
    g.get_gripper_angle_input_port().FixValue(ctx, [0.0])
    sim.AdvanceTo(0.2)
    assert g.get_attached_output_port().Eval(ctx)[0] == 0


# ----------------------------------------------------------------------------- the apps
def _reach_demos(n=3, seed=0):
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        T = 20 + i
        t = np.arange(T) * 0.2
        target = np.array([0.55, -0.3, 0.3]) + rng.uniform(-0.03, 0.03, 3)
        start = np.array([0.5, 0.3, 0.45])
        s = (1 - np.cos(np.linspace(0, np.pi, T))) / 2
        hand = start + s[:, None] * (target + [0, 0, 0.03] - start)
        hand[5] = np.nan  # a gap: the hand marker not seen in one frame
        out.append(Demonstration(t=t, hand=hand, objects={"target": np.tile(target, (T, 1))},
                                 meta={"task": "obstacle"}).validate())
    return out


def test_imitate_help_and_bad_arguments(capsys, tmp_path):
    from mmlearn.apps.imitate import main

    rc, out, _ = run_main(main, ["--help"], capsys)
    assert rc == 0 and "--swap-tables" in out and "--global" in out
    bad_usage(main, ["--task", "juggle"], capsys, "--task")
    bad_usage(main, ["--demos", "0"], capsys, "--demos")
    bad_usage(main, ["--seed", "-1"], capsys, "--seed")
    bad_usage(main, ["--demos-file", str(tmp_path / "none.json")], capsys, "--demos-file",
              "not found")
    (tmp_path / "bad.json").write_text("{not json")
    bad_usage(main, ["--demos-file", str(tmp_path / "bad.json")], capsys, "--demos-file")
    bad_usage(main, ["--html-out", str(tmp_path / "no" / "x.html")], capsys, "--html-out")


@pytest.mark.slow
def test_imitate_short_run_from_a_demos_file(capsys, tmp_path):
    from mmlearn.apps.imitate import main

    f = tmp_path / "demos.json"
    save_demonstrations(f, _reach_demos())
    html = tmp_path / "run.html"
    rc, out, err = run_main(main, ["--task", "obstacle", "--demos-file", str(f), "--seed", "2",
                                   "--json", "--html-out", str(html)], capsys)
    assert rc == 0, err
    rec = json.loads(out)
    for k in ("success", "place_error_m", "min_obstacle_clearance_m", "reproduction_seconds",
              "learn_seconds", "reach_error_m"):
        assert k in rec
    assert rec["demos"] == 3 and rec["failed_steps"] == 0
    assert rec["min_obstacle_clearance_m"] is not None
    assert rec["reach_error_m"] < 0.05
    # the recording holds the demonstrations, the learned means / ellipsoids and the trail
    # (Meshcat's commands are embedded as base64 msgpack)
    import base64
    import re

    msgs = b"".join(base64.b64decode(b) for b in
                    re.findall(r"base64,([A-Za-z0-9+/=]+)", html.read_text()))
    for key in (b"imitation/demonstrations/demo_2", b"imitation/model/target/ellipsoids/slice_0000",
                b"imitation/trail/dot_00005",
                b"# mmlearn legend: Imitation: obstacle learned from 3 demonstrations",
                b"# learned hand path relative to the target", b"# reproduction "):
        assert key in msgs, key


def test_experiments_help_report_only_and_bad_arguments(capsys, tmp_path):
    from mmlearn.apps.imitation_experiments import main

    rc, out, _ = run_main(main, ["--help"], capsys)
    assert rc == 0 and "--report-only" in out
    bad_usage(main, ["--experiments", "demos,juggle"], capsys, "--experiments", "juggle")
    bad_usage(main, ["--seeds", "0"], capsys, "--seeds")
    bad_usage(main, ["--report-only", str(tmp_path / "none.jsonl"), "--out-dir",
                     str(tmp_path)], capsys, "--report-only")
    lines = []
    for i, (n, err) in enumerate([(1, 0.3), (1, 0.2), (4, 0.01), (4, 0.015)]):
        lines.append({"key": f"k{i}", "format": 2, "spec": {
            "fn": "imitation.reproduce@1", "seed": i,
            "params": {"task": "pick_place", "demos": n},
            "label": f"pick_place {n} demo{'s' if n > 1 else ''} seed {i}"},
            "record": {"task": "pick_place", "finished": True, "success": err < 0.02,
                       "place_error_m": err, "min_obstacle_clearance_m": None,
                       "reproduction_seconds": 5.0, "learn_seconds": 0.1}, "error": None,
            "wall_s": 5.0})
    lines.append({"key": "k9", "format": 2,
                  "spec": {"fn": "imitation.reproduce@1", "seed": 9, "params": {},
                           "label": "pick_place 4 demos seed 9"},
                  "record": None, "error": "RuntimeError: boom", "wall_s": 1.0})
    res_file = tmp_path / "r.jsonl"
    res_file.write_text("".join(json.dumps(x) + "\n" for x in lines))
    rc, out, _ = run_main(main, ["--report-only", str(res_file), "--out-dir", str(tmp_path),
                                 "--json"], capsys)
    assert rc == 1  # a trial raised
    res = json.loads(out)
    rows = {r["condition"]: r for r in res["conditions"]}
    assert rows["pick_place 1 demo"]["successes"] == 0
    assert rows["pick_place 4 demos"]["successes"] == 2
    assert rows["pick_place 4 demos"]["errors"] == 1
    assert rows["pick_place 4 demos"]["mean_place_error_m"] == pytest.approx(0.0125)
    assert (tmp_path / "imitation_success.png").is_file()
    assert (tmp_path / "imitation_place_error.png").is_file()


def test_held_offset_correction_places_the_held_object_not_the_hand():
    rep = _reach().reproducer
    hand = np.array([0.3, 0.0, 0.5])
    off = np.array([0.01, -0.02, 0.03])  # grasp holds the object this far off the learned relation
    objs = {"target": hand + OFFSET + off, "other": np.array([1.0, 2.0, 3.0])}
    shift = rep.held_offset(4, hand, objs, ["target"])
    np.testing.assert_allclose(shift, [-0.01, 0.02, 0.0], atol=1e-12)  # horizontal only
    moved = rep._correct_for_held(4, hand, objs, ["target"])
    np.testing.assert_allclose(moved["target"], objs["target"])        # the held one stays
    # a hand at (other - mu_other) then carries the object to other - mu_other + OFFSET in x, y
    hand_new = moved["other"] - np.array([0.2, 0.1, 0.0])
    held_at = hand_new + (objs["target"] - hand)
    want = objs["other"] - np.array([0.2, 0.1, 0.0]) + OFFSET
    np.testing.assert_allclose(held_at[:2], want[:2], atol=1e-12)
    big = rep.held_offset(4, hand, {"target": hand + OFFSET + [1.0, 0, 0]}, ["target"])
    assert np.isclose(np.linalg.norm(big), DbnReproducerConfig().carry_tolerance)
    assert not np.any(rep.held_offset(4, hand, {"target": np.full(3, np.nan)}, ["target"]))


def test_global_plan_points_cover_the_forearm_between_the_body_points():
    """The global plan checks the arm every <= 5 cm (PLAN_BODY_POINTS): a thin box across the
    forearm halfway between two BODY_POINTS, more than the 6 cm plan clearance from every one
    of them, is seen by the plan points (U obstacle: the forearm grazed the U)."""
    from mmlearn.models.imitation.types import Obstacle

    im = _reach()
    kin = im.reproducer.kinematics()
    q = np.array(im.start_command[:6], float)
    sparse, dense = kin.body_points(q), kin.plan_points(q)
    assert dense.shape == (16, 3) and np.all(np.isfinite(dense))
    # consecutive plan points lie along the arm, at most 5 cm apart
    gaps = np.linalg.norm(np.diff(dense, axis=0), axis=1)
    assert gaps.max() <= 0.05 + 1e-9
    # the sparse elbow (x5 origin) and mid-forearm points bracket a gap of >= 17 cm
    elbow, mid = sparse[0], sparse[1]
    assert np.linalg.norm(mid - elbow) > 0.17
    c = 0.5 * (elbow + mid)
    ob = Obstacle(centre=c, half_size=np.full(3, 0.01))
    clear = 0.06
    assert np.all(ob.signed_distance(sparse) > clear)          # missed by the sparse points
    assert np.any(ob.signed_distance(dense) < clear)           # seen by the plan points


def test_plan_body_points_errors():
    from mmlearn.systems.imitation.dbn_reproducer import DbnReproducer

    im = _reach()
    plant = im.plant
    with pytest.raises(ValueError, match="plan_body_points"):
        DbnReproducer(plant=plant, model=_reach_model(),
                      arm_joints=[plant.GetJointByName(f"q{i}", im.robot) for i in range(1, 7)],
                      tcp_frame=plant.GetBodyByName("x8", im.robot).body_frame(),
                      plan_body_points=[("x6", (0.0, np.nan, 0.1))])
