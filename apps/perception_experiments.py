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

__all__ = ["EXPERIMENTS", "trial_specs", "report", "format_report", "run", "main",
           "THESIS_STAGE_S"]

EXPERIMENTS = ("distance", "angle")
OBJECTS = ("drawer", "door")
DISTANCES = (0.8, 1.3, 1.8, 2.3, 2.8)
ANGLES = (0.0, 15.0, 30.0, 45.0)
QUICK_DISTANCES = (1.0, 2.0)
QUICK_ANGLES = (0.0, 30.0)
ANGLE_DISTANCE = 1.5
#: thesis Sec. 5.2.2, seconds on one 2 GHz Pentium core (masks: per plane; sampling: per
#: candidate; the others per frame)
THESIS_STAGE_S = {"planes": 0.845, "masks": 0.008, "sampling": 0.010, "optimisation": 0.313,
                  "check": 0.0023}
#: targets of the front perception (detection rate, distance, errors, time per frame)
TARGET_DETECTION, TARGET_DISTANCE_M, TARGET_POS_M, TARGET_ORIENT_DEG, TARGET_MS = (
    0.90, 2.3, 0.01, 2.0, 100.0)
PREDICTION_N = 30


def trial_specs(*, only=EXPERIMENTS, quick: bool = False, seed: int = 1000, seeds: int = 10,
                frames: int = 60, objects=OBJECTS, distances=None, angles=None,
                temporal_filter: bool = True, camera_rate_hz: float = 30.0) -> list:
    """One spec per (experiment, object, distance or angle, seed); ``distances`` (m) and
    ``angles`` (deg, at 1.5 m) replace the default grids when given."""
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
                                   else {"temporal_filter": False})}))
    return specs


def _mean(v):
    v = [x for x in v if x is not None and np.isfinite(x)]
    return float(np.mean(v)) if v else None


def _std(v):
    v = [x for x in v if x is not None and np.isfinite(x)]
    return float(np.std(v)) if v else None


def _group(recs, key):
    """Rows per (object, key value) with means and standard deviations over the runs."""
    rows = []
    for obj in OBJECTS:
        vals = sorted({r[key] for r in recs if r["object"] == obj})
        for v in vals:
            rs = [r for r in recs if r["object"] == obj and r[key] == v]
            rows.append({
                "object": obj, key: v, "runs": len(rs),
                "detection_rate": _mean([r["detection_rate"] for r in rs]),
                "detection_rate_std": _std([r["detection_rate"] for r in rs]),
                "detection_rate_visible": _mean([r.get("detection_rate_visible") for r in rs]),
                "detection_rate_eligible": _mean([r["detection_rate_eligible"] for r in rs]),
                "detection_rate_eligible_open": _mean([r.get("detection_rate_eligible_open")
                                                       for r in rs]),
                "detection_rate_eligible_min": (min(r["detection_rate_eligible"] for r in rs
                                                    if r["detection_rate_eligible"] is not None)
                                                if any(r["detection_rate_eligible"] is not None
                                                       for r in rs) else None),
                "pos_error_m": _mean([r["pos_error_m"] for r in rs]),
                "pos_error_m_std": _std([r["pos_error_m"] for r in rs]),
                "orient_error_deg": _mean([r["orient_error_deg"] for r in rs]),
                "orient_error_deg_std": _std([r["orient_error_deg"] for r in rs]),
                "model_right": sum(bool(r["model_right"]) for r in rs),
                "selected": {m: sum(r["selected_model"] == m for r in rs)
                             for m in sorted({str(r["selected_model"]) for r in rs})},
                "model_right_from": _mean([r["model_right_from"] for r in rs]),
                "ms_per_frame": _mean([r["ms_per_frame"] for r in rs]),
            })
    return rows


def _selection(recs):
    """Per object: share of runs selecting each model on the first n observations, and the
    mean held-out prediction error of the selected model, against n."""
    out = {}
    for obj in OBJECTS:
        rs = [r for r in recs if r["object"] == obj and r.get("selection_vs_n")]
        if not rs:
            continue
        n_max = max(max(r["selection_vs_n"]["n"]) for r in rs)
        ns = list(range(3, n_max + 1))
        share = {m: [] for m in ("rigid", "prismatic", "revolute", "gp")}
        ep, eo, runs_at = [], [], []
        for n in ns:
            sel, a, b = [], [], []
            for r in rs:
                s = r["selection_vs_n"]
                if n in s["n"]:
                    i = s["n"].index(n)
                    sel.append(s["selected"][i])
                    a.append(s["heldout_pos_error_m"][i])
                    b.append(s["heldout_orient_error_deg"][i])
            runs_at.append(len(sel))
            for m in share:
                share[m].append(sum(x == m for x in sel) / len(sel) if sel else None)
            ep.append(_mean(a))
            eo.append(_mean(b))
        # prediction error of the model learned from PREDICTION_N observations (or the
        # longest prefix leaving >= 5 later observations to predict)
        pe, oe, used = [], [], []
        for r in rs:
            s = r["selection_vs_n"]
            N = max(s["n"])
            n = min(PREDICTION_N, N - 5)
            if n < 3 or n not in s["n"]:
                continue
            i = s["n"].index(n)
            pe.append(s["heldout_pos_error_m"][i])
            oe.append(s["heldout_orient_error_deg"][i])
            used.append(n)
        out[obj] = {"n": ns, "runs": runs_at, "share": share, "heldout_pos_error_m": ep,
                    "heldout_orient_error_deg": eo,
                    "prediction_pos_error_m": _mean(pe), "prediction_orient_error_deg": _mean(oe),
                    "prediction_n": used,
                    "right_in_the_end": sum(bool(r["model_right"]) for r in rs),
                    "runs_total": len(rs),
                    "model_right_from_mean": _mean([r["model_right_from"] for r in rs]),
                    "model_right_from_max": (max(r["model_right_from"] for r in rs
                                                 if r["model_right_from"] is not None)
                                             if any(r["model_right_from"] is not None
                                                    for r in rs) else None)}
    return out


def _timing(recs):
    stages = {s: _mean([r["stage_ms"].get(s) for r in recs]) for s in THESIS_STAGE_S}
    return {"stage_ms": stages, "ms_per_frame": _mean([r["ms_per_frame"] for r in recs]),
            "cpu_ms_per_frame": _mean([r.get("cpu_ms_per_frame") for r in recs]),
            "cpu_ms_per_frame_max": max((r["cpu_ms_per_frame"] for r in recs
                                         if r.get("cpu_ms_per_frame") is not None),
                                        default=None),
            "ms_per_frame_max": max((r["ms_per_frame"] for r in recs
                                     if r["ms_per_frame"] is not None), default=None),
            "thesis_stage_ms": {k: 1e3 * v for k, v in THESIS_STAGE_S.items()}}


def _targets(dist_rows, recs):
    """The targets, each with its measured value and met / not met."""
    near = [r for r in recs if r["experiment"] == "distance"
            and r["distance_m"] <= TARGET_DISTANCE_M + 1e-9]
    out = {}
    for obj in OBJECTS:
        rs = [r for r in near if r["object"] == obj]
        if not rs:
            continue
        rows = [x for x in dist_rows if x["object"] == obj
                and x["distance"] <= TARGET_DISTANCE_M + 1e-9]
        worst_all = min(x["detection_rate"] for x in rows)
        el = [x["detection_rate_eligible"] for x in rows
              if x["detection_rate_eligible"] is not None]
        worst_el = min(el) if el else None
        pe = _mean([r["pos_error_m"] for r in rs])
        oe = _mean([r["orient_error_deg"] for r in rs])
        right = sum(bool(r["model_right"]) for r in rs)
        out[obj] = {
            "detection_rate_all_frames_worst_distance": worst_all,
            "detection_rate_eligible_worst_distance": worst_el,
            "detection_met_all_frames": worst_all >= TARGET_DETECTION,
            "detection_met_eligible": worst_el is not None and worst_el >= TARGET_DETECTION,
            "pos_error_m": pe, "pos_met": pe is not None and pe < TARGET_POS_M,
            "orient_error_deg": oe, "orient_met": oe is not None and oe < TARGET_ORIENT_DEG,
            "model_right": f"{right}/{len(rs)}", "model_met": right == len(rs),
            "seeds_per_distance": min(x["runs"] for x in rows)}
    ms = [r["ms_per_frame"] for r in recs if r["ms_per_frame"] is not None]
    if ms:
        out["ms_per_frame_median_of_runs"] = float(np.median(ms))
    cpu = [r.get("cpu_ms_per_frame") for r in recs if r.get("cpu_ms_per_frame") is not None]
    if cpu:
        out["cpu_ms_per_frame_median_of_runs"] = float(np.median(cpu))
        out["cpu_ms_per_frame_worst_run"] = float(np.max(cpu))
        out["ms_met"] = float(np.max(cpu)) < TARGET_MS
    return out


def _fmt(v, f):
    return "   n/a" if v is None else format(v, f)


def report(lines: list[dict]) -> dict:
    """The results from results-file lines (a run or ``--report-only``): per experiment its
    rows, the model selection, the timing and the targets, the trials that raised."""
    settings = {ln["spec"]["params"].get("frames") for ln in lines}
    if len(settings) > 1:
        raise ValueError(f"the results file mixes settings (frames {sorted(settings)}); use one "
                         "results file per setting")
    ok = [ln["record"] for ln in lines if ln.get("error") is None]
    res = {}
    for exp, key in (("distance", "distance_m"), ("angle", "angle_deg")):
        recs = [r for r in ok if r["experiment"] == exp]
        if not recs:
            continue
        rows = _group(recs, key)
        for r in rows:
            r[key.split("_")[0]] = r.pop(key)
        res[exp] = {"rows": rows}
    if ok:
        res["selection"] = _selection(ok)
        res["timing"] = _timing(ok)
        if "distance" in res:
            res["targets"] = _targets(res["distance"]["rows"], ok)
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
        camera_rate_hz: float = 30.0) -> dict:
    """Run the experiments through the sweep runner; returns the report's results (plus
    "plots" written to ``out`` and "sweep"). Bad settings raise ``ValueError``."""
    args = argparse.Namespace(
        only=only if isinstance(only, str) else ",".join(only), objects=list(objects),
        quick=quick, seed=seed, seeds=seeds, frames=frames, distances=distances,
        angles=angles, out_dir=out, no_progress=not progress,
        no_temporal_filter=not temporal_filter, camera_rate=camera_rate_hz, report_only=None)
    app = PerceptionExperiments()
    app.check(args)
    return experiment.run_experiment(app, args, results=results, executor=executor, jobs=jobs,
                                     ray_address=ray_address)


DESCRIPTION = (__doc__.split("\n\n")[0] + " Exit status: 0 every trial ran, 1 a trial raised "
               "an error, 2 bad input.")


class PerceptionExperiments(Experiment):
    """The command line (:mod:`mmlearn.apps.common.experiment`)."""

    name = "perception_experiments"
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
                           camera_rate_hz=args.camera_rate)

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
