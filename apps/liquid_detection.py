"""Liquid detection by rolling a grasped container (thesis Sec. 7.3, Table 7.4, Fig. 7.11).

Usage::

    python -m mmlearn.apps.liquid_detection [--with-weight] [--containers N | --names A,B]
        [--trials N] [--no-dummy] [--roll-cycles C] [--roll-profile sweep|sine|triangle]
        [--feature coast_detrended|coast|whole] [--coast-delay S] [--plot FILE] [--results FILE]
        [--jobs J] [--report-only RESULTS.jsonl] [--meshcat] [--html-out FILE] --seed S [--json]

Each trial (:func:`mmlearn.diagrams.tactile.trials.liquid_roll_trial`) grasps a random
instance of a container standing on a table with the PR2-like gripper (Eq. 7.8 switching controller,
then a finger position hold), lifts it and rolls it side to side with the wrist at 0.6 Hz
(+-0.7 rad, constant rate with smooth 0.25 s reversals). The liquid is its first sloshing
mode, a mass on a spring-damper with the cap as a barrier
(:func:`mmlearn.models.tactile.liquid.first_slosh_mode`); nothing but the simulated taxels (24 Hz,
noise 1e-4 of saturation) and the wrist force sensor is recorded. Features (:mod:`mmlearn.models.tactile.liquid`): each taxel through a
first-order 5 Hz Butterworth high-pass, the Euclidean norm over the 30 taxels (Eq. 7.9) and
its spread:

* ``whole`` (the thesis, Eq. 7.11): the standard deviation over the whole roll;
* ``coast`` (a deviation): the standard deviation over the coast phases only -- the samples
  where the robot's own roll command turns at a constant rate, from ``--coast-delay`` s
  (0.12 s, four time constants of the high-pass) after each reversal ends
  (:func:`mmlearn.diagrams.tactile.liquid_roll.roll_change_windows`,
  :func:`mmlearn.models.tactile.liquid.coast_mask`);
* ``coast_detrended`` (the default; a deviation): the spread about a quadratic trend fitted
  in each coast phase (:func:`mmlearn.models.tactile.liquid.coast_feature`). A rigid body's load on
  the pads shifts with gravity as the wrist turns, smoothly within a coast phase (the 5 Hz
  first-order high-pass passes it at ~20 %, as large as the liquid's ringing); the liquid
  keeps ringing at its sloshing frequency after the container's motion stops changing.

With ``--with-weight`` also the weight from the wrist force sensor (the mean vertical force
while the lifted container is held still, tared with the reading before contact). A decision
tree (entropy criterion, as the thesis' C4.5) is scored by stratified 10-fold
cross-validation on liquid / no liquid, for every feature (the one chosen with ``--feature``
at the top level of the output).

Containers (``--containers N`` takes the first N of
:data:`~mmlearn.diagrams.tactile.liquid_roll.LIQUID_CONTAINERS`, default 4: the Odwalla and water
bottles half full and empty; all 11: the full experiment) and, unless ``--no-dummy``, the
heavy rigid dummy (a rigid 0.2-0.3 kg weight in an Odwalla shell: the
weight and walls of a half-full bottle, nothing that sloshes), read two ways (``dummy``: its
feature and how it was classified, "no_liquid" is the correct answer): held out, classified by
the tree trained on all container trials (``predicted_no_liquid*``, the stricter test: no heavy
object without liquid in training), and, as in the thesis, inside the cross-validation as one
more "no liquid" object (``in_cv_*``: Table 7.5's 61 "no liquid" instances are Table 7.4's 56
empty-container trials plus the dummy's 5, 136 in all).

``--json`` prints one object::

    {"feature", "rate", "rate_tactile", "rate_with_weight", "with_weight", "labels",
     "confusion", "per_class", "table": [{"container", "liquid", "trials", "weight_n",
     "feature_mean", "feature_std"}], "dummy": {"trials", "feature_mean", "feature_std",
     "feature_values", "weight_n", "predicted_no_liquid", "predicted_no_liquid_tactile",
     "predicted_no_liquid_with_weight", "in_cv_no_liquid_tactile", "in_cv_no_liquid_with_weight",
     "in_cv_rate_tactile", "in_cv_rate_with_weight"}, "features": {FEATURE: {"rate_tactile",
     "rate_with_weight", "confusion", "labels", "table", "dummy"}}, "n_trials", "errors",
     "settings", "sweep"}

``--plot FILE`` draws Fig. 7.11 (raw taxels and the filtered norm of an empty and a liquid
trial of the same container) and the feature per container. Trials run through the sweep
runner (:mod:`mmlearn.apps.common.sweep`): ``--results`` keeps them, with every trial's taxel and
wrist-force series and its roll command (a rerun resumes), and ``--report-only`` recomputes
everything from such a file (any feature, any ``--coast-delay``) without simulating.

Exit status: 0 success, 1 a trial raised, 2 bad input, 130 interrupted.
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
from mmlearn.models.common.config import param, validate_fields
from mmlearn.apps.common.sweep import report_only_result
from mmlearn.diagrams.tactile.trials import liquid_roll_plan, liquid_roll_trial
from mmlearn.models.tactile.evaluation import (COAST_DELAY, cell_saturation_force,
                                               evaluate_rolls, roll_record)

__all__ = ["LiquidDetectionConfig", "run", "report", "main"]

@dataclass
class LiquidDetectionConfig:
    """Settings of one run.

    Attributes:
        containers: container labels (keys of ``LIQUID_CONTAINERS``).
        trials: trials per container.
        dummy: also roll the heavy rigid dummy (``trials`` times).
        with_weight: the weight (N) as the second feature.
        roll_cycles: roll cycles per trial.
        roll_profile: "sweep" (constant rate, smooth 0.25 s reversals), "sine" or "triangle"
            (abrupt reversals, the earlier roll).
        feature: the tactile feature the rate, the table and the dummy's class use:
            "coast_detrended" (the spread of the high-passed taxel norm about its slow trend
            within each coast phase of the roll, where the commanded roll rate is constant:
            a deviation, see the module docstring), "coast" (its plain spread over the coast
            samples) or "whole" (over the whole roll, thesis Eq. 7.11). All that the trials
            allow are reported.
        coast_delay: the coast samples start this long after each change of the commanded
            roll rate ends, s (0 <= delay < 0.3).
        folds: cross-validation folds (at most the smaller class' count).
        seed: seed of the trials and the folds.
        plot: image file or None.
        results, executor, jobs, ray_address, progress: the sweep runner's settings.
    """

    containers: tuple = param(("odwalla_half", "odwalla_empty", "water_half", "water_empty"),
                              length=(1, None))
    trials: int = param(3, integer=True, ge=2)
    dummy: bool = param(True)
    with_weight: bool = param(False)
    roll_cycles: float = param(2.0, ge=0.5)
    roll_profile: str = param("sweep", choices=("sweep", "sine", "triangle"))
    feature: str = param("coast_detrended")
    coast_delay: float = param(COAST_DELAY, unit="s", ge=0, lt=0.3)
    folds: int = param(10)
    seed: int = param(0)
    plot: str | None = param(None, optional=True)
    results: str | None = param(None, optional=True)
    executor: str = param("local")
    jobs: int | None = param(None, optional=True)
    ray_address: str | None = param(None, optional=True)
    progress: bool = param(False)


def _check(c: LiquidDetectionConfig) -> None:
    from mmlearn.diagrams.tactile.liquid_roll import LIQUID_CONTAINERS
    from mmlearn.models.tactile.liquid import FEATURES

    validate_fields(c)
    bad = [n for n in c.containers if n not in LIQUID_CONTAINERS]
    if bad:
        raise ValueError(f"containers: unknown {', '.join(map(repr, bad))}; choose from "
                         f"{', '.join(LIQUID_CONTAINERS)}")
    if len(set(c.containers)) != len(c.containers):
        raise ValueError("containers: a container is named twice")
    if c.feature not in FEATURES:
        raise ValueError(f"feature: expected one of {', '.join(FEATURES)}, got {c.feature!r}")
    if c.feature != "whole" and c.roll_profile == "sine":
        raise ValueError("feature: the coast feature needs constant-rate phases (roll_profile "
                         "sweep or triangle); the sine roll has none, use feature='whole'")
    liq = [LIQUID_CONTAINERS[n][1] is not None for n in c.containers]
    if all(liq) or not any(liq):
        raise ValueError("containers: need at least one container with liquid and one "
                         "without to learn to tell them apart")


def _specs(c: LiquidDetectionConfig):
    from mmlearn.apps.common.sweep import TrialSpec

    return [TrialSpec(**d) for d in liquid_roll_plan(
        c.containers, c.trials, seed=c.seed, dummy=c.dummy, roll_cycles=c.roll_cycles,
        roll_profile=c.roll_profile)]


def report(lines: list[dict], c: LiquidDetectionConfig) -> dict:
    """Rates, Table 7.4 and the dummy from results-file lines (a run or ``--report-only``),
    for ``c.feature`` at the top level and for every tactile feature the trials allow under
    ``"features"`` (``"coast"`` needs constant-rate roll phases, ``"whole"`` always)."""
    # the trials in the order of their specs' seeds, not of their completion (parallel jobs
    # finish in any order), so that the folds and the rates do not depend on the run
    lines = sorted(lines, key=lambda ln: (ln.get("spec", {}).get("seed", 0),
                                          str(ln.get("key"))))
    errors = [{"trial": ln["spec"].get("label") or ln["key"], "error": ln["error"]}
              for ln in lines if ln.get("error")]
    ok = [ln for ln in lines if not ln.get("error") and ln.get("record")]
    cont = [ln for ln in ok if ln["record"]["container"] != "dummy"]
    dummy = [ln for ln in ok if ln["record"]["container"] == "dummy"]
    if not cont:
        raise ValueError("no container trial finished")

    def feats(lns):
        return [roll_record(ln["record"], coast_delay=c.coast_delay) for ln in lns]

    rr, dr = feats(cont), feats(dummy)
    y = np.array(["liquid" if r.liquid else "no_liquid" for r in rr])
    counts = np.unique(y, return_counts=True)[1]
    if len(counts) < 2:
        raise ValueError("the finished trials hold only one class (liquid or not)")
    k = int(min(c.folds, counts.min()))
    if k < 2:
        raise ValueError("too few trials per class for cross-validation (use more --trials)")
    from mmlearn.models.tactile.liquid import FEATURES, liquid_features
    from mmlearn.models.tactile.types import TactileDataError

    avail, why = [], {}
    for f in FEATURES:
        try:
            liquid_features(rr + dr, feature=f)
            avail.append(f)
        except TactileDataError as e:
            why[f] = str(e)
    if c.feature not in avail:
        raise ValueError(f"feature {c.feature}: not available for these trials ({why[c.feature]}); "
                         f"use --feature whole, or a roll with longer constant-rate phases")
    by_feature = {f: evaluate_rolls(rr, dr, y, feature=f, k=k, seed=c.seed,
                                    with_weight=c.with_weight) for f in avail}
    out = {"feature": c.feature, "with_weight": bool(c.with_weight), "folds": k}
    out.update(by_feature[c.feature])
    out["features"] = {f: {kk: v for kk, v in ev.items()
                           if kk in ("rate_tactile", "rate_with_weight", "confusion", "labels",
                                     "table", "dummy")}
                       for f, ev in by_feature.items()}
    out["n_trials"] = len(rr)
    out["errors"] = errors
    out["settings"] = {"containers": list(c.containers), "trials": c.trials,
                       "dummy": c.dummy, "roll_cycles": c.roll_cycles,
                       "roll_profile": c.roll_profile, "seed": c.seed,
                       "feature": c.feature, "coast_delay_s": c.coast_delay,
                       "classifier": "tree (entropy)", "highpass": "Butterworth order 1, 5 Hz",
                       "taxel_rate_hz": 24.0, "roll_hz": 0.6,
                       "feature_unit": "normalised taxel pressure (1 = saturation)",
                       "taxel_saturation_force_n": cell_saturation_force()}
    return out


def run(*, config: LiquidDetectionConfig) -> dict:
    """Run (or resume) the trials and report (see the module docstring)."""
    from mmlearn.apps.common.sweep import run_sweep

    c = config
    _check(c)
    sweep = run_sweep(_specs(c), results=c.results, executor=c.executor, jobs=c.jobs,
                      ray_address=c.ray_address, show_progress=c.progress, desc="rolls")
    out = report(sweep.lines, c)
    out["sweep"] = sweep.summary()
    if c.plot:
        plot_report(sweep.lines, out, c.plot)
    return json_clean(out)


def plot_report(lines: list[dict], res: dict, path) -> None:
    """Fig. 7.11 (raw taxels and the high-passed norm of one empty and one liquid trial of
    the first container class that has both) and the feature per container."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from mmlearn.models.tactile.liquid import filtered_norm

    recs = [ln["record"] for ln in lines if not ln.get("error") and ln.get("record")]
    by_cls: dict = {}
    for r in recs:
        cls = r["instance"]["name"]
        by_cls.setdefault(cls, {}).setdefault(bool(r["liquid"]), r)
    pair = next((v for v in by_cls.values() if len(v) == 2), None)
    fig, ax = plt.subplots(3, 2, figsize=(11, 9))
    if pair is not None:
        for col, liq in enumerate((False, True)):
            r = pair[liq]
            t = np.asarray(r["t"])
            rf = roll_record(r)
            m = (t >= r["roll_window"][0]) & (t <= r["roll_window"][1])
            ax[0, col].plot(t[m], rf.taxels, lw=0.6)
            ax[0, col].set_title(f"{r['container']}: raw taxels")
            ax[0, col].set_ylabel("pressure (normalised)")
            fn = filtered_norm(rf.taxels, rate_hz=rf.rate_hz)
            ax[1, col].plot(t[m], fn, color="k")
            if rf.coast is not None:
                ax[1, col].plot(t[m][rf.coast], fn[rf.coast], ".", color="tab:orange",
                                label="coast samples")
                ax[1, col].legend(fontsize=7)
            ax[1, col].set_title("5 Hz high-pass, norm over taxels (Eq. 7.9)")
            ax[1, col].set_xlabel("t (s)")
    rows = res["table"]
    names = [f"{r['container']}" for r in rows]
    ax[2, 0].bar(range(len(rows)), [r["feature_mean"] for r in rows],
                 yerr=[r["feature_std"] for r in rows],
                 color=["tab:blue" if r["liquid"] else "tab:gray" for r in rows])
    ax[2, 0].set_xticks(range(len(rows)), names, rotation=30, fontsize=7)
    ax[2, 0].set_ylabel(f"feature sigma ({res['feature']})")
    if "dummy" in res:
        ax[2, 0].axhline(res["dummy"]["feature_mean"], color="tab:red", ls="--",
                         label="rigid dummy")
        ax[2, 0].legend()
    ax[2, 1].axis("off")
    txt = "".join(f"{f}: rate (tactile) {ev['rate_tactile']:.3f}, with weight "
                  f"{ev['rate_with_weight']:.3f}\n" for f, ev in res["features"].items())
    ax[2, 1].text(0.0, 0.5, txt + "thesis (whole roll): 0.919 / 0.985", fontsize=11)
    fig.tight_layout()
    save_figure(fig, path, dpi=90)
    plt.close(fig)


def format_report(res: dict) -> str:
    lines = [f"liquid detection, {res['n_trials']} trials, decision tree, {res['folds']}-fold CV, "
             f"feature {res['feature']}: rate {res['rate']:.3f} (tactile "
             f"{res['rate_tactile']:.3f}, with weight {res['rate_with_weight']:.3f}; thesis "
             f"0.919 / 0.985)"]
    for f, ev in res["features"].items():
        d = ev.get("dummy")
        dm = (f"; dummy {d['feature_mean']:.5f} +- {d['feature_std']:.5f}, classified no "
              f"liquid {d['predicted_no_liquid_tactile']}/{d['trials']} (tactile), "
              f"{d['predicted_no_liquid_with_weight']}/{d['trials']} (with weight); inside the "
              f"cross-validation {d['in_cv_no_liquid_tactile']}/{d['trials']} (tactile), "
              f"{d['in_cv_no_liquid_with_weight']}/{d['trials']} (with weight)") if d else ""
        lines.append(f"  feature {f:15s}: tactile {ev['rate_tactile']:.3f}, with weight "
                     f"{ev['rate_with_weight']:.3f}{dm}")
    feats = list(res["features"])
    lines.append(f"{'container':16s} {'liquid':6s} {'trials':>6s} {'weight N':>9s} "
                 + " ".join(f"{f:>19s}" for f in feats))
    rows = {f: {(r["container"], r["liquid"]): r for r in ev["table"]}
            for f, ev in res["features"].items()}
    for r in res["table"]:
        key = (r["container"], r["liquid"])
        lines.append(f"{r['container']:16s} {str(r['liquid']):6s} {r['trials']:6d} "
                     f"{r['weight_n']:9.3f} " + " ".join(
                         f"{rows[f][key]['feature_mean']:.5f} +- {rows[f][key]['feature_std']:.5f}"
                         for f in feats))
    if "dummy" in res:
        lines.append(f"{'dummy (rigid)':16s} {'-':6s} {res['dummy']['trials']:6d} "
                     f"{res['dummy']['weight_n']:9.3f} " + " ".join(
                         f"{res['features'][f]['dummy']['feature_mean']:.5f} +- "
                         f"{res['features'][f]['dummy']['feature_std']:.5f}" for f in feats))
    for e in res["errors"]:
        lines.append(f"error in {e['trial']}: {e['error']}")
    return "\n".join(lines)


def _show_one(name: str, *, seed: int, meshcat, html_out) -> None:
    """One roll of ``name`` drawn in Meshcat (and recorded)."""
    from pydrake.geometry import MeshcatVisualizer
    from pydrake.systems.analysis import Simulator

    from mmlearn.diagrams.tactile.liquid_roll import (LiquidRollConfig, MakeLiquidRollDiagram,
                                                      make_instance)

    inst = make_instance(name, np.random.default_rng([int(seed), 17]))
    cfg = LiquidRollConfig(seed=int(seed), grasp_height=inst.height / 2, roll_cycles=1.0)
    diagram, _ = MakeLiquidRollDiagram(cfg, container=inst, meshcat=meshcat)
    vis = next(s for s in diagram.GetSystems() if isinstance(s, MeshcatVisualizer))
    vis.StartRecording(False)
    sim = Simulator(diagram)
    sim.AdvanceTo(cfg.duration)
    vis.PublishRecording()
    if html_out:
        from mmlearn.apps.common.cli import save_html

        save_html(meshcat, html_out)


def _config(args) -> LiquidDetectionConfig:
    """The run's settings from the command line (checked)."""
    from mmlearn.diagrams.tactile.liquid_roll import LIQUID_CONTAINERS

    if args.names is not None:
        names = tuple(args.names)
    else:
        if args.containers > len(LIQUID_CONTAINERS):
            raise UsageError(f"--containers: at most {len(LIQUID_CONTAINERS)}, got "
                             f"{args.containers}")
        names = tuple(list(LIQUID_CONTAINERS)[:args.containers])
    cfg = LiquidDetectionConfig(
        containers=names, trials=args.trials, dummy=not args.no_dummy,
        with_weight=args.with_weight, roll_cycles=args.roll_cycles,
        roll_profile=args.roll_profile, feature=args.feature, coast_delay=args.coast_delay,
        folds=args.folds, seed=args.seed, plot=args.plot, progress=args.progress)
    try:
        _check(cfg)
    except ValueError as e:
        raise UsageError(str(e)) from None
    return cfg


class LiquidDetection(Experiment):
    """The command line (:mod:`mmlearn.apps.common.experiment`)."""

    name = "liquid_detection"
    trials = (liquid_roll_trial,)
    description = ("Detect liquid in a grasped container by rolling it (thesis Sec. 7.3): "
                   "5 Hz high-pass of the taxels, spread of their norm, decision tree, "
                   "10-fold CV. Exit status: 0 success, 1 a trial raised, 2 bad input, "
                   "130 interrupted.")
    seed_help = "seed of the trials and folds"
    json_help = "print results as one JSON object"
    desc = "rolls"
    viewer = None  # the Meshcat of --meshcat / --html-out, once shown

    def add_arguments(self, ap):
        from mmlearn.diagrams.tactile.liquid_roll import LIQUID_CONTAINERS

        ap.add_argument("--with-weight", action="store_true",
                        help="the weight from the wrist force sensor as a second feature")
        ap.add_argument("--containers", type=pos_int, default=4, metavar="N",
                        help=f"roll the first N containers of the list "
                             f"({', '.join(LIQUID_CONTAINERS)}; default 4, all "
                             f"{len(LIQUID_CONTAINERS)} for the full experiment)")
        ap.add_argument("--names", type=name_list(list(LIQUID_CONTAINERS)), default=None,
                        help="comma-separated container names instead of --containers")
        ap.add_argument("--trials", type=pos_int, default=3,
                        help="trials per container (default 3; the thesis had 5)")
        ap.add_argument("--no-dummy", action="store_true", help="leave out the rigid dummy")
        ap.add_argument("--roll-cycles", type=pos_float, default=2.0,
                        help="roll cycles per trial at 0.6 Hz (default 2)")
        ap.add_argument("--roll-profile", choices=("sweep", "sine", "triangle"),
                        default="sweep",
                        help="the wrist's roll: sweep (default: constant rate, smooth 0.25 s "
                             "reversals), sine, or triangle (abrupt reversals, the earlier "
                             "roll)")
        ap.add_argument("--feature", choices=("coast_detrended", "coast", "whole"),
                        default="coast_detrended",
                        help="the tactile feature the rate, table and dummy use: "
                             "coast_detrended (default: the spread of the high-passed taxel "
                             "norm about its slow trend within each constant-rate phase of the "
                             "roll), coast (its plain spread over those phases) or whole (over "
                             "the whole roll, thesis Eq. 7.11); all are reported")
        ap.add_argument("--coast-delay", type=float, default=COAST_DELAY, metavar="S",
                        help=f"coast samples start S s after each change of the commanded roll "
                             f"rate ends (0 <= S < 0.3; default {COAST_DELAY:g})")
        ap.add_argument("--folds", type=pos_int, default=10, help="CV folds (default 10)")
        ap.add_argument("--plot", metavar="FILE", default=None,
                        help="write Fig. 7.11 and the per-container features as an image")
        ap.add_argument("--meshcat", action="store_true",
                        help="also show one roll (the first container) live in Meshcat")
        ap.add_argument("--html-out", metavar="FILE", default=None,
                        help="also record one roll (the first container) as Meshcat HTML")
        ap.add_argument("--progress", action="store_true", help="progress bar of the trials")

    def check(self, args):
        from mmlearn.apps.common.sweep import report_only_lines

        args.config = _config(args)
        check_out_file("--plot", args.plot)
        check_out_file("--html-out", args.html_out)
        args.lines = report_only_lines(args, simulates="a roll", trials=self.trials)

    def specs(self, args):
        if args.meshcat or args.html_out:  # one roll shown before the trials run
            self.show(args)
        return _specs(args.config)

    def show_progress(self, args) -> bool:
        return args.progress

    def report(self, lines, args):
        return report(lines, args.config)

    def finish(self, res, args):
        if args.report_only:
            if args.plot:
                plot_report(args.lines, res, args.plot)
            return report_only_result(res, args.report_only)
        if args.plot:
            plot_report(args.lines_run, res, args.plot)
        return json_clean(res)

    def attach_sweep(self, res, sweep, args):
        res["sweep"] = sweep.summary()
        args.lines_run = sweep.lines

    def show(self, args):
        """One roll of the first container drawn in Meshcat (and recorded) before the trials."""
        from mmlearn.apps.common.cli import make_meshcat

        self.viewer = make_meshcat(announce=args.meshcat)
        self.viewing = {"html_out": args.html_out, "live": args.meshcat}
        _show_one(args.config.containers[0], seed=args.seed, meshcat=self.viewer,
                  html_out=args.html_out)

    def print_table(self, res, args):
        print(format_report(res))
        if args.plot:
            print(f"plot written to {args.plot}")

    def to_json(self, res):
        return json.dumps(res, indent=1)


def main(argv=None) -> int:
    app = LiquidDetection()
    rc = experiment.main(app, argv)
    if app.viewer is not None:
        from mmlearn.apps.common.cli import finish_viewing

        finish_viewing(**app.viewing)
    return rc


if __name__ == "__main__":
    sys.exit(main())
