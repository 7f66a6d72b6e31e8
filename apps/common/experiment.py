"""One front-end for the experiments apps: an app is its arguments, its trials and its table.

An experiments app describes itself as an :class:`Experiment` (its name, its own flags, the
trials a command line asks for, the report of their records, its table) and its ``main`` is
``experiment.main(MyExperiment(), argv)``. The front-end does the rest, the same way for
every app:

* the flags every experiments app shares: ``--seed`` (unless the app has none), the sweep
  flags of :func:`mmlearn.apps.common.sweep.add_sweep_args` (``--results``, ``--executor``,
  ``--ray-address``, ``--jobs``, ``--report-only``) and ``--json``;
* bad input (an app's :meth:`Experiment.check`, the sweep flags) exits with status 2 and a
  one-line message naming the flag, before any trial runs;
* the trials (:meth:`Experiment.specs`) run through :func:`~mmlearn.apps.common.sweep.run_sweep`
  (resumable results file ``<name>_results.jsonl``, or a temporary one for an app that keeps
  no results by default, :attr:`Experiment.keeps_results`; local processes or Ray); with
  ``--report-only FILE`` nothing runs and the report is recomputed from the file's records;
  a command line that asks for no trial (empty specs: a mode that reads data files, say) is
  reported directly, without a sweep;
* the result is printed as the app's table or, with ``--json``, as one JSON object;
* the exit status is :func:`~mmlearn.apps.common.sweep.exit_status`'s: 0 every trial ran,
  1 a trial raised (named on stderr), 130 interrupted.

A minimal app::

    class Noise(Experiment):
        name = "noise_experiments"
        description = "..."

        def add_arguments(self, ap):
            ap.add_argument("--runs", type=pos_int, default=10)

        def specs(self, args):
            return [TrialSpec(fn=noise_trial, seed=args.seed + i) for i in range(args.runs)]

        def report(self, lines, args):
            return {"rates": [...], "errors": errors_of(lines)}

        def print_table(self, res, args):
            print(...)

    def main(argv=None) -> int:
        return experiment.main(Noise(), argv)
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from mmlearn.apps.common.cli import ArgumentParser, UsageError, fail, json_clean, nonneg_int
from mmlearn.apps.common.sweep import (SweepResult, add_sweep_args, exit_status, report_lines,
                                       run_sweep, sweep_kwargs)

__all__ = ["Experiment", "main", "parser", "run_experiment", "report_only", "errors_of",
           "run_main"]


class Experiment:
    """What an experiments app adds to the shared front-end. Override the methods an app
    needs; every method gets the parsed command line ``args``."""

    #: the app's module name (``python -m mmlearn.apps.<name>``, ``<name>_results.jsonl``)
    name: str = ""
    #: the ``--help`` text (its exit statuses included)
    description: str = ""
    #: ``--seed``'s default (None: the app has no ``--seed``) and help
    seed_default: int | None = 0
    seed_help: str | None = None
    #: ``--json``'s help
    json_help: str = "print the results as JSON"
    #: the progress bar's label
    desc: str = "trials"
    #: without ``--results``, keep the trials' records in ``<name>_results.jsonl`` (True) or
    #: in a temporary file removed after the run (False: nothing to resume)
    keeps_results: bool = True
    #: the trial functions whose records this experiment reports: ``--report-only`` skips
    #: (and names) the lines of any other trial (empty: lines of any trial are read)
    trials: tuple = ()

    @property
    def prog(self) -> str:
        return f"python -m mmlearn.apps.{self.name}"

    # ------------------------------------------------------------------ the app's parts
    def add_arguments(self, ap: argparse.ArgumentParser) -> None:
        """Add the app's own flags."""

    def check(self, args) -> None:
        """Raise :class:`UsageError` for bad input found before anything runs (called with
        and without ``--report-only``)."""

    def out_dir(self, args) -> str | Path:
        """The folder of the default results file (the app's ``--out-dir`` or the current
        folder)."""
        return getattr(args, "out_dir", None) or "."

    def specs(self, args) -> list:
        """The trials (:class:`~mmlearn.apps.common.sweep.TrialSpec`) the command line asks
        for; a ``ValueError`` is bad input. None asked for: :meth:`report` gets no lines and
        nothing runs."""
        raise NotImplementedError

    def shared(self, args):
        """Large inputs every trial needs, sent once per worker (None: none)."""
        return None

    def show_progress(self, args) -> bool:
        return not args.json

    def report(self, lines: list[dict], args) -> dict:
        """The experiment's result from results-file lines (a run or ``--report-only``); a
        ``ValueError`` names what is wrong with the file."""
        raise NotImplementedError

    def attach_sweep(self, res: dict, sweep: SweepResult, args) -> None:
        """Put what the sweep itself did in the result (after a run, not with
        ``--report-only``)."""
        res["sweep"] = sweep.summary()

    def finish(self, res: dict, args) -> dict:
        """Outputs written after the report (plots, files); returns the result."""
        return res

    def print_table(self, res: dict, args) -> None:
        """Print the result without ``--json``."""
        print(json.dumps(json_clean(res), indent=1))

    def to_json(self, res: dict) -> str:
        """The result as printed with ``--json``."""
        return json.dumps(json_clean(res))

    def failed(self, res: dict) -> list[str]:
        """The names of the trials that raised (for the exit status)."""
        return [e["trial"] for e in res.get("errors") or []]

    def interrupted(self, res: dict) -> bool:
        return bool((res.get("sweep") or {}).get("interrupted"))

    def error_message(self, error: Exception, args) -> str:
        """The one-line message of bad input found while building the trials."""
        return str(error)


def errors_of(lines: list[dict]) -> list[dict]:
    """The trials that raised, as results list them: ``{"trial": label, "error": ...}``."""
    return [{"trial": ln["spec"].get("label") or ln["key"], "error": ln["error"]}
            for ln in lines if ln.get("error") is not None]


def parser(experiment: Experiment) -> ArgumentParser:
    """The app's argument parser: its own flags, then ``--seed``, the sweep flags and
    ``--json``."""
    ap = ArgumentParser(prog=experiment.prog, description=experiment.description)
    experiment.add_arguments(ap)
    if experiment.seed_default is not None:
        ap.add_argument("--seed", type=nonneg_int, default=experiment.seed_default,
                        help=experiment.seed_help)
    add_sweep_args(ap, app=experiment.name, keeps_results=experiment.keeps_results)
    ap.add_argument("--json", action="store_true", help=experiment.json_help)
    return ap


def run_experiment(experiment: Experiment, args, *, results=None, executor: str = "local",
                   jobs: int | None = None, ray_address: str | None = None) -> dict:
    """Run the trials of ``args`` through the sweep runner and report them (the sweep's
    keyword arguments as :func:`~mmlearn.apps.common.sweep.sweep_kwargs` gives them). With no
    trial to run, the report is made at once (no sweep)."""
    specs = experiment.specs(args)
    if not specs:
        return experiment.finish(experiment.report([], args), args)
    sweep = run_sweep(specs, results=results, executor=executor, jobs=jobs,
                      ray_address=ray_address, shared=experiment.shared(args),
                      show_progress=experiment.show_progress(args), desc=experiment.desc)
    res = experiment.report(sweep.lines, args)
    experiment.attach_sweep(res, sweep, args)
    return experiment.finish(res, args)


def report_only(experiment: Experiment, args) -> dict:
    """The report recomputed from ``args.report_only`` (nothing runs): the file's sound
    lines of the experiment's trials (the others named and counted on stderr), reported;
    records of a shape the report cannot use are bad input, never a traceback."""
    lines = report_lines(args.report_only, trials=experiment.trials)
    try:
        res = experiment.report(lines, args)
        return experiment.finish(res, args)
    except ValueError as e:
        raise UsageError(f"--report-only: {args.report_only}: {e}") from None
    except (KeyError, TypeError, IndexError, AttributeError, ZeroDivisionError) as e:
        raise UsageError(f"--report-only: {args.report_only}: its records are not of the shape "
                         f"{experiment.name} reports ({type(e).__name__}: {e})") from None


def main(experiment: Experiment, argv=None) -> int:
    """Parse ``argv``, run (or with ``--report-only`` re-report) the experiment, print its
    table or JSON; returns the exit status."""
    ap = parser(experiment)
    args = ap.parse_args(argv)
    try:
        experiment.check(args)
        sweep = None if args.report_only else sweep_kwargs(
            args, app=experiment.name,
            out_dir=experiment.out_dir(args) if experiment.keeps_results else None)
    except UsageError as e:
        return fail(ap.prog, str(e))
    try:
        res = report_only(experiment, args) if args.report_only else \
            run_experiment(experiment, args, **sweep)
    except UsageError as e:
        return fail(ap.prog, str(e))
    except (ValueError, OSError) as e:
        return fail(ap.prog, experiment.error_message(e, args))
    if args.json:
        print(experiment.to_json(res))
    else:
        experiment.print_table(res, args)
    return exit_status(ap.prog, {"errors": [{"trial": t} for t in experiment.failed(res)],
                                 "sweep": {"interrupted": experiment.interrupted(res)}})


def run_main(experiment: Experiment) -> None:
    """``sys.exit(main(experiment))``: the ``if __name__ == "__main__"`` of an app."""
    sys.exit(main(experiment))
