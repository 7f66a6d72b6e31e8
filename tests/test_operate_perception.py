"""open_cabinet --perception depth: the robot looks at the cabinet with its head depth camera,
detects the front and derives the handle."""

import json
import math

import numpy as np
import pytest

from mmlearn.diagrams.articulation.operate import ARM_START
from mmlearn.diagrams.articulation.operate_perception import LookAtFront, LookConfig, LookResult
from mmlearn.models.perception.handle import (HandleFromFrontConfig, handle_from_front,
                                              select_front)
from mmlearn.models.common.camera import PinholeIntrinsics
from mmlearn.models.perception.fronts import FrontRectangle
from mmlearn.sdf.mechanisms import MechanismSpec


def _start(spec: MechanismSpec, distance=1.0, lateral=0.1, yaw_off=0.2):
    p, n, _ = spec.handle_world(0.0)
    n = np.array([n[0], n[1], 0.0]) / np.hypot(n[0], n[1])
    p0 = p + distance * n + lateral * np.array([-n[1], n[0], 0.0])
    return np.array([p0[0], p0[1], math.atan2(-n[1], -n[0]) + yaw_off, *ARM_START])


@pytest.mark.parametrize("spec", [
    MechanismSpec(kind="left_door", width=0.45, height=0.6, bottom=0.3, handle_offset=0.07,
                  handle_height=0.3, pose=[0.05, -0.05, 0.1]),
    MechanismSpec(kind="drawer", width=0.5, height=0.2, depth=0.55, bottom=0.65,
                  limit=0.5, pose=[-0.05, 0.05, -0.1]),
], ids=["door", "drawer"])
def test_handle_from_a_rendered_frame_within_2cm(spec):
    r = LookAtFront(spec, _start(spec), config=LookConfig(frames=1), seed=3)
    assert r.found and r.frames_found == 1
    e = r.estimate
    true_h, true_n, true_bar = spec.handle_world(0.0)
    err = float(np.linalg.norm(e.handle - true_h))
    assert err < 0.02, (err, e.handle, true_h, e.source)
    assert e.source == "bar" and e.bar_points > 50
    assert math.degrees(math.acos(min(1.0, float(e.normal @ true_n)))) < 3.0
    assert abs(float(e.bar @ true_bar)) > 0.99
    # the chosen rectangle is the front (its centre within a few cm of the true one)
    from mmlearn.diagrams.articulation.operate_perception import front_centre
    assert np.linalg.norm(e.front.center - front_centre(spec)) < 0.1


def test_select_front_rejects_implausible_and_far():
    X = np.eye(4)
    X[:3, :3] = [[0, 0, 1.0], [1.0, 0, 0], [0, 1.0, 0]]  # normal +x, horizontal width
    X[:3, 3] = [0, 0, 0.6]
    good = FrontRectangle(X, 0.45, 0.6)
    tiny = FrontRectangle(X, 0.05, 0.05)
    cam = np.array([1.5, 0.0, 1.5])
    assert select_front([], cam, [0, 0, 0.6]) is None
    assert select_front([tiny], cam, [0, 0, 0.6]) is None
    assert select_front([tiny, good], cam, [0, 0, 0.6]) is good
    assert select_front([good], cam, [0, 1.0, 0.6]) is None  # too far from the target
    # seen from behind: the normal points away from the camera
    assert select_front([good], np.array([-1.5, 0.0, 1.5]), [0, 0, 0.6]) is None
    with pytest.raises(ValueError, match="finite 3-vectors"):
        select_front([good], [np.nan, 0, 0], [0, 0, 0.6])


def test_handle_by_convention_when_the_bar_is_not_seen():
    K = PinholeIntrinsics.from_fov(64, 48, 58.0)
    X = np.eye(4)
    X[:3, :3] = [[0, 0, 1.0], [1.0, 0, 0], [0, 1.0, 0]]
    X[:3, 3] = [0, 0, 0.6]
    rect = FrontRectangle(X, 0.4, 0.6)
    depth = np.full((48, 64), np.nan)  # nothing measured: no bar points
    for kind, y_expect in (("left_door", 0.2 - 0.07), ("right_door", -0.2 + 0.07),
                           ("drawer", 0.0)):
        e = handle_from_front(kind, rect, depth, K, np.eye(4))
        assert e.source == "rectangle" and e.bar_points == 0
        assert abs(e.handle[1] - y_expect) < 1e-9, (kind, e.handle)
    with pytest.raises(ValueError, match="kind must be one of"):
        handle_from_front("window", rect, depth, K, np.eye(4))
    with pytest.raises(ValueError, match="HandleFromFrontConfig: bar_radius"):
        handle_from_front("drawer", rect, depth, K, np.eye(4),
                          HandleFromFrontConfig(bar_radius=math.nan))
    with pytest.raises(ValueError, match="expected"):
        handle_from_front("drawer", rect, np.zeros((5, 5)), K, np.eye(4))


@pytest.mark.slow
def test_open_cabinet_perception_depth_short_trial_runs(capsys):
    from mmlearn.apps.open_cabinet import main

    rc = main(["--object", "drawer", "--seed", "1", "--perception", "depth",
               "--max-time", "3", "--json"])
    assert rc in (0, 1)
    r = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert r["perception"] == "depth" and r["front_found"] is True
    assert r["handle_error_m"] < 0.03 and r["handle_source"] in ("bar", "rectangle")
    assert r["sim_seconds"] == pytest.approx(3.0, abs=0.3)


def test_no_front_is_a_failed_trial_not_a_crash(monkeypatch):
    import mmlearn.diagrams.articulation.operate as operate
    from mmlearn.apps import open_cabinet

    def blind(spec, start, *, config=None, seed=0):
        return LookResult(found=False, estimate=None, frames_found=0, frames=3,
                          target=np.zeros(3), X_WC=np.eye(4), per_frame=np.zeros((0, 3)),
                          rectangles=[0, 0, 0])

    monkeypatch.setattr(operate, "LookAtFront", blind)
    r = open_cabinet.run(kind="left_door", seed=0, perception="depth", show_progress=False)
    assert r["success"] is False and r["outcome"] == "no front detected"
    assert r["front_found"] is False and r["handle_error_m"] is None
    json.dumps(r)


def test_bad_perception_flag_exits_2(capsys):
    from mmlearn.apps.open_cabinet import main as oc_main
    from mmlearn.apps.operate_trials import main as ot_main

    for main in (oc_main, ot_main):
        with pytest.raises(SystemExit) as ex:
            main(["--perception", "lidar"])
        assert ex.value.code == 2
        assert "--perception" in capsys.readouterr().err
