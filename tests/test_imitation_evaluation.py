"""The metrics of the imitation experiments (models/imitation/evaluation.py) and the plan of
their trials (diagrams/imitation/trials.py), on hand-made demonstrations and records."""

import numpy as np
import pytest

from mmlearn.models.imitation.evaluation import (PLACE_TOL, REACH_TOL, SPONGE_RADIUS,
                                                 condition_table, coverage, densify, final_point,
                                                 place_spot, plane_distance, reach_score,
                                                 whiteboard_score)
from mmlearn.models.imitation.types import Demonstration


def _demo(hand, **objects):
    hand = np.asarray(hand, float)
    t = np.arange(len(hand)) * 0.2
    objs = {k: np.repeat(np.asarray(v, float)[None], len(hand), axis=0) for k, v in objects.items()}
    return Demonstration(t=t, hand=hand, objects=objs).validate()


def test_final_point_skips_trailing_gaps_and_densify_keeps_the_corners():
    track = np.array([[0.0, 0.0, 0.0], [1.0, 2.0, 3.0], [np.nan] * 3])
    assert final_point(track).tolist() == [1.0, 2.0, 3.0]
    path = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.1, 0.05, 0.0]])
    d = densify(path, step=0.01)
    steps = np.linalg.norm(np.diff(d, axis=0), axis=1)
    assert np.allclose(d[0], path[0]) and np.allclose(d[-1], path[-1])
    assert steps.max() <= 0.01 + 1e-12 and any(np.allclose(p, path[1]) for p in d)


def _board(scale=1.0):
    """Corners of a board in the plane x = 0.6, 0.2 x 0.2 m times ``scale``."""
    h = 0.1 * scale
    return np.array([[0.6, -h, 1.0 - h], [0.6, h, 1.0 - h], [0.6, h, 1.0 + h], [0.6, -h, 1.0 + h]])


def _zigzag(corners, rows, x):
    c = np.asarray(corners)
    ys, zs = (c[:, 1].min(), c[:, 1].max()), np.linspace(c[:, 2].min(), c[:, 2].max(), rows)
    pts = [p for i, z in enumerate(zs) for p in ([x, ys[i % 2], z], [x, ys[1 - i % 2], z])]
    return np.array(pts)


def test_coverage_counts_the_grid_the_sponge_passed_in_the_board_plane():
    C = _board()
    full = densify(_zigzag(C, 4, 0.6))           # rows 6.7 cm apart: every cell within 4 cm
    assert coverage(full, C, plane_tol=0.02) == 1.0
    assert coverage(full + [0.1, 0.0, 0.0], C, plane_tol=0.02) == 0.0   # 10 cm off the board
    line = densify(np.array([[0.6, -0.1, 1.005], [0.6, 0.1, 1.005]]))   # one stroke, mid-height
    share = coverage(line, C, plane_tol=0.02)
    # the rows within the sponge radius (4 cm) of the line: z = 0.97 .. 1.04, 8 of 21 rows
    assert share == pytest.approx(8 / 21) and SPONGE_RADIUS == 0.04


def test_whiteboard_score_compares_with_the_demonstrations_own_coverage():
    C = _board()
    corners = {f"board_c{k}": c for k, c in enumerate(C)}
    demos = [_demo(densify(_zigzag(C, 4, 0.61)), **corners) for _ in range(2)]
    assert plane_distance(demos) == pytest.approx(0.01)
    good = whiteboard_score(densify(_zigzag(C, 4, 0.6)), corners, demos)
    assert good == {"coverage": 1.0, "demo_coverage": 1.0, "success": True}
    half = whiteboard_score(densify(_zigzag(C, 4, 0.6))[:40], corners, demos)
    assert half["coverage"] < 0.9 and not half["success"]


def test_place_spot_and_reach_score_apply_the_demonstrated_offset_to_this_scene():
    demos = [_demo([[0.0, 0.0, 0.0], [0.5, 0.1, 0.8]], cup=[0.52, 0.1, 0.75],
                   table_b=[0.5, 0.0, 0.7], target=[0.5, 0.1, 0.9]),
             _demo([[0.0, 0.0, 0.0], [0.4, 0.1, 0.8]], cup=[0.44, 0.1, 0.75],
                   table_b=[0.4, 0.0, 0.7], target=[0.4, 0.1, 0.9])]
    # mean cup - table_b offset (0.03, 0.1, 0.05) applied to this scene's table
    assert np.allclose(place_spot(demos, [1.0, 1.0, 0.7]), [1.03, 1.1, 0.75]) and PLACE_TOL == 0.02
    # the hand ended 0.1 m below the target in both: that spot relative to this target
    hit = reach_score([2.0, 0.0, 0.9], [2.0, 0.0, 1.0], demos, clearance=None)
    assert hit == {"reach_error_m": pytest.approx(0.0, abs=1e-12), "success": True}
    near = reach_score([2.0, 0.0, 0.9 + REACH_TOL / 2], [2.0, 0.0, 1.0], demos, clearance=0.01)
    assert near["success"] and near["reach_error_m"] == pytest.approx(REACH_TOL / 2)
    assert not reach_score([2.0, 0.0, 0.9], [2.0, 0.0, 1.0], demos, clearance=-0.001)["success"]
    assert not reach_score([2.0, 0.0, 0.95], [2.0, 0.0, 1.0], demos, clearance=None)["success"]


def test_condition_table_groups_by_label_and_counts_errors_beside_the_means():
    def line(label, seed, record=None, error=None):
        return {"key": f"{label}{seed}", "spec": {"label": f"{label} seed {seed}", "params": {}},
                "record": record, "error": error}

    lines = [line("pick 4 demos", 1, {"success": True, "place_error_m": 0.01,
                                      "reproduction_seconds": 2.0, "learn_seconds": 0.1}),
             line("pick 4 demos", 2, {"success": False, "place_error_m": 0.05,
                                      "reproduction_seconds": 4.0, "learn_seconds": 0.3}),
             line("pick 4 demos", 3, error="RuntimeError: no plan"),
             line("reach", 1, {"success": True, "min_obstacle_clearance_m": 0.02,
                               "reach_error_m": 0.01})]
    rows, errors = condition_table(lines)
    pick, reach = rows
    assert (pick["condition"], pick["trials"], pick["errors"], pick["successes"]) == \
        ("pick 4 demos", 2, 1, 1)
    assert pick["success_rate"] == 0.5 and pick["mean_place_error_m"] == pytest.approx(0.03)
    assert pick["median_place_error_m"] == pytest.approx(0.03) and pick["place_error_runs"] == 2
    assert pick["mean_reproduction_seconds"] == pytest.approx(3.0)
    assert pick["min_clearance_m"] is None and pick["mean_coverage"] is None
    assert reach["min_clearance_m"] == 0.02 and reach["positive_clearance"] == 1
    assert errors == [{"trial": "pick 4 demos seed 3", "error": "RuntimeError: no plan"}]


def test_reproduction_plan_gives_every_condition_its_seeds():
    from mmlearn.diagrams.imitation.trials import reproduction_plan, reproduction_trial

    conds = [("pick_place 1 demo", {"task": "pick_place", "demos": 1}),
             ("u_obstacle global", {"task": "u_obstacle", "global_mode": True})]
    plan = reproduction_plan(conds, 3, 100)
    assert len(plan) == 6 and all(p["fn"] is reproduction_trial for p in plan)
    assert [p["seed"] for p in plan] == [100, 101, 102] * 2
    assert plan[4]["label"] == "u_obstacle global seed 101"
    assert plan[4]["params"] == {"task": "u_obstacle", "global_mode": True}
    assert reproduction_trial.trial_name == "imitation.reproduce"
