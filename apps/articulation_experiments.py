"""Reproduce the thesis' synthetic articulation analysis (Sec. 4.4.4) and Table 4.2.

Usage::

    python -m mmlearn.apps.articulation_experiments [--runs 100] [--quick] [--seed 0]
        [--out-dir DIR] [--only noise,outliers,...] [--json]
        [--results FILE] [--executor local|ray] [--ray-address ADDR] [--jobs N]
    python -m mmlearn.apps.articulation_experiments --report-only RESULTS.jsonl [--out-dir DIR]

Experiments (ground truths: models/articulation/sim.py; rigid, prismatic and revolute
estimators on their own ground truth, the GP on the roll-up door, Fig. 4.19):

- ``noise``     (Fig. 4.20): sample error vs Gaussian noise sigma_pos, n = 100, gamma = 0.
- ``outliers``  (Fig. 4.21): sample error vs outlier ratio gamma, sigma = 0.01 m / 3 deg.
  By default each training sequence has exactly round(gamma n) outliers at random positions
  (the thesis generates "an observation sequence with outlier ratio gamma").
  ``--outliers bernoulli`` draws each observation as an outlier with probability gamma (the
  mixture of Eq. 4.13-4.15); then some runs have no more inliers than a minimal sample (1
  rigid, 2 prismatic, 3 revolute) and any minimal sample of outliers explains the data as
  well, so no estimator can find the model: at n = 100, gamma = 0.95 that is P(k <= 1) =
  3.7% of the rigid runs, each with an error of ~0.5 m (outliers fill a 1 m cube). The table
  therefore also gives the median, the mean over the identifiable runs and their share.
- ``gamma``     (Fig. 4.22): estimated vs true outlier ratio (same runs as ``outliers``).
- ``size``      (Fig. 4.23): sample error vs training size n, sigma = 0.05 m, gamma = 0.
- ``time``      (Fig. 4.24): fit time of each estimator vs n.
- ``bic_n``     (Fig. 4.25): BIC and selection vs n on the roll-up door, samples presented in
  the order of the configuration (vertical segment, quarter circle, horizontal segment).
- ``bic_noise`` (Fig. 4.26): BIC and selection vs the assumed noise, roll-up door, n = 50,
  true noise 0.002 m / 2 deg (assumed noise from the true level upwards).
- ``selection``: the observation-model variants of SELECTION_VARIANTS compared on
  real tracks (``--tracks``, default the copies in the repository's tests/data: Cody's
  drawers, doors and dishwasher, position-only, and the cosine-synth GP tracks; the expected
  joint is read from the file name) at assumed sigma_pos 0.005-0.1 m, on the simulated
  garage door of Table 4.2 (10 folds, n = 20) and on the outlier-ratio estimate of a
  revolute link with 30 % outliers (mean |estimated - true gamma|).
- ``table``     (Table 4.2): simulated microwave door and drawer (sigma 0.002 m / 2 deg) and
  garage door (0.05 m / 5 deg), 200 samples, 10 folds, n = 20 training samples per fold
  (microwave and drawer also with motion-capture-level true noise, 0.3 mm / 0.3 deg, under the
  same assumed 2 mm / 2 deg: the thesis' rows come from a motion capture studio, and its
  0.0003 m / 0.15 deg for the microwave is below what 20 samples with 2 mm / 2 deg noise allow);
  prediction errors of every candidate on the held-out samples (against the noisy
  observations, as on real data, and against the noise-free truth), gamma and the selection.
  The simulated garage door is the roll-up path scaled by 2.
  Measured (``--runs 10``; the observation model of models/articulation/link.py): garage door GP
  in 7/10 folds at seed 0 (8, 9, 9 at seeds 1-3; thesis: GP), microwave revolute and drawer
  prismatic in 10/10. Fig. 4.25: prismatic up to n = 20, revolute at 21-22, GP from 23
  (thesis: revolute 24-28, GP from 29).
  Fig. 4.26 deviates at high assumed noise: GP up to sigma 0.05, revolute 0.1-0.5, rigid at
  1.0 (thesis: GP up to 0.02, revolute to 0.2, rigid above): the configuration prior is the
  integral along the path, not n^-d, and charges less where the noise blurs the
  configurations (see models/articulation/link.py).

The *sample error* is the mean distance between noise-free test poses and their projection
f(f^-1(z)) onto the fitted model (thesis Sec. 4.4.4). Tables are printed; plots are written to
``--out-dir`` (PNG per experiment); ``--json`` prints all numbers as one JSON object.
``--quick`` uses 2 runs and small grids (seconds; used by the test suite).

The trials run through the sweep runner (``mmlearn.apps.common.sweep``; one trial: ``--runs``
fits of one model at one grid point, the fit times at one n, one run of Fig. 4.25 / 4.26,
one object of Table 4.2, one variant of ``selection``): in parallel processes (``--jobs``,
default all cores) or as Ray tasks (``--executor ray``), streamed to ``--results``
(default ``articulation_experiments_results.jsonl`` in ``--out-dir``); re-running the same
command resumes, ``--report-only FILE`` redraws the tables and plots from a results file.
Each trial has its own random stream (``_rng``: seed, experiment, model, grid point), so its
numbers do not depend on ``--jobs`` or on the other trials. Before the sweep runner one
stream ran through all experiments in turn: the numbers of a seed changed then, not the
conclusions (``--runs 10``, seed 0, old / new: the selections of Fig. 4.25 and 4.26, of
Table 4.2's microwave and drawer and on every real track identical; Table 4.2's garage door
GP in 9/10 / 7/10 folds; the sample errors within their run-to-run spread). Fit times
(Fig. 4.24) with several jobs on few cores include the other jobs' load.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from mmlearn.apps.common import experiment
from mmlearn.apps.common.cli import check_out_dir, name_list, pos_int, save_figure
from mmlearn.apps.common.experiment import Experiment
from mmlearn.models.articulation.evaluation import LINK_EXPERIMENTS as EXPERIMENTS
from mmlearn.models.articulation.evaluation import LINK_MODELS as MODELS
from mmlearn.models.articulation.evaluation import (SELECTION_VARIANTS, TABLE_OBJECTS,
                                                    link_experiment_trial,
                                                    link_experiments_report, link_grid,
                                                    selection_tracks, tracks_sha1)

__all__ = ["run", "main", "EXPERIMENTS"]


def trial_specs(*, only, runs: int, seed: int, quick: bool, exact: bool = True,
                tracks_sha1: str = "") -> list:
    """The sweep's trials of the experiments in ``only``: one per (model, grid point) of
    noise / outliers / size (``runs`` fits each), one per n of time, one per run of bic_n /
    bic_noise, one per object of Table 4.2, one per variant of selection."""
    from mmlearn.apps.common.sweep import TrialSpec

    fn = link_experiment_trial
    base = {"quick": quick, "runs": runs}
    specs = []

    def add(experiment, label, **p):
        specs.append(TrialSpec(fn=fn, seed=seed, label=f"{experiment} {label}",
                               params={**base, "experiment": experiment, **p}))

    exps = [e for e in EXPERIMENTS if e in only or (e == "outliers" and "gamma" in only)]
    for e in exps:
        if e in ("noise", "outliers", "size"):
            for m in MODELS:
                for i, x in enumerate(link_grid(e, quick)):
                    extra = {"exact": exact} if e == "outliers" else {}
                    add(e, f"{m} {x}", model=m, i=i, x=x, **extra)
        elif e == "time":
            for i, x in enumerate(link_grid(e, quick)):
                add(e, f"n {x}", i=i, x=x)
        elif e in ("bic_n", "bic_noise"):
            for r in range(1 if quick else max(1, runs // 10)):
                add(e, f"run {r}", i=r)
        elif e == "table":
            for i, obj in enumerate(TABLE_OBJECTS):
                add(e, obj[0], i=i)
        elif e == "selection":
            for i, v in enumerate(SELECTION_VARIANTS):
                add(e, f"variant {i}", i=i, tracks_sha1=tracks_sha1)
    return specs


def _nan(vs) -> list:
    return [np.nan if v is None else v for v in vs]


def _label(ax, xlabel, ylabel, title, *, logx=False, logy=False, title_size=None):
    if logx:
        ax.set_xscale("log")
    if logy:
        ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title, **({"fontsize": title_size} if title_size else {}))
    ax.legend(fontsize=7)


def _plot_noise(plt, r):
    fig, ax = plt.subplots(figsize=(5, 3.5))
    for m in MODELS:
        mu, sd = np.array(_nan(r["error_mean"][m])), np.array(_nan(r["error_std"][m]))
        ax.plot(r["sigma_pos"], mu, "o-", label=m)
        ax.fill_between(r["sigma_pos"], mu - sd, mu + sd, alpha=0.15)
    ax.plot(r["sigma_pos"], r["sigma_pos"], "k--", lw=0.8, label="noise level")
    _label(ax, "sigma_pos [m]", "sample error [m]", "Fig. 4.20: error vs Gaussian noise",
           logx=True, logy=True)
    return [(fig, "fig4_20_noise.png")]


def _plot_error_vs(plt, r, xk, xlabel, title, name):
    """Fig. 4.21 / 4.23: sample error against ``xk``, the noise level as a line."""
    fig, ax = plt.subplots(figsize=(5, 3.5))
    for m in MODELS:
        ax.plot(r[xk], _nan(r["error_mean"][m]), "o-", label=m)
    ax.axhline(r["sigma_pos"], color="k", ls="--", lw=0.8, label="noise level")
    _label(ax, xlabel, "sample error [m]", title, logy=True)
    return fig, name


def _plot_outliers(plt, r):
    figs = [_plot_error_vs(plt, r, "gamma", "outlier ratio gamma",
                           "Fig. 4.21: error vs outlier ratio", "fig4_21_outliers.png")]
    fig, ax = plt.subplots(figsize=(4.5, 4))
    for m in MODELS:
        ax.plot(_nan(r["gamma_true_mean"][m]), _nan(r["gamma_est_mean"][m]), "o-", label=m)
    ax.plot([0, 1], [0, 1], "k--", lw=0.8)
    _label(ax, "true gamma", "estimated gamma", "Fig. 4.22: estimated vs true outlier ratio")
    return figs + [(fig, "fig4_22_gamma.png")]


def _plot_size(plt, r):
    return [_plot_error_vs(plt, r, "n", "training size n", "Fig. 4.23: error vs training size",
                           "fig4_23_size.png")]


def _plot_time(plt, r):
    fig, ax = plt.subplots(figsize=(5, 3.5))
    for m in MODELS:
        ax.plot(r["n"], _nan(r["seconds"][m]), "o-", label=m)
    ax.plot(r["n"], _nan(r["all_four_seconds"]), "k-", label="all four")
    _label(ax, "training size n", "time [s]", "Fig. 4.24: fit time")
    return [(fig, "fig4_24_time.png")]


def _plot_bic(plt, r, key, xk, title, name):
    fig, ax = plt.subplots(figsize=(5.5, 3.8))
    for m in MODELS:
        ax.plot(r[xk], r["bic_mean"][m], ".-", label=m)
    _label(ax, xk, "BIC", title, logx=key == "bic_noise", title_size=9)
    return [(fig, name)]


def _plots(res, out_dir: Path):
    """The figures of the experiments in ``res`` as PNG files in ``out_dir``; their paths."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir.mkdir(parents=True, exist_ok=True)
    figs = []
    for key, draw in (("noise", _plot_noise), ("outliers", _plot_outliers),
                      ("size", _plot_size), ("time", _plot_time)):
        if key in res:
            figs += draw(plt, res[key])
    for key, xk, title, name in [("bic_n", "n", "Fig. 4.25: BIC vs n (roll-up door)",
                                  "fig4_25_bic_n.png"),
                                 ("bic_noise", "assumed_sigma_pos",
                                  "Fig. 4.26: BIC vs assumed noise (n = 50)",
                                  "fig4_26_bic_noise.png")]:
        if key in res:
            figs += _plot_bic(plt, res[key], key, xk, title, name)
    written = []
    for fig, name in figs:
        fig.tight_layout()
        save_figure(fig, out_dir / name, dpi=100)
        plt.close(fig)
        written.append(str(out_dir / name))
    return written


def _f(v, w, d):
    return " " * (w - 3) + "n/a" if v is None else f"{v:{w}.{d}f}"


def _print_failed(p, r, w):
    """The "failed" row under a table: runs whose fit raised, left out of the means."""
    for m in MODELS:
        p(f"{'  failed':9s} " + " ".join(f"{v:{w}d}" for v in r["failed"][m])
          + f"   ({m}: runs left out of the mean, of {r.get('runs_per_point', '?')})")


def _print_noise(p, r):
    p("\nFig. 4.20  sample error [m] vs Gaussian noise sigma_pos (n = 100, gamma = 0)")
    p("sigma_pos " + " ".join(f"{s:>9.3f}" for s in r["sigma_pos"]))
    for m in MODELS:
        p(f"{m:9s} " + " ".join("      n/a" if v is None else f"{v:9.4f}"
                                for v in r["error_mean"][m]))
    _print_failed(p, r, 9)


def _print_outliers(p, r):
    p(f"\nFig. 4.21  sample error [m] vs outlier ratio (sigma_pos = {r['sigma_pos']} m)")
    p("gamma     " + " ".join(f"{g:>7.2f}" for g in r["gamma"]))
    for m in MODELS:
        p(f"{m:9s} " + " ".join(_f(v, 7, 4) for v in r["error_mean"][m])
          + f"   below noise up to gamma = {r['below_noise_up_to'][m]}")
    _print_failed(p, r, 7)
    p("median error / mean error over runs with more inliers than a minimal sample / "
      "% runs with at most a minimal sample of inliers (unidentifiable)")
    for m in MODELS:
        p(f"{m:9s} " + " ".join(_f(v, 7, 4) for v in r["error_median"][m]))
        p(f"{'  ident.':9s} " + " ".join(_f(v, 7, 4)
                                         for v in r["error_mean_identifiable"][m]))
        p(f"{'  % unid.':9s} " + " ".join(_f(v, 7, 1)
                                          for v in r["unidentifiable_runs_pct"][m]))
    p("\nFig. 4.22  estimated gamma (mean) / mean |estimated - true|")
    for m in MODELS:
        p(f"{m:9s} " + " ".join(_f(v, 7, 3) for v in r["gamma_est_mean"][m]))
        p(f"{'  |dev|':9s} " + " ".join(_f(v, 7, 3) for v in r["gamma_abs_dev_mean"][m]))


def _print_size(p, r):
    p(f"\nFig. 4.23  sample error [m] vs training size (sigma_pos = {r['sigma_pos']} m)")
    p("n         " + " ".join(f"{n:>7d}" for n in r["n"]))
    for m in MODELS:
        p(f"{m:9s} " + " ".join("    n/a" if v is None else f"{v:7.4f}"
                                for v in r["error_mean"][m])
          + f"   below noise from n = {r['converged_n'][m]}")
    _print_failed(p, r, 7)


def _print_time(p, r):
    p("\nFig. 4.24  median fit time [ms] vs n")
    p("n         " + " ".join(f"{n:>7d}" for n in r["n"]))

    def ms(vs):
        return " ".join("    n/a" if v is None else f"{1e3 * v:7.1f}" for v in vs)

    for m in MODELS:
        p(f"{m:9s} " + ms(r["seconds"][m]))
    p(f"{'all four':9s} " + ms(r["all_four_seconds"]))


def _print_bic(p, r, xk, title):
    """Fig. 4.25 / 4.26: the selected model over the runs of ``xk`` values."""
    p(f"\n{title}")
    runs_ = []
    cur, start, prev = None, None, None
    for x, s in zip(r[xk], r["selected"]):
        if s != cur:
            if cur is not None:
                runs_.append(f"{cur} [{start}..{prev}]")
            cur, start = s, x
        prev = x
    runs_.append(f"{cur} [{start}..{prev}]")
    p("  " + ", ".join(runs_))
    nf = {m: int(sum(v)) for m, v in r.get("failed", {}).items() if sum(v)}
    p(f"  candidate fits that failed (left out of the BIC means and the selection), of "
      f"{r['runs'] * len(r[xk])}: " + (", ".join(f"{m} {c}" for m, c in nf.items())
                                      if nf else "none"))


def _print_selection(p, r):
    p(f"\nSelection on {sum(r['n_tracks'].values())} real tracks {r['n_tracks']}: right "
      "joint per assumed sigma_pos (prismatic / revolute / gp), tracks selected rigid; "
      "Table 4.2 garage door (n = 20) selections; mean |gamma - 0.3| of a revolute link")
    for v in r["variants"]:
        p(f"  {v['label']}")
        for s_ in r["sigma_pos"]:
            rr = v["real"][str(s_)]
            p(f"    sigma {s_:<6g} " + "  ".join(f"{k} {rr[k]}" for k in sorted(rr))
              + f"   rigid {v['rigid_at'][str(s_)]}"
              + f"   failed {v.get('failed_at', {}).get(str(s_), 0)}")
        p(f"    garage door {v['garage_n20']}   |gamma - 0.3| "
          f"{v['gamma_abs_dev_at_0.3']:.3f}")


def _print_table(p, table):
    p("\nTable 4.2  held-out prediction error (vs noisy obs. | vs truth), 10-fold, n = 20;"
      " a candidate whose fit failed in a fold is left out of that fold's mean (folds "
      "used / skipped)")
    for obj, r in table.items():
        p(f"{obj} (assumed sigma {r['sigma_pos']} m / {r['sigma_orient_deg']} deg, true "
          f"{r['true_sigma_pos']} m / {r['true_sigma_orient_deg']} deg), selected: "
          f"{r['selected_counts']}")
        for m in MODELS:
            a = r["models"].get(m, {})
            if not a.get("folds"):
                continue
            p(f"  {m:9s} pos {a['pos']:.4f} | {a['pos_true']:.4f} m   orient "
              f"{a['ori']:6.2f} | {a['ori_true']:6.2f} deg   gamma {a['gamma']:.3f}   "
              f"folds {a['folds']} / skipped {a['skipped_folds']}")
        for m in MODELS:
            a = r["models"].get(m, {})
            if not a.get("folds"):
                p(f"  {m:9s} fit failed in all {r['folds']} folds")


def _print(res, file=None):
    """Every table of the result, in the order of the thesis' figures."""
    def p(*a):
        print(*a, file=file or sys.stdout)

    for key, show in (("noise", _print_noise), ("outliers", _print_outliers),
                      ("size", _print_size), ("time", _print_time)):
        if key in res:
            show(p, res[key])
    for key, xk, title in [("bic_n", "n", "Fig. 4.25  selection vs n (roll-up door)"),
                           ("bic_noise", "assumed_sigma_pos",
                            "Fig. 4.26  selection vs assumed sigma_pos (roll-up door, n = 50)")]:
        if key in res:
            _print_bic(p, res[key], xk, title)
    if "selection" in res:
        _print_selection(p, res["selection"])
    if "table" in res:
        _print_table(p, res["table"])
    for e in res.get("errors", []):
        p(f"error: trial {e['trial']} raised {e['error']} (its runs count as failed above)")


class ArticulationExperiments(Experiment):
    name = "articulation_experiments"
    trials = (link_experiment_trial,)
    description = ("Synthetic robustness / convergence analysis of the articulation models "
                   "(thesis Sec. 4.4.4, Fig. 4.20-4.26) and Table 4.2. Every table gives the "
                   "number of failed runs (left out of its means). The trials run through "
                   "the sweep runner (resumable, local processes or Ray). Exit status: 0 "
                   "every trial ran, 1 a trial raised an error, 2 bad input.")
    json_help = "print all results as JSON"
    desc = "articulation trials"

    def __init__(self):
        self._tracks = {}

    def add_arguments(self, ap):
        ap.add_argument("--runs", type=pos_int, default=100, help="repetitions (thesis: 100)")
        ap.add_argument("--quick", action="store_true", help="2 runs, small grids (seconds)")
        ap.add_argument("--only", type=name_list(EXPERIMENTS), default=list(EXPERIMENTS),
                        help=f"comma-separated subset of {','.join(EXPERIMENTS)}")
        ap.add_argument("--out-dir", default="articulation_experiments_out",
                        help="folder for the plots and the default results file ('' for no "
                             "plots; the results file then goes to the current folder)")
        ap.add_argument("--outliers", choices=("exact", "bernoulli"), default="exact",
                        help="outlier sampling of Fig. 4.21/4.22: exactly round(gamma n) "
                             "outliers per sequence (default) or each observation with "
                             "probability gamma")
        ap.add_argument("--tracks", default=None,
                        help="real track files or folder for --only selection (default: the "
                             "repository's tests/data copies)")

    def check(self, args):
        check_out_dir("--out-dir", args.out_dir)

    def _only(self, args) -> list:
        only = args.only
        only = [o.strip() for o in (only.split(",") if isinstance(only, str) else only)]
        bad = [o for o in only if o not in EXPERIMENTS]
        if bad:
            raise ValueError(f"unknown experiment(s) {bad}; choose from {EXPERIMENTS}")
        return only

    def _selection(self, args):
        """The real tracks of ``selection`` (read once) and their SHA-1."""
        if "selection" not in self._only(args):
            return None, ""
        if "data" not in self._tracks:
            data = selection_tracks(args.tracks)
            self._tracks.update(data=data, sha1=tracks_sha1(data))
        return {"selection": self._tracks["data"]}, self._tracks["sha1"]

    def specs(self, args):
        if args.outliers not in ("exact", "bernoulli"):
            raise ValueError(f"outliers must be 'exact' or 'bernoulli', got {args.outliers!r}")
        runs = min(args.runs, 2) if args.quick else args.runs
        return trial_specs(only=self._only(args), runs=runs, seed=args.seed,
                           quick=args.quick, exact=(args.outliers == "exact"),
                           tracks_sha1=self._selection(args)[1])

    def shared(self, args):
        return self._selection(args)[0]

    def report(self, lines, args):
        if lines:
            return link_experiments_report(lines)
        return {"runs": min(args.runs, 2) if args.quick else args.runs, "seed": args.seed,
                "quick": args.quick, "errors": []}

    def finish(self, res, args):
        res["plots"] = _plots(res, Path(args.out_dir)) if args.out_dir else []
        return res

    def print_table(self, res, args):
        _print(res)
        if res["plots"]:
            print("\nplots: " + ", ".join(res["plots"]))

    def to_json(self, res):
        return json.dumps(res, indent=1, default=float)


def run(*, runs: int = 100, seed: int = 0, quick: bool = False, only=EXPERIMENTS,
        out_dir: str | None = "articulation_experiments_out", progress: bool = True,
        outliers: str = "exact", tracks: str | None = None, results: str | None = None,
        executor: str = "local", jobs: int | None = None,
        ray_address: str | None = None) -> dict:
    """Run the selected experiments; returns a dict of results (plus "plots": written
    files, "errors": trials that raised). ``outliers``: "exact" (exactly round(gamma n)
    outliers per training sequence) or "bernoulli" (each observation an outlier with
    probability gamma).

    The trials (:func:`trial_specs`) run through the sweep runner (``mmlearn.apps.common.sweep``):
    streamed to ``results`` (a JSON Lines file; None: a temporary one; trials already in it
    are not run again), ``executor`` "local" (``jobs`` processes, default all cores) or
    "ray" (``ray_address``: a cluster, None: a local Ray instance of ``jobs`` CPUs). The
    real tracks of ``selection`` are read here and sent once (``shared``)."""
    args = argparse.Namespace(runs=runs, seed=seed, quick=quick, only=only, out_dir=out_dir,
                              json=not progress, outliers=outliers, tracks=tracks)
    return experiment.run_experiment(ArticulationExperiments(), args, results=results,
                                     executor=executor, jobs=jobs, ray_address=ray_address)


def main(argv=None) -> int:
    return experiment.main(ArticulationExperiments(), argv)


if __name__ == "__main__":
    sys.exit(main())
