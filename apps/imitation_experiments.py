"""The experiments of thesis 8.2 over many seeds, with plots.

    python -m mmlearn.apps.imitation_experiments --seeds 10 --out-dir imitation_out
    python -m mmlearn.apps.imitation_experiments --report-only imitation_out/imitation_experiments_results.jsonl

Experiments (each trial is one reproduction on its own seed,
:func:`mmlearn.diagrams.imitation.trials.reproduction_trial`, scored by
:mod:`mmlearn.models.imitation.evaluation`):

* ``demos``: pick_place after 1, 2 and 4 demonstrations (thesis Fig. 8.6: one fails, two
  miss the place spot, four converge);
* ``swap``: pick_place after 4 demonstrations with the tables swapped (Fig. 8.5);
* ``board``: the whiteboard with the area scaled by 0.8, 1.0 and 1.25 (Fig. 8.8);
* ``obstacle``: the reach with a box obstacle, incremental (Fig. 8.7);
* ``u_obstacle``: the reach into a U-shaped obstacle, incremental and global (Fig. 8.10);
* ``teaching``: pick_place with swapped tables, batch after 1, 2, 3 and 4 demonstrations
  (the thesis' learner), batch after 2 with the interactive learner's isotropic prior, and
  interactive teaching (:func:`mmlearn.diagrams.imitation.teaching.teaching_trial`, at most 6
  demonstrations, finally tested in batch learning's situation of the same seed); the
  ``demos`` column is the mean number of demonstrations used.

Trials run through the sweep runner (``mmlearn.apps.common.sweep``, the shared front-end of
``mmlearn.apps.common.experiment``) and are streamed to ``--results`` (re-running resumes);
``--report-only`` redraws the table and the plots from a results file. Every row states how
many trials raised an error beside the means.
"""

from __future__ import annotations

import sys
from pathlib import Path

from mmlearn.apps.common import experiment
from mmlearn.apps.common.cli import check_out_dir, name_list, pos_int, save_figure
from mmlearn.apps.common.experiment import Experiment
from mmlearn.apps.common.sweep import TrialSpec, run_sweep
from mmlearn.diagrams.imitation.teaching import TEACHING_PRIOR, teaching_trial
from mmlearn.diagrams.imitation.trials import reproduction_plan, reproduction_trial
from mmlearn.models.imitation.evaluation import condition_table

EXPERIMENTS = ("demos", "swap", "board", "obstacle", "u_obstacle", "teaching")
TEACHING_MAX_DEMOS = 6
BOARD_SCALES = (0.8, 1.0, 1.25)


def conditions(experiments) -> list[tuple]:
    """(condition label, trial parameters[, trial function]) of the chosen experiments."""
    out = []
    for e in experiments:
        if e == "demos":
            out += [(f"pick_place {n} demo{'s' if n > 1 else ''}",
                     {"task": "pick_place", "demos": n}) for n in (1, 2, 4)]
        elif e == "swap":
            out.append(("pick_place 4 demos, swapped tables",
                        {"task": "pick_place", "demos": 4, "swap_tables": True}))
        elif e == "board":
            out += [(f"whiteboard scale {s:g}", {"task": "whiteboard", "board_scale": s})
                    for s in BOARD_SCALES]
        elif e == "obstacle":
            out.append(("obstacle incremental", {"task": "obstacle"}))
        elif e == "u_obstacle":
            out += [("u_obstacle incremental", {"task": "u_obstacle"}),
                    ("u_obstacle global", {"task": "u_obstacle", "global_mode": True})]
        elif e == "teaching":
            out += [(f"pick_place {n} demo{'s' if n > 1 else ''}, swapped tables",
                     {"task": "pick_place", "demos": n, "swap_tables": True}) for n in (1, 2, 3, 4)]
            out.append(("pick_place 2 demos, swapped tables, isotropic prior",
                        {"task": "pick_place", "demos": 2, "swap_tables": True,
                         "isotropic_prior": TEACHING_PRIOR}))
            out.append(("pick_place interactive, swapped tables",
                        {"task": "pick_place", "swap_tables": True,
                         "max_demos": TEACHING_MAX_DEMOS}, teaching_trial))
        else:
            raise ValueError(f"unknown experiment {e!r}; choose from {', '.join(EXPERIMENTS)}")
    return out


def run(*, experiments=EXPERIMENTS, seeds: int = 10, seed: int = 100, results=None,
        executor: str = "local", jobs=None, ray_address=None, show_progress: bool = True,
        out_dir: str = "") -> dict:
    """Run the trials and return the report (and write the plots into ``out_dir``)."""
    if seeds < 1:
        raise ValueError(f"seeds must be >= 1, got {seeds}")
    sweep = run_sweep(_specs(experiments, seeds, seed), results=results, executor=executor,
                      jobs=jobs, ray_address=ray_address, show_progress=show_progress,
                      desc="imitation trials")
    res = report(sweep.lines, out_dir=out_dir)
    res["sweep"] = sweep.summary()
    return res


def _specs(experiments, seeds: int, seed: int) -> list:
    return [TrialSpec(**d) for d in reproduction_plan(conditions(experiments), seeds, seed)]


def report(lines: list[dict], *, out_dir: str = "") -> dict:
    """Per-condition success, place error, clearance (from results-file lines,
    :func:`mmlearn.models.imitation.evaluation.condition_table`)."""
    table, errors = condition_table(lines)
    res = {"conditions": table, "errors": errors}
    if out_dir:
        res["plots"] = plot(table, out_dir)
    return res


def plot(table: list[dict], out_dir: str) -> list[str]:
    """Success rate per condition and place error against the number of demonstrations."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = []
    fig, ax = plt.subplots(figsize=(9, 4))
    labels = [r["condition"] for r in table]
    rates = [r["success_rate"] or 0.0 for r in table]
    ax.barh(labels, rates, color="tab:blue")
    for i, r in enumerate(table):
        ax.text(min(rates[i] + 0.02, 0.9), i, f"{r['successes']}/{r['trials']}"
                + (f" ({r['errors']} errors)" if r["errors"] else ""), va="center")
    ax.set_xlim(0, 1.05)
    ax.set_xlabel("success rate")
    ax.invert_yaxis()
    fig.tight_layout()
    out.append(str(save_figure(fig, Path(out_dir) / "imitation_success.png")))
    plt.close(fig)
    demo_rows = [r for r in table if r["condition"].startswith("pick_place")
                 and "swapped" not in r["condition"] and r["mean_place_error_m"] is not None]
    if demo_rows:
        fig, ax = plt.subplots(figsize=(5, 4))
        n = [int(r["condition"].split()[1]) for r in demo_rows]
        ax.plot(n, [r["median_place_error_m"] for r in demo_rows], "o-", label="median")
        ax.plot(n, [r["mean_place_error_m"] for r in demo_rows], "s--", label="mean")
        ax.axhline(0.02, color="k", lw=0.8, ls=":", label="2 cm success bound")
        ax.set_xlabel("demonstrations")
        ax.set_ylabel("place error (m)")
        ax.set_yscale("log")
        ax.set_xticks(n)
        ax.legend()
        fig.tight_layout()
        out.append(str(save_figure(fig, Path(out_dir) / "imitation_place_error.png")))
        plt.close(fig)
    return out


def format_table(res: dict) -> str:
    lines = [f"{'condition':38s} {'success':>9s} {'errors':>6s} {'place err mean/med':>19s} "
             f"{'min clearance':>13s} {'coverage':>8s} {'reach err':>9s} {'repro s':>8s} "
             f"{'demos':>5s}"]

    def f(v, fmt):
        return "-" if v is None else format(v, fmt)

    for r in res["conditions"]:
        pe = ("-" if r["mean_place_error_m"] is None else
              f"{r['mean_place_error_m']:.3f}/{r['median_place_error_m']:.3f}")
        lines.append(f"{r['condition']:38s} {r['successes']:>4d}/{r['trials']:<4d} "
                     f"{r['errors']:>6d} {pe:>19s} {f(r['min_clearance_m'], '.3f'):>13s} "
                     f"{f(r['mean_coverage'], '.2f'):>8s} {f(r['mean_reach_error_m'], '.3f'):>9s} "
                     f"{f(r['mean_reproduction_seconds'], '.1f'):>8s} "
                     f"{f(r.get('mean_demos'), '.1f'):>5s}")
    lines.append("means over the trials that ran; trials that raised are counted under errors")
    for p in res.get("plots", []):
        lines.append(f"plot: {p}")
    return "\n".join(lines)


class ImitationExperiments(Experiment):
    """The command line (:mod:`mmlearn.apps.common.experiment`)."""

    name = "imitation_experiments"
    trials = (reproduction_trial, teaching_trial)
    description = ("Thesis 8.2's imitation experiments over many seeds, with plots. Exit status: "
                   "0 all trials ran, 1 a trial raised, 2 bad input.")
    seed_default = 100
    seed_help = "seed of the first trial"
    desc = "imitation trials"

    def add_arguments(self, ap):
        ap.add_argument("--experiments", type=name_list(EXPERIMENTS), default=list(EXPERIMENTS),
                        help="comma-separated: " + ", ".join(EXPERIMENTS))
        ap.add_argument("--seeds", type=pos_int, default=10, help="trials per condition")
        ap.add_argument("--out-dir", default="imitation_out",
                        help="folder of the plots and results")

    def check(self, args):
        check_out_dir("--out-dir", args.out_dir)

    def specs(self, args):
        return _specs(args.experiments, args.seeds, args.seed)

    def report(self, lines, args):
        return report(lines, out_dir=args.out_dir)

    def print_table(self, res, args):
        print(format_table(res))


def main(argv=None) -> int:
    return experiment.main(ImitationExperiments(), argv)


if __name__ == "__main__":
    sys.exit(main())
