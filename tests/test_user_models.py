"""A user's own SDFormat / URDF furniture as the opening task's mechanism: parsing, placement,
handle finding, errors (quick) and openings end to end (slow)."""

import json
import math
from pathlib import Path

import numpy as np
import pytest

from mmlearn.sdf.user_model import (UserModelError, load_user_mechanism, parse_pose,
                                    user_model_args)

DATA = Path(__file__).parent / "data" / "user_models"
MODELS = {"wall_cabinet": "door_hinge", "wardrobe": "left_wing", "drawer": "slide",
          "light_door": "hinge"}


def _load(name, ext, **kw):
    return load_user_mechanism(DATA / f"{name}.{ext}", MODELS[name], **kw)


@pytest.mark.parametrize("name", list(MODELS))
def test_sdf_and_urdf_give_the_same_mechanism(name):
    a, b = _load(name, "sdf"), _load(name, "urdf")
    assert a.kind == b.kind and a.joint_type == b.joint_type and a.sign == b.sign
    for u, v in zip(a.handle_world(0.3), b.handle_world(0.3)):
        np.testing.assert_allclose(u, v, atol=1e-6)
    np.testing.assert_allclose(a.axis_world()[0], b.axis_world()[0], atol=1e-9)
    assert a.handle_geometry.split("::")[-1] == b.handle_geometry.split("::")[-1]


@pytest.mark.parametrize("name, kind, sign, geometry, radius", [
    ("wall_cabinet", "left_door", 1, "handle_bar", 0.40 - 0.06 + 0.007),
    ("wardrobe", "right_door", -1, "knob", 0.55 - 0.07 + 0.007),
    ("drawer", "drawer", 1, "handle_bar", None),
    ("light_door", "left_door", 1, "handle_bar", 0.35 - 0.05 + 0.006)])
def test_kind_opening_direction_and_handle_from_the_geometry(name, kind, sign, geometry,
                                                            radius):
    m = _load(name, "sdf")
    assert (m.kind, m.sign, m.handle_source) == (kind, sign, "geometry")
    assert m.handle_geometry.split("::")[-1].startswith(geometry)
    # placed: the lowest point on the floor, the front facing +x, its centre over the origin
    assert m.corners_world()[:, 2].min() == pytest.approx(0.0, abs=1e-9)
    h, n, _ = m.handle_world(0.0)
    np.testing.assert_allclose(n, [1, 0, 0], atol=1e-9)
    assert abs(m.front_centre()[1]) < 1e-9 and abs(m.front_centre()[0]) < 1e-9
    assert 0.03 < h[0] < 0.1   # the handle stands off the front face
    # opening moves the handle out of the front (towards the robot)
    assert m.handle_world(0.2)[0][0] > h[0] + 0.02
    if radius is None:
        assert "radius_m" not in m.true_joint()
        np.testing.assert_allclose(m.handle_world(0.25)[0] - h, [0.25, 0, 0], atol=1e-9)
    else:
        assert m.true_joint()["radius_m"] == pytest.approx(radius, abs=0.003)
        assert np.dot(m.task_directions()[0], h - m.axis_world()[1]) > 0  # side: free edge


def test_the_side_of_the_front_comes_from_the_carcass_without_limits():
    m = _load("light_door", "urdf")
    assert math.isinf(m.limit) and m.normal_source == "carcass"
    assert m.true_joint()["damping"] == pytest.approx(2.0)


def test_odd_origin_and_model_pose():
    m = _load("wardrobe", "sdf")
    # the file's frame is turned by 2 rad: the default placement turns it back
    assert abs(math.atan2(m.X_WM[1, 0], m.X_WM[0, 0])) > 1.0
    T = parse_pose("0.5 -0.2 0.1 0 0 1.5707963")
    p = _load("wardrobe", "sdf", pose=T)
    np.testing.assert_allclose(p.X_WM, T)
    h_M = p.handle_M
    np.testing.assert_allclose(p.handle_world(0)[0], T[:3, :3] @ h_M + T[:3, 3])
    with pytest.raises(UserModelError, match="6 finite numbers"):
        user_model_args("1 2 3")


def test_a_given_handle_is_used_and_decides_the_front_side():
    m = _load("light_door", "sdf")
    h = m.handle_M + [0.0, 0.0, -0.05]
    g = _load("light_door", "sdf", handle=h)
    assert g.handle_source == "given"
    np.testing.assert_allclose(g.handle_M, h)
    np.testing.assert_allclose(g.normal_M, m.normal_M, atol=1e-9)


def _door_sdf(tmp_path, *, handle=True, joint="revolute", extra=""):
    bar = ("<collision name='bar'><pose>0.07 0.3 0.3 0 0 0</pose><geometry><cylinder>"
           "<radius>0.01</radius><length>0.2</length></cylinder></geometry></collision>"
           if handle else "")
    text = f"""<?xml version="1.0"?><sdf version="1.9"><model name="m">
      <link name="box"><collision name="c"><pose>-0.2 0.2 0.3 0 0 0</pose><geometry><box>
        <size>0.4 0.44 0.6</size></box></geometry></collision></link>
      <link name="door"><pose>0.01 0 0 0 0 0</pose><collision name="p"><pose>0 0.2 0.3 0 0 0</pose>
        <geometry><box><size>0.02 0.4 0.6</size></box></geometry></collision>{bar}</link>
      <joint name="j" type="{joint}"><parent>box</parent><child>door</child>
        <axis><xyz>0 0 -1</xyz><limit><lower>0</lower><upper>2</upper></limit></axis></joint>
      {extra}</model></sdf>"""
    p = tmp_path / "door.sdf"
    p.write_text(text)
    return p


def test_without_a_handle_geometry_the_free_edge_is_used(tmp_path):
    m = load_user_mechanism(_door_sdf(tmp_path, handle=False), "j")
    assert m.handle_source == "fallback" and m.kind == "left_door"
    # on the front face, 7 cm inside the edge away from the hinge
    assert m.true_joint()["radius_m"] == pytest.approx(math.hypot(0.40 - 0.07, 0.01), abs=1e-6)
    assert m.handle_M[0] == pytest.approx(0.02, abs=1e-6)


@pytest.mark.parametrize("args, message", [
    (["--model", "/no/such/file.sdf", "--joint", "j"], "no such file"),
    (["--model", "{bad}", "--joint", "j"], "cannot parse"),
    (["--model", "{door}", "--joint", "k"], "no joint 'k' in the model; its joints: j"),
    (["--model", "{ball}", "--joint", "j"], "'j' is a ball joint"),
    (["--model", "{door}", "--joint", "j", "--model-pose", "0 0 1.5 0 0 0"],
     "m above the arm's reach"),
    (["--model", "{door}"], "needs --joint"),
    (["--joint", "j"], "needs --model"),
    (["--model", "{bare}", "--joint", "j"], "no handle found and --handle not given")])
def test_bad_models_are_one_line_errors_with_status_2(tmp_path, capsys, args, message):
    from mmlearn.apps.open_cabinet import main

    door = _door_sdf(tmp_path)
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot name='x'><link name='a'></robot>")
    ball_dir = tmp_path / "ball"
    ball_dir.mkdir()
    ball = _door_sdf(ball_dir, joint="ball")
    bare = tmp_path / "bare.sdf"   # the door has no collision geometry
    text = door.read_text()
    i, j = text.index('<link name="door">'), text.index("<joint")
    bare.write_text(text[:i] + '<link name="door"><pose>0.01 0 0 0 0 0</pose></link>'
                    + text[j:])
    args = [a.format(door=door, bad=bad, ball=ball, bare=bare) for a in args]
    assert main(args + ["--json"]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err
    if "reach" in message:   # says how far
        assert " m above the floor, " in err


def test_trial_specs_name_the_model(tmp_path):
    from mmlearn.apps.operate_trials import trial_specs

    specs = trial_specs(trials=2, model=str(DATA / "drawer.urdf"), joint="slide")
    assert [s.label for s in specs] == ["drawer.urdf:slide seed 0", "drawer.urdf:slide seed 1"]
    assert specs[0].params["model"] == str((DATA / "drawer.urdf").resolve())
    assert specs[0].params["joint"] == "slide"


def test_scene_reports_the_user_joints_opening():
    from mmlearn.diagrams.common.scene import MakeSceneDiagram, SceneConfig

    m = _load("wardrobe", "urdf")
    scene = MakeSceneDiagram(SceneConfig(arm="7dof", tool="hook", mobile_base=True,
                                         cabinet=False, mechanism=m))
    ctx = scene.diagram.CreateDefaultContext()
    pc = scene.plant.GetMyMutableContextFromRoot(ctx)
    joint = scene.plant.GetJointByName("left_wing")
    joint.set_angle(pc, -0.4)   # this door opens towards negative angles
    np.testing.assert_allclose(scene.diagram.GetOutputPort("mechanism_state").Eval(ctx),
                               [0.4, 0.0], atol=1e-12)
    # the handle moves with the door as the mechanism says
    X0 = scene.plant.EvalBodyPoseInWorld(pc, joint.child_body()).GetAsMatrix4()
    joint.set_angle(pc, 0.0)
    Xq = scene.plant.EvalBodyPoseInWorld(pc, joint.child_body()).GetAsMatrix4()
    h = X0 @ np.linalg.inv(Xq) @ np.r_[m.handle_world(0.0)[0], 1.0]
    np.testing.assert_allclose(h[:3], m.handle_world(0.4)[0], atol=1e-9)


@pytest.mark.slow
@pytest.mark.parametrize("name, ext, perception", [("drawer", "urdf", "click"),
                                                    ("wall_cabinet", "sdf", "click"),
                                                    ("wall_cabinet", "urdf", "depth")])
def test_user_models_open_end_to_end(name, ext, perception, capsys):
    from mmlearn.apps.open_cabinet import main

    status = main(["--model", str(DATA / f"{name}.{ext}"), "--joint", MODELS[name],
                   "--seed", "1", "--perception", perception, "--json"])
    r = json.loads(capsys.readouterr().out)
    assert status == 0 and r["success"] and r["right_kind"], r["outcome"]
    assert r["object"] == f"{name}.{ext}:{MODELS[name]}"
    assert r["true_joint"]["kind"] == r["true_kind"]
    if r["true_kind"] == "revolute":
        assert r["radius_error_m"] < 0.05


def _write(tmp_path, name, links, joints):
    p = tmp_path / name
    p.write_text(f'<?xml version="1.0"?><sdf version="1.9"><model name="m">{links}{joints}'
                 f'</model></sdf>')
    return p


def _box(name, xyz, size):
    return (f'<collision name="{name}"><pose>{xyz} 0 0 0</pose><geometry><box><size>{size}'
            f'</size></box></geometry></collision>')


def test_a_sliding_door_and_a_handle_on_its_own_welded_link(tmp_path):
    carcass = '<link name="carcass">' + _box("c", "-0.25 0 0.4", "0.5 1.0 0.8") + '</link>'
    panel = ('<link name="panel"><pose>0.02 -0.25 0.1 0 0 0</pose>'
             + _box("p", "0 0 0.3", "0.02 0.5 0.6") + '</link>')
    grip = ('<link name="grip"><pose>0.02 -0.25 0.1 0 0 0</pose>'
            + _box("bar", "0.06 0.2 0.3", "0.02 0.02 0.2")
            + _box("post", "0.03 0.2 0.3", "0.04 0.01 0.01") + '</link>')
    joints = ('<joint name="slide" type="prismatic"><parent>carcass</parent><child>panel'
              '</child><axis><xyz>0 -1 0</xyz><limit><lower>0</lower><upper>0.45</upper>'
              '</limit></axis></joint><joint name="w" type="fixed"><parent>panel</parent>'
              '<child>grip</child></joint>')
    m = load_user_mechanism(_write(tmp_path, "s.sdf", carcass + panel + grip, joints), "slide")
    assert (m.kind, m.handle_source) == ("sliding_door", "geometry")
    assert m.handle_geometry.endswith("bar")
    side, pull = m.task_directions()
    h, n, bar = m.handle_world(0.0)
    np.testing.assert_allclose(n, [1, 0, 0], atol=1e-9)
    np.testing.assert_allclose(pull, m.axis_world()[0], atol=1e-9)   # along the opening
    np.testing.assert_allclose(side, -pull, atol=1e-9)
    assert abs(bar[2]) == pytest.approx(1.0)
    assert m.limit == pytest.approx(0.45)


def test_a_flat_drawer_is_not_a_sliding_door(tmp_path):
    carcass = '<link name="carcass">' + _box("c", "-0.3 0 0.5", "0.6 0.5 0.3") + '</link>'
    tray = ('<link name="tray"><pose>0.01 0 0.7 0 0 0</pose>' + _box("f", "0 0 0", "0.02 0.5 0.06")
            + _box("b", "-0.25 0 -0.02", "0.5 0.46 0.01")
            + _box("knob", "0.04 0 0", "0.03 0.03 0.03") + '</link>')
    joints = ('<joint name="t" type="prismatic"><parent>carcass</parent><child>tray</child>'
              '<axis><xyz>1 0 0</xyz></axis></joint>')
    m = load_user_mechanism(_write(tmp_path, "t.sdf", carcass + tray, joints), "t")
    assert m.kind == "drawer" and m.handle_geometry.endswith("knob")
    assert m.normal_source == "carcass" and math.isinf(m.limit)
    np.testing.assert_allclose(m.task_directions()[1], [1, 0, 0], atol=1e-9)


def test_the_apps_say_where_the_handle_came_from(tmp_path):
    from mmlearn.apps.open_cabinet import _model_line
    from mmlearn.models.articulation.evaluation import operate_records

    line = _model_line(_load("wardrobe", "urdf"))
    assert line.startswith("wardrobe.urdf:left_wing: revolute joint (like a right_door")
    assert "from its geometry (wardrobe::knob_col)" in line
    bare = load_user_mechanism(_door_sdf(tmp_path, handle=False), "j")
    assert "NOT found on the geometry: put on the front's edge away from the hinge" in \
        _model_line(bare)
    # a user model's trial that raised is named by its file and joint in the table
    rec = operate_records([{"error": "boom", "spec": {"seed": 3, "params": {
        "kind": "left_door", "model": "/x/y/cab.urdf", "joint": "j"}}}])[0]
    assert rec["object"] == "cab.urdf:j" and rec["error"] == "boom"


def test_a_front_free_to_close_stops_at_its_start_in_the_scene():
    from mmlearn.diagrams.common.scene import MakeSceneDiagram, SceneConfig

    m = _load("light_door", "sdf")
    assert m.closed_stop and not _load("wall_cabinet", "sdf").closed_stop
    scene = MakeSceneDiagram(SceneConfig(arm="7dof", tool="hook", mobile_base=True,
                                         cabinet=False, mechanism=m))
    j = scene.plant.GetJointByName("hinge")
    lo, hi = j.position_lower_limits()[0], j.position_upper_limits()[0]
    assert lo == pytest.approx(m.q0) and math.isinf(hi)
    assert m.true_joint()["closed_stop"] is True


def test_operate_trials_refuses_a_bad_model_before_running(tmp_path, capsys):
    from mmlearn.apps.operate_trials import main

    assert main(["--model", str(DATA / "drawer.sdf"), "--joint", "hinge",
                 "--results", str(tmp_path / "r.jsonl")]) == 2
    err = capsys.readouterr().err.strip()
    assert "no joint 'hinge' in the model; its joints: slide (prismatic)" in err
    assert "\n" not in err and not (tmp_path / "r.jsonl").exists()
