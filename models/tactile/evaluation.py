"""Metrics of the tactile experiments (thesis ch. 6-7), from the records of the trials in
:mod:`mmlearn.diagrams.tactile.trials`: plain numpy, no simulation.

* **Object and state from grasp dynamics** (Sec. 7.1-7.2): the six features of Table 7.1 of
  iCub grasps (:func:`icub_features`) or of simulated container grasps
  (:func:`container_grasp_features`, :func:`grasp_from_record`), k-fold cross-validation with
  the other classifiers' rates beside (:func:`fold_cv`, :func:`cv_with_compare`), the rates
  of the simulated experiment (:func:`state_recognition_report`) and of the real iCub grasps
  (:func:`icub_state_report`).
* **Object recognition by touch** (ch. 6): the labelled tactile set of the grasp records
  (:func:`recognition_dataset`, :func:`observation_from_record`), the randomised 2-fold
  cross-validation of Sec. 6.3 (:func:`evaluate_recognition`) and the grasp-height strategies
  of Fig. 6.7 (:data:`STRATEGIES`, :func:`strategy_trials`, :func:`compare_strategies`).
* **Liquid detection** (Sec. 7.3): a roll record's taxels, weight and coast samples
  (:func:`roll_record`) and the rates, Table 7.4 and the rigid dummy for one tactile feature
  (:func:`evaluate_rolls`).
"""

from __future__ import annotations

from collections import Counter

import numpy as np

from mmlearn.models.tactile.liquid import RollRecord, coast_mask, liquid_features, liquid_table
from mmlearn.models.tactile.pad import PAD_PR2
from mmlearn.models.tactile.recognition import (TactileRecognitionConfig, TactileRecognizer,
                                                TactileSet, height_actions, posterior)
from mmlearn.models.tactile.state import (CLASSIFIERS, ClassificationReport, cross_validate,
                                          evaluate_split,
                                          feature_matrix, make_classifier)
from mmlearn.models.tactile.types import TactileDataError, TactileGrasp, TactileObservation

__all__ = ["icub_features", "grasp_from_record", "container_grasp_features", "SIM_CONTACT_FORCE",
           "SIM_REST_VELOCITY", "fold_cv", "cv_with_compare", "single_class_report",
           "state_recognition_report", "icub_state_report", "observation_from_record", "recognition_dataset",
           "split_two_fold", "fit_recognizer", "random_trials", "STRATEGIES", "strategy_trials",
           "evaluate_recognition", "compare_strategies", "SUBSETS", "subset_classes",
           "HEIGHT_RESOLUTION", "TARE_WINDOW", "COAST_DELAY", "roll_record",
           "cell_saturation_force", "evaluate_rolls"]


# ----------------------------------------------------------------------------- grasp dynamics
#: simulated container grasps: contact threshold F per finger (N) and rest threshold V (m/s)
SIM_CONTACT_FORCE = 1.0
SIM_REST_VELOCITY = 0.002


def icub_features(trials, *, contact_level, rest_velocity, steady_average):
    """The feature matrix (n, 6) of iCub grasp trials
    (:class:`~mmlearn.models.tactile.icub_grasp.ICubTrial`), their labels (n,) and the
    per-grasp :class:`~mmlearn.models.tactile.state.GraspFeatures`; ``contact_level`` (sensor
    counts), ``rest_velocity`` (rad per slice) and ``steady_average`` as
    :func:`~mmlearn.models.tactile.state.extract_grasp_features`."""
    grasps = [t.to_grasp() for t in trials]
    peaks = [float(np.max(g.finger_force)) for g in grasps if g.finger_force is not None
             and g.finger_force.size]
    if peaks and contact_level >= max(peaks):
        raise TactileDataError(f"contact level {contact_level:g} counts is above the highest "
                               f"finger pressure in any of the {len(grasps)} grasps "
                               f"({max(peaks):g} counts): no grasp would make contact")
    X, feats = feature_matrix(grasps, contact_force=contact_level, rest_velocity=rest_velocity,
                              steady_average=steady_average)
    y = np.array([t.label for t in trials])
    return X, y, feats


def grasp_from_record(rec: dict) -> TactileGrasp:
    """The :class:`TactileGrasp` of a
    :func:`~mmlearn.diagrams.tactile.trials.container_grasp_trial` record."""
    return TactileGrasp(t=rec["t"], p=rec["p"], f=rec["f"], finger_force=rec["finger_force"],
                        container=rec.get("container"), state=rec.get("state"),
                        label=f"{rec.get('container')}/{rec.get('state')}")


def container_grasp_features(records, *, steady_average=False):
    """The features of simulated container grasps (records of
    :func:`~mmlearn.diagrams.tactile.trials.container_grasp_trial`, thresholds
    :data:`SIM_CONTACT_FORCE` and :data:`SIM_REST_VELOCITY`): (X (n, 6), container labels (n,),
    state labels (n,), per-grasp :class:`~mmlearn.models.tactile.state.GraspFeatures`)."""
    grasps = [grasp_from_record(r) for r in records]
    X, feats = feature_matrix(grasps, contact_force=SIM_CONTACT_FORCE,
                              rest_velocity=SIM_REST_VELOCITY, steady_average=steady_average)
    yc = np.array([r["container"] for r in records])
    ys = np.array([r["state"] for r in records])
    return X, yc, ys, feats


def single_class_report(y) -> ClassificationReport:
    """The report of a data set with one class (nothing to tell apart: every grasp right)."""
    return ClassificationReport([str(y[0])], np.array([[len(y)]]), y, y)


def fold_cv(X, y, *, classifier, folds, seed):
    """``folds``-fold cross-validation, fewer folds when a class has fewer grasps; returns
    (report, the number of folds)."""
    k = int(min(folds, np.unique(y, return_counts=True)[1].min()))
    if k < 2:
        raise ValueError("too few grasps per class for cross-validation (use more --trials)")
    return cross_validate(X, y, classifier=classifier, folds=k, seed=seed), k


def cv_with_compare(X, y, *, classifier, folds, seed):
    """:func:`fold_cv` with ``classifier`` and the rates of the other classifiers on the same
    folds: (report, {classifier: rate}, the number of folds)."""
    rep, k = fold_cv(X, y, classifier=classifier, folds=folds, seed=seed)
    other = [c for c in CLASSIFIERS if c != classifier]
    cmp_ = {c: cross_validate(X, y, classifier=c, folds=k, seed=seed).rate for c in other}
    return rep, cmp_, k


def state_recognition_report(X, yc, ys, *, classifier: str, folds: int, seed: int) -> dict:
    """The rates of the simulated ch. 7 experiment from the grasp features ``X`` with their
    container labels ``yc`` and state labels ``ys`` (:func:`container_grasp_features`), by
    ``folds``-fold cross-validation with ``classifier`` (the others' rates under
    ``*_compare``): ``container_rate`` (class from all grasps), ``state_rate_by_container``
    {class: rate of the state given the class}, ``combined_rate`` (all class x state labels)
    and ``combined_rate_without_water`` (the thesis' 11-label experiment), with the confusion
    matrices."""
    kw = dict(classifier=classifier, folds=folds, seed=seed)
    out = {}
    if len(set(yc.tolist())) > 1:
        rep, cmp_, k = cv_with_compare(X, yc, **kw)
    else:  # one class: nothing to tell apart
        rep = single_class_report(yc)
        cmp_ = {}
    out["container_rate"] = rep.rate
    out["container_confusion"] = {"labels": rep.labels,
                                  "confusion": rep.confusion.astype(int).tolist()}
    out["container_compare"] = cmp_
    out["state_rate_by_container"], out["state_compare"], out["state_confusion"] = {}, {}, {}
    for name in sorted(set(yc.tolist())):
        m = yc == name
        r, cm, _ = cv_with_compare(X[m], ys[m], **kw)
        out["state_rate_by_container"][name] = r.rate
        out["state_compare"][name] = cm
        out["state_confusion"][name] = {"labels": r.labels,
                                        "confusion": r.confusion.astype(int).tolist()}
    yy = np.array([f"{a}/{b}" for a, b in zip(yc, ys)])
    r, cm, _ = cv_with_compare(X, yy, **kw)
    out["combined_rate"], out["combined_compare"] = r.rate, cm
    m = yc != "water"
    if m.any() and len(set(yc[m].tolist())) > 1:
        r, _, _ = cv_with_compare(X[m], yy[m], **kw)
        out["combined_rate_without_water"] = r.rate
    return out


def icub_state_report(train, test=None, *, classifier: str, folds: int, seed: int,
                      contact_level: float, rest_velocity: float, steady_average: bool):
    """Object and state recognition on iCub grasp trials (Sec. 7.1-7.2): ``classifier``
    trained on the trials ``train`` and scored on the trials ``test`` or, without, by
    ``folds``-fold cross-validation (thresholds as :func:`icub_features`). Returns (result,
    :class:`~mmlearn.models.tactile.state.ClassificationReport`); the result holds
    ``evaluation`` ("test" or "<k>-fold CV"), ``n_train``, ``n_test``, ``compare`` (the other
    classifiers' rates), the report's rate, per-class rates, labels and confusion, and
    ``no_contact`` (the scored grasps without contact per label)."""
    kw = dict(contact_level=contact_level, rest_velocity=rest_velocity,
              steady_average=steady_average)
    X, y, feats = icub_features(train, **kw)
    other = [c for c in CLASSIFIERS if c != classifier]
    out = {}
    if test is None:
        rep = cross_validate(X, y, classifier=classifier, folds=folds, seed=seed)
        out["evaluation"] = f"{folds}-fold CV"
        out["n_train"], out["n_test"] = int(len(y)), int(len(y))
        out["compare"] = {c: cross_validate(X, y, classifier=c, folds=folds, seed=seed).rate
                          for c in other}
        eval_feats, eval_y = feats, y
    else:
        Xt, yt, feats_t = icub_features(test, **kw)
        rep, _ = evaluate_split(X, y, Xt, yt, classifier=classifier, seed=seed)
        out["evaluation"] = "test"
        out["n_train"], out["n_test"] = int(len(y)), int(len(yt))
        out["compare"] = {c: evaluate_split(X, y, Xt, yt, classifier=c, seed=seed)[0].rate
                          for c in other}
        eval_feats, eval_y = feats_t, yt
    out.update(rep.to_dict())
    out.pop("n", None)
    nc = Counter(lab for f, lab in zip(eval_feats, eval_y.tolist()) if not f.contact)
    out["no_contact"] = {lab: int(nc.get(lab, 0)) for lab in rep.labels}
    return out, rep


# ----------------------------------------------------------------------------- recognition
#: grasp heights are grouped into actions on this grid, m (the action grid of Sec. 6.2)
HEIGHT_RESOLUTION = 0.01
#: the class subsets of Fig. 6.6
SUBSETS = ("all", "household", "industrial", "soft_vs_tennis")


def observation_from_record(rec: dict) -> TactileObservation:
    """The :class:`~mmlearn.models.tactile.types.TactileObservation` of an
    :func:`~mmlearn.diagrams.tactile.trials.object_grasp_trial` record (label = its class)."""
    return TactileObservation(rec["left"], rec["right"], rec["height"], rec["width"],
                              rec["cls"])


def recognition_dataset(records):
    """A labelled TactileSet and the group of each label from trial records (with contact)."""
    recs = [r for r in records if r.get("contact")]
    if not recs:
        raise ValueError("no grasp touched its object: nothing to recognise")
    ts = TactileSet(np.array([r["left"] for r in recs]), np.array([r["right"] for r in recs]),
                    np.array([r["height"] for r in recs]), np.array([r["width"] for r in recs]),
                    np.array([r["cls"] for r in recs], dtype=object))
    groups = {r["cls"]: r["group"] for r in recs}
    return ts, groups


def split_two_fold(labels, rng):
    """Randomised 2-fold split, stratified by class: (idx_a, idx_b)."""
    a, b = [], []
    for c in sorted(set(labels.tolist())):
        idx = rng.permutation(np.flatnonzero(labels == c))
        h = len(idx) // 2 + (rng.random() < 0.5 if len(idx) % 2 else 0)
        a.extend(idx[:h])
        b.extend(idx[h:])
    return np.sort(np.array(a, int)), np.sort(np.array(b, int))


def _pick(idx, T, rng):
    if len(idx) >= T:
        return rng.choice(idx, T, replace=False), False
    return rng.choice(idx, T, replace=True), True


def fit_recognizer(train, *, k, alpha, seed):
    # at most half the training grasps: with every grasp a centre the model's default
    # length scale (a fraction of the distance to the nearest other centre) degenerates
    k_used = int(min(k, max(1, len(train) // 2)))
    rec = TactileRecognizer(TactileRecognitionConfig(k=k_used, alpha=alpha, seed=seed))
    return rec.fit(train), k_used


def random_trials(rec, test, classes, T, n, rng):
    """``n`` recognitions of random classes from T random test grasps each: (correct after
    t = 1..T (n, T) bool, true class index (n,), predicted class index after T (n,), number
    drawn with replacement)."""
    L = np.log(np.maximum(rec.likelihood(test), 1e-300))
    cls = list(rec.classes)
    ok = np.zeros((n, T), bool)
    true = np.zeros(n, int)
    pred = np.zeros(n, int)
    repl = 0
    for i in range(n):
        c = classes[rng.integers(len(classes))]
        pick, r = _pick(np.flatnonzero(test.labels == c), T, rng)
        repl += r
        ci = cls.index(c)
        # cumulative log posterior after t grasps (uniform prior)
        cum = np.cumsum(L[pick], axis=0)
        ok[i] = np.argmax(cum, axis=1) == ci
        true[i], pred[i] = ci, int(np.argmax(posterior(L[pick])))
    return ok, true, pred, repl


#: strategies of the ``--informed`` comparison (Fig. 6.7): random test grasps (the thesis'
#: baseline); random heights, each height once before any is repeated (the control for the
#: no-repeat rule alone); the next height by expected information gain with the
#: cross-entropy estimator of H(c | z) (the default of
#: :meth:`TactileRecognizer.information_gain`); the same with the thesis' plug-in entropy of
#: the updated belief. The informed ones prefer heights not yet grasped too.
STRATEGIES = ("random", "random_heights", "informed", "informed_entropy")



def strategy_trials(rec, train, test, objects, T, rng, *, strategy, Ltr=None, fresh=True):
    """Recognitions of the given ``objects`` (class names, one per trial) from T test grasps
    each: (correct after t = 1..T (n, T) bool, distinct heights grasped per trial (n,)).

    ``strategy`` "random": T random test grasps of the object (without replacement; with
    replacement only when it has fewer than T). "random_heights": each next grasp at a random
    height where the object still has an unused test grasp, heights not yet grasped first.
    "informed" / "informed_entropy": each next grasp at the height with the largest expected
    information gain (Eq. 6.12-6.13, :meth:`TactileRecognizer.next_action`) among the heights
    where the object still has an unused test grasp, preferring heights not yet grasped
    (``fresh=False``: no preference); estimator "cross_entropy" /
    "entropy". ``Ltr``: the leave-one-out likelihoods of ``train`` (computed when None)."""
    L = np.log(np.maximum(rec.likelihood(test), 1e-300))
    cls = list(rec.classes)
    a_te = height_actions(test.height, resolution=HEIGHT_RESOLUTION)
    n = len(objects)
    ok = np.zeros((n, T), bool)
    distinct = np.zeros(n, int)
    if strategy not in STRATEGIES:
        raise ValueError(f"strategy: expected one of {', '.join(STRATEGIES)}, got {strategy!r}")
    if strategy.startswith("informed"):
        est = {"informed": "cross_entropy", "informed_entropy": "entropy"}[strategy]
        a_tr = height_actions(train.height, resolution=HEIGHT_RESOLUTION)
        if Ltr is None:
            Ltr = rec.likelihood_loo(train)
    for i, c in enumerate(objects):
        mine = np.flatnonzero(test.labels == c)
        ci = cls.index(c)
        if strategy == "random":
            used = list(_pick(mine, T, rng)[0])
        else:
            belief = np.full(len(cls), 1.0 / len(cls))
            used = []
            for t in range(T):
                left = np.setdiff1d(mine, used)
                if not len(left):  # every test grasp of the object used: repeat one
                    left = mine
                if strategy == "random_heights":
                    fresh_left = left[~np.isin(a_te[left], a_te[used])] if used else left
                    a = rng.choice(np.unique(a_te[fresh_left if len(fresh_left) else left]))
                    used.append(int(rng.choice(left[a_te[left] == a])))
                    continue
                try:
                    a, _ = rec.next_action(belief, train, a_tr, train_likelihood=Ltr,
                                           estimator=est, feasible=set(a_te[left].tolist()),
                                           taken=set(a_te[used].tolist()) if fresh else ())
                    cand = left[a_te[left] == a]
                except ValueError:  # no height of the object's left grasps was trained
                    cand = left
                used.append(int(rng.choice(cand)))
                belief = posterior(L[used])
        cum = np.cumsum(L[np.asarray(used)], axis=0)  # log posterior after t grasps
        ok[i] = np.argmax(cum, axis=1) == ci
        distinct[i] = len(set(a_te[used].tolist()))
    return ok, distinct


def evaluate_recognition(data, classes, *, k=50, alpha=0.5, T=10, recognitions=500, cv_repeats=1,
             seed=0, informed_trials=0) -> dict:
    """Recognition rates of a recogniser trained on ``classes`` only (randomised 2-fold
    CV, both directions, ``cv_repeats`` times). Returns {"rate", "rate_by_T", "per_class",
    "labels", "confusion", "k_used", "n_classes", "with_replacement", "recognitions"} and,
    with ``informed_trials``, {"informed": {"random", "informed", "informed_entropy": rates
    after t = 1..T, "mean_over_T", "distinct_heights", "paired_t", "recognitions"}}
    (:data:`STRATEGIES`; the same objects for each)."""
    sel = np.flatnonzero(np.isin(data.labels, list(classes)))
    sub = data.subset(sel)
    labels = sorted(set(sub.labels.tolist()))
    if len(labels) < 2:
        raise ValueError(f"need grasps of at least two classes, got {labels}")
    # separate streams: the splits and the random recognitions do not depend on whether the
    # informed strategy runs too
    rng = np.random.default_rng([int(seed), 17, len(labels)])
    rng_rec = np.random.default_rng([int(seed), 18, len(labels)])
    rng_inf = np.random.default_rng([int(seed), 19, len(labels)])
    oks, C, repl, ks = [], np.zeros((len(labels), len(labels)), int), 0, []
    inf = {st: [] for st in STRATEGIES}
    inf_d = {st: [] for st in STRATEGIES}
    for _ in range(cv_repeats):
        A, B = split_two_fold(sub.labels, rng)
        for tr, te in ((A, B), (B, A)):
            train, test = sub.subset(tr), sub.subset(te)
            missing = sorted((set(labels) - set(test.labels.tolist()))
                             | (set(labels) - set(train.labels.tolist())))
            if missing:
                raise ValueError(f"classes {missing} have fewer than 2 grasps with contact")
            rec, k_used = fit_recognizer(train, k=k, alpha=alpha, seed=seed)
            ks.append(k_used)
            ok, true, pred, r = random_trials(rec, test, labels, T, recognitions, rng_rec)
            oks.append(ok)
            repl += r
            order = [labels.index(c) for c in rec.classes]  # rec.classes is sorted too
            np.add.at(C, (np.take(order, true), np.take(order, pred)), 1)
            if informed_trials:
                # the same objects for every strategy (paired comparison)
                objs = [labels[j] for j in rng_inf.integers(len(labels), size=informed_trials)]
                Ltr = rec.likelihood_loo(train)
                for st in STRATEGIES:
                    o, d = strategy_trials(rec, train, test, objs, T, rng_inf, strategy=st,
                                            Ltr=Ltr)
                    inf[st].append(o)
                    inf_d[st].append(d)
    ok = np.concatenate(oks)
    diag = np.diag(C)
    tot = C.sum(axis=1)
    out = {"rate": float(ok[:, -1].mean()), "rate_by_T": ok.mean(axis=0).tolist(),
           "per_class": {c: (float(diag[i] / tot[i]) if tot[i] else None)
                         for i, c in enumerate(labels)},
           "labels": labels, "confusion": C.tolist(), "k_used": sorted(set(ks)),
           "n_classes": len(labels), "with_replacement": int(repl),
           "recognitions": int(len(ok)), "n_grasps": int(len(sub))}
    if informed_trials:
        out["informed"] = compare_strategies(inf, inf_d)
    return out


def compare_strategies(inf, inf_d) -> dict:
    """Rates after t = 1..T per strategy, the mean over t, distinct heights per recognition
    and a paired t-test of each informed strategy against random (per recognition: its mean
    correctness over t = 1..T; the thesis' test for Fig. 6.7)."""
    from scipy.stats import ttest_rel

    ok = {st: np.concatenate(v) for st, v in inf.items()}
    per = {st: o.mean(axis=1) for st, o in ok.items()}
    out = {st: o.mean(axis=0).tolist() for st, o in ok.items()}
    out["mean_over_T"] = {st: float(o.mean()) for st, o in ok.items()}
    out["distinct_heights"] = {st: float(np.concatenate(d).mean()) for st, d in inf_d.items()}
    out["paired_t"] = {}
    for st in ok:
        if st == "random":
            continue
        diff = per[st] - per["random"]
        if np.allclose(diff, 0.0):
            t, p = 0.0, 1.0
        else:
            t, p = ttest_rel(per[st], per["random"])
        out["paired_t"][st] = {"mean_difference": float(diff.mean()), "t": float(t),
                               "p": float(p)}
    out["recognitions"] = int(len(per["random"]))
    return out


def subset_classes(name, groups):
    if name == "all":
        return sorted(groups)
    if name == "soft_vs_tennis":
        return [c for c in ("soft_ball", "tennis_ball") if c in groups]
    return sorted(c for c, g in groups.items() if g == name)


# ----------------------------------------------------------------------------- liquid
TARE_WINDOW = (0.05, 0.3)
"""Wrist force before the fingers touch anything, s (the tare of the weight)."""

COAST_DELAY = 0.12
"""Start of the coast samples after each change of the commanded roll rate ends, s (see
:func:`mmlearn.models.tactile.liquid.coast_mask`): about four time constants of the 5 Hz first-order
high-pass (1 / (2 pi 5 Hz) = 32 ms), so that the filter's response to the reversal has died
out (e^-3.8 = 2 %). Chosen on the development seeds 7 and 11 among 0, 0.0955, 0.12 and
0.15 s (0.12 and 0.15 keep the same samples at 24 Hz)."""


def roll_record(rec: dict, *, coast_delay: float = COAST_DELAY) -> RollRecord:
    """A :func:`~mmlearn.diagrams.tactile.trials.liquid_roll_trial` record ->
    :class:`~mmlearn.models.tactile.liquid.RollRecord` (the taxels while rolling, the weight in
    N from the wrist force sensor, the coast samples: constant commanded roll rate, from
    ``coast_delay`` s after each change of the record's ``roll_changes``, none for the sine
    roll) built from the sensor series and the robot's own roll command only; the labels are
    attached from the record's ``liquid`` / ``container``."""
    t = np.asarray(rec["t"], float)
    taxels = np.asarray(rec["taxels"], float)
    wf = np.asarray(rec["wrist_force"], float)
    if taxels.ndim != 2 or len(taxels) != len(t) or wf.shape != (len(t), 3):
        raise TactileDataError(f"trial {rec.get('container')}: series of unequal length")
    r0, r1 = rec["roll_window"]
    w0, w1 = rec["weight_window"]
    roll = (t >= r0) & (t <= r1)
    hold = (t >= w0) & (t <= w1)
    tare = (t >= TARE_WINDOW[0]) & (t <= TARE_WINDOW[1])
    if roll.sum() < 3 or not hold.any() or not tare.any():
        raise TactileDataError(f"trial {rec.get('container')}: too few samples in the roll, "
                               f"hold or tare window")
    weight = -(wf[hold, 2].mean() - wf[tare, 2].mean())
    if "roll_changes" not in rec:
        raise TactileDataError(f"trial {rec.get('container')}: the record holds no roll command "
                               f"(roll_changes)")
    changes = rec["roll_changes"]
    coast = None
    if changes is not None:
        changes = np.asarray(changes, float).reshape(-1, 2)
        coast = coast_mask(t[roll], changes, start=r0, end=r1, delay=coast_delay)
        if coast.sum() < 2:
            raise TactileDataError(f"trial {rec.get('container')}: fewer than 2 coast samples "
                                   f"(coast delay {coast_delay:g} s)")
    return RollRecord(taxels=taxels[roll], rate_hz=float(rec.get("rate_hz", 24.0)),
                      weight=float(weight), liquid=bool(rec["liquid"]),
                      container=str(rec["container"]), coast=coast)


def cell_saturation_force() -> float:
    """Force on one PR2-like taxel cell at saturation, N (multiply the feature by it to
    compare with Table 7.4's newtons)."""
    P = PAD_PR2
    return float(P.p_sat * P.length * P.width / (P.rows * P.cols))


def evaluate_rolls(rr, dr, y, *, feature: str, k: int, seed: int = 0,
                   with_weight: bool = False) -> dict:
    """Rates (tactile alone, with weight), confusion, Table 7.4 and the dummy for one tactile
    feature: decision trees (entropy) by ``k``-fold cross-validation on the container rolls
    ``rr`` (:class:`~mmlearn.models.tactile.liquid.RollRecord`, labels ``y`` "liquid" /
    "no_liquid"), the rigid dummy's rolls ``dr`` read held out and inside the
    cross-validation; ``with_weight``: the top-level rate, confusion and the dummy's
    ``predicted_no_liquid`` with the weight as the second feature."""
    for i, r in enumerate(rr + dr):
        if r.liquid is None:
            raise TactileDataError(f"record {i}: no liquid ground truth")
    # every trial's feature and weight once (column 0: the feature, 1: the weight); "tactile"
    # is column 0 alone (as mmlearn.models.tactile.liquid.evaluate_liquid with and without weight)
    Xr = liquid_features(rr, with_weight=True, feature=feature)
    ncol = {False: 1, True: 2}
    rep_t, rep_w = (cross_validate(Xr[:, :ncol[ww]], y, classifier="tree", folds=k, seed=seed)
                    for ww in (False, True))
    rep = rep_w if with_weight else rep_t
    out = {"rate": rep.rate, "rate_tactile": rep_t.rate, "rate_with_weight": rep_w.rate}
    out.update({kk: v for kk, v in rep.to_dict().items() if kk != "rate"})
    out["table"] = liquid_table(rr, feature=feature)
    if dr:
        d = {"trials": len(dr), "weight_n": float(np.mean([r.weight for r in dr]))}
        Xd = liquid_features(dr, with_weight=True, feature=feature)
        for ww in (False, True):
            clf = make_classifier("tree", seed=seed)
            clf.fit(Xr[:, :ncol[ww]], y)
            pred = clf.predict(Xd[:, :ncol[ww]])
            key = "predicted_no_liquid" + ("_with_weight" if ww else "_tactile")
            d[key] = int(np.sum(pred == "no_liquid"))
        # the thesis' Table 7.4 lists the dummy among the objects of its data set: the same
        # reading here, the dummy's trials inside the cross-validation as "no liquid" (so the
        # training folds hold a heavy object without liquid), its out-of-fold predictions
        kd = int(min(k, len(dr) + int(np.sum(y == "no_liquid"))))
        X_all = np.vstack([Xr, Xd])
        y_all = np.concatenate([y, ["liquid" if r.liquid else "no_liquid" for r in dr]])
        for ww in (False, True):
            rep_d = cross_validate(X_all[:, :ncol[ww]], y_all, classifier="tree", folds=kd,
                                   seed=seed)
            key = "in_cv_no_liquid" + ("_with_weight" if ww else "_tactile")
            d[key] = int(np.sum(rep_d.y_pred[len(rr):] == "no_liquid"))
            d["in_cv_rate" + ("_with_weight" if ww else "_tactile")] = rep_d.rate
        d["feature_mean"] = float(Xd[:, 0].mean())
        d["feature_std"] = float(Xd[:, 0].std(ddof=1)) if len(dr) > 1 else 0.0
        d["feature_values"] = [float(v) for v in Xd[:, 0]]
        d["predicted_no_liquid"] = d["predicted_no_liquid" + ("_with_weight" if with_weight
                                                               else "_tactile")]
        out["dummy"] = d
    return out
