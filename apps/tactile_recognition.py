"""Object recognition by touch (thesis ch. 6): simulated grasps -> tactile images -> bag of
tactile features.

Usage::

    python -m mmlearn.apps.tactile_recognition [--grasps-per-class 20] [--k 50] [--alpha 0.5]
        [--T 10] [--recognitions 200] [--cv-repeats 5] [--k-sweep] [--alpha-sweep]
        [--informed] [--classes a,b,..] [--plot FILE] --seed S [--json]
        [--results FILE] [--jobs J] [--executor local|ray] [--report-only RESULTS.jsonl]

**Grasps** (Drake, :mod:`mmlearn.diagrams.tactile.objects`): the two-finger gripper with the
ch. 6 taxel pads (14 x 6 cells over 51 x 24 mm) and the switching grasp controller closes
on each of the 16 objects / 21 classes of :mod:`mmlearn.sdf.tactile_objects` (a fresh
seeded instance per grasp: size, mass, friction, stiffness; placement error 1.5 mm in
height and 1 mm sideways), ``--grasps-per-class`` grasps per class at the heights of the
class' 1 cm grid from bottom to top (cycling: grasp j at grid height j mod n). Each grasp
gives ``z = (Z_left, Z_right, h, w)``: the two taxel images once the force is established,
the commanded height and the finger distance from the encoders. Grasps run through the
sweep runner (:mod:`mmlearn.apps.common.sweep`): ``--results`` keeps them (default
``tactile_recognition_results.jsonl`` in the current folder), a rerun resumes, and
``--report-only FILE`` recomputes every figure from a results file without simulating.

**Recognition** (:mod:`mmlearn.models.tactile.recognition`): vocabulary of ``--k`` features
(Eq. 6.1-6.3 distance, medoid clustering), soft codebook histograms (6.4), histogram
intersection (6.6), posterior over T grasps (6.8). Evaluation as Sec. 6.3: randomised
2-fold cross-validation (per class, half of the grasps train, half test, both directions,
``--cv-repeats`` times); each of ``--recognitions`` trials per fold picks a random class and
``--T`` random test grasps of it (without replacement; with replacement only when a class
has fewer test grasps than T, counted in ``with_replacement``) and takes the MAP class after
them. The split alone moves the rate: on the 418 grasps of ``--seed 0`` (20 per class) one
split with 500 recognitions per fold gave 79.6 / 88.8 / 86.0 / 90.4 / 88.3 % on all classes
for evaluation seeds 0-4, five splits with 200 per fold 87.4 / 87.0 / 86.4 / 87.5 / 86.6 %:
hence 5 repeats by default. Reported: ``recognition_rate`` (all classes), and the same with
a recogniser trained on each subset alone (thesis Fig. 6.6): ``household``,
``industrial``, ``soft_vs_tennis`` (soft ball vs tennis ball), each with the rate after
t = 1..T grasps, per-class rates and the confusion matrix, beside the thesis' 84.6 / 96.2 /
58.0 / 93.8 %. ``--k-sweep`` and ``--alpha-sweep`` add Tables 6.1 / 6.2 on all classes;
``--informed`` adds Fig. 6.7 on all classes and on the industrial ones: the rate after each
grasp t = 1..T for the same ``--informed-trials`` objects per fold (paired) under three
strategies: ``random`` test grasps (as the recognition rate above), ``informed`` (the next
height maximises the expected information gain of Eq. 6.12-6.13 given the grasps so far,
with H(c | z) estimated by the cross-entropy on the labelled training outcomes, heights not
yet grasped first) and ``informed_entropy`` (the same with the thesis' plug-in entropy of
the updated belief), with the mean over t, the distinct heights grasped and a paired t-test
against random (see :mod:`mmlearn.models.tactile.recognition` for why the plug-in entropy
fails here). A subset
whose training half has fewer than 2k grasps uses k = half its number of training grasps
(``k_used``; e.g. soft vs tennis ball with 20 grasps per class: 20 training grasps, k = 10).

``--json`` prints one object: ``{"recognition_rate", "rates": {"all", "household",
"industrial", "soft_vs_tennis": {"rate", "rate_by_T", "per_class", "labels", "confusion",
"k_used", "n_classes", "with_replacement"}}, "thesis", "k_sweep", "alpha_sweep",
"informed": {subset: {"random", "informed", "informed_entropy", "mean_over_T",
"distinct_heights", "paired_t", "recognitions"}},
"example_images": {class: {"height", "width", "left", "right"}}, "n_grasps", "no_contact",
"errors", "settings", "sweep"}``. ``--plot FILE`` draws the confusion matrices, the rate
after t grasps and one grasp's tactile images per class.

Exit status: 0 success, 1 a grasp raised an error (named on stderr), 2 bad input, 130
interrupted (rerun to resume).
"""

from __future__ import annotations

import json
import sys
from dataclasses import dataclass

import numpy as np

from mmlearn.apps.common.cli import (ArgumentParser, UsageError, check_out_file, fail,
                                     json_clean, name_list, nonneg_int, pos_float, pos_int,
                                     save_figure)
from mmlearn.diagrams.tactile.objects import object_grasp_trial
from mmlearn.models.common.config import param, validate_fields

__all__ = ["RecognitionExperimentConfig", "run", "report", "main", "grasp_specs",
           "evaluate", "THESIS_RATES", "SUBSETS", "STRATEGIES"]

TRIAL_FN = "tactile.object_grasp"
#: Sec. 6.3.2 (T = 10): all 21 classes, household, industrial, soft vs tennis ball.
THESIS_RATES = {"all": 0.846, "household": 0.962, "industrial": 0.580, "soft_vs_tennis": 0.938}
#: Table 6.1 and 6.2 of the thesis (T = 10).
THESIS_K = {10: 0.582, 20: 0.728, 30: 0.717, 40: 0.844, 50: 0.830}
THESIS_ALPHA = {0.0: 0.669, 0.25: 0.843, 0.5: 0.810, 0.75: 0.783, 1.0: 0.760}
K_SWEEP = (10, 20, 30, 40, 50)
ALPHA_SWEEP = (0.0, 0.25, 0.5, 0.75, 1.0)
SUBSETS = ("all", "household", "industrial", "soft_vs_tennis")
HEIGHT_RESOLUTION = 0.01  # m: the action grid of Sec. 6.2


@dataclass
class RecognitionExperimentConfig:
    """Settings of one run.

    Attributes:
        grasps_per_class: simulated grasps per class.
        classes: class labels to grasp (default: all 21).
        k: vocabulary size.
        alpha: tactile vs width weight of Eq. 6.3, in [0, 1].
        T: grasps per recognition.
        recognitions: recognition trials per fold and subset.
        cv_repeats: repetitions of the randomised 2-fold split.
        k_sweep, alpha_sweep: add Tables 6.1 / 6.2.
        informed: add informed vs random grasp heights (Fig. 6.7).
        informed_trials: recognitions per fold and strategy for ``informed`` (the same
            objects for every strategy).
        f_target: grasp force per finger, N.
        seed: seeds the grasps, the splits and the recognition trials.
        plot: image file for confusion matrices and rate curves, or None.
        results, executor, jobs, ray_address: the sweep runner's settings.
        progress: progress bar.
    """

    grasps_per_class: int = param(20, integer=True)
    classes: tuple = param(())
    k: int = param(50, integer=True, ge=1)
    alpha: float = param(0.5, ge=0, le=1)
    T: int = param(10, integer=True, ge=1)
    recognitions: int = param(200, integer=True, ge=1)
    cv_repeats: int = param(5, integer=True, ge=1)
    k_sweep: bool = param(False)
    alpha_sweep: bool = param(False)
    informed: bool = param(False)
    informed_trials: int = param(100)
    f_target: float = param(15.0, unit="N")
    seed: int = param(0)
    plot: str | None = param(None, optional=True)
    results: str | None = param(None, optional=True)
    executor: str = param("local")
    jobs: int | None = param(None, optional=True)
    ray_address: str | None = param(None, optional=True)
    progress: bool = param(False)


# ----------------------------------------------------------------------------- grasps
def grasp_specs(classes, grasps_per_class: int, *, seed: int, f_target: float = 15.0):
    """The sweep's trial specs: grasp j of class c at grid height j mod n (bottom to top)."""
    from mmlearn.apps.common.sweep import TrialSpec
    from mmlearn.diagrams.tactile.objects import grid_heights
    from mmlearn.sdf.tactile_objects import CLASSES

    specs = []
    for c in classes:
        ci = list(CLASSES).index(c)
        hs = grid_heights(c)
        for j in range(grasps_per_class):
            h = float(hs[j % len(hs)])
            specs.append(TrialSpec(fn=object_grasp_trial, seed=int(seed) * 1_000_003 + ci * 1000 + j,
                                   params={"cls": c, "height": h, "f_target": float(f_target)},
                                   label=f"{c} h={h:.2f} #{j}"))
    return specs


def _dataset(records):
    """A labelled TactileSet and the group of each label from trial records (with contact)."""
    from mmlearn.models.tactile.recognition import TactileSet

    recs = [r for r in records if r.get("contact")]
    if not recs:
        raise ValueError("no grasp touched its object: nothing to recognise")
    ts = TactileSet(np.array([r["left"] for r in recs]), np.array([r["right"] for r in recs]),
                    np.array([r["height"] for r in recs]), np.array([r["width"] for r in recs]),
                    np.array([r["cls"] for r in recs], dtype=object))
    groups = {r["cls"]: r["group"] for r in recs}
    return ts, groups


# ----------------------------------------------------------------------------- evaluation
def _split(labels, rng):
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


def _fit(train, *, k, alpha, seed):
    from mmlearn.models.tactile.recognition import TactileRecognitionConfig, TactileRecognizer

    # at most half the training grasps: with every grasp a centre the model's default
    # length scale (a fraction of the distance to the nearest other centre) degenerates
    k_used = int(min(k, max(1, len(train) // 2)))
    rec = TactileRecognizer(TactileRecognitionConfig(k=k_used, alpha=alpha, seed=seed))
    return rec.fit(train), k_used


def _random_trials(rec, test, classes, T, n, rng):
    """``n`` recognitions of random classes from T random test grasps each: (correct after
    t = 1..T (n, T) bool, true class index (n,), predicted class index after T (n,), number
    drawn with replacement)."""
    from mmlearn.models.tactile.recognition import posterior

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


def _strategy_trials(rec, train, test, objects, T, rng, *, strategy, Ltr=None, fresh=True):
    """Recognitions of the given ``objects`` (class names, one per trial) from T test grasps
    each: (correct after t = 1..T (n, T) bool, distinct heights grasped per trial (n,)).

    ``strategy`` "random": T random test grasps of the object (without replacement; with
    replacement only when it has fewer than T). "random_heights": each next grasp at a random
    height where the object still has an unused test grasp, heights not yet grasped first.
    "informed" / "informed_entropy": each next grasp at the height with the largest expected
    information gain (Eq. 6.12-6.13, :meth:`TactileRecognizer.next_action`) among the heights
    where the object still has an unused test grasp, preferring heights not yet grasped
    (``fresh=False``: no preference, the first version's rule); estimator "cross_entropy" /
    "entropy". ``Ltr``: the leave-one-out likelihoods of ``train`` (computed when None)."""
    from mmlearn.models.tactile.recognition import height_actions, posterior

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


def evaluate(data, classes, *, k=50, alpha=0.5, T=10, recognitions=500, cv_repeats=1,
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
        A, B = _split(sub.labels, rng)
        for tr, te in ((A, B), (B, A)):
            train, test = sub.subset(tr), sub.subset(te)
            missing = sorted((set(labels) - set(test.labels.tolist()))
                             | (set(labels) - set(train.labels.tolist())))
            if missing:
                raise ValueError(f"classes {missing} have fewer than 2 grasps with contact")
            rec, k_used = _fit(train, k=k, alpha=alpha, seed=seed)
            ks.append(k_used)
            ok, true, pred, r = _random_trials(rec, test, labels, T, recognitions, rng_rec)
            oks.append(ok)
            repl += r
            order = [labels.index(c) for c in rec.classes]  # rec.classes is sorted too
            np.add.at(C, (np.take(order, true), np.take(order, pred)), 1)
            if informed_trials:
                # the same objects for every strategy (paired comparison)
                objs = [labels[j] for j in rng_inf.integers(len(labels), size=informed_trials)]
                Ltr = rec.likelihood_loo(train)
                for st in STRATEGIES:
                    o, d = _strategy_trials(rec, train, test, objs, T, rng_inf, strategy=st,
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
        out["informed"] = _compare_strategies(inf, inf_d)
    return out


def _compare_strategies(inf, inf_d) -> dict:
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


def _subset_classes(name, groups):
    if name == "all":
        return sorted(groups)
    if name == "soft_vs_tennis":
        return [c for c in ("soft_ball", "tennis_ball") if c in groups]
    return sorted(c for c, g in groups.items() if g == name)


def report(lines: list[dict], config: RecognitionExperimentConfig) -> dict:
    """Every figure from results-file lines (a run or ``--report-only``)."""
    c = config
    lines = [ln for ln in lines if ln.get("spec", {}).get("fn", "").split("@")[0] == TRIAL_FN]
    if not lines:
        raise ValueError("no recognition grasp in the results")
    # one order whatever the order the grasps finished in: the splits depend on it
    lines = sorted(lines, key=lambda ln: (str(ln["spec"]["params"].get("cls")),
                                          int(ln["spec"]["seed"])))
    errors = [{"trial": ln["spec"].get("label") or ln["key"], "error": ln["error"]}
              for ln in lines if ln.get("error")]
    records = [ln["record"] for ln in lines if ln.get("error") is None and ln.get("record")]
    if c.classes:
        records = [r for r in records if r["cls"] in c.classes]
    no_contact = sorted(f"{r['cls']} h={r['height']:.2f}" for r in records
                        if not r.get("contact"))
    data, groups = _dataset(records)
    kw = dict(k=c.k, alpha=c.alpha, T=c.T, recognitions=c.recognitions,
              cv_repeats=c.cv_repeats, seed=c.seed)
    rates = {}
    skipped = {}
    for name in SUBSETS:
        cl = _subset_classes(name, groups)
        if len(cl) < 2:
            skipped[name] = f"needs two classes, grasped: {cl}"
            continue
        want_inf = c.informed and name in ("all", "industrial")
        rates[name] = evaluate(data, cl, informed_trials=c.informed_trials if want_inf else 0,
                               **kw)
    out = {"recognition_rate": rates["all"]["rate"] if "all" in rates else None,
           "rates": rates, "skipped_subsets": skipped,
           "thesis": {"rates": THESIS_RATES, "k_sweep": THESIS_K, "alpha_sweep": THESIS_ALPHA},
           "n_grasps": len(records), "no_contact": no_contact, "errors": errors,
           "classes": sorted(groups),
           "grasps_per_class": {cl: int(np.sum(data.labels == cl)) for cl in sorted(groups)}}
    # Fig. 6.3: one grasp per class (the one nearest the middle of its heights), both pads
    out["example_images"] = {}
    for cl in sorted(groups):
        rs = [r for r in records if r["cls"] == cl and r.get("contact")]
        mid = np.median([r["height"] for r in rs])
        r = min(rs, key=lambda r: abs(r["height"] - mid))
        out["example_images"][cl] = {"height": r["height"], "width": r["width"],
                                     "left": r["left"], "right": r["right"]}
    allc = _subset_classes("all", groups)
    if c.k_sweep and len(allc) >= 2:
        out["k_sweep"] = {str(k): evaluate(data, allc, **dict(kw, k=k))["rate"]
                          for k in K_SWEEP}
    if c.alpha_sweep and len(allc) >= 2:
        out["alpha_sweep"] = {f"{a:g}": evaluate(data, allc, **dict(kw, alpha=a))["rate"]
                              for a in ALPHA_SWEEP}
    if c.informed:
        out["informed"] = {k: v.pop("informed") for k, v in rates.items() if "informed" in v}
    out["settings"] = {"k": c.k, "alpha": c.alpha, "T": c.T, "recognitions": c.recognitions,
                       "cv_repeats": c.cv_repeats, "seed": c.seed,
                       "informed_trials": c.informed_trials if c.informed else None}
    return out


def run(*, config: RecognitionExperimentConfig) -> dict:
    """Simulate the grasps (resuming from ``config.results``) and report (see the module
    docstring for the result)."""
    from mmlearn.apps.common.sweep import run_sweep
    from mmlearn.sdf.tactile_objects import CLASSES

    c = config
    _check(c)
    classes = list(c.classes) or list(CLASSES)
    specs = grasp_specs(classes, c.grasps_per_class, seed=c.seed, f_target=c.f_target)
    sweep = run_sweep(specs, results=c.results, executor=c.executor, jobs=c.jobs,
                      ray_address=c.ray_address, show_progress=c.progress, desc="grasps")
    out = report(sweep.lines, c)
    out["sweep"] = sweep.summary()
    out["settings"].update(grasps_per_class=c.grasps_per_class, f_target=c.f_target)
    return json_clean(out)


def _check(c: RecognitionExperimentConfig) -> None:
    from mmlearn.sdf.tactile_objects import CLASSES

    validate_fields(c)
    if c.grasps_per_class < 2:
        raise ValueError(f"grasps_per_class: expected at least 2 (2-fold CV), got "
                         f"{c.grasps_per_class}")
    bad = [x for x in c.classes if x not in CLASSES]
    if bad:
        raise ValueError(f"classes: unknown {bad}; choose from {', '.join(CLASSES)}")


# ----------------------------------------------------------------------------- output
def format_report(res: dict) -> str:
    names = {"all": "all classes", "household": "household", "industrial": "industrial",
             "soft_vs_tennis": "soft vs tennis ball"}
    lines = [f"{res['n_grasps']} grasps of {len(res['classes'])} classes "
             f"({len(res['no_contact'])} without contact, {len(res['errors'])} raised); "
             f"k {res['settings']['k']}, alpha {res['settings']['alpha']}, "
             f"T = {res['settings']['T']}:"]
    for name, r in res["rates"].items():
        lines.append(f"  {names[name]:20s} {100 * r['rate']:5.1f} %   (thesis "
                     f"{100 * THESIS_RATES[name]:.1f} %; {r['n_classes']} classes, "
                     f"{r['recognitions']} recognitions, k {r['k_used']})")
    for name, why in res.get("skipped_subsets", {}).items():
        lines.append(f"  {names[name]:20s} skipped: {why}")
    if "all" in res["rates"]:
        r = res["rates"]["all"]
        lines.append("  rate after t grasps: " + " ".join(f"{x:.3f}" for x in r["rate_by_T"]))
        worst = sorted((v, k) for k, v in r["per_class"].items() if v is not None)[:5]
        lines.append("  lowest per class: " + ", ".join(f"{k} {v:.2f}" for v, k in worst))
    if "k_sweep" in res:
        lines.append("  k sweep (Table 6.1):     " + "  ".join(
            f"k={k}: {100 * v:.1f}% ({100 * THESIS_K[int(k)]:.1f})"
            for k, v in res["k_sweep"].items()))
    if "alpha_sweep" in res:
        lines.append("  alpha sweep (Table 6.2): " + "  ".join(
            f"a={a}: {100 * v:.1f}% ({100 * THESIS_ALPHA[float(a)]:.1f})"
            for a, v in res["alpha_sweep"].items()))
    for name, d in res.get("informed", {}).items():
        for strat in STRATEGIES:
            v = d[strat]
            pt = d["paired_t"].get(strat)
            extra = (f", vs random {100 * pt['mean_difference']:+.1f} % (paired t p = "
                     f"{pt['p']:.2g})" if pt else "")
            lines.append(f"  {names[name]:12s} {strat:16s} " + " ".join(f"{x:.3f}" for x in v)
                         + f"   mean {np.mean(v):.3f}, {d['distinct_heights'][strat]:.1f} "
                           f"heights{extra}")
    for e in res["errors"]:
        lines.append(f"  error: {e['trial']}: {e['error'].splitlines()[0][:160]}")
    return "\n".join(lines)


def plot_report(res: dict, path) -> None:
    """Confusion matrices of the subsets (Fig. 6.6), the rate after t grasps, random vs
    informed where measured (Fig. 6.7), and below the left and right tactile images of one
    grasp per class (Fig. 6.3)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    subs = [s for s in ("all", "household", "industrial") if s in res["rates"]]
    ex = res.get("example_images", {})
    ncol = len(subs) + 1
    fig = plt.figure(figsize=(6 * ncol, 5.5 + (3.2 if ex else 0)))
    gs = fig.add_gridspec(2 if ex else 1, ncol, height_ratios=[5.5, 3.2] if ex else [1])
    axes = [fig.add_subplot(gs[0, i]) for i in range(ncol)]
    if ex:
        sub = gs[1, :].subgridspec(1, len(ex))
        for i, (cl, e) in enumerate(ex.items()):
            ax = fig.add_subplot(sub[0, i])
            img = np.hstack([np.asarray(e["left"]), np.full((len(e["left"]), 1), np.nan),
                             np.asarray(e["right"])])
            ax.imshow(img, cmap="gray_r", vmin=0, vmax=max(0.05, np.nanmax(img)))
            ax.set_title(f"{cl}\nh {100 * e['height']:.0f} w {1000 * e['width']:.0f}",
                         fontsize=6)
            ax.set_xticks([])
            ax.set_yticks([])
    for ax, s in zip(axes, subs):
        r = res["rates"][s]
        C = np.asarray(r["confusion"], float)
        C = C / np.maximum(C.sum(axis=1, keepdims=True), 1)
        ax.imshow(C, cmap="Blues", vmin=0, vmax=1)
        n = len(r["labels"])
        ax.set_xticks(range(n), r["labels"], rotation=70, ha="right", fontsize=7)
        ax.set_yticks(range(n), r["labels"], fontsize=7)
        ax.set_title(f"{s}: {100 * r['rate']:.1f} % (thesis {100 * THESIS_RATES[s]:.1f} %)",
                     fontsize=9)
    ax = axes[-1]
    for s in subs:
        v = res["rates"][s]["rate_by_T"]
        ax.plot(range(1, len(v) + 1), v, "-o", ms=3, label=f"{s} (random)")
    for s, d in res.get("informed", {}).items():
        for st, sty in (("random", ":^"), ("informed", "--s")):
            ax.plot(range(1, len(d[st]) + 1), d[st], sty, ms=3,
                    label=f"{s} ({st}, Fig. 6.7 trials)")
    ax.set_xlabel("grasps t")
    ax.set_ylabel("recognition rate")
    ax.set_ylim(0, 1.02)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, path, dpi=100)
    plt.close(fig)


def _show_one(cls: str, *, seed: int, meshcat, html_out) -> dict:
    """One grasp of ``cls`` at its middle grid height, drawn in Meshcat (and recorded)."""
    from pydrake.geometry import MeshcatVisualizer

    from mmlearn.diagrams.tactile import objects as to

    hs = to.grid_heights(cls)
    vis_holder = {}

    def hook(diagram):
        for s in diagram.GetSystems():
            if isinstance(s, MeshcatVisualizer):
                vis_holder["vis"] = s
                s.StartRecording(False)

    rec = to.object_grasp_trial(seed=seed, cls=cls, height=float(hs[len(hs) // 2]),
                                meshcat=meshcat, on_diagram=hook)
    if "vis" in vis_holder:
        vis_holder["vis"].PublishRecording()
    if html_out:
        from mmlearn.apps.common.cli import save_html

        save_html(meshcat, html_out)
    return rec


def main(argv=None) -> int:
    from mmlearn.apps.common.sweep import (add_sweep_args, apply_sweep_args, exit_status,
                                           report_only_lines, report_only_result)
    from mmlearn.sdf.tactile_objects import CLASSES

    ap = ArgumentParser(
        prog="python -m mmlearn.apps.tactile_recognition",
        description="Recognise objects by touch (thesis ch. 6): simulated grasps of 16 "
                    "objects / 21 classes -> tactile images -> bag of tactile features, "
                    "2-fold CV. Exit status: 0 success, 1 a grasp raised, 2 bad input, "
                    "130 interrupted.")
    ap.add_argument("--grasps-per-class", type=pos_int, default=20,
                    help="simulated grasps per class (default 20; the thesis had ~40: "
                         "830 grasps of 21 classes)")
    ap.add_argument("--classes", type=name_list(list(CLASSES)), default=[],
                    help="comma-separated class labels (default: all 21)")
    ap.add_argument("--k", type=pos_int, default=50, help="vocabulary size (default 50)")
    ap.add_argument("--alpha", type=float, default=0.5,
                    help="weight of the tactile term against the width term, in [0, 1] "
                         "(default 0.5)")
    ap.add_argument("--T", type=pos_int, default=10, help="grasps per recognition (default 10)")
    ap.add_argument("--recognitions", type=pos_int, default=200,
                    help="recognition trials per fold and subset (default 200)")
    ap.add_argument("--cv-repeats", type=pos_int, default=5,
                    help="repetitions of the randomised 2-fold split (default 5: with one "
                         "split the rate moves by a few %% with the split alone)")
    ap.add_argument("--k-sweep", action="store_true", help="add Table 6.1 (k = 10..50)")
    ap.add_argument("--alpha-sweep", action="store_true", help="add Table 6.2 (alpha 0..1)")
    ap.add_argument("--informed", action="store_true",
                    help="add informed (expected information gain) vs random grasp heights")
    ap.add_argument("--informed-trials", type=pos_int, default=100,
                    help="recognitions per fold and strategy with --informed (default 100; "
                         "the same objects for every strategy)")
    ap.add_argument("--f-target", type=pos_float, default=15.0, metavar="N",
                    help="grasp force per finger, newtons (default 15)")
    ap.add_argument("--seed", type=nonneg_int, default=0,
                    help="seed of the grasps, the splits and the recognitions")
    ap.add_argument("--plot", metavar="FILE", default=None,
                    help="write confusion matrices and rate curves as an image")
    ap.add_argument("--meshcat", action="store_true",
                    help="also show one grasp (the first class) live in Meshcat")
    ap.add_argument("--html-out", metavar="FILE", default=None,
                    help="also record one grasp (the first class) as standalone Meshcat HTML")
    ap.add_argument("--progress", action="store_true", help="progress bar of the grasps")
    add_sweep_args(ap, app="tactile_recognition")
    ap.add_argument("--json", action="store_true", help="print results as one JSON object")
    args = ap.parse_args(argv)
    cfg = RecognitionExperimentConfig(
        grasps_per_class=args.grasps_per_class, classes=tuple(args.classes), k=args.k,
        alpha=args.alpha, T=args.T, recognitions=args.recognitions,
        cv_repeats=args.cv_repeats, k_sweep=args.k_sweep, alpha_sweep=args.alpha_sweep,
        informed=args.informed, informed_trials=args.informed_trials, f_target=args.f_target,
        seed=args.seed, plot=args.plot, progress=args.progress)
    try:
        if not (np.isfinite(args.alpha) and 0.0 <= args.alpha <= 1.0):
            raise UsageError(f"--alpha: expected a number in [0, 1], got {args.alpha!r}")
        check_out_file("--plot", args.plot)
        check_out_file("--html-out", args.html_out)
        lines = report_only_lines(args, simulates="a grasp")
        if lines is None:
            apply_sweep_args(cfg, args, app="tactile_recognition")
            _check(cfg)
    except (UsageError, ValueError) as e:
        return fail(ap.prog, str(e))
    try:
        if args.meshcat or args.html_out:
            from mmlearn.apps.common.cli import finish_viewing, make_meshcat

            mc = make_meshcat(announce=args.meshcat)
            _show_one((cfg.classes or tuple(CLASSES))[0], seed=cfg.seed, meshcat=mc,
                      html_out=args.html_out)
        if args.report_only:
            res = report_only_result(report(lines, cfg), args.report_only)
        else:
            res = run(config=cfg)
    except ValueError as e:
        return fail(ap.prog, str(e))
    if args.plot:
        plot_report(res, args.plot)
    if args.json:
        print(json.dumps(res, indent=1))
    else:
        print(format_report(res))
        if args.plot:
            print(f"plot written to {args.plot}")
    if args.meshcat or args.html_out:
        finish_viewing(html_out=args.html_out, live=args.meshcat)
    return exit_status(ap.prog, res)


if __name__ == "__main__":
    sys.exit(main())
