"""Object recognition by touch (thesis ch. 6): simulated grasps -> tactile images -> bag of
tactile features.

Usage::

    python -m mmlearn.apps.tactile_recognition [--grasps-per-class 20] [--k 50] [--alpha 0.5]
        [--T 10] [--recognitions 200] [--cv-repeats 5] [--k-sweep] [--alpha-sweep]
        [--informed] [--classes a,b,..] [--plot FILE] --seed S [--json]
        [--results FILE] [--jobs J] [--executor local|ray] [--report-only RESULTS.jsonl]

**Grasps** (Drake, :func:`mmlearn.diagrams.tactile.trials.object_grasp_trial`): the
two-finger gripper with the ch. 6 taxel pads (14 x 6 cells over 51 x 24 mm) and the switching grasp controller closes
on each of the 16 objects / 21 classes of :mod:`mmlearn.sdf.tactile_objects` (a fresh
seeded instance per grasp: size, mass, friction, stiffness; placement error 1.5 mm in
height and 1 mm sideways), ``--grasps-per-class`` grasps per class at the heights of the
class' 1 cm grid from bottom to top (cycling: grasp j at grid height j mod n). Each grasp
gives ``z = (Z_left, Z_right, h, w)``: the two taxel images once the force is established,
the commanded height and the finger distance from the encoders. Grasps run through the
sweep runner (:mod:`mmlearn.apps.common.sweep`): ``--results`` keeps them (default
``tactile_recognition_results.jsonl`` in the current folder), a rerun resumes, and
``--report-only FILE`` recomputes every figure from a results file without simulating.

**Recognition** (:mod:`mmlearn.models.tactile.recognition`, the evaluation in
:mod:`mmlearn.models.tactile.evaluation`): vocabulary of ``--k`` features
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

from mmlearn.apps.common import experiment
from mmlearn.apps.common.cli import (UsageError, check_out_file, json_clean, name_list,
                                     pos_float, pos_int, save_figure)
from mmlearn.apps.common.experiment import Experiment
from mmlearn.diagrams.tactile.trials import object_grasp_plan, object_grasp_trial
from mmlearn.models.common.config import param, validate_fields
from mmlearn.models.tactile.evaluation import (STRATEGIES, SUBSETS, evaluate_recognition,
                                               recognition_dataset, subset_classes)

__all__ = ["RecognitionExperimentConfig", "run", "report", "main", "grasp_specs",
           "THESIS_RATES"]

#: the registered name of the grasps' trial (results-file lines of other trials are ignored)
TRIAL_FN = object_grasp_trial.trial_name
#: Sec. 6.3.2 (T = 10): all 21 classes, household, industrial, soft vs tennis ball.
THESIS_RATES = {"all": 0.846, "household": 0.962, "industrial": 0.580, "soft_vs_tennis": 0.938}
#: Table 6.1 and 6.2 of the thesis (T = 10).
THESIS_K = {10: 0.582, 20: 0.728, 30: 0.717, 40: 0.844, 50: 0.830}
THESIS_ALPHA = {0.0: 0.669, 0.25: 0.843, 0.5: 0.810, 0.75: 0.783, 1.0: 0.760}
K_SWEEP = (10, 20, 30, 40, 50)
ALPHA_SWEEP = (0.0, 0.25, 0.5, 0.75, 1.0)


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
    """The sweep's trial specs (:func:`mmlearn.diagrams.tactile.trials.object_grasp_plan`)."""
    from mmlearn.apps.common.sweep import TrialSpec

    return [TrialSpec(**d) for d in object_grasp_plan(classes, grasps_per_class, seed=seed,
                                                      f_target=f_target)]


# ----------------------------------------------------------------------------- report
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
    data, groups = recognition_dataset(records)
    kw = dict(k=c.k, alpha=c.alpha, T=c.T, recognitions=c.recognitions,
              cv_repeats=c.cv_repeats, seed=c.seed)
    rates = {}
    skipped = {}
    for name in SUBSETS:
        cl = subset_classes(name, groups)
        if len(cl) < 2:
            skipped[name] = f"needs two classes, grasped: {cl}"
            continue
        want_inf = c.informed and name in ("all", "industrial")
        rates[name] = evaluate_recognition(
            data, cl, informed_trials=c.informed_trials if want_inf else 0, **kw)
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
    allc = subset_classes("all", groups)
    if c.k_sweep and len(allc) >= 2:
        out["k_sweep"] = {str(k): evaluate_recognition(data, allc, **dict(kw, k=k))["rate"]
                          for k in K_SWEEP}
    if c.alpha_sweep and len(allc) >= 2:
        out["alpha_sweep"] = {
            f"{a:g}": evaluate_recognition(data, allc, **dict(kw, alpha=a))["rate"]
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

    from mmlearn.diagrams.tactile.trials import grid_heights

    hs = grid_heights(cls)
    vis_holder = {}

    def hook(diagram):
        for s in diagram.GetSystems():
            if isinstance(s, MeshcatVisualizer):
                vis_holder["vis"] = s
                s.StartRecording(False)

    rec = object_grasp_trial(seed=seed, cls=cls, height=float(hs[len(hs) // 2]),
                                meshcat=meshcat, on_diagram=hook)
    _frame_and_legend(meshcat, rec)
    if "vis" in vis_holder:
        vis_holder["vis"].PublishRecording()
    if html_out:
        from mmlearn.apps.common.cli import save_html

        save_html(meshcat, html_out)
    return rec


def _frame_and_legend(meshcat, rec: dict) -> None:
    """Frame the gripper and the object seen obliquely (the taxel displays sit on the
    fingers' outer faces) and draw a legend naming what is drawn, with the grasp's numbers."""
    from pydrake.geometry import Rgba

    from mmlearn.systems.common.meshcat_view import draw_legend, frame_camera
    from mmlearn.systems.tactile.taxel_visualizer import taxel_colors

    h = float(rec["height"])
    box = np.array([[x, y, z] for x in (-0.09, 0.09) for y in (-0.06, 0.06)
                    for z in (0.0, h + 0.06)])
    frame_camera(meshcat, box, view_from=(1.0, -0.6, 0.5), min_distance=0.1)
    lo, mid, hi = (Rgba(*c) for c in taxel_colors(np.array([0.0, 0.5, 1.0])))
    top = {side: float(np.max(rec[side])) for side in ("left", "right")}
    rows = [(lo, "box", "taxel cell reading 0: each pad's 14 x 6 cells, on the finger's outer face"),
            (mid, "box", "half the colour scale"),
            (hi, "box", "the grasp's largest reading, rounded up to 0.05 (1 = saturated); "
                        "a cell rises with its reading"),
            (None, "", f"object {rec['object']} (class {rec['cls']}, group {rec['group']}), "
                       f"grasped {1000 * h:.0f} mm above its base"),
            (None, "", f"finger distance {1000 * float(rec['width']):.1f} mm, grasp force "
                       f"{float(rec['force']):.1f} N; contact: {'yes' if rec['contact'] else 'no'}"),
            (None, "", f"largest cell reading at the end: left {top['left']:.2f}, "
                       f"right {top['right']:.2f}")]
    draw_legend(meshcat, f"Tactile grasp for recognition: {rec['cls']}", rows)


class TactileRecognition(Experiment):
    """The command line (:mod:`mmlearn.apps.common.experiment`)."""

    name = "tactile_recognition"
    trials = (object_grasp_trial,)
    description = ("Recognise objects by touch (thesis ch. 6): simulated grasps of 16 "
                   "objects / 21 classes -> tactile images -> bag of tactile features, "
                   "2-fold CV. Exit status: 0 success, 1 a grasp raised, 2 bad input, "
                   "130 interrupted.")
    seed_help = "seed of the grasps, the splits and the recognitions"
    json_help = "print results as one JSON object"
    desc = "grasps"
    viewer = None  # the Meshcat of --meshcat / --html-out, once shown

    def add_arguments(self, ap):
        from mmlearn.sdf.tactile_objects import CLASSES

        ap.add_argument("--grasps-per-class", type=pos_int, default=20,
                        help="simulated grasps per class (default 20; the thesis had ~40: "
                             "830 grasps of 21 classes)")
        ap.add_argument("--classes", type=name_list(list(CLASSES)), default=[],
                        help="comma-separated class labels (default: all 21)")
        ap.add_argument("--k", type=pos_int, default=50, help="vocabulary size (default 50)")
        ap.add_argument("--alpha", type=float, default=0.5,
                        help="weight of the tactile term against the width term, in [0, 1] "
                             "(default 0.5)")
        ap.add_argument("--T", type=pos_int, default=10,
                        help="grasps per recognition (default 10)")
        ap.add_argument("--recognitions", type=pos_int, default=200,
                        help="recognition trials per fold and subset (default 200)")
        ap.add_argument("--cv-repeats", type=pos_int, default=5,
                        help="repetitions of the randomised 2-fold split (default 5: with one "
                             "split the rate moves by a few %% with the split alone)")
        ap.add_argument("--k-sweep", action="store_true", help="add Table 6.1 (k = 10..50)")
        ap.add_argument("--alpha-sweep", action="store_true",
                        help="add Table 6.2 (alpha 0..1)")
        ap.add_argument("--informed", action="store_true",
                        help="add informed (expected information gain) vs random grasp heights")
        ap.add_argument("--informed-trials", type=pos_int, default=100,
                        help="recognitions per fold and strategy with --informed (default 100; "
                             "the same objects for every strategy)")
        ap.add_argument("--f-target", type=pos_float, default=15.0, metavar="N",
                        help="grasp force per finger, newtons (default 15)")
        ap.add_argument("--plot", metavar="FILE", default=None,
                        help="write confusion matrices and rate curves as an image")
        ap.add_argument("--meshcat", action="store_true",
                        help="also show one grasp (the first class) live in Meshcat")
        ap.add_argument("--html-out", metavar="FILE", default=None,
                        help="also record one grasp (the first class) as standalone Meshcat "
                             "HTML")
        ap.add_argument("--progress", action="store_true", help="progress bar of the grasps")

    def check(self, args):
        from mmlearn.apps.common.sweep import report_only_lines

        args.config = RecognitionExperimentConfig(
            grasps_per_class=args.grasps_per_class, classes=tuple(args.classes), k=args.k,
            alpha=args.alpha, T=args.T, recognitions=args.recognitions,
            cv_repeats=args.cv_repeats, k_sweep=args.k_sweep, alpha_sweep=args.alpha_sweep,
            informed=args.informed, informed_trials=args.informed_trials,
            f_target=args.f_target, seed=args.seed, plot=args.plot, progress=args.progress)
        if not (np.isfinite(args.alpha) and 0.0 <= args.alpha <= 1.0):
            raise UsageError(f"--alpha: expected a number in [0, 1], got {args.alpha!r}")
        check_out_file("--plot", args.plot)
        check_out_file("--html-out", args.html_out)
        if report_only_lines(args, simulates="a grasp", trials=self.trials) is None:
            try:
                _check(args.config)
            except ValueError as e:
                raise UsageError(str(e)) from None

    def specs(self, args):
        if args.meshcat or args.html_out:  # one grasp shown before the grasps run
            self.show(args)
        c = args.config
        return grasp_specs(list(c.classes) or list(_all_classes()), c.grasps_per_class,
                           seed=c.seed, f_target=c.f_target)

    def show_progress(self, args) -> bool:
        return args.progress

    def report(self, lines, args):
        return report(lines, args.config)

    def attach_sweep(self, res, sweep, args):
        res["sweep"] = sweep.summary()
        res["settings"].update(grasps_per_class=args.grasps_per_class, f_target=args.f_target)

    def finish(self, res, args):
        from mmlearn.apps.common.sweep import report_only_result

        res = (report_only_result(res, args.report_only) if args.report_only
               else json_clean(res))
        if args.plot:
            plot_report(res, args.plot)
        return res

    def show(self, args):
        """One grasp of the first class drawn in Meshcat (and recorded) before the grasps."""
        from mmlearn.apps.common.cli import make_meshcat

        self.viewer = make_meshcat(announce=args.meshcat)
        self.viewing = {"html_out": args.html_out, "live": args.meshcat}
        _show_one((args.config.classes or tuple(_all_classes()))[0], seed=args.seed,
                  meshcat=self.viewer, html_out=args.html_out)

    def print_table(self, res, args):
        print(format_report(res))
        if args.plot:
            print(f"plot written to {args.plot}")

    def to_json(self, res):
        return json.dumps(res, indent=1)


def _all_classes():
    from mmlearn.sdf.tactile_objects import CLASSES

    return CLASSES


def main(argv=None) -> int:
    app = TactileRecognition()
    rc = experiment.main(app, argv)
    if app.viewer is not None:
        from mmlearn.apps.common.cli import finish_viewing

        finish_viewing(**app.viewing)
    return rc


if __name__ == "__main__":
    sys.exit(main())
