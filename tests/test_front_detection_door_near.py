"""The door seen from 0.8 m at small openings (a short VTK render of the kitchen):
the opened door's plane, tilted towards the cabinet's face by RANSAC, is refitted on its own
pixels, and planes crossing at 3-5 deg are told apart; and the tracker's orientation noise,
with which a door seen turning by only 20 deg (then out of view) is revolute."""

import dataclasses
import math

import numpy as np
import pytest
from conftest import perception_frame_at

from mmlearn.models.perception.evaluation import match_front
from mmlearn.diagrams.perception.diagram import FrontPerceptionConfig, MakeFrontPerceptionDiagram
from mmlearn.models.perception.detection import FrontDetectorConfig, detect_fronts
from mmlearn.models.perception.tracking import align_rectangle, as_rectangle


@pytest.fixture(scope="module")
def door_08():
    cfg = FrontPerceptionConfig(front="door", add_noise=False)
    cfg.camera.distance = 0.8
    return MakeFrontPerceptionDiagram(cfg)


def _frame_at(P, q_target):
    """Noise-free depth, X_WC, the true door pose and q at the first time the stepped profile
    reaches ``q_target`` (rad)."""
    return perception_frame_at(P, q_target, depth_port="clean_depth", t_end=6.0)


def _hinge_error(P, depth, X_WC, X, cfg):
    rects, _ = detect_fronts(depth, P.intrinsics, X_WC, cfg, rng=1)
    w_true, h_true = P.kinematics.width, P.kinematics.height
    hit = match_front(rects, X, w_true, h_true, max_size_m=0.1)
    if hit is None:
        return None
    r = as_rectangle(rects[hit["index"]])
    Xa, w, h, _ = align_rectangle(X, r.X_WR, r.width, r.height)
    dl = X[:3, :3].T @ (Xa[:3, 3] - X[:3, 3])
    # the side nearer the hinge: the one of the two width sides the true door turns about
    sides = ((dl[0] - w / 2) + w_true / 2, w_true / 2 - (dl[0] + w / 2))
    return hit["pos_error_m"], sides


@pytest.mark.parametrize("q", [0.085, 0.14])
def test_door_opened_5_to_8_deg_from_0_8_m_keeps_its_hinge_side(door_08, q):
    """Before (crossing from 5 deg, no refit on the plane's own pixels) the door's hinge side
    came out 46-53 mm short on these noise-free renders (its plane tilted ~2 deg towards the
    cabinet's face, which then took a 5 cm strip of the door; at 4.8 deg the planes counted
    as parallel); now both width sides are within 5 mm."""
    depth, X_WC, X, qa = _frame_at(door_08, q)
    assert abs(qa - q) < 0.03
    new = _hinge_error(door_08, depth, X_WC, X, FrontDetectorConfig())
    assert new is not None and max(abs(e) for e in new[1]) < 0.005, new
    assert new[0] < 0.004
    old = _hinge_error(door_08, depth, X_WC, X, dataclasses.replace(
        FrontDetectorConfig(), own_pixel_refit_deg=0.0, crossing_angle_deg=5.0))
    assert old is None or max(abs(e) for e in old[1]) > 0.03, old


def test_refit_on_own_pixels_config_errors():
    with pytest.raises(ValueError, match="own_pixel_refit_deg"):
        FrontDetectorConfig(own_pixel_refit_deg=-1.0).validate()
    with pytest.raises(ValueError, match="own_pixel_refit_deg"):
        FrontDetectorConfig(own_pixel_refit_deg=math.nan).validate()


def _door_track(n, q_max, sigma_deg, seed):
    """n centre poses (x, y, z, qx, qy, qz, qw) of a 0.395 m door turning 0 -> q_max about a
    vertical hinge at its edge, with Gaussian noise (3 mm, ``sigma_deg`` per axis)."""
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(seed)
    q = np.linspace(0.0, q_max, n)
    r = 0.1975
    pos = np.column_stack([r * np.sin(q), -r * np.cos(q), np.full(n, 0.6)])
    pos += rng.normal(0, 0.003, pos.shape)
    rot = Rotation.from_rotvec(np.column_stack([np.zeros(n), np.zeros(n), q]))
    rot = Rotation.from_rotvec(rng.normal(0, math.radians(sigma_deg), (n, 3))) * rot
    return np.column_stack([pos, rot.as_quat()])


def test_tracker_noise_resolves_a_door_seen_turning_20_deg():
    """15 observations over 20 deg with the detector's orientation noise (0.5 deg, measured
    0.2-0.6 deg for the door): with the tracker's former 3 deg the turn is within what noise
    alone spreads (the revolute model demoted, rigid selected), with its 1.5 deg revolute.
    A still front stays rigid with 1.5 deg."""
    from mmlearn.models.perception.tracking import fit_track_model, front_observation_model
    from mmlearn.systems.perception.front_tracker import FrontTrackerConfig

    so = FrontTrackerConfig().sigma_orient_deg
    assert so == pytest.approx(1.5)
    P = _door_track(15, math.radians(20.0), 0.5, 0)
    now = fit_track_model(P, obs=front_observation_model(0.02, math.radians(so)), rng=0)
    before = fit_track_model(P, obs=front_observation_model(0.02, math.radians(3.0)), rng=0)
    assert now.selected == "revolute", now.demoted
    assert before.selected == "rigid" and "revolute" in before.demoted
    still = _door_track(15, 0.0, 0.5, 1)
    assert fit_track_model(still, obs=front_observation_model(0.02, math.radians(so)),
                           rng=0).selected == "rigid"
