"""Inputs that are valid one by one but make the result meaningless are refused with the
reason."""

import numpy as np
import pytest


def test_track_scale_problem():
    from mmlearn.models.articulation.sim import simulate_link
    from mmlearn.models.articulation.structure import track_scale_problem

    Z = simulate_link("revolute", 30, rng=0).Z
    assert track_scale_problem(Z, 0.01) is None
    big = Z.copy()
    big[:, :3] *= 1e6
    assert "are they in metres" in track_scale_problem(big, 0.01)
    assert "times the assumed position noise" in track_scale_problem(Z, 1e-9)
    assert track_scale_problem(Z[:1], 0.01) is None  # nothing to compare


def test_camera_distance_beyond_range():
    from mmlearn.diagrams.perception.diagram import FrontPerceptionConfig

    cfg = FrontPerceptionConfig()
    cfg.check_distance(4.0)
    with pytest.raises(ValueError, match="beyond the camera's range 5 m .noise.max_range."):
        cfg.check_distance(1e6)
    cfg.add_noise = False
    cfg.check_distance(9.0)  # the clean render reaches z_far
    with pytest.raises(ValueError, match="camera.z_far"):
        cfg.check_distance(10.0)
    cfg.camera.distance = 1e6
    with pytest.raises(ValueError, match="camera.distance"):
        cfg.validate()


def test_slice_period_longer_than_a_demonstration():
    from mmlearn.models.imitation.dbn import align_demonstrations, learn_task
    from mmlearn.models.imitation.types import Demonstration, ImitationDataError

    t = np.linspace(0.0, 1.0, 11)
    demos = [Demonstration(t=t, hand=np.c_[t, t, t], objects={"cup": np.ones((11, 3))})
             for _ in range(2)]
    for f in (align_demonstrations, learn_task):
        with pytest.raises(ImitationDataError, match="not shorter than the shortest"):
            f(demos, dt=2.0)
        with pytest.raises(ImitationDataError, match="positive period"):
            f(demos, dt=float("nan"))
    assert learn_task(demos, dt=0.1, h=0.1).S > 1


def test_contact_level_above_every_pressure():
    from pathlib import Path

    from mmlearn.models.tactile.evaluation import icub_features
    from mmlearn.models.tactile.icub_grasp import load_icub_dir
    from mmlearn.models.tactile.types import TactileDataError

    trials, _ = load_icub_dir(Path(__file__).parent / "data" / "icub_grasp")
    X, y, feats = icub_features(trials, contact_level=18.0, rest_velocity=0.01,
                                steady_average=False)
    assert any(f.contact for f in feats)
    with pytest.raises(TactileDataError, match="above the highest finger pressure"):
        icub_features(trials, contact_level=1e9, rest_velocity=0.01, steady_average=False)


def test_scene_time_step_against_the_marker_rate():
    from mmlearn.diagrams.common.scene import SceneConfig

    SceneConfig().validate()
    with pytest.raises(ValueError, match="longer than a marker frame"):
        SceneConfig(time_step=0.5).validate()
