"""The ch. 6 objects (sdf/tactile_objects.py), one recognition grasp in Drake
(diagrams/tactile/objects.py) and the tactile_recognition app."""

import json

import numpy as np
import pytest
from conftest import bad_usage, run_main

from mmlearn.sdf.tactile_objects import (CLASSES, MATERIALS, OBJECTS, class_of, object_sdf,
                                         sample_object)


# ------------------------------------------------------------------ objects
def test_catalog_has_16_objects_21_classes_in_two_groups():
    assert len(OBJECTS) == 16 and len(CLASSES) == 21
    groups = [o.group for o in OBJECTS.values()]
    assert groups.count("industrial") == 5 and groups.count("household") == 11
    two = [o.name for o in OBJECTS.values() if len(o.yaws) == 2]
    assert len(two) == 5 and {"mug", "tea_box"} <= set(two)
    assert class_of("mug@90").yaw == 90 and class_of("soft_ball").object == "soft_ball"
    with pytest.raises(ValueError, match="unknown tactile object class 'jar'"):
        class_of("jar")
    with pytest.raises(ValueError, match="unknown tactile object 'jar'"):
        sample_object("jar", np.random.default_rng(0))
    # the two balls: same size, one soft and one hard
    s, t = OBJECTS["soft_ball"].parts[0], OBJECTS["tennis_ball"].parts[0]
    assert s.dims == t.dims
    assert MATERIALS[s.material].modulus < 0.1 * MATERIALS[t.material].modulus


def test_every_class_loads_in_drake_and_instances_vary_with_the_seed():
    from pydrake.multibody.parsing import Parser
    from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
    from pydrake.systems.framework import DiagramBuilder

    for name, c in CLASSES.items():
        inst = sample_object(c.object, np.random.default_rng(1), yaw=c.yaw)
        builder = DiagramBuilder()
        plant, sg = AddMultibodyPlantSceneGraph(builder, 0.001)
        mi = Parser(plant).AddModelsFromString(object_sdf(inst), "sdf")[0]
        plant.Finalize()
        body = plant.GetBodyByName("base", mi)
        assert len(plant.GetCollisionGeometriesForBody(body)) == len(OBJECTS[c.object].parts)
    a = sample_object("bottle", np.random.default_rng(3))
    b = sample_object("bottle", np.random.default_rng(3))
    d = sample_object("bottle", np.random.default_rng(4))
    assert object_sdf(a) == object_sdf(b) and object_sdf(a) != object_sdf(d)
    assert a.scale != d.scale and a.modulus_scale != d.modulus_scale
    # yaw 90 turns the mug's handle from +y to -x
    h0 = sample_object("mug", nominal=True, yaw=0).parts[1].xyz
    h90 = sample_object("mug", nominal=True, yaw=90).parts[1].xyz
    assert h0[1] > 0.05 and abs(h0[0]) < 1e-9 and h90[0] < -0.05 and abs(h90[1]) < 1e-9


# ------------------------------------------------------------------ grasps in Drake
@pytest.mark.slow
def test_soft_and_tennis_ball_differ_by_touch():
    from mmlearn.diagrams.tactile.objects import object_grasp_trial, observation_from_record

    soft = object_grasp_trial(seed=5, cls="soft_ball", height=0.035)
    hard = object_grasp_trial(seed=5, cls="tennis_ball", height=0.035)
    assert soft["contact"] and hard["contact"]
    assert abs(soft["force"] - 30.0) < 6 and abs(hard["force"] - 30.0) < 6  # 15 N per finger
    # same 67 mm ball: the foam yields > 10 mm per side, the tennis ball a few mm
    assert 0.060 < hard["width"] < 0.066 and soft["width"] < hard["width"] - 0.015
    # the soft ball spreads the same force over a larger patch: lower peak, more cells
    Ls, Lh = np.array(soft["left"]), np.array(hard["left"])
    assert Ls.max() < 0.6 * Lh.max() and (Ls > 0.02).sum() > 1.5 * (Lh > 0.02).sum()
    assert set(soft) >= {"left", "right", "height", "width", "cls", "group"}
    obs = observation_from_record(soft)
    assert obs.left.shape == (14, 6) and obs.label == "soft_ball" and obs.width == soft["width"]


@pytest.mark.slow
def test_slotted_and_flat_profile_faces_and_no_contact():
    from mmlearn.diagrams.tactile.objects import object_grasp_trial

    slot = np.array(object_grasp_trial(seed=2, cls="profile_a", height=0.05)["left"])
    flat = np.array(object_grasp_trial(seed=2, cls="profile_b@0", height=0.05)["left"])
    # the 8 mm slot is in the middle two of the 6 columns (4 mm each): no pressure there
    assert slot[:, 2:4].mean() < 0.2 * slot[:, [0, 1, 4, 5]].mean()
    assert flat[:, 2:4].mean() > 0.7 * flat[:, [0, 1, 4, 5]].mean()
    miss = object_grasp_trial(seed=2, cls="soft_ball", height=0.3, max_time=2.0)
    assert not miss["contact"] and miss["width"] < 0.01


# ------------------------------------------------------------------ evaluation (numpy)
def test_grasp_heights_are_one_absolute_grid_inside_each_object():
    from mmlearn.diagrams.tactile.objects import HEIGHT_STEP, grid_heights

    for cls in CLASSES:
        lo, hi = OBJECTS[class_of(cls).object].heights
        h = grid_heights(cls)
        assert h.size >= 2 and lo - 1e-9 <= h[0] and h[-1] <= hi + 1e-9
        np.testing.assert_allclose(np.diff(h), HEIGHT_STEP)
        np.testing.assert_allclose(h / HEIGHT_STEP, np.round(h / HEIGHT_STEP), atol=1e-6)
    np.testing.assert_allclose(np.diff(grid_heights(next(iter(CLASSES)), step=0.02)), 0.02)


def test_evaluate_separates_distinct_classes_and_not_identical_ones():
    from mmlearn.apps.tactile_recognition import evaluate
    from mmlearn.models.tactile.synth import make_objects, sample_grasps

    rng = np.random.default_rng(0)
    objs = make_objects(4, 5, rng=rng)
    cl = np.repeat(np.arange(4), 20)
    hh = np.tile(np.arange(5), 16)
    d = sample_grasps(objs, cl, hh, rng=rng, names=["a", "b", "c", "d"])
    r = evaluate(d, ["a", "b", "c", "d"], k=20, T=5, recognitions=100, seed=1)
    assert r["rate"] > 0.85 and r["n_classes"] == 4 and len(r["rate_by_T"]) == 5
    C = np.array(r["confusion"])
    assert C.sum() == r["recognitions"] == 200 and r["with_replacement"] == 0
    # "a" and "b" are grasps of one object under two names: a coin toss between them
    one = sample_grasps(make_objects(1, 5, rng=rng), np.zeros(60, int), np.tile(np.arange(5), 12),
                        rng=rng, names=["x"])
    one.labels = np.array(["a", "b"] * 30, dtype=object)
    r2 = evaluate(one, ["a", "b"], k=10, T=1, recognitions=300, seed=1)
    assert 0.3 < r2["rate"] < 0.7


@pytest.mark.slow
def test_informed_heights_beat_random_where_one_height_tells_the_classes_apart():
    """Four classes in two pairs: within a pair the objects are identical at heights 0-3 and
    differ only at height 4. At a uniform belief the expected gain is largest at height 4
    (it splits all four classes, the others only the pairs), so the first informed grasp
    recognises the object; a random first grasp only tells the pair (rate ~0.6)."""
    from mmlearn.apps.tactile_recognition import STRATEGIES, evaluate
    from mmlearn.models.tactile.synth import sample_grasps

    rng = np.random.default_rng(4)
    objs = {"pattern": np.array([[0, 1, 2, 3, 8], [0, 1, 2, 3, 9],
                                 [4, 5, 6, 7, 10], [4, 5, 6, 7, 11]]),
            "width": np.array([[0.03, 0.04, 0.05, 0.06, 0.03], [0.03, 0.04, 0.05, 0.06, 0.05],
                               [0.07, 0.06, 0.05, 0.04, 0.07], [0.07, 0.06, 0.05, 0.04, 0.09]])}
    # 40 grasps per class: 4 per height in a training half, so that the leave-one-out outcome
    # likelihoods still see the class at every height
    cl = np.repeat(np.arange(4), 40)
    hh = np.tile(np.arange(5), 32)
    d = sample_grasps(objs, cl, hh, rng=rng, names=["a", "b", "c", "d"], noise=0.05)
    r = evaluate(d, ["a", "b", "c", "d"], k=12, T=3, recognitions=20, seed=2,
                 informed_trials=40)["informed"]
    assert set(STRATEGIES) <= set(r) and r["recognitions"] == 80
    assert r["informed"][0] > 0.9 and r["random"][0] < 0.8, r
    assert r["mean_over_T"]["informed"] > r["mean_over_T"]["random"] + 0.05, r
    pt = r["paired_t"]["informed"]
    assert pt["p"] < 0.01 and pt["mean_difference"] > 0
    # informed grasps never repeat a height while the object has fresh ones (5 > T = 3)
    assert r["distinct_heights"]["informed"] == r["distinct_heights"]["random_heights"] == 3.0


# ------------------------------------------------------------------ the app
@pytest.mark.slow
def test_app_short_run_and_report_only(tmp_path, capsys):
    from mmlearn.apps.tactile_recognition import main

    res = tmp_path / "g.jsonl"
    argv = ["--classes", "soft_ball,tennis_ball,round_bar,stepped_shaft", "--grasps-per-class",
            "2", "--k", "4", "--T", "2", "--recognitions", "40", "--cv-repeats", "2", "--jobs", "1",
            "--results",
            str(res), "--seed", "3", "--json"]
    rc, out, err = run_main(main, argv, capsys)
    assert rc == 0, err
    d = json.loads(out)
    assert d["n_grasps"] == 8 and not d["errors"] and not d["no_contact"]
    assert set(d["rates"]) == {"all", "household", "industrial", "soft_vs_tennis"}
    for r in d["rates"].values():
        assert 0.0 <= r["rate"] <= 1.0 and r["recognitions"] == 160
    assert d["rates"]["all"]["n_classes"] == 4 and d["thesis"]["rates"]["all"] == 0.846
    assert d["rates"]["all"]["k_used"] == [2]  # half of the 4 training grasps
    lines = [json.loads(x) for x in res.read_text().splitlines()]
    assert len(lines) == 8 and all(ln["error"] is None for ln in lines)
    png = tmp_path / "rec.png"
    rc, out2, err = run_main(main, ["--report-only", str(res), "--k", "4", "--T", "2",
                                    "--recognitions", "40", "--cv-repeats", "2", "--seed", "3",
                                    "--plot", str(png), "--json"], capsys)
    assert rc == 0, err
    d2 = json.loads(out2)
    assert d2["rates"] == d["rates"]  # the same figures from the file alone
    assert set(d2["example_images"]) == {"soft_ball", "tennis_ball", "round_bar",
                                         "stepped_shaft"}
    assert png.stat().st_size > 10_000


@pytest.mark.slow
def test_one_grasp_recorded_as_meshcat_html(tmp_path):
    from mmlearn.apps.common.cli import make_meshcat
    from mmlearn.apps.tactile_recognition import _show_one

    html = tmp_path / "grasp.html"
    rec = _show_one("round_bar", seed=0, meshcat=make_meshcat(announce=False), html_out=html)
    assert rec["contact"] and html.stat().st_size > 100_000


@pytest.mark.parametrize("argv, needles", [
    (["--alpha", "2"], ["--alpha", "[0, 1]"]),
    (["--classes", "jar"], ["--classes", "jar"]),
    (["--grasps-per-class", "1"], ["grasps_per_class", "at least 2"]),
    (["--k", "0"], ["--k"]),
    (["--report-only", "/nonexistent/x.jsonl"], ["--report-only", "no results file"]),
    (["--report-only", "x.jsonl", "--html-out", "y.html"], ["--report-only simulates nothing"]),
])
def test_app_bad_arguments(argv, needles, capsys):
    from mmlearn.apps.tactile_recognition import main

    bad_usage(main, argv, capsys, *needles)


def test_app_help(capsys):
    from mmlearn.apps.tactile_recognition import main

    rc, out, _ = run_main(main, ["--help"], capsys)
    assert rc == 0 and "--grasps-per-class" in out and "--report-only" in out
