"""Tactile learning models of thesis ch. 6-7 (plain numpy): distances, codebook, posterior,
information gain, grasp features, liquid feature."""

import numpy as np
import pytest

from mmlearn.models.tactile.recognition import (TactileRecognitionConfig, TactileRecognizer,
                                                TactileSet, d1, d2, entropy, height_actions,
                                                kmedoids_available, pairwise_d2, posterior,
                                                shift_rows)
from mmlearn.models.tactile.synth import make_objects, pattern_bank, sample_grasps
from mmlearn.models.tactile.types import TactileDataError, TactileGrasp, TactileObservation


def _bar(row, rows=14, cols=6, value=1.0):
    im = np.zeros((rows, cols))
    im[row, :] = value
    return im


# --------------------------------------------------------------------------- distances
def test_d1_is_the_l1_distance_and_broadcasts():
    R = np.zeros((14, 6))
    S = np.zeros((14, 6))
    S[3, 2] = 0.5
    S[7, 1] = 0.25
    assert d1(R, S) == pytest.approx(0.75)
    assert d1(S, R) == pytest.approx(0.75)
    stack = np.stack([R, S, 2 * S])
    np.testing.assert_allclose(d1(stack, R), [0.0, 0.75, 1.5])


def test_d2_discounts_vertical_shifts_up_to_m_rows():
    R, S = _bar(5), _bar(6)
    assert d1(R, S) == pytest.approx(12.0)  # two rows of 6 cells differ by 1
    assert d2(R, S, max_shift=0) == pytest.approx(12.0)
    assert d2(R, S, max_shift=1) == pytest.approx(0.0)
    far = _bar(9)
    assert d2(R, far, max_shift=2) == pytest.approx(12.0)  # 4 rows away: not discounted
    assert d2(R, far, max_shift=4) == pytest.approx(0.0)
    # a horizontal shift is not discounted
    C = np.zeros((14, 6))
    C[:, 2] = 1.0
    C2 = np.zeros((14, 6))
    C2[:, 3] = 1.0
    assert d2(C, C2, max_shift=0) == pytest.approx(28.0)
    # (shifting the column by 3 rows pushes 3 of its cells off the pad: 14 + 11 = 25)
    assert d2(C, C2, max_shift=3) == pytest.approx(25.0)
    # shifting drops rows at the edge and fills with zeros
    np.testing.assert_array_equal(shift_rows(_bar(13), 1), np.zeros((14, 6)))
    np.testing.assert_array_equal(shift_rows(_bar(0), 1), _bar(1))
    np.testing.assert_array_equal(shift_rows(_bar(0), -1), np.zeros((14, 6)))


def test_pairwise_d2_matches_the_definition():
    rng = np.random.default_rng(1)
    A, B = rng.uniform(size=(5, 14, 6)), rng.uniform(size=(4, 14, 6))
    D = pairwise_d2(A, B, max_shift=2)
    ref = np.array([[d2(a, b, max_shift=2) for b in B] for a in A])
    np.testing.assert_allclose(D, ref)


def _pair_set(widths, images):
    images = np.asarray(images)
    return TactileSet(images, images, np.zeros(len(widths)), np.asarray(widths, float),
                      np.array(["a"] * len(widths), dtype=object))


def test_alpha_weights_tactile_against_width_with_unit_variance_scaling():
    ims = [_bar(2), _bar(2), _bar(8)]
    ts = _pair_set([0.05, 0.08, 0.05], ims)
    rec = TactileRecognizer(TactileRecognitionConfig(k=3, alpha=0.5, max_shift=0))
    rec.fit(ts)
    tac = np.array([0, 24, 24])  # pairs (0,1), (0,2), (1,2): both pads, 2 rows x 6 cells
    wd = np.array([0.03, 0.0, 0.03])
    assert rec.s_tac == pytest.approx(np.std(tac))
    assert rec.s_w == pytest.approx(np.std(wd))
    for alpha in (0.0, 0.25, 1.0):
        rec.config.alpha = alpha
        D = rec.distance(ts, ts)
        assert D[0, 1] == pytest.approx((1 - alpha) * 0.03 / rec.s_w)  # same images
        assert D[0, 2] == pytest.approx(alpha * 24 / rec.s_tac)  # same width
    with pytest.raises(ValueError, match="alpha"):
        TactileRecognitionConfig(alpha=1.5)
    with pytest.raises(ValueError, match="k"):
        TactileRecognitionConfig(k=0)
    with pytest.raises(ValueError, match="clustering"):
        TactileRecognitionConfig(clustering="kmeans++")


def test_bad_tactile_input_is_named():
    im = np.zeros((14, 6))
    with pytest.raises(TactileDataError, match="left: NaN"):
        TactileObservation(np.full((14, 6), np.nan), im, 0.1, 0.05)
    with pytest.raises(TactileDataError, match="right: values above 1"):
        TactileObservation(im, im + 2, 0.1, 0.05)
    with pytest.raises(TactileDataError, match="width"):
        TactileObservation(im, im, 0.1, float("nan"))
    with pytest.raises(TactileDataError, match="no observations"):
        TactileSet(np.zeros((0, 14, 6)), np.zeros((0, 14, 6)), [], [])


# --------------------------------------------------------------------------- codebook, posterior
@pytest.fixture(scope="module")
def easy_world():
    rng = np.random.default_rng(3)
    nc, nh = 5, 6
    objs = make_objects(nc, nh, rng=rng)
    cl = np.repeat(np.arange(nc), nh * 3)
    hh = np.tile(np.repeat(np.arange(nh), 3), nc)
    train = sample_grasps(objs, cl, hh, rng=rng, noise=0.05)
    test = sample_grasps(objs, cl, hh, rng=rng, noise=0.05)
    rec = TactileRecognizer(TactileRecognitionConfig(k=20, clustering="agglomerative")).fit(train)
    return rec, train, test, nc


@pytest.mark.slow
def test_codebook_and_histograms_are_distributions(easy_world):
    rec, train, test, nc = easy_world
    assert rec.codebook.shape == (nc, 20)
    np.testing.assert_allclose(rec.codebook.sum(axis=1), 1.0)
    assert np.all(rec.codebook > 0)
    h = rec.histograms(test.subset(np.arange(7)))
    np.testing.assert_allclose(h.sum(axis=1), 1.0)
    L = rec.likelihood(test.subset(np.arange(7)))
    assert L.shape == (7, nc) and np.all((L > 0) & (L <= 1 + 1e-12))
    assert len(np.unique(rec.centres.height.round(6) * 1e3 + rec.centres.width)) >= 1
    assert rec.clustering_used == "agglomerative"


@pytest.mark.slow
def test_posterior_concentrates_on_the_right_class_with_more_grasps(easy_world):
    rec, train, test, nc = easy_world
    rng = np.random.default_rng(0)
    L = rec.likelihood(test)
    p1, p8, ok1, ok8 = [], [], 0, 0
    for trial in range(100):
        c = trial % nc
        idx = np.flatnonzero(test.labels == f"obj{c}")
        pick = rng.choice(idx, 8, replace=False)
        ci = list(rec.classes).index(f"obj{c}")
        a = posterior(np.log(L[pick[:1]]))
        b = posterior(np.log(L[pick]))
        p1.append(a[ci])
        p8.append(b[ci])
        ok1 += int(np.argmax(a) == ci)
        ok8 += int(np.argmax(b) == ci)
    assert np.mean(p8) > np.mean(p1) + 0.2
    assert ok8 >= 95 and ok8 > ok1
    # the recogniser's own posterior on one object's grasps agrees
    idx = np.flatnonzero(test.labels == "obj2")[:8]
    label, p = rec.classify(test.subset(idx))
    assert label == "obj2" and p.sum() == pytest.approx(1.0)


@pytest.mark.slow
def test_leave_one_out_likelihood_only_removes_the_observation_itself(easy_world):
    rec, train, test, nc = easy_world
    L = rec.likelihood(train)
    Lo = rec.likelihood_loo(train)
    y = np.searchsorted(rec.classes, train.labels)
    own = np.zeros_like(L, dtype=bool)
    own[np.arange(len(y)), y] = True
    np.testing.assert_allclose(Lo[~own], L[~own])  # other classes untouched
    assert np.mean(Lo[own]) < np.mean(L[own])  # no longer matching itself
    # by hand for one observation: its class histogram rebuilt without it
    i = 7
    raw = np.exp(-rec.distance(rec.centres, train.subset([i]))[:, 0] / rec.length_scale)
    same = np.flatnonzero(train.labels == train.labels[i])
    others = np.setdiff1d(same, [i])
    H = np.exp(-rec.distance(rec.centres, train.subset(others)) / rec.length_scale).sum(axis=1)
    ref = np.minimum(raw / raw.sum(), H / H.sum()).sum()
    assert Lo[i, y[i]] == pytest.approx(ref)
    with pytest.raises(ValueError, match="fit"):
        rec.likelihood_loo(test)


@pytest.mark.slow
def test_recognizer_round_trips_through_json(easy_world):
    import json

    rec, train, test, _ = easy_world
    d = json.loads(json.dumps(rec.to_dict()))
    back = TactileRecognizer.from_dict(d)
    np.testing.assert_allclose(back.likelihood(test), rec.likelihood(test))
    np.testing.assert_allclose(back.likelihood_loo(train), rec.likelihood_loo(train))
    del d["codebook"]
    with pytest.raises(ValueError, match="missing key 'codebook'"):
        TactileRecognizer.from_dict(d)
    with pytest.raises(ValueError, match="schema"):
        TactileRecognizer.from_dict({"schema": "other"})


def test_posterior_and_entropy_helpers():
    np.testing.assert_allclose(posterior(np.log([[0.2, 0.8], [0.5, 0.5]])), [0.2, 0.8])
    np.testing.assert_allclose(posterior(np.log([0.5, 0.5]), prior=[0.25, 0.75]), [0.25, 0.75])
    assert entropy([0.5, 0.5]) == pytest.approx(np.log(2))
    assert entropy([1.0, 0.0]) == pytest.approx(0.0)
    with pytest.raises(ValueError, match="prior"):
        posterior(np.log([0.5, 0.5]), prior=[1.0])


def test_information_gain_prefers_the_only_discriminative_height():
    """Two objects identical at heights 0-3 (same pattern and width), different only at height
    4: the expected gain is largest there, for either weighting of p(z | a)."""
    rng = np.random.default_rng(5)
    nh = 5
    objs = {"pattern": np.array([[0, 3, 6, 9, 12], [0, 3, 6, 9, 13]]),
            "width": np.array([[0.03, 0.04, 0.05, 0.06, 0.04],
                               [0.03, 0.04, 0.05, 0.06, 0.08]])}
    cl = np.repeat([0, 1], nh * 6)
    hh = np.tile(np.repeat(np.arange(nh), 6), 2)
    train = sample_grasps(objs, cl, hh, rng=rng, noise=0.05)
    # l fixed at the scale of the noise between grasps of one segment (the default, peaked
    # one lets grasps of identical segments fall on class-specific medoids of the training set)
    rec = TactileRecognizer(TactileRecognitionConfig(k=10, clustering="agglomerative",
                                                     length_scale=0.5)).fit(train)
    acts = height_actions(train.height, resolution=0.02)
    for weighting in ("belief", "count"):
        best, gains = rec.next_action([0.5, 0.5], train, acts, weighting=weighting)
        assert best == 4, gains
        assert gains[4] > 0.1 and max(gains[a] for a in range(4)) < 0.1 * gains[4], gains
    # with the default (peaked) length scale the discriminative height still wins
    rec_default = TactileRecognizer(TactileRecognitionConfig(k=10, clustering="agglomerative"))
    assert rec_default.fit(train).next_action([0.5, 0.5], train, acts)[0] == 4
    # with a certain belief nothing is gained anywhere
    _, gains = rec.next_action([1.0, 0.0], train, acts)
    assert max(gains.values()) == pytest.approx(0.0, abs=1e-12)
    with pytest.raises(ValueError, match="belief"):
        rec.information_gain([0.5, 0.5, 0.0], train, acts)


def _two_class_recognizer():
    """A recogniser fitted on 12 grasps of two classes "a" / "b" at heights 0 / 1 / 2 cm (two
    per class and height); the tests below give its outcome likelihoods as a table."""
    rng = np.random.default_rng(3)
    labels = np.array(["a", "b"] * 6, dtype=object)
    heights = np.repeat([0.0, 0.01, 0.02], 4)
    train = TactileSet(rng.random((12, 14, 6)), rng.random((12, 14, 6)), heights,
                       0.05 + 0.01 * rng.random(12), labels)
    rec = TactileRecognizer(TactileRecognitionConfig(k=3, clustering="agglomerative"))
    return rec.fit(train), train, height_actions(heights, resolution=0.01)


def test_informed_choice_prefers_the_height_that_separates_the_classes():
    """A synthetic table p(z | c) of the training outcomes: at height 0 every outcome is
    uninformative (0.5 / 0.5), at height 1 it separates the classes (0.9 / 0.1 towards the
    true one), at height 2 the model is confidently *wrong* (0.001 / 0.999 towards the other
    class). The cross-entropy estimator (default) picks height 1; the thesis' plug-in entropy
    of the updated belief is fooled by the confident outcomes of height 2."""
    rec, train, acts = _two_class_recognizer()
    y = (train.labels == "b").astype(int)
    table = {0: [[0.5, 0.5], [0.5, 0.5]], 1: [[0.9, 0.1], [0.1, 0.9]],
             2: [[0.001, 0.999], [0.999, 0.001]]}
    L = np.array([table[a][c] for a, c in zip(acts, y)])
    best, g = rec.next_action([0.5, 0.5], train, acts, train_likelihood=L)
    assert best == 1, g
    assert g[0] == pytest.approx(0.0, abs=1e-12)
    assert g[1] == pytest.approx(np.log(0.9) - np.log(0.5))  # expected rise of log p(true)
    assert g[2] < 0.0  # the truth loses belief there
    best_e, g_e = rec.next_action([0.5, 0.5], train, acts, train_likelihood=L,
                                  estimator="entropy")
    assert best_e == 2 and g_e[2] > g_e[1] > g_e[0] == pytest.approx(0.0, abs=1e-12)
    # given the grasps so far: with "b" ruled out nothing is left to learn anywhere
    _, g_b = rec.next_action([1.0, 0.0], train, acts, train_likelihood=L)
    assert max(abs(v) for v in g_b.values()) == pytest.approx(0.0, abs=1e-12)
    # a height already grasped is not chosen again while another feasible one is left
    assert rec.next_action([0.5, 0.5], train, acts, train_likelihood=L, taken={1})[0] == 0
    assert rec.next_action([0.5, 0.5], train, acts, train_likelihood=L, taken={0, 1, 2})[0] == 1
    assert rec.next_action([0.5, 0.5], train, acts, train_likelihood=L, feasible={0, 2})[0] == 0
    with pytest.raises(ValueError, match="no feasible action"):
        rec.next_action([0.5, 0.5], train, acts, train_likelihood=L, feasible={7})
    with pytest.raises(ValueError, match="estimator"):
        rec.information_gain([0.5, 0.5], train, acts, estimator="kl")
    with pytest.raises(ValueError, match="train_likelihood"):
        rec.information_gain([0.5, 0.5], train, acts, train_likelihood=L[:, :1])
    with pytest.raises(ValueError, match="belief"):
        rec.information_gain([np.nan, 0.5], train, acts)


@pytest.mark.slow
@pytest.mark.skipif(not kmedoids_available(), reason="kmedoids not installed")
def test_kmedoids_vocabulary_has_k_distinct_training_medoids(easy_world):
    _, train, _, _ = easy_world
    rec = TactileRecognizer(TactileRecognitionConfig(k=15, clustering="kmedoids")).fit(train)
    assert rec.clustering_used == "kmedoids" and len(rec.centres) == 15
    D = rec.distance(rec.centres, rec.centres)
    assert np.all(np.diag(D) == pytest.approx(0.0))
    assert len(pattern_bank()) >= 15


# --------------------------------------------------------------------------- grasp features
def _profile(*, touch=True, settle=True):
    t = np.round(np.arange(0, 301) * 0.01, 10)
    p = np.where(t < 1.0, 0.08 - 0.02 * t, np.where(t < 1.5, 0.06 - 0.02 * (t - 1.0), 0.05))
    v = np.where(t < 1.5, -0.02, 0.0)
    f = np.where(t < 1.0, 0.0, np.where(t < 1.5, 4.0 + 32.0 * (t - 1.0), 20.0))
    if not settle:
        p = 0.08 - 0.02 * t
        v = np.full_like(t, -0.02)
    if not touch:
        f = np.zeros_like(t)
    ff = np.stack([f / 2, f / 2], axis=1)
    return TactileGrasp(t=t, p=p, v=v, f=f, finger_force=ff)


def test_six_features_on_a_known_profile():
    from mmlearn.models.tactile.state import FEATURE_NAMES, extract_grasp_features

    ft = extract_grasp_features(_profile(), contact_force=1.0, rest_velocity=1e-3)
    assert ft.contact and ft.steady
    expect = {"p_first": 0.06, "p_steady": 0.05, "f_steady": 20.0, "dt": 0.5,
              "dp_dt": -0.02, "df_dt": 32.0}
    got = ft.as_dict()
    for k in FEATURE_NAMES:
        assert got[k] == pytest.approx(expect[k], abs=1e-9), k
    # a contact threshold above one finger's force but below the sum: both fingers must touch
    ft2 = extract_grasp_features(_profile(), contact_force=2.5, rest_velocity=1e-3)
    assert ft2.as_dict()["p_first"] < 0.06  # later first contact (finger force > 2.5 N)
    # never at rest: the last sample stands in
    ft3 = extract_grasp_features(_profile(settle=False), contact_force=1.0, rest_velocity=1e-3)
    assert ft3.contact and not ft3.steady and ft3.i_steady == 300
    # never touching: "no contact" and the final state, no exception
    ft4 = extract_grasp_features(_profile(touch=False), contact_force=1.0, rest_velocity=1e-3)
    assert not ft4.contact and ft4.values[3] == 0.0 and ft4.values[0] == pytest.approx(0.05)
    # steady-phase averaging changes nothing on a noise-free constant steady state
    ft5 = extract_grasp_features(_profile(), contact_force=1.0, rest_velocity=1e-3,
                                 steady_average=True)
    np.testing.assert_allclose(ft5.values, ft.values, atol=1e-12)


def test_grasp_validation_names_the_field():
    t = np.arange(5.0)
    with pytest.raises(TactileDataError, match="f: values below 0"):
        TactileGrasp(t=t, p=np.ones(5), f=-np.ones(5))
    with pytest.raises(TactileDataError, match="p: NaN"):
        TactileGrasp(t=t, p=[1, 2, np.nan, 3, 4], f=np.ones(5))
    with pytest.raises(TactileDataError, match="t: not strictly increasing"):
        TactileGrasp(t=[0, 1, 1, 2, 3], p=np.ones(5), f=np.ones(5))
    with pytest.raises(TactileDataError, match="p: expected 5 samples"):
        TactileGrasp(t=t, p=np.ones(4), f=np.ones(5))
    g = TactileGrasp(t=t, p=t ** 2, f=np.ones(5))
    np.testing.assert_allclose(g.v, np.gradient(t ** 2, t))


@pytest.mark.slow
def test_classifiers_and_cross_validation_on_separable_features():
    from mmlearn.models.tactile.state import cross_validate, evaluate_split, make_classifier

    rng = np.random.default_rng(0)
    X = np.concatenate([rng.normal(0, 1, (30, 6)), rng.normal(4, 1, (30, 6))])
    y = np.array(["a"] * 30 + ["b"] * 30)
    for kind in ("tree", "forest", "boost"):
        rep = cross_validate(X, y, classifier=kind, folds=10 if kind == "tree" else 3, seed=0)
        assert rep.rate > 0.9 and rep.confusion.sum() == 60
        assert set(rep.per_class()) == {"a", "b"}
    assert make_classifier("tree").criterion == "entropy"
    assert type(make_classifier("boost")).__name__ == "GradientBoostingClassifier"
    rep, _ = evaluate_split(X[::2], y[::2], X[1::2], y[1::2], classifier="tree")
    assert rep.rate > 0.85
    # random labels give chance level, not a perfect score
    yr = rng.permutation(y)
    assert cross_validate(rng.normal(size=(60, 6)), yr, classifier="tree", seed=1).rate < 0.75
    with pytest.raises(ValueError, match="at least 10 instances per class"):
        cross_validate(X[25:], y[25:])  # 5 of class a
    with pytest.raises(ValueError, match="NaN"):
        cross_validate(np.full((20, 6), np.nan), y[:20], folds=2)
    with pytest.raises(ValueError, match="unknown"):
        make_classifier("svm")


# --------------------------------------------------------------------------- liquid
def _roll(rng, *, slosh: bool, n_taxels=44, seconds=20.0, rate=24.0, load=2.0):
    t = np.arange(0, seconds, 1 / rate)
    gains = rng.uniform(0.5, 1.5, n_taxels)
    roll = np.sin(2 * np.pi * 0.6 * t)  # wrist roll angle (normalised)
    base = load * (1 + 0.3 * roll)[:, None] * gains[None, :] / n_taxels
    sig = base + rng.normal(0, 0.0005, base.shape)
    if slosh:
        # a decaying 6 Hz pressure oscillation after each reversal of the roll
        rev = (np.arange(1, int(seconds * 1.2) + 1) - 0.5) / 1.2
        resp = np.zeros_like(t)
        for tr in rev:
            dt = t - tr
            resp += np.where(dt >= 0, np.exp(-dt / 0.3) * np.sin(2 * np.pi * 6 * dt), 0.0)
        sig = sig + 0.02 * resp[:, None] * gains[None, :]
    return sig


def test_highpass_removes_constant_load_and_slow_roll():
    from mmlearn.models.tactile.liquid import filtered_norm, highpass

    const = np.full((100, 3), 5.0)
    np.testing.assert_allclose(highpass(const), 0.0, atol=1e-12)  # no start-up transient
    t = np.arange(0, 30, 1 / 24)
    slow = np.sin(2 * np.pi * 0.6 * t)[:, None]
    fast = np.sin(2 * np.pi * 9.0 * t)[:, None]
    # first order at 5 Hz: 0.6 Hz is attenuated about 8x, 9 Hz passes
    assert np.std(highpass(slow)[48:]) < 0.15 * np.std(slow)
    assert np.std(highpass(fast)[48:]) > 0.8 * np.std(fast)
    assert filtered_norm(np.hstack([fast, fast])).shape == (len(t),)
    with pytest.raises(ValueError, match="cutoff"):
        highpass(const, rate_hz=8.0)


def test_liquid_feature_separates_sloshing_from_rigid_and_classifies():
    from mmlearn.models.tactile.liquid import RollRecord, liquid_feature, liquid_features
    from mmlearn.models.tactile.state import cross_validate

    rng = np.random.default_rng(2)
    rigid = [liquid_feature(_roll(rng, slosh=False, load=rng.uniform(1, 4))) for _ in range(10)]
    wet = [liquid_feature(_roll(rng, slosh=True, load=rng.uniform(1, 4))) for _ in range(10)]
    assert min(wet) > 3 * max(rigid), (rigid, wet)
    recs = [RollRecord(_roll(rng, slosh=s), weight=w, liquid=s)
            for s, w in [(False, 1.0), (True, 3.0)] * 10]
    X = liquid_features(recs, with_weight=True)
    assert X.shape == (20, 2)
    y = np.array([r.liquid for r in recs])
    assert cross_validate(X[:, :1], y, classifier="tree", folds=10).rate >= 0.9
    from mmlearn.models.tactile.liquid import evaluate_liquid, liquid_table

    for r, k in zip(recs, range(20)):
        r.container = f"c{k % 2}"
    rep = evaluate_liquid(recs, with_weight=True, folds=5)
    assert rep.labels == ["liquid", "no_liquid"] and rep.rate >= 0.9
    tab = liquid_table(recs)
    assert [(t["container"], t["liquid"], t["trials"]) for t in tab] == [("c0", False, 10),
                                                                         ("c1", True, 10)]
    assert tab[1]["feature_mean"] > 3 * tab[0]["feature_mean"] and tab[1]["weight_n"] == 3.0
    with pytest.raises(TactileDataError, match="taxels: NaN"):
        RollRecord(np.full((10, 4), np.nan))
    with pytest.raises(TactileDataError, match="weight"):
        liquid_features([RollRecord(np.ones((10, 4)))], with_weight=True)


@pytest.mark.slow
def test_own_k_medoids_covers_dense_groups_not_outliers(easy_world):
    """The numpy k-medoids (the default without the kmedoids package): 4 dense groups of 30
    points and 6 far single points, k = 4 -> one medoid inside each group (average linkage
    spends clusters on the outliers: fewer groups covered); the total distance is never
    above the build's; deterministic; bad input named; "auto" uses it without kmedoids."""
    from scipy.spatial.distance import cdist

    from mmlearn.models.tactile.recognition import k_medoids

    rng = np.random.default_rng(0)
    centres = np.array([[0, 0], [10, 0], [0, 10], [10, 10]], float)
    ang = np.arange(6) * np.pi / 3  # single points 60 apart from each other and the groups
    X = np.vstack([c + rng.normal(0, 1.0, (30, 2)) for c in centres]
                  + [5.0 + 60.0 * np.column_stack([np.cos(ang), np.sin(ang)])])
    group = np.r_[np.repeat(np.arange(4), 30), np.full(6, -1)]
    D = cdist(X, X)
    med = k_medoids(D, 4)
    assert sorted(group[med]) == [0, 1, 2, 3]
    build = k_medoids(D, 4, max_iter=0)  # the greedy build alone
    assert D[:, med].min(axis=1).sum() <= D[:, build].min(axis=1).sum()
    assert np.array_equal(med, k_medoids(D, 4))
    from mmlearn.models.tactile.recognition import TactileRecognizer as TR
    agg, _ = TR._cluster(D, 4, 0, "agglomerative")
    assert len(set(group[agg]) - {-1}) < 4  # the outliers took clusters
    for bad, k in ((D[:5], 2), (np.full((3, 3), np.nan), 2), (D, 0), (D, len(D) + 1)):
        with pytest.raises(ValueError, match="k_medoids"):
            k_medoids(bad, k)
    _, train, _, _ = easy_world
    if not kmedoids_available():
        rec = TactileRecognizer(TactileRecognitionConfig(k=12)).fit(train)
        assert rec.clustering_used == "medoids" and len(rec.centres) == 12
        assert len(set(rec.centres.labels.tolist())) >= 4
