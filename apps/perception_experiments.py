"""The experiments of thesis Sec. 5.2 on the simulated kitchen: marker-less detection of a
drawer and a door in noisy depth images, their tracks and the learned articulation models.

    python -m mmlearn.apps.perception_experiments [--quick] [--seeds 10] [--seed 1000] \\
        [--frames 60] [--only distance,angle] [--distances 0.8,1.3] [--angles=0,30] \\
        [--out-dir DIR] [--jobs 2] [--json] [--results R.jsonl] [--report-only R.jsonl]

Every trial is one :func:`mmlearn.diagrams.perception.trials.fronts_trial` (the kitchen
scene, the drawer or the door opening in steps, ``--frames`` camera frames over the opening,
FrontDetector -> FrontTracker -> link model), run through the sweep runner
(``mmlearn.apps.common.sweep``: streamed to a JSON Lines results file, resumable, ``--jobs``
processes). The report (tables, plots in
``--out-dir``) is redrawn from that file by ``--report-only``.

Experiments:

* ``distance`` (thesis Fig. 5.8): drawer and door straight in front of the camera at 0.8,
  1.3, 1.8, 2.3, 2.8 m (quick: 1.0, 2.0; ``--distances`` for others), ``--seeds`` runs each:
  detection rate (all frames, and the target measure: the eligible frames, in which the
  front is wholly in view at < 70 deg incidence, closed fronts included, see track_fronts),
  position and orientation error of the found front against the true pose;
* ``angle``: the same at 1.5 m, 0, 15, 30, 45 deg off the front's normal (quick: 0, 30;
  ``--angles`` for others);
* the model selection (thesis Figs. 5.9 / 5.10) and the time per stage (thesis: 0.845 s
  planes, 0.008 s masks, 0.010 s sampling, 0.313 s optimisation, 0.0023 s check, on one 2 GHz
  core) are read from the runs of both experiments: for every run the moving front's track
  (the published track with most observations matching the true front) is fitted on its
  first n observations, n = 3 ... all, and the selection and the error of the selected model
  in predicting the later observations are recorded (thesis: rigid for the first ~10
  observations, right after 30; prediction errors 0.01 m / 7 deg drawer, 0.01 m / 3.5 deg
  door).

Timings: wall-clock medians per frame of the whole detector and of each stage, measured
inside the FrontDetector while the trials run (``--jobs`` processes on a shared machine:
inflated by the load), and the median CPU time of the whole detector per frame (one thread,
one BLAS thread), which the "< 100 ms per frame on one core" target is checked against.
"""

import argparse
import sys
from pathlib import Path

import numpy as np

from mmlearn.apps.common import experiment
from mmlearn.apps.common.cli import UsageError, check_out_dir, float_list, name_list, pos_int, \
    save_figure
from mmlearn.apps.common.experiment import Experiment, errors_of
from mmlearn.apps.common.sweep import TrialSpec
from mmlearn.diagrams.perception.trials import fronts_trial
from mmlearn.models.perception.evaluation import (FRONT_OBJECTS, PREDICTION_N, TARGET_DETECTION,
                                                  TARGET_DISTANCE_M, TARGET_MS,
                                                  TARGET_ORIENT_DEG, TARGET_POS_M,
                                                  THESIS_STAGE_S, fronts_report)

__all__ = ["EXPERIMENTS", "trial_specs", "report", "format_report", "run", "main",
           "THESIS_STAGE_S"]

EXPERIMENTS = ("distance", "angle")
OBJECTS = FRONT_OBJECTS
DISTANCES = (0.8, 1.3, 1.8, 2.3, 2.8)
ANGLES = (0.0, 15.0, 30.0, 45.0)
QUICK_DISTANCES = (1.0, 2.0)
QUICK_ANGLES = (0.0, 30.0)
ANGLE_DISTANCE = 1.5


def trial_specs(*, only=EXPERIMENTS, quick: bool = False, seed: int = 1000, seeds: int = 10,
                frames: int = 60, objects=OBJECTS, distances=None, angles=None,
                temporal_filter: bool = True, camera_rate_hz: float = 30.0,
                plane_method: str = "ransac") -> list:
    """One spec per (experiment, object, distance or angle, seed); ``distances`` (m) and
    ``angles`` (deg, at 1.5 m) replace the default grids when given; ``plane_method``: the
    detector's plane stage (``FrontDetectorConfig.plane_method``)."""
    fn = fronts_trial
    specs = []
    for exp in only:
        if exp == "distance":
            grid = [(d, 0.0) for d in (distances if distances is not None
                                       else QUICK_DISTANCES if quick else DISTANCES)]
        elif exp == "angle":
            grid = [(ANGLE_DISTANCE, a) for a in (angles if angles is not None
                                                  else QUICK_ANGLES if quick else ANGLES)]
        else:
            raise ValueError(f"unknown experiment {exp!r}; choose from {', '.join(EXPERIMENTS)}")
        for j in range(seeds):  # seeds outermost: an interrupted sweep covers every setting
            for obj in objects:
                for d, a in grid:
                    specs.append(TrialSpec(
                        fn=fn, seed=seed + j,
                        label=f"{exp} {obj} {d:.1f} m {a:+.0f} deg seed {seed + j}",
                        params={"experiment": exp, "object": obj, "distance": float(d),
                                "angle": float(a), "frames": int(frames),
                                **({"camera_rate_hz": float(camera_rate_hz)} if temporal_filter
                                   else {"temporal_filter": False}),
                                **({} if plane_method == "ransac"
                                   else {"plane_method": plane_method})}))
    return specs


def _fmt(v, f):
    return "   n/a" if v is None else format(v, f)


def report(lines: list[dict]) -> dict:
    """The results from results-file lines (a run or ``--report-only``):
    :func:`~mmlearn.models.perception.evaluation.fronts_report` and the trials that raised."""
    res = fronts_report(lines)
    res["errors"] = errors_of(lines)
    return res


def _rows_table(exp: str, rows: list[dict]) -> str:
    kname, unit = {"distance": ("distance", "m"), "angle": ("angle", "deg")}[exp]
    t = [f"{exp}: detection and pose error of the moving front (mean over runs; "
         "vis = wholly in view (thesis 5.2.1); elig = in view at < 70 deg incidence, "
         "closed fronts included: the target measure; open = the eligible frames with the "
         "front out of the cabinet face by >= 0.02 m)",
         f"  object {kname:>8s} runs  det.all  det.vis  det.elig (min)  det.open  "
         "pos err m   orient deg  right  right-from  ms/frame"]
    for r in rows:
        t.append(f"  {r['object']:6s} {r[kname]:6.1f}{unit:>3s} {r['runs']:3d}  "
                 f"{_fmt(r['detection_rate'], '7.2f')}  "
                 f"{_fmt(r['detection_rate_visible'], '7.2f')}  "
                 f"{_fmt(r['detection_rate_eligible'], '6.2f')} "
                 f"({_fmt(r['detection_rate_eligible_min'], '4.2f')})  "
                 f"{_fmt(r['detection_rate_eligible_open'], '7.2f')}   "
                 f"{_fmt(r['pos_error_m'], '.4f')}     {_fmt(r['orient_error_deg'], '5.2f')}  "
                 f"    {r['model_right']:2d}/{r['runs']:<2d} "
                 f"{_fmt(r['model_right_from'], '6.1f')}"
                 f"      {_fmt(r['ms_per_frame'], '6.0f')}")
    return "\n".join(t)


def _selection_table(sel: dict) -> str:
    t = ["model selection on the moving front's track against the number of observations "
         "n (share of runs; thesis: rigid for the first ~10, right after 30)"]
    for obj, s in sel.items():
        t.append(f"  {obj}: right in the end in {s['right_in_the_end']}/{s['runs_total']} "
                 f"runs, right from n = {_fmt(s['model_right_from_mean'], '.1f')} on average"
                 f" (at most {s['model_right_from_max']}); prediction error of the model "
                 f"from n = {PREDICTION_N} (or N - 5): "
                 f"{_fmt(s['prediction_pos_error_m'], '.4f')} m / "
                 f"{_fmt(s['prediction_orient_error_deg'], '.2f')} deg (thesis: "
                 f"{'0.01 m / 7 deg' if obj == 'drawer' else '0.01 m / 3.5 deg'})")
        for n in (3, 5, 10, 15, 20, 30, 40, 50):
            if n in s["n"]:
                i = s["n"].index(n)
                if not s["runs"][i]:
                    continue
                t.append(f"    n = {n:2d} ({s['runs'][i]:3d} runs): " + ", ".join(
                    f"{m} {_fmt(v[i], '.2f')}" for m, v in s["share"].items()))
    return "\n".join(t)


def _timing_table(tim: dict) -> str:
    t = ["time per stage (median per frame, ms, mean over runs) vs the thesis (one 2 GHz "
         "core; masks per plane, sampling per candidate)"]
    for s, v in tim["stage_ms"].items():
        t.append(f"  {s:13s} {_fmt(v, '8.1f')}   thesis {tim['thesis_stage_ms'][s]:8.1f}")
    t.append(f"  whole detector {_fmt(tim['ms_per_frame'], '7.1f')} ms per frame wall "
             f"(worst run {_fmt(tim['ms_per_frame_max'], '.1f')}), CPU "
             f"{_fmt(tim['cpu_ms_per_frame'], '.1f')} ms (worst run "
             f"{_fmt(tim['cpu_ms_per_frame_max'], '.1f')}); thesis ~1200 ms")
    return "\n".join(t)


def _targets_table(tg: dict) -> str:
    def met(ok):
        return "met" if ok else "NOT met"

    t = [f"targets (distance runs up to {TARGET_DISTANCE_M} m)"]
    for obj in OBJECTS:
        if obj in tg:
            g = tg[obj]
            t.append(f"  {obj}: detection >= {TARGET_DETECTION:.0%} at every distance: "
                     "all frames "
                     f"{_fmt(g['detection_rate_all_frames_worst_distance'], '.2f')}"
                     f" ({met(g['detection_met_all_frames'])}), "
                     "in view at < 70 deg (the target measure) "
                     f"{_fmt(g['detection_rate_eligible_worst_distance'], '.2f')}"
                     f" ({met(g['detection_met_eligible'])}); "
                     f"pos {_fmt(g['pos_error_m'], '.4f')} m ({met(g['pos_met'])}); orient "
                     f"{_fmt(g['orient_error_deg'], '.2f')} deg ({met(g['orient_met'])}); "
                     f"model right {g['model_right']} ({met(g['model_met'])}); "
                     f"{g['seeds_per_distance']} seeds per distance")
    if "ms_met" in tg:
        t.append(f"  whole detector < {TARGET_MS:.0f} ms on one core: CPU time per "
                 f"frame, median of runs {tg['cpu_ms_per_frame_median_of_runs']:.1f} ms,"
                 f" worst run {tg['cpu_ms_per_frame_worst_run']:.1f} ms "
                 f"({met(tg['ms_met'])}); wall clock while the "
                 f"trials ran: median {tg['ms_per_frame_median_of_runs']:.1f} ms")
    return "\n".join(t)


def format_report(res: dict) -> str:
    """The tables of :func:`report`'s result, one block per experiment, the model selection,
    the timing and the targets, then the trials that raised."""
    text = [_rows_table(exp, res[exp]["rows"]) for exp in EXPERIMENTS if exp in res]
    for key, table in (("selection", _selection_table), ("timing", _timing_table),
                       ("targets", _targets_table)):
        if key in res:
            text.append(table(res[key]))
    text += [f"error: trial {e['trial']} raised {e['error']} (left out above)"
             for e in res["errors"]]
    return "\n\n".join(text) + "\n"


def _plots(res, out) -> list:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for exp, key, label in (("distance", "distance", "distance to the camera [m]"),
                            ("angle", "angle", "angle off the front's normal [deg]")):
        if exp not in res:
            continue
        rows = res[exp]["rows"]
        fig, (a1, a2, a3) = plt.subplots(3, 1, figsize=(6, 8), sharex=True)
        for obj, col in (("drawer", "tab:red"), ("door", "tab:blue")):
            rs = [r for r in rows if r["object"] == obj]
            if not rs:
                continue
            x = [r[key] for r in rs]

            def y(k):
                return np.array([np.nan if r[k] is None else r[k] for r in rs], float)

            a1.plot(x, y("detection_rate"), "o-", color=col, label=f"{obj}, all frames")
            a1.plot(x, y("detection_rate_eligible"), "s--", color=col,
                    label=f"{obj}, in view < 70 deg")
            a2.errorbar(x, y("pos_error_m"), yerr=y("pos_error_m_std"), fmt="o-", color=col,
                        label=obj, capsize=3)
            a3.errorbar(x, y("orient_error_deg"), yerr=y("orient_error_deg_std"), fmt="o-",
                        color=col, label=obj, capsize=3)
        a1.axhline(TARGET_DETECTION, color="0.5", lw=0.8, ls=":")
        a1.set_ylabel("detection rate")
        a1.set_ylim(0, 1.05)
        a1.legend(fontsize=7)
        a2.axhline(TARGET_POS_M, color="0.5", lw=0.8, ls=":")
        a2.set_ylabel("position error [m]")
        a2.legend(fontsize=7)
        a3.axhline(TARGET_ORIENT_DEG, color="0.5", lw=0.8, ls=":")
        a3.set_ylabel("orientation error [deg]")
        a3.set_xlabel(label)
        p = out / f"detection_vs_{exp}.png"
        save_figure(fig, p, dpi=100)
        plt.close(fig)
        written.append(str(p))
    for obj, s in res.get("selection", {}).items():
        fig, (a1, a2) = plt.subplots(2, 1, figsize=(6, 6), sharex=True)
        n = np.array(s["n"])
        for m, v in s["share"].items():
            a1.plot(n, [np.nan if x is None else x for x in v], label=m)
        a1.set_ylabel("share of runs selecting")
        a1.set_ylim(-0.02, 1.02)
        a1.legend(fontsize=7)
        a1.set_title(f"{obj}: model selection vs observations")
        a2.plot(n, [np.nan if x is None else x for x in s["heldout_pos_error_m"]], "k-",
                label="position [m]")
        a2.set_ylabel("prediction error [m]")
        a2.set_yscale("log")
        ax2 = a2.twinx()
        ax2.plot(n, [np.nan if x is None else x for x in s["heldout_orient_error_deg"]], "g--",
                 label="orientation [deg]")
        ax2.set_ylabel("prediction error [deg]", color="g")
        a2.set_xlabel("observations n")
        p = out / f"selection_{obj}.png"
        save_figure(fig, p, dpi=100)
        plt.close(fig)
        written.append(str(p))
    if "timing" in res:
        tim = res["timing"]
        st = list(THESIS_STAGE_S)
        fig, ax = plt.subplots(figsize=(6, 3))
        xs = np.arange(len(st))
        ax.bar(xs - 0.2, [tim["stage_ms"][s] or 0 for s in st], 0.4, label="this detector")
        ax.bar(xs + 0.2, [tim["thesis_stage_ms"][s] for s in st], 0.4, label="thesis")
        ax.set_xticks(xs, st)
        ax.set_yscale("log")
        ax.set_ylabel("ms")
        ax.legend()
        p = out / "time_per_stage.png"
        save_figure(fig, p, dpi=100)
        plt.close(fig)
        written.append(str(p))
    return written


def run(*, only=EXPERIMENTS, quick: bool = False, seed: int = 1000, seeds: int = 10,
        frames: int = 60, objects=OBJECTS, distances=None, angles=None, out: str | None = None,
        progress: bool = True, results: str | None = None, executor: str = "local",
        jobs: int | None = None, ray_address: str | None = None, temporal_filter: bool = True,
        camera_rate_hz: float = 30.0, plane_method: str = "ransac") -> dict:
    """Run the experiments through the sweep runner; returns the report's results (plus
    "plots" written to ``out`` and "sweep"). Bad settings raise ``ValueError``."""
    args = argparse.Namespace(
        only=only if isinstance(only, str) else ",".join(only), objects=list(objects),
        quick=quick, seed=seed, seeds=seeds, frames=frames, distances=distances,
        angles=angles, out_dir=out, no_progress=not progress,
        no_temporal_filter=not temporal_filter, camera_rate=camera_rate_hz,
        plane_method=plane_method, report_only=None)
    app = PerceptionExperiments()
    app.check(args)
    return experiment.run_experiment(app, args, results=results, executor=executor, jobs=jobs,
                                     ray_address=ray_address)


DESCRIPTION = (__doc__.split("\n\n")[0] + " Exit status: 0 every trial ran, 1 a trial raised "
               "an error, 2 bad input.")


class PerceptionExperiments(Experiment):
    """The command line (:mod:`mmlearn.apps.common.experiment`)."""

    name = "perception_experiments"
    trials = (fronts_trial,)
    description = DESCRIPTION
    seed_default = 1000
    seed_help = "first seed"
    json_help = "print JSON instead of tables"
    desc = "perception trials"

    def add_arguments(self, ap):
        ap.add_argument("--only", default=",".join(EXPERIMENTS),
                        help="comma-separated experiments: distance, angle (default: both)")
        ap.add_argument("--objects", type=name_list(list(OBJECTS)), default=list(OBJECTS),
                        help="comma-separated moving fronts (default: drawer,door)")
        ap.add_argument("--quick", action="store_true",
                        help="small setting: 1 seed, 16 frames, 2 distances / angles")
        ap.add_argument("--seeds", type=pos_int, default=10, help="runs per setting")
        ap.add_argument("--frames", type=pos_int, default=60,
                        help="camera frames per run (thesis: ~60 images per log)")
        ap.add_argument("--no-temporal-filter", action="store_true",
                        help="no DepthTemporalFilter between camera and detector (each frame "
                             "on its own)")
        ap.add_argument("--camera-rate", type=float, default=30.0,
                        help="camera frames per second with the temporal filter, Hz (default "
                             "30; 0 = one frame per detector period, as before)")
        ap.add_argument("--plane-method", choices=("ransac", "cells"), default="ransac",
                        help="the detector's plane stage: sequential RANSAC (default) or the "
                             "cell grid of the organised image (FrontDetectorConfig."
                             "plane_method)")
        ap.add_argument("--distances", type=float_list, default=None,
                        help="comma-separated camera distances of the distance experiment, m "
                             "(default 0.8,1.3,1.8,2.3,2.8)")
        ap.add_argument("--angles", type=float_list, default=None,
                        help="comma-separated angles off the normal of the angle experiment, "
                             "deg, at 1.5 m (default 0,15,30,45; --angles=-30,0 for a minus)")
        ap.add_argument("--out-dir", default=None,
                        help="folder for the plots (PNG) and the default results file")
        ap.add_argument("--no-progress", action="store_true", help="no progress bars")

    def check(self, args):
        check_out_dir("--out-dir", args.out_dir)
        only = [x.strip() for x in args.only.split(",") if x.strip()]
        bad = [x for x in only if x not in EXPERIMENTS]
        if bad or not only:
            raise UsageError(f"--only: unknown experiment {bad[0] if bad else args.only!r}; "
                             "choose from " + ", ".join(EXPERIMENTS))
        if not args.objects or set(args.objects) - set(OBJECTS):
            raise UsageError(f"--objects: expected some of {', '.join(OBJECTS)}, got "
                             f"{args.objects!r}")
        if args.frames < 5:
            raise UsageError(f"--frames must be >= 5, got {args.frames}")
        if not (np.isfinite(args.camera_rate) and args.camera_rate >= 0):
            raise UsageError(f"--camera-rate must be a finite number >= 0 Hz, got "
                             f"{args.camera_rate}")
        if args.distances is not None and not (
                args.distances and all(np.isfinite(x) and x > 0.2 for x in args.distances)):
            raise UsageError(f"--distances must all be > 0.2 m, got {args.distances}")
        if args.angles is not None and not (
                args.angles and all(np.isfinite(x) and abs(x) < 80 for x in args.angles)):
            raise UsageError(f"--angles must all be within +-80 deg, got {args.angles}")
        args.experiments = only

    def specs(self, args):
        seeds, frames = (min(args.seeds, 1), min(args.frames, 16)) if args.quick else \
            (args.seeds, args.frames)
        return trial_specs(only=args.experiments, quick=args.quick, seed=args.seed,
                           seeds=seeds, frames=frames, objects=args.objects,
                           distances=args.distances, angles=args.angles,
                           temporal_filter=not args.no_temporal_filter,
                           camera_rate_hz=args.camera_rate, plane_method=args.plane_method)

    def show_progress(self, args) -> bool:
        return not args.no_progress

    def report(self, lines, args):
        try:
            return report(lines)
        except (ValueError, KeyError, TypeError) as e:
            if not args.report_only:
                raise
            raise ValueError(repr(e)) from None  # a file the report cannot read

    def finish(self, res, args):
        if args.out_dir:
            res["plots"] = _plots(res, args.out_dir)
        return res

    def print_table(self, res, args):
        print(format_report(res), flush=True)
        if res.get("plots"):
            print("plots: " + ", ".join(res["plots"]))


def main(argv=None) -> int:
    return experiment.main(PerceptionExperiments(), argv)


if __name__ == "__main__":
    sys.exit(main())
