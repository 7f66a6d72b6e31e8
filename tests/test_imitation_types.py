"""Tests of the imitation data types (demonstrations, task models, obstacles) and their files."""

import json

import numpy as np
import pytest

from mmlearn.models.imitation.types import (
                                            Demonstration, ImitationDataError, Obstacle, TaskModel, load_demonstrations, save_demonstrations)


def _demo(T=10, D=3, gap=True):
    t = np.linspace(0, 1.8, T)
    hand = np.stack([np.sin(t), np.cos(t), t][:D], axis=1)
    cup = np.tile(np.arange(D, dtype=float), (T, 1))
    if gap:
        hand[3] = np.nan
    return Demonstration(t=t, hand=hand, objects={"cup": cup}, gripper=np.linspace(1, 0, T),
                         meta={"task": "pick_place", "seed": 3})


def test_demonstration_roundtrip_keeps_gaps(tmp_path):
    demos = [_demo(), _demo(T=7, D=2, gap=False)]
    p = save_demonstrations(tmp_path / "d.json", demos)
    doc = json.loads(p.read_text())
    assert doc["format"] == "mmlearn.demonstrations" and doc["demonstrations"][0]["hand"][3] == [None] * 3
    back = load_demonstrations(p)
    assert len(back) == 2 and back[1].D == 2 and back[0].meta == {"task": "pick_place", "seed": 3}
    np.testing.assert_array_equal(back[0].hand, demos[0].hand)  # NaN gap survives (equal_nan)
    np.testing.assert_allclose(back[0].gripper, demos[0].gripper)
    assert back[0].joints is None and np.isnan(back[0].hand[3]).all()


@pytest.mark.parametrize("change,match", [
    (dict(t=np.array([0.0])), "at least 2 samples"),
    (dict(t=np.array([0.0, 1.0, 1.0, 2.0] + [3.0 + i for i in range(6)])), "not strictly increasing at index 2"),
    (dict(hand=np.zeros((9, 3))), r"hand: expected 10 samples"),
    (dict(hand=np.full((10, 3), np.nan)), "hand: NaN in every frame"),
    (dict(hand=np.full((10, 3), np.inf)), "hand: infinite"),
    (dict(objects={"cup": np.zeros((10, 2))}), r"objects\['cup'\]: expected 3 columns"),
    (dict(objects={"a:b": np.zeros((10, 3))}), "bad object name"),
    (dict(gripper=np.full(10, 2.0)), r"gripper: opening outside \[0, 1\]"),
    (dict(meta={"x": object()}), "meta is not JSON"),
])
def test_bad_demonstration_names_problem(change, match):
    d = _demo()
    for k, v in change.items():
        setattr(d, k, v)
    with pytest.raises(ImitationDataError, match=match):
        d.validate()


def test_load_errors(tmp_path):
    with pytest.raises(ImitationDataError, match="file not found"):
        load_demonstrations(tmp_path / "missing.json")
    p = tmp_path / "bad.json"
    p.write_text("{not json")
    with pytest.raises(ImitationDataError, match="not valid JSON"):
        load_demonstrations(p)
    p.write_text(json.dumps({"format": "other", "version": 1}))
    with pytest.raises(ImitationDataError, match="expected a JSON object with format"):
        load_demonstrations(p)
    doc = {"format": "mmlearn.demonstrations", "version": 1,
           "demonstrations": [_demo().to_dict(), dict(_demo().to_dict(), hnad=[])]}
    p.write_text(json.dumps(doc))
    with pytest.raises(ImitationDataError, match=r"demonstration 1: unknown key\(s\) \['hnad'\]"):
        load_demonstrations(p)


def test_task_model_roundtrip_and_validation(tmp_path):
    S = 5
    m = TaskModel(t=np.arange(S) * 0.2, constraints=["obj:cup", "gripper"],
                  mean={"obj:cup": np.zeros((S, 3)), "gripper": np.ones((S, 1))},
                  var={"obj:cup": np.tile(np.eye(3) * 0.01, (S, 1, 1)), "gripper": np.full((S, 1), 0.1)},
                  meta={"h": 0.2})
    back = TaskModel.load(m.save(tmp_path / "m.json"))
    assert back.constraints == ["obj:cup", "gripper"] and back.full_covariance and back.objects == ["cup"]
    np.testing.assert_allclose(back.covariance("gripper", 2), [[0.1]])
    np.testing.assert_allclose(back.covariance("obj:cup", 0), np.eye(3) * 0.01)
    m.var["gripper"] = np.zeros((S, 1))
    with pytest.raises(ImitationDataError, match=r"var\['gripper'\]: variances must be positive"):
        m.validate()
    m.var["gripper"] = np.ones((S, 1))
    m.constraints = ["obj:cup", "grip"]
    with pytest.raises(ImitationDataError, match="bad name 'grip'"):
        m.validate()


def test_obstacle_signed_distance_and_closest_point():
    box = Obstacle(centre=[1.0, 0.0, 0.5], half_size=[0.1, 0.2, 0.5])
    p = np.array([[1.0, 0.0, 1.3], [1.0, 0.0, 0.5], [1.3, 0.6, 0.5]])
    np.testing.assert_allclose(box.signed_distance(p), [0.3, -0.1, np.hypot(0.2, 0.4)])
    np.testing.assert_allclose(box.closest_point(p), [[1.0, 0.0, 1.0], [1.1, 0.0, 0.5], [1.1, 0.2, 0.5]])
    c, s = np.cos(0.5), np.sin(0.5)
    rot = Obstacle(centre=[0.0, 0.0], half_size=[1.0, 0.1], R=[[c, -s], [s, c]])
    q = rot.centre + 0.3 * np.array([-s, c])          # along the rotated short axis
    assert rot.signed_distance(q) == pytest.approx(0.2)
    with pytest.raises(ImitationDataError, match="half_size positive"):
        Obstacle(centre=[0, 0], half_size=[1, 0])
    with pytest.raises(ImitationDataError, match="dimension 3 for a 2-D box"):
        rot.signed_distance([0, 0, 0])
