"""The robot's surprise at its own reproduction under the learned DBN
(models/imitation/confidence.py): low for a reproduction that keeps the demonstrated relation
to the object that matters, high for one that keeps a relation that varied."""

import numpy as np
import pytest

from mmlearn.models.imitation.confidence import (ConfidenceConfig, SurpriseMonitor,
                                                 demonstration_surprise, reference_surprise,
                                                 smooth, trajectory_surprise)
from mmlearn.models.imitation.dbn import learn_task
from mmlearn.models.imitation.types import Demonstration, ImitationDataError

T = np.linspace(0.0, 4.0, 41)


def _demo(rng, goal, other):
    """A 2-D reach from the origin to 5 cm short of ``goal``; ``other`` is a distractor."""
    s = 0.5 - 0.5 * np.cos(np.pi * T / T[-1])
    hand = np.outer(s, goal - [0.05, 0.0]) + rng.normal(0, 0.002, (T.size, 2))
    return Demonstration(t=T.copy(), hand=hand,
                         objects={"goal": np.tile(goal, (T.size, 1)),
                                  "other": np.tile(other, (T.size, 1))})


def _scene(rng):
    return rng.uniform([0.8, -0.3], [1.0, 0.3]), rng.uniform([-0.5, 0.5], [0.5, 1.0])


@pytest.fixture(scope="module")
def taught():
    rng = np.random.default_rng(4)
    demos = [_demo(rng, *_scene(rng)) for _ in range(5)]
    return learn_task(demos, h=0.2), demos


def _follow(model, goal, other, rel_to="goal"):
    """The hand that keeps each slice's mean relation to ``rel_to``."""
    obj = {"goal": goal, "other": other}[rel_to]
    hand = obj - model.mean[f"obj:{rel_to}"]
    objs = {"goal": np.tile(goal, (model.S, 1)), "other": np.tile(other, (model.S, 1))}
    return hand, objs


def test_demonstrations_explain_themselves(taught):
    model, demos = taught
    s = demonstration_surprise(model, demos)
    assert len(s) == 5 and all(np.all(np.isfinite(x)) for x in s)
    assert reference_surprise(model, demos, window=0.4) < 5.0


def test_surprise_separates_the_relevant_relation(taught):
    model, _ = taught
    rng = np.random.default_rng(11)
    goal, other = _scene(rng)
    ks = np.arange(model.S)
    good = trajectory_surprise(model, ks, *_follow(model, goal, other, "goal"))
    bad = trajectory_surprise(model, ks, *_follow(model, goal, other, "other"))
    late = slice(model.S // 2, None)          # where the two relations lead elsewhere
    assert np.nanmean(good[late]) < 5.0
    assert np.nanmean(bad[late]) > 50.0 * np.nanmean(good[late])


def test_monitor_flags_only_the_wrong_reproduction(taught):
    model, demos = taught
    rng = np.random.default_rng(12)
    goal, other = _scene(rng)
    cfg = ConfidenceConfig(window=0.4, ignore_start=0.0)
    for rel, expect in (("goal", False), ("other", True)):
        mon = SurpriseMonitor(model, demos, sample_period=0.1, config=cfg)
        hand, objs = _follow(model, goal, other, rel)
        flags = [mon.update(k, hand[k], {n: v[k] for n, v in objs.items()})
                 for k in range(model.S)]
        assert mon.flagged is expect
        assert flags[-1] is expect
        summ = mon.summary(0.1)
        assert summ["unsure"] is expect and summ["threshold"] == pytest.approx(
            cfg.factor * summ["reference_surprise"])
        assert (summ["unsure_at_s"] is None) is (not expect)


def test_monitor_ignores_the_start_and_unseen_objects(taught):
    model, demos = taught
    mon = SurpriseMonitor(model, demos, sample_period=0.1,
                          config=ConfidenceConfig(window=0.2, ignore_start=1.0))
    far = np.array([5.0, 5.0])
    for k in range(10):                       # 1 s far away: not judged
        assert not mon.update(k, far, {"goal": np.zeros(2), "other": np.zeros(2)})
    assert not mon.update(10, far, {})        # nothing observed: no evidence
    assert mon.update(11, far, {"goal": np.zeros(2)}) is False  # one sample < window
    assert mon.update(12, far, {"goal": np.zeros(2)}) is True


def test_smooth_skips_nan():
    out = smooth([1.0, np.nan, 3.0, 5.0], 2)
    assert out[0] == 1.0 and out[1] == 1.0 and out[2] == 3.0 and out[3] == 4.0
    assert np.isnan(smooth([np.nan, np.nan], 2)).all()


def test_bad_input(taught):
    model, demos = taught
    with pytest.raises(ImitationDataError, match="no object"):
        trajectory_surprise(model, [0], np.zeros((1, 2)), {"cup": np.zeros((1, 2))})
    with pytest.raises(ImitationDataError, match="shape"):
        trajectory_surprise(model, [0], np.zeros((1, 2)), {"goal": np.zeros((1, 3))})
    with pytest.raises(ImitationDataError, match="slices"):
        trajectory_surprise(model, [0, 1], np.zeros((1, 2)), {"goal": np.zeros((1, 2))})
    with pytest.raises(ImitationDataError, match="sample_period"):
        SurpriseMonitor(model, demos, sample_period=0.0)
    with pytest.raises(ImitationDataError, match="no demonstrations"):
        demonstration_surprise(model, [])
    with pytest.raises(ValueError, match="factor"):
        ConfidenceConfig(factor=0.5).validate()
