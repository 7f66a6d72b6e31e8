"""The metrics of the tactile experiments (models/tactile/evaluation.py): grasp features and
cross-validation of the ch. 7 container grasps, the recognition evaluation of ch. 6 and the
liquid-detection rolls, on synthetic records."""

import numpy as np
import pytest

from mmlearn.models.tactile.evaluation import (STRATEGIES, container_grasp_features,
                                               evaluate_recognition, evaluate_rolls, fold_cv,
                                               grasp_from_record, recognition_dataset,
                                               roll_record, split_two_fold,
                                               state_recognition_report)
from mmlearn.models.tactile.liquid import RollRecord
from mmlearn.models.tactile.types import TactileDataError


# ------------------------------------------------------------------ container grasps (ch. 7)
def _grasp_record(container, state, squeeze, rng):
    """A container grasp record: the fingers close at 20 mm/s, touch at 80 mm, squeeze by
    ``squeeze`` m while the force rises to 40 N and rest."""
    t = np.arange(0.0, 2.6, 0.04)
    p = np.clip(0.1 - 0.02 * t, 0.08, None)
    touch = t >= 1.0
    ramp = np.clip((t - 1.0) / 0.6, 0.0, 1.0)
    p = np.where(touch, 0.08 - squeeze * ramp, p) + rng.normal(0, 2e-5, t.shape)
    f = np.where(touch, 40.0 * ramp + 0.5, 0.0)
    return {"t": t.tolist(), "p": p.tolist(), "f": f.tolist(),
            "finger_force": np.stack([f / 2, f / 2], axis=1).tolist(),
            "container": container, "state": state}


def test_container_grasp_features_and_rates_from_records():
    rng = np.random.default_rng(0)
    squeeze = {("can", "empty"): 0.004, ("can", "full"): 0.001,
               ("bottle", "empty"): 0.009, ("bottle", "full"): 0.006}
    recs = [_grasp_record(c, s, q * rng.uniform(0.95, 1.05), rng)
            for (c, s), q in squeeze.items() for _ in range(6)]
    g = grasp_from_record(recs[0])
    assert (g.container, g.state, g.label) == ("can", "empty", "can/empty")
    X, yc, ys, feats = container_grasp_features(recs)
    assert X.shape == (24, 6) and all(f.contact and f.steady for f in feats)
    assert yc.tolist() == ["can"] * 12 + ["bottle"] * 12 and ys[0] == "empty"
    rep, k = fold_cv(X, yc, classifier="tree", folds=10, seed=0)
    assert k == 10 and rep.rate == 1.0
    rep, k = fold_cv(X[:8], ys[:8], classifier="tree", folds=10, seed=0)
    assert k == 2  # six empty, two full grasps: at most 2 folds
    out = state_recognition_report(X, yc, ys, classifier="tree", folds=3, seed=0)
    assert out["container_rate"] == 1.0 and set(out["container_compare"]) == {"forest", "boost"}
    assert out["state_rate_by_container"] == {"bottle": 1.0, "can": 1.0}
    assert out["combined_rate"] == 1.0 and out["combined_rate_without_water"] == 1.0
    one = state_recognition_report(X[:12], yc[:12], ys[:12], classifier="tree", folds=3, seed=0)
    assert one["container_rate"] == 1.0 and one["container_compare"] == {}
    with pytest.raises(ValueError, match="too few grasps per class"):
        fold_cv(X[:7], ys[:7], classifier="tree", folds=10, seed=0)


def test_icub_state_report_by_cross_validation_and_on_a_test_set():
    """The real iCub grasps of tests/data: k-fold CV scores every grasp once; a split scores
    the test trials; the grasps of the empty hand count as without contact."""
    from pathlib import Path

    from mmlearn.models.tactile.icub_grasp import CONTACT_LEVEL, REST_VELOCITY, load_icub_dir
    from mmlearn.models.tactile.evaluation import icub_state_report

    trials, _ = load_icub_dir(Path(__file__).parent / "data" / "icub_grasp")
    kw = dict(classifier="tree", seed=3, contact_level=CONTACT_LEVEL,
              rest_velocity=REST_VELOCITY, steady_average=False)
    cv, rep = icub_state_report(trials, folds=4, **kw)
    assert cv["evaluation"] == "4-fold CV" and cv["n_train"] == cv["n_test"] == len(trials)
    assert np.sum(cv["confusion"]) == len(trials) and cv["rate"] == rep.rate
    assert set(cv["compare"]) == {"forest", "boost"} and cv["no_contact"]["none"] == 4
    train = [t for t in trials if int(t.trial) <= 2]
    test = [t for t in trials if int(t.trial) > 2]
    split, _ = icub_state_report(train, test, folds=4, **kw)
    assert split["evaluation"] == "test" and split["n_test"] == len(test)
    assert np.sum(split["confusion"]) == len(test)


def test_recognition_dataset_and_the_stratified_two_fold_split():
    recs = [{"left": np.full((14, 6), i / 10).tolist(), "right": np.zeros((14, 6)).tolist(),
             "height": 0.01 * i, "width": 0.05, "cls": "ab"[i % 2], "group": "g" + "ab"[i % 2],
             "contact": i != 4} for i in range(9)]
    data, groups = recognition_dataset(recs)
    assert len(data) == 8 and groups == {"a": "ga", "b": "gb"}
    A, B = split_two_fold(data.labels, np.random.default_rng(1))
    assert sorted(np.concatenate([A, B]).tolist()) == list(range(8))
    for half in (A, B):
        assert sorted(data.labels[half].tolist()) == ["a", "a", "b", "b"]
    with pytest.raises(ValueError, match="no grasp touched"):
        recognition_dataset([dict(r, contact=False) for r in recs])


# ------------------------------------------------------------------ recognition (ch. 6)
def test_evaluate_separates_distinct_classes_and_not_identical_ones():
    from mmlearn.models.tactile.synth import make_objects, sample_grasps

    rng = np.random.default_rng(0)
    objs = make_objects(4, 5, rng=rng)
    cl = np.repeat(np.arange(4), 20)
    hh = np.tile(np.arange(5), 16)
    d = sample_grasps(objs, cl, hh, rng=rng, names=["a", "b", "c", "d"])
    r = evaluate_recognition(d, ["a", "b", "c", "d"], k=20, T=5, recognitions=100, seed=1)
    assert r["rate"] > 0.85 and r["n_classes"] == 4 and len(r["rate_by_T"]) == 5
    C = np.array(r["confusion"])
    assert C.sum() == r["recognitions"] == 200 and r["with_replacement"] == 0
    # "a" and "b" are grasps of one object under two names: a coin toss between them
    one = sample_grasps(make_objects(1, 5, rng=rng), np.zeros(60, int), np.tile(np.arange(5), 12),
                        rng=rng, names=["x"])
    one.labels = np.array(["a", "b"] * 30, dtype=object)
    r2 = evaluate_recognition(one, ["a", "b"], k=10, T=1, recognitions=300, seed=1)
    assert 0.3 < r2["rate"] < 0.7


@pytest.mark.slow
def test_informed_heights_beat_random_where_one_height_tells_the_classes_apart():
    """Four classes in two pairs: within a pair the objects are identical at heights 0-3 and
    differ only at height 4. At a uniform belief the expected gain is largest at height 4
    (it splits all four classes, the others only the pairs), so the first informed grasp
    recognises the object; a random first grasp only tells the pair (rate ~0.6)."""
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
    r = evaluate_recognition(d, ["a", "b", "c", "d"], k=12, T=3, recognitions=20, seed=2,
                 informed_trials=40)["informed"]
    assert set(STRATEGIES) <= set(r) and r["recognitions"] == 80
    assert r["informed"][0] > 0.9 and r["random"][0] < 0.8, r
    assert r["mean_over_T"]["informed"] > r["mean_over_T"]["random"] + 0.05, r
    pt = r["paired_t"]["informed"]
    assert pt["p"] < 0.01 and pt["mean_difference"] > 0
    # informed grasps never repeat a height while the object has fresh ones (5 > T = 3)
    assert r["distinct_heights"]["informed"] == r["distinct_heights"]["random_heights"] == 3.0


# ------------------------------------------------------------------ liquid detection (Sec. 7.3)
def test_roll_record_takes_the_coast_samples_from_the_stored_roll_command():
    """The coast samples follow the roll command the record stores (``roll_changes``, where
    the commanded rate changed; None for the sine roll, which has no coast phases); a record
    without it is refused by name."""
    from mmlearn.diagrams.tactile.liquid_roll import LiquidRollConfig, roll_change_windows

    c = LiquidRollConfig()
    t = np.arange(0.0, c.duration, 1 / 24)
    base = {"t": t.tolist(), "taxels": np.full((len(t), 4), 0.1).tolist(),
            "wrist_force": np.zeros((len(t), 3)).tolist(),
            "roll_window": [c.t_roll, c.t_roll + c.roll_duration],
            "weight_window": [1.7, 1.9], "liquid": False, "container": "x"}
    sweep = dict(base, roll_changes=roll_change_windows(c).tolist())
    assert roll_record(sweep).coast.sum() == 35  # 3 phases of 11 + 2 single samples
    assert roll_record(sweep, coast_delay=0.0).coast.sum() > 35
    assert roll_record(dict(base, roll_changes=None)).coast is None
    with pytest.raises(TactileDataError, match="roll_changes"):
        roll_record(base)


def test_dummy_read_held_out_and_inside_the_cross_validation():
    """The dummy's two readings: held out (trained on the containers alone) and, as Table 7.5
    counts it, inside the cross-validation as one more "no liquid" object. Synthetic records:
    liquid trials ring, empty ones and the heavy dummy do not; with weight in the held-out
    reading the tree may split on weight (the dummy weighs as much as a half-full bottle), in
    the thesis' reading the training folds hold heavy trials without liquid, so it cannot."""
    rng = np.random.default_rng(0)
    t = np.arange(120) / 24.0

    def rec(liquid, weight, name):
        amp = 0.01 if liquid else 0.0005
        tax = 0.2 + amp * np.sin(2 * np.pi * 7.0 * t)[:, None] * rng.uniform(0.5, 1.5, 4)
        tax = tax + 1e-4 * rng.standard_normal(tax.shape)
        return RollRecord(taxels=tax, weight=weight + 0.05 * rng.standard_normal(),
                          liquid=liquid, container=name)

    rr = [rec(True, 2.5, "full") for _ in range(12)] + [rec(False, 0.3, "empty") for _ in range(12)]
    dr = [rec(False, 2.5, "dummy") for _ in range(4)]
    y = np.array(["liquid" if r.liquid else "no_liquid" for r in rr])
    out = evaluate_rolls(rr, dr, y, feature="whole", k=4, seed=0)
    d = out["dummy"]
    assert d["trials"] == 4
    assert d["predicted_no_liquid_tactile"] == 4          # the feature alone: no liquid
    assert d["in_cv_no_liquid_tactile"] == 4
    assert d["in_cv_no_liquid_with_weight"] == 4          # weight cannot decide inside the CV
    assert d["in_cv_rate_with_weight"] == pytest.approx(1.0)
    assert 0 <= d["predicted_no_liquid_with_weight"] <= 4
