"""The ch. 6 objects (sdf/tactile_objects.py) and one recognition grasp of them in Drake
(object_grasp_trial, diagrams/tactile/trials.py) with the plan of the experiment's grasps."""

import numpy as np
import pytest

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
    from mmlearn.diagrams.tactile.trials import object_grasp_trial
    from mmlearn.models.tactile.evaluation import observation_from_record

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
    from mmlearn.diagrams.tactile.trials import object_grasp_trial

    slot = np.array(object_grasp_trial(seed=2, cls="profile_a", height=0.05)["left"])
    flat = np.array(object_grasp_trial(seed=2, cls="profile_b@0", height=0.05)["left"])
    # the 8 mm slot is in the middle two of the 6 columns (4 mm each): no pressure there
    assert slot[:, 2:4].mean() < 0.2 * slot[:, [0, 1, 4, 5]].mean()
    assert flat[:, 2:4].mean() > 0.7 * flat[:, [0, 1, 4, 5]].mean()
    miss = object_grasp_trial(seed=2, cls="soft_ball", height=0.3, max_time=2.0)
    assert not miss["contact"] and miss["width"] < 0.01


def test_object_grasp_plan_cycles_the_grid_heights_bottom_to_top():
    from mmlearn.diagrams.tactile.trials import (GRIPPER_CH6, grid_heights, object_grasp_plan,
                                                 object_grasp_trial)

    hs = grid_heights("soft_ball")
    lo, hi = OBJECTS["soft_ball"].heights
    assert np.all(np.diff(hs) > 0) and lo - 1e-9 <= hs[0] and hs[-1] <= hi + 1e-9
    assert np.allclose(np.diff(hs), 0.01) and GRIPPER_CH6.open_gap == 0.12
    plan = object_grasp_plan(["soft_ball", "mug@90"], len(hs) + 1, seed=2, f_target=12.0)
    assert len(plan) == 2 * (len(hs) + 1) and all(p["fn"] is object_grasp_trial for p in plan)
    ball = plan[:len(hs) + 1]
    assert [p["params"]["height"] for p in ball] == [float(h) for h in hs] + [float(hs[0])]
    assert all(p["params"]["f_target"] == 12.0 and p["params"]["cls"] == "soft_ball" for p in ball)
    seeds = [p["seed"] for p in plan]
    assert len(set(seeds)) == len(seeds)
    assert object_grasp_trial.trial_name == "tactile.object_grasp"
