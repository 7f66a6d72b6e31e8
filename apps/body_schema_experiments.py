"""Body-schema experiments of thesis Sec. 3.4: Fig. 3.10, the noise-free accuracy, the 7-DOF
arm with an occluded part, Table 3.1 (recovery after failures) and Table 3.2 (control with a
bent link).

Where each runs:

* **Drake simulation** (the arm in a MultibodyPlant with implicit PD control, observed by
  the MarkerSensor; data gathered by motor babbling with the SchemaLearner in the loop;
  failures in the plant: JointBlocker / hidden locked joints):
  Fig. 3.10 (2-DOF, sigma 0.044 m; the schema is re-fitted on the first n Drake samples for
  each n; mean of ``--fig310-runs`` runs), the noise-free accuracy (2-DOF, 20 and 100
  samples), the 7-DOF 10-part arm with x4 occluded (noise-free accuracy, and the structure
  convergence with the sensor noise of Fig. 3.10 over ``--structure-runs`` runs),
  ``--drake-runs`` runs of Table 3.1 per failure (2-DOF arm: joint q2 blocked, tool changed;
  the schema is learned from scratch in block 1) and ``--drake-runs`` / 2 runs of Table 3.2
  (4-DOF arm, link x3 bent by 45 deg in the plant; the goal commands are solved on the
  learned model by the SchemaController's solver and the error is measured on the plant's
  kinematics at those commands).
* **numpy simulation** (:mod:`mmlearn.models.body_schema.kinematic_sim`) for the many-run statistics:
  Table 3.1 (7-DOF, ``--runs`` runs of 4 x 100 samples, engineered seed model) and
  Table 3.2 (4-DOF, 30 way points).

Prediction errors are measured on independent test configurations against the true
(noise-free) part poses, relative to the root part.

    python -m mmlearn.apps.body_schema_experiments --out-dir results/   # ~15-20 min
    python -m mmlearn.apps.body_schema_experiments --quick --json        # ~1 min CPU
        [--results FILE] [--executor local|ray] [--ray-address ADDR] [--jobs N]
    python -m mmlearn.apps.body_schema_experiments --report-only RESULTS.jsonl [--out-dir DIR]

Every run (of Fig. 3.10, the 7-DOF structure convergence, each table) is a trial of the
sweep runner (``mmlearn.apps.common.sweep``): run in parallel processes (``--jobs``, default all
cores) or as Ray tasks (``--executor ray``), streamed to ``--results`` (default
``body_schema_experiments_results.jsonl`` in ``--out-dir``); re-running the same command
resumes, ``--report-only FILE`` redraws the tables, the plot and the JSON from a results
file without running anything.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from mmlearn.apps.common import experiment
from mmlearn.apps.common.cli import atomic_write_text, check_out_dir, pos_int, save_figure
from mmlearn.apps.common.experiment import Experiment
from mmlearn.diagrams.body_schema.trials import body_schema_trial
from mmlearn.models.body_schema.evaluation import body_schema_report


def trial_specs(*, quick: bool = False, runs: int = 20, seed: int = 0, structure_runs: int = 5,
                drake_runs: int = 6, fig310_runs: int = 3) -> list:
    """The sweep's trials (one per run of every experiment), with the seeds of the
    experiments: Fig. 3.10 seed + 100 r, noise-free seed + 1, 7-DOF occluded seed + 2, 7-DOF
    structure seed + 10 + r, the tables seed + r."""
    from mmlearn.apps.common.sweep import TrialSpec

    fn = body_schema_trial

    def spec(block, r, s, label, **kw):
        return TrialSpec(fn=fn, seed=s, label=f"{label} run {r} seed {s}",
                         params={"block": block, "run": r, "quick": quick, "kwargs": kw})

    sizes = [5, 10, 15, 20] if quick else [5, 10, 15, 20, 30, 50, 100]
    specs = [spec("fig_3_10", r, seed + 100 * r, "Fig. 3.10", arm="2dof", noise=0.044,
                  sizes=sizes, n_test=30 if quick else 200, n_control=1 if quick else 20)
             for r in range(1 if quick else fig310_runs)]
    specs.append(spec("noise_free", 0, seed + 1, "noise-free 2-DOF", arm="2dof", noise=0.0,
                      sizes=[20] if quick else [20, 100], n_test=30 if quick else 60,
                      n_control=0))
    specs.append(spec("7dof_occluded", 0, seed + 2, "7-DOF occluded", arm="7dof", noise=0.0,
                      sizes=[15] if quick else [10, 15, 20, 50, 100],
                      n_test=20 if quick else 100, n_control=0, occlude=["x4"]))
    specs += [spec("7dof_structure", r, seed + 10 + r, "7-DOF structure", arm="7dof",
                   noise=0.044, sizes=[8, 10, 12] if quick else [8, 10, 12, 15, 20, 30],
                   n_test=10 if quick else 60, n_control=0, occlude=["x4"])
              for r in range(1 if quick else structure_runs)]
    nkw = dict(n_block=20) if quick else {}
    for failure, vis in (("joint", 0.919), ("tool", 0.790)):
        specs += [spec("table_3_1_numpy", r, seed + r, f"Table 3.1 numpy {failure}",
                       failure=failure, visibility=vis, **nkw)
                  for r in range(1 if quick else runs)]
    ckw = dict(n_learn=30, n_waypoints=6, n_adapt=40) if quick else {}
    specs += [spec("table_3_2_numpy", r, seed + r, "Table 3.2 numpy", **ckw)
              for r in range(max(1, (1 if quick else runs) // 4))]
    for failure in ("joint", "tool"):
        specs += [spec("table_3_1_drake", r, seed + r, f"Table 3.1 Drake {failure}",
                       failure=failure, n_block=10 if quick else 100, n_first=30)
                  for r in range(1 if quick else drake_runs)]
    specs += [spec("table_3_2_drake", r, seed + r, "Table 3.2 Drake",
                   n_learn=30 if quick else 100, n_adapt=30 if quick else 150,
                   n_waypoints=4 if quick else 30)
              for r in range(1 if quick else max(1, drake_runs // 2))]
    return specs


def _plot(fig310, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = [r for r in fig310["rows"] if "pred_error_m" in r]
    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    n = [r["n"] for r in rows]
    ax[0].plot(n, [r["pred_error_m"] for r in rows], "o-", label="prediction (learned model)")
    ax[0].axhline(fig310["obs_noise_m"], color="r", ls="--", label="observation noise")
    ax[0].set_xlabel("samples")
    ax[0].set_ylabel("mean position error [m]")
    ax[0].set_title("Fig. 3.10: 2-DOF, sigma 0.044 m (Drake)")
    ax[0].legend()
    if any("positioning_error_m" in r for r in rows):
        ax[1].plot(n, [r.get("positioning_error_m", np.nan) for r in rows], "s-")
    ax[1].set_xlabel("samples")
    ax[1].set_ylabel("positioning error [m]")
    ax[1].set_title("positioning by the learned model")
    for a in ax:
        a.set_xscale("log")
        a.grid(True, alpha=0.3)
    fig.tight_layout()
    save_figure(fig, path, dpi=100)
    plt.close(fig)


def write_outputs(res: dict, out_dir: str | Path) -> dict:
    """Fig. 3.10's plot and ``body_schema_experiments.json`` in ``out_dir``."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    res["plots"] = []
    if "fig_3_10" in res:
        _plot(res["fig_3_10"], out / "fig_3_10.png")
        res["plots"].append(str(out / "fig_3_10.png"))
    atomic_write_text(out / "body_schema_experiments.json", json.dumps(res, indent=1))
    return res


class BodySchemaExperiments(Experiment):
    name = "body_schema_experiments"
    trials = (body_schema_trial,)
    description = ("Reproduce the body-schema experiments of thesis Sec. 3.4 (Fig. 3.10, "
                   "noise-free accuracy, 7-DOF with an occluded part, Tables 3.1 and 3.2). "
                   "Learning runs in the Drake simulation; the many-run statistics of the "
                   "tables use the numpy simulation. Every mean says how many runs failed "
                   "and were left out. Every run is a trial of the sweep runner (resumable, "
                   "local processes or Ray). Exit status: 0 every trial ran, 1 a trial "
                   "raised an error, 2 bad input.")
    json_help = "print the results as JSON"
    desc = "body-schema runs"

    def add_arguments(self, ap):
        ap.add_argument("--quick", action="store_true",
                        help="one run of each, fewer samples (about a minute of CPU time)")
        ap.add_argument("--runs", type=pos_int, default=20,
                        help="numpy runs of Table 3.1 per failure, a quarter as many of Table "
                             "3.2 (20)")
        ap.add_argument("--structure-runs", type=pos_int, default=5,
                        help="Drake runs of the 7-DOF structure convergence (5)")
        ap.add_argument("--drake-runs", type=pos_int, default=6,
                        help="Drake runs of Table 3.1 per failure, half as many of Table 3.2 "
                             "(6)")
        ap.add_argument("--fig310-runs", type=pos_int, default=3,
                        help="Drake runs averaged in Fig. 3.10 (3)")
        ap.add_argument("--out-dir", type=Path, default=Path("."),
                        help="where plots, the JSON and the default results file go (default: "
                             "current directory)")

    def check(self, args):
        check_out_dir("--out-dir", args.out_dir)

    def specs(self, args):
        counts = (args.runs, args.structure_runs, args.drake_runs, args.fig310_runs)
        if min(counts) < 1:
            raise ValueError("runs, structure_runs, drake_runs and fig310_runs must be >= 1, "
                             "got " + ", ".join(map(str, counts)))
        return trial_specs(quick=args.quick, runs=args.runs, seed=args.seed,
                           structure_runs=args.structure_runs, drake_runs=args.drake_runs,
                           fig310_runs=args.fig310_runs)

    def report(self, lines, args):
        return body_schema_report(lines)

    def attach_sweep(self, res, sweep, args):
        res["seconds"] = sweep.wall_s
        res["sweep"] = sweep.summary()

    def finish(self, res, args):
        return write_outputs(res, args.out_dir)

    def print_table(self, res, args):
        print(format_report(res))

    def to_json(self, res):
        return json.dumps(res)


def run(*, quick: bool = False, runs: int = 20, seed: int = 0, out_dir: str | Path = ".",
        show_progress: bool = True, structure_runs: int = 5, drake_runs: int = 6,
        fig310_runs: int = 3, results: str | None = None, executor: str = "local",
        jobs: int | None = None, ray_address: str | None = None) -> dict:
    """Run every experiment; write ``fig_3_10.png`` and ``body_schema_experiments.json`` to
    ``out_dir``; return the results. ``runs``: numpy runs of Table 3.1 per failure (runs // 4
    of Table 3.2); ``structure_runs``: Drake runs of the 7-DOF structure convergence (sensor
    noise 0.044 m); ``drake_runs``: Drake runs of Table 3.1 per failure and drake_runs // 2
    of Table 3.2; ``fig310_runs``: Drake runs averaged in Fig. 3.10.

    Every run is a trial of the sweep runner (``mmlearn.apps.common.sweep``): streamed to
    ``results`` (a JSON Lines file; None: a temporary one; runs already in it are not run
    again), ``executor`` "local" (``jobs`` processes, default all cores) or "ray"
    (``ray_address``: a cluster, None: a local Ray instance of ``jobs`` CPUs)."""
    args = argparse.Namespace(quick=quick, runs=runs, seed=seed, out_dir=out_dir,
                              json=not show_progress, structure_runs=structure_runs,
                              drake_runs=drake_runs, fig310_runs=fig310_runs)
    return experiment.run_experiment(BodySchemaExperiments(), args, results=results,
                                     executor=executor, jobs=jobs, ray_address=ray_address)


def _runs(d) -> str:
    """"k runs" or "k runs, f failed" (failed runs are left out of the means)."""
    f = d.get("failed_runs", 0)
    return f"{d['runs']} runs" + (f", {f} failed: left out of the mean" if f else ", 0 failed")


_NAN = float("nan")


def _fig_3_10_lines(f) -> list[str]:
    nan = _NAN
    L = [f"Fig. 3.10 [Drake, mean of {f['runs']} runs] 2-DOF, sigma 0.044 m; "
         f"observation noise (mean position "
         f"error of a marker) {f['obs_noise_m']:.4f} m; online structure correct from "
         f"sample {f['online_converged_at_runs']}; "
         f"schema update median "
         f"{f['update_ms_median']:.2f} ms",
         "   n  structure  prediction [m]  [deg]  positioning [m]  runs in mean (left "
         "out: no complete schema / fit failed)"]
    for r in f["rows"]:
        L.append(f"{r['n']:4d}  {'correct' if r['correct'] else 'wrong  '}    "
                 f"{r.get('pred_error_m', nan):.4f}        "
                 f"{r.get('pred_error_deg', nan):.2f}   "
                 f"{r.get('positioning_error_m', nan):.4f}           "
                 f"{r.get('runs_in_mean', f['runs'])}/{f['runs']}")
    return L


def _accuracy_lines(title, d) -> list[str]:
    L = [f"{title} [Drake]:"]
    for r in d["rows"]:
        if "error" in r:
            L.append(f"  n={r['n']:3d}: fit failed ({r['error']})")
        elif "pred_error_m" not in r:
            L.append(f"  n={r['n']:3d}: structure {'correct' if r['correct'] else 'WRONG'},"
                     f" schema incomplete: no prediction error")
        else:
            L.append(f"  n={r['n']:3d}: structure "
                     f"{'correct' if r['correct'] else 'WRONG'}, error "
                     f"{1000 * r['pred_error_m']:.2f} mm / {r['pred_error_deg']:.3f} deg")
    return L


def _structure_line(st) -> str:
    cf = [d["correct_from"] for d in st]
    ok = [c for c in cf if c is not None]
    return (f"7-DOF, 10 parts, x4 occluded, sigma 0.044 m [Drake, {len(st)} runs]: "
            f"structure correct from n = {cf} (median "
            f"{'n/a' if not ok else f'{float(np.median(ok)):g}'} over {len(ok)} runs; "
            f"{len(cf) - len(ok)} never correct up to the largest n, left out; tested n = "
            f"{[r['n'] for r in st[0]['rows']]})")


def _table_3_1_lines(t31n, t31d) -> list[str]:
    nan3 = {"mean": [_NAN] * 3, "runs": 0, "per_run": []}
    L = ["Table 3.1: samples until a valid model again (first / restore / second)"]
    for fl, name in (("joint", "joint stuck"), ("tool", "tool exchange")):
        nm = (t31n or {}).get(fl, nan3)
        m = nm["mean"]
        d = (t31d or {}).get(fl, nan3)
        dm = d["mean"]
        L.append(f"  {name:14s} numpy 7-DOF ({_runs(nm)}): "
                 f"{m[0]:.2f} / {m[1]:.2f} / {m[2]:.2f};  Drake 2-DOF ({_runs(d)}): "
                 f"{dm[0]:.2f} / {dm[1]:.2f} / {dm[2]:.2f}  (per run {d['per_run']})")
    return L


def _table_3_2_lines(n, d) -> list[str]:
    L = ["Table 3.2: control error [m] (intact static / bent static / bent adaptive)"]
    if n:
        L.append(f"  numpy 4-DOF ({_runs(n)}): {n['intact_static']:.3f} / "
                 f"{n['bent_static']:.3f} / {n['bent_adaptive']:.3f}")
    if d:
        L.append(f"  Drake 4-DOF ({_runs(d)}): {d['intact_static']:.3f} / "
                 f"{d['bent_static']:.3f} / "
                 f"{d['bent_adaptive']:.3f}")
    return L


def _failure_lines(res, t31n, t31d, n, d) -> list[str]:
    L = []
    for t in (t31n, t31d):
        for fl in ("joint", "tool"):
            for why in (t or {}).get(fl, {}).get("failures", []):
                L.append(f"  failed run (Table 3.1 {fl}): {why}")
    for t in (n, d):
        for why in (t or {}).get("failures", []):
            L.append(f"  failed run (Table 3.2): {why}")
    for e in res.get("errors", []):
        L.append(f"  error: trial {e['trial']} raised {e['error']}")
    return L


def format_report(res) -> str:
    """The tables of :func:`~mmlearn.models.body_schema.evaluation.body_schema_report`'s
    result (sections without any run are left out)."""
    L = []
    if "fig_3_10" in res:
        L += _fig_3_10_lines(res["fig_3_10"])
    for key, title in (("noise_free", "noise-free 2-DOF"),
                       ("7dof_occluded", "7-DOF, 10 parts, x4 occluded, noise-free")):
        if key in res:
            L += _accuracy_lines(title, res[key])
    if "7dof_structure" in res:
        L.append(_structure_line(res["7dof_structure"]))
    t31n, t31d = res.get("table_3_1_numpy"), res.get("table_3_1_drake")
    if t31n or t31d:
        L += _table_3_1_lines(t31n, t31d)
    n, d = res.get("table_3_2_numpy"), res.get("table_3_2_drake")
    if n or d:
        L += _table_3_2_lines(n, d)
    L += _failure_lines(res, t31n, t31d, n, d)
    L.append(f"plots: {', '.join(res.get('plots', []))}; {res['seconds']:.0f} s")
    return "\n".join(L)


def main(argv=None) -> int:
    return experiment.main(BodySchemaExperiments(), argv)


if __name__ == "__main__":
    sys.exit(main())
