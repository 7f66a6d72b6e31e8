"""Structure experiments of thesis 4.4.1 / 4.4.3 on the simulated objects (sdf/objects.py).

Usage::

    python -m mmlearn.apps.structure_experiments [--only fig48,fig49,fig411,garage,fig416,fig417,fig418]
        [--quick] [--seeds N] [--n N] [--seed S] [--sensor ideal|camera] [--json] [--out-dir DIR]
        [--results FILE] [--executor local|ray] [--ray-address ADDR] [--jobs N]
    python -m mmlearn.apps.structure_experiments --report-only RESULTS.jsonl [--out-dir DIR]

- fig48: two-drawer cabinet, structure while the lower drawer alone moves, then both.
- fig49: table pushed on the floor: selected link model (rigid, prismatic, gp, gp2) as the
  motion grows.
- fig411: car door and window on a curved guide (r = 1.9 m): structure and window radius.
- garage: roll-up garage door (neither revolute nor prismatic): selected model.
- fig416: yardstick, open chain (3 hinges) and closed loop (4 links): structure and DOFs for
  several seeds (right DOF = 3 open, 1 closed).
- fig417: DOFs while the data arrive (open chain opened segment by segment; closed loop).
- fig418: closed yardstick: BIC of the spanning tree, local search and exhaustive search and
  their run times as n grows.

``--sensor``: ``ideal`` (default) observes the objects' markers with the scenarios' Gaussian
noise (``mmlearn.diagrams.common.object_tracks``); ``camera`` renders the same motion with
ArUco-textured marker squares on the parts and reads them with the
:class:`~mmlearn.systems.common.camera_marker_sensor.CameraMarkerSensor` (one 1920 x 1440 camera
placed by ``auto_cameras``; markers it does not detect are missing samples), and every
experiment adds a line with what the camera saw (share of frames per part, median position
error, share of orientations off by > 20 deg). Slow: ~0.3-1 s per sample.

Tables go to stdout, ``--json`` prints all results, ``--out-dir DIR`` writes the plots (PNG).
``--quick`` runs a small setting (for the test suite).

The trials (each experiment; fig416: each yardstick run; fig417: each yardstick; fig418:
each n) run through the sweep runner (``mmlearn.apps.common.sweep``): in parallel processes
(``--jobs``, default all cores) or as Ray tasks (``--executor ray``), streamed to
``--results`` (default ``structure_experiments_results.jsonl`` in ``--out-dir`` or the
current folder); re-running the same command resumes, ``--report-only FILE`` redraws the
tables and plots from a results file. Run times are those of each trial's process (with
several jobs on few cores they include the others' load).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from mmlearn.apps.common import experiment
from mmlearn.apps.common.cli import UsageError, check_out_dir, pos_int, save_figure
from mmlearn.apps.common.experiment import Experiment
from mmlearn.diagrams.articulation.trials import SENSORS, STRUCTURE_RUNNERS, structure_trial
from mmlearn.models.articulation.evaluation import STRUCTURE_EXPERIMENTS as EXPERIMENTS
from mmlearn.models.articulation.evaluation import structure_report

__all__ = ["run", "main", "EXPERIMENTS"]


def _plots(results, out):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    if "fig418" in results:
        rows = results["fig418"]["rows"]
        fig, (a1, a2) = plt.subplots(2, 1, figsize=(6, 6), sharex=True)
        ns = [r["n"] for r in rows]
        for r in rows:
            a1.plot([r["n"]] * len(r["all_bics"]), r["all_bics"], ".", color="0.7")
        for key, st in (("tree", "r-"), ("local", "b--"), ("exhaustive", "g:")):
            a1.plot(ns, [r[key]["bic"] for r in rows], st, label=key)
            a2.plot(ns, [r[key]["seconds"] for r in rows], st, label=key)
        a1.set_ylabel("BIC")
        a1.legend()
        a2.set_ylabel("search time [s]")
        a2.set_xlabel("training samples n")
        save_figure(fig, out / "fig418_search.png", dpi=100)
        plt.close(fig)
        written.append(str(out / "fig418_search.png"))
    if "fig417" in results:
        fig, ax = plt.subplots(figsize=(6, 3))
        for key, d in results["fig417"].items():
            if key == "seconds":
                continue
            d = np.asarray(d)
            ax.step(d[:, 0], d[:, 1], where="post", label=key)
        ax.set_xlabel("training samples n")
        ax.set_ylabel("estimated DOFs")
        ax.legend()
        save_figure(fig, out / "fig417_dofs.png", dpi=100)
        plt.close(fig)
        written.append(str(out / "fig417_dofs.png"))
    if "fig49" in results:
        rows = results["fig49"]["rows"]
        fig, ax = plt.subplots(figsize=(6, 3))
        keys = [k for k in rows[-1]["bic"]]
        for k in keys:
            ax.plot([r["n"] for r in rows], [r["bic"].get(k) if r["bic"].get(k) is not None
                                             else np.nan for r in rows], label=k)
        ax.set_xlabel("samples n")
        ax.set_ylabel("BIC")
        ax.legend()
        save_figure(fig, out / "fig49_table.png", dpi=100)
        plt.close(fig)
        written.append(str(out / "fig49_table.png"))
    return written


def trial_specs(*, only=EXPERIMENTS, quick: bool = False, seed: int = 0, seeds: int = 10,
                n: int = 200, sensor: str = "ideal") -> list:
    """The sweep's trials: one per experiment of :data:`STRUCTURE_RUNNERS`, one per yardstick run of
    fig416 (2 x ``seeds``), one per yardstick of fig417 (2), one per n of fig418. A
    ``sensor`` other than "ideal" is one more parameter of every trial (so the ideal
    trials' keys, and results files, stay as they were)."""
    from mmlearn.apps.common.sweep import TrialSpec

    fn = structure_trial
    specs = []
    for k in only:
        if k in STRUCTURE_RUNNERS:
            specs.append(TrialSpec(fn=fn, seed=seed, label=k,
                                   params={"experiment": k, "quick": quick}))
        elif k == "fig416":
            ns, nn = (min(seeds, 2), 60) if quick else (seeds, n)
            specs += [TrialSpec(fn=fn, seed=seed + j, label=f"fig416 "
                                f"{'closed' if closed else 'open'} seed {seed + j}",
                                params={"experiment": k, "closed": closed, "n": nn,
                                        "quick": quick})
                      for closed in (False, True) for j in range(ns)]
        elif k == "fig417":
            specs += [TrialSpec(fn=fn, seed=seed, label=f"fig417 "
                                f"{'closed' if closed else 'open_staged'}",
                                params={"experiment": k, "closed": closed, "quick": quick})
                      for closed in (False, True)]
        elif k == "fig418":
            specs += [TrialSpec(fn=fn, seed=seed, label=f"fig418 n {m}",
                                params={"experiment": k, "n": m, "quick": quick})
                      for m in ([40, 80] if quick else [25, 50, 100, 150, 200])]
    if sensor != "ideal":
        specs = [TrialSpec(fn=sp.fn, seed=sp.seed, label=f"{sp.label} ({sensor})",
                           params={**sp.params, "sensor": sensor}) for sp in specs]
    return specs


def _only(only) -> list:
    if isinstance(only, str):
        only = [x.strip() for x in only.split(",") if x.strip()]
    return list(only)


class StructureExperiments(Experiment):
    name = "structure_experiments"
    trials = (structure_trial,)
    description = (__doc__.split("\n\n")[0] + " Exit status: 0 every trial ran, 1 a trial "
                   "raised an error, 2 bad input.")
    seed_help = "random seed"
    json_help = "print JSON instead of tables"
    desc = "structure trials"

    def __init__(self):
        self.text: list[str] = []

    def add_arguments(self, ap):
        ap.add_argument("--only", default=",".join(EXPERIMENTS),
                        help="comma-separated experiments (default: all)")
        ap.add_argument("--quick", action="store_true", help="small, fast setting")
        ap.add_argument("--seeds", type=pos_int, default=10, help="yardstick seeds (fig416)")
        ap.add_argument("--n", type=pos_int, default=200, help="yardstick samples (fig416)")
        ap.add_argument("--sensor", choices=list(SENSORS), default="ideal",
                        help="ideal: the scenarios' Gaussian marker noise (default); camera: "
                             "ArUco markers on the parts read from rendered images (slow)")
        ap.add_argument("--out-dir", default=None,
                        help="folder for the plots (PNG) and the default results file")
        ap.add_argument("--out", dest="out_dir", help=argparse.SUPPRESS)  # old spelling
        ap.add_argument("--no-progress", action="store_true", help="no progress bars")

    def check(self, args):
        check_out_dir("--out-dir", args.out_dir)
        if args.report_only:
            bad = [x for x in _only(args.only) if x not in EXPERIMENTS]
            if bad:
                raise UsageError(f"--only: unknown experiment {bad[0]!r}; choose from "
                                 + ", ".join(EXPERIMENTS))

    def show_progress(self, args):
        return not args.no_progress

    def specs(self, args):
        only = _only(args.only)
        for k in only:
            if k not in EXPERIMENTS:
                raise ValueError(f"unknown experiment {k!r}; choose from "
                                 f"{', '.join(EXPERIMENTS)}")
        if args.seeds < 1 or args.n < 20:
            raise ValueError("--seeds must be >= 1 and --n >= 20")
        if args.sensor not in SENSORS:
            raise ValueError(f"sensor must be one of {', '.join(SENSORS)}, got {args.sensor!r}")
        return trial_specs(only=only, quick=args.quick, seed=args.seed, seeds=args.seeds,
                           n=args.n, sensor=args.sensor)

    def report(self, lines, args):
        res, self.text = structure_report(lines, only=_only(args.only))
        return res

    def finish(self, res, args):
        if args.out_dir:
            res["plots"] = _plots(res, args.out_dir)
        return res

    def print_table(self, res, args):
        print("\n".join(self.text) + "\n", flush=True)
        if res.get("plots"):
            print("plots: " + ", ".join(res["plots"]))


def run(*, only=EXPERIMENTS, quick: bool = False, seed: int = 0, seeds: int = 10, n: int = 200,
        out: str | None = None, progress: bool = True, echo=None, results: str | None = None,
        executor: str = "local", jobs: int | None = None,
        ray_address: str | None = None, sensor: str = "ideal") -> dict:
    """Run the selected experiments; returns {experiment: result} (plus "errors": trials
    that raised, "plots": files written to ``out``). ``echo``: callable taking the table
    lines of every experiment at the end.

    The trials (see :func:`trial_specs`) run through the sweep runner
    (``mmlearn.apps.common.sweep``): streamed to ``results`` (a JSON Lines file; None: a temporary
    one; trials already in it are not run again), ``executor`` "local" (``jobs`` processes,
    default all cores) or "ray" (``ray_address``: a cluster, None: a local Ray instance).
    ``sensor``: "ideal" or "camera" (see :func:`observe`)."""
    exp = StructureExperiments()
    args = argparse.Namespace(only=only, quick=quick, seed=seed, seeds=seeds, n=n,
                              out_dir=out, no_progress=not progress, sensor=sensor)
    res = experiment.run_experiment(exp, args, results=results, executor=executor, jobs=jobs,
                                    ray_address=ray_address)
    if echo is not None:
        echo(exp.text)
    return res


def main(argv=None) -> int:
    return experiment.main(StructureExperiments(), argv)


if __name__ == "__main__":
    sys.exit(main())
