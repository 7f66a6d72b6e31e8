"""Priors from experience (Algorithm 2) on real Cody trajectories (tests/data/articulation_priors)."""

import json
from pathlib import Path

import numpy as np
import pytest

from mmlearn.models.articulation.priors import (PriorDatabase, align_trajectory,
                                                evaluate_priors, learn_priors, merge_bic,
                                                thin_trajectory)
from mmlearn.models.common.track_io import read_track

DATA = Path(__file__).parent / "data" / "articulation_priors"
OBJECTS = ("drawer", "left_door", "right_door", "dishwasher")


def _load(names):
    return [read_track(DATA / f"{n}.log").poses for n in names]


@pytest.fixture(scope="module")
def all_names():
    # interleaved order: every object appears before any repeats
    return [f"{o}_{k:03d}" for k in (1, 2) for o in OBJECTS]


@pytest.fixture(scope="module")
def db(all_names):
    return learn_priors(_load(all_names), all_names, rng=0)


def test_one_cluster_per_object(db):
    assert len(db.clusters) == 4
    for c in db.clusters:
        objs = {m.rsplit("_", 1)[0] for m in c.members}
        assert len(objs) == 1 and len(c.members) == 2
    models = {c.members[0].rsplit("_", 1)[0]: c.model.name for c in db.clusters}
    assert models["drawer"] == "prismatic"
    assert models["left_door"] == models["right_door"] == models["dishwasher"] == "revolute"


def test_separate_objects_do_not_merge():
    # a left and a right door (mirror images) stay apart; two drawers merge
    pdb = PriorDatabase()
    a, b, c = _load(["left_door_001", "right_door_001", "drawer_001"])
    assert pdb.add(a, "L") == 0
    assert pdb.add(b, "R") == 1
    dec = pdb.merge_test(c)
    assert dec.cluster is None
    d = pdb.merge_test(_load(["left_door_002"])[0])
    assert d.cluster == 0 and d.delta_bic[0] < d.new_bic < d.delta_bic[1]


def test_alignment_and_thinning():
    raw = _load(["drawer_002"])[0]
    a = align_trajectory(raw)
    assert np.allclose(a[0], 0) and np.allclose(a[1:] - a[0], raw[1:] - raw[0])
    t = thin_trajectory(a, 20)
    assert t.shape == (20, 3) and np.allclose(t[-1], a[-1])
    with pytest.raises(ValueError, match="alignment"):
        align_trajectory(raw, "centroid")
    with pytest.raises(ValueError, match="too short"):
        PriorDatabase().prepare(raw[:2])


def test_save_load_roundtrip(tmp_path, db):
    p = tmp_path / "priors.json"
    db.save(p)
    d2 = PriorDatabase.load(p)
    assert d2.assignments() == db.assignments()
    assert d2.model_names() == db.model_names()
    Z = db.clusters[0].data[0]
    assert np.allclose(d2.clusters[0].model.project(Z), db.clusters[0].model.project(Z))
    assert merge_bic(d2.clusters[0].model, d2.clusters[0].data) == pytest.approx(db.clusters[0].bic)
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"format": "something else"}))
    with pytest.raises(ValueError, match="not a prior database"):
        PriorDatabase.load(bad)
    bad.write_text("{not json")
    with pytest.raises(ValueError, match="not valid JSON"):
        PriorDatabase.load(bad)
    with pytest.raises(FileNotFoundError):
        PriorDatabase.load(tmp_path / "missing.json")


def test_partial_trajectory_predicted_better_with_priors(db):
    # (the first 30-40 % of a left-door trajectory is a nearly straight pull along the
    # drawers' direction and merges with the drawers: a genuine ambiguity of partial data)
    pdb = PriorDatabase.from_dict(db.to_dict())
    pdb.remove("right_door_002")
    raw = align_trajectory(_load(["right_door_002"])[0])
    full = pdb.prepare(raw)
    part = raw[: int(0.4 * len(raw))]
    dec = pdb.merge_test(part, rng=0)
    assert dec.cluster is not None
    assert "right_door_001" in pdb.clusters[dec.cluster].members
    e_with = dec.model.prediction_errors(full)[0]
    e_without = dec.new_model.prediction_errors(full)[0]
    assert e_with < 0.03
    assert e_without > 3 * e_with


def test_leave_one_out_error_reduction(all_names):
    names = ["drawer_001", "drawer_002", "right_door_001", "right_door_002"]
    r = evaluate_priors(_load(names), names, fractions=[0.5, 1.0], rng=0)
    assert r["error_with"].shape == (4, 2)
    assert r["merged"][:, 0].all()
    assert r["error_without"][:, 0].mean() > 3 * r["error_with"][:, 0].mean()


def test_prior_input_errors():
    with pytest.raises(ValueError, match="unknown link model"):
        PriorDatabase(models=("rigid", "helical"))
    with pytest.raises(ValueError, match="joint_models"):
        PriorDatabase(joint_models="best")
    with pytest.raises(ValueError, match="unique"):
        learn_priors(_load(["drawer_001", "drawer_002"]), ["a", "a"])
    pdb = PriorDatabase()
    pdb.add(_load(["drawer_001"])[0], "d")
    rng = np.random.default_rng(0)
    full = np.hstack([rng.normal(size=(20, 3)), np.tile([0, 0, 0, 1.0], (20, 1))])
    with pytest.raises(ValueError, match="columns"):
        pdb.merge_test(full)
    with pytest.raises(KeyError):
        pdb.remove("nope")
    with pytest.raises(ValueError, match="NaN"):
        pdb.add(np.full((10, 3), np.nan))


def test_learn_priors_run_save_then_load(tmp_path):
    from mmlearn.apps.learn_priors import run

    db = tmp_path / "db.json"
    first = [str(DATA / "drawer_001.log"), str(DATA / "left_door_001.log")]
    out = run(paths=first, save=str(db), progress=False)
    assert len(out["clusters"]) == 2
    out2 = run(paths=[str(DATA / "drawer_002.log")], load=str(db), progress=False)
    assert len(out2["clusters"]) == 2
    drawer = [c for c in out2["clusters"] if first[0] in c][0]
    assert str(DATA / "drawer_002.log") in drawer


def test_a_cluster_whose_joint_fit_fails_is_reported_not_dropped(monkeypatch):
    pdb = PriorDatabase()
    a, b = _load(["left_door_001", "left_door_002"])
    pdb.add(a, "L1")
    real = PriorDatabase._fit_joint

    def failing(self, cluster, Z, rng):
        if cluster.members == ["L1"]:
            raise ValueError("no candidate fits")
        return real(self, cluster, Z, rng)

    monkeypatch.setattr(PriorDatabase, "_fit_joint", failing)
    dec = pdb.merge_test(b)
    assert dec.cluster is None and 0 not in dec.delta_bic
    assert dec.not_tried == {0: "joint fit failed: no candidate fits"}
    monkeypatch.setattr(PriorDatabase, "_fit_joint", real)
    assert pdb.merge_test(b).not_tried == {} and pdb.merge_test(b).cluster == 0
    monkeypatch.setattr(PriorDatabase, "_fit_joint", failing)
    with pytest.warns(UserWarning, match="could not be tested against cluster 0"):
        assert pdb.add(b, "L2") == 1
