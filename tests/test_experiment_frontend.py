"""The experiments apps' shared front-end (apps/common/experiment.py): flags, run, report-only,
JSON, exit status."""

import json

import pytest

from mmlearn.apps.common import experiment
from mmlearn.apps.common.cli import UsageError, pos_int
from mmlearn.apps.common.experiment import Experiment, errors_of
from mmlearn.apps.common.sweep import TrialSpec, probe_trial


class Probe(Experiment):
    """A toy experiment of the sweep's probe trial: ``--n`` trials, the seeds in
    ``--fail`` raise."""

    name = "probe_experiments"
    description = "probe trials"

    def add_arguments(self, ap):
        ap.add_argument("--n", type=pos_int, default=3)
        ap.add_argument("--fail", type=int, nargs="*", default=[])
        ap.add_argument("--limit", type=int, default=10)

    def check(self, args):
        if args.n > args.limit:
            raise UsageError(f"--n: at most {args.limit}, got {args.n}")

    def specs(self, args):
        return [TrialSpec(fn=probe_trial, seed=args.seed + i, label=f"probe {args.seed + i}",
                          params={"fail_seeds": list(args.fail)}) for i in range(args.n)]

    def report(self, lines, args):
        seeds = [ln["record"]["seed"] for ln in lines if ln.get("error") is None]
        if not lines:
            raise ValueError("no probe trial")
        return {"seeds": seeds, "errors": errors_of(lines)}

    def print_table(self, res, args):
        print("seeds: " + " ".join(map(str, res["seeds"])))


def _run(argv, capsys, tmp_path):
    rc = experiment.main(Probe(), ["--jobs", "1", "--results", str(tmp_path / "r.jsonl"),
                                   *argv])
    out, err = capsys.readouterr()
    return rc, out, err


def test_runs_the_trials_and_prints_the_table_or_json(tmp_path, capsys):
    rc, out, err = _run(["--n", "3", "--seed", "5"], capsys, tmp_path)
    assert rc == 0, err
    assert out.strip() == "seeds: 5 6 7"
    rc, out, err = _run(["--n", "3", "--seed", "5", "--json"], capsys, tmp_path)
    res = json.loads(out)
    assert rc == 0 and res["seeds"] == [5, 6, 7]
    assert res["sweep"]["resumed"] == 3  # the second run read every trial from the file
    assert res["sweep"]["results_file"] == str(tmp_path / "r.jsonl")


def test_report_only_reads_the_records_back_without_running(tmp_path, capsys):
    _run(["--n", "2"], capsys, tmp_path)
    rc = experiment.main(Probe(), ["--report-only", str(tmp_path / "r.jsonl"), "--json",
                                   "--n", "9"])
    out, err = capsys.readouterr()
    assert rc == 0, err
    assert json.loads(out) == {"seeds": [0, 1], "errors": []}  # no sweep: nothing ran


def test_a_raising_trial_exits_1_and_is_named(tmp_path, capsys):
    rc, out, err = _run(["--n", "3", "--fail", "1", "--json"], capsys, tmp_path)
    assert rc == 1
    assert "1 trial(s) raised an error: probe 1" in err
    res = json.loads(out)
    assert res["seeds"] == [0, 2] and res["errors"][0]["trial"] == "probe 1"


@pytest.mark.parametrize("argv, message", [
    (["--n", "11"], "--n: at most 10"),                   # the app's own check
    (["--n", "0"], "--n: expected a positive integer"),   # argparse types
    (["--seed", "-1"], "--seed"),                        # the shared --seed
    (["--ray-address", "auto"], "--ray-address needs --executor ray"),
])
def test_bad_input_exits_2_before_any_trial(argv, message, tmp_path, capsys):
    try:  # argparse's own errors exit; the checks return the status
        rc = experiment.main(Probe(), ["--results", str(tmp_path / "r.jsonl"), *argv])
    except SystemExit as e:
        rc = e.code
    assert rc == 2 and message in capsys.readouterr().err
    assert not (tmp_path / "r.jsonl").exists()


def test_report_only_of_a_missing_or_bad_file_is_bad_input(tmp_path, capsys):
    rc = experiment.main(Probe(), ["--report-only", str(tmp_path / "none.jsonl")])
    assert rc == 2 and "--report-only: no results file" in capsys.readouterr().err
    # a file whose records the report cannot use: the message names the file
    _run(["--n", "1", "--fail", "0"], capsys, tmp_path)
    bad = Probe()
    bad.report = lambda lines, args: (_ for _ in ()).throw(ValueError("mixed settings"))
    rc = experiment.main(bad, ["--report-only", str(tmp_path / "r.jsonl")])
    err = capsys.readouterr().err
    assert rc == 2 and f"--report-only: {tmp_path / 'r.jsonl'}: mixed settings" in err


def test_an_app_without_seed_and_its_help(capsys):
    class NoSeed(Probe):
        seed_default = None

        def specs(self, args):
            return []

    ap = experiment.parser(NoSeed())
    assert "--seed" not in ap.format_help()
    for flag in ("--results", "--executor", "--jobs", "--report-only", "--json"):
        assert flag in ap.format_help()
    assert experiment.parser(Probe()).parse_args([]).seed == 0


def test_no_trials_asked_for_reports_at_once_without_a_sweep(tmp_path, capsys, monkeypatch):
    """An experiment whose command line asks for no trial (a mode that reads data files) is
    reported directly: no sweep in the result, no results file written."""
    class DataOnly(Probe):
        def specs(self, args):
            return [] if args.n == 1 else super().specs(args)

        def report(self, lines, args):
            return {"lines": len(lines), "errors": []}

    monkeypatch.chdir(tmp_path)
    rc = experiment.main(DataOnly(), ["--n", "1", "--json"])
    assert rc == 0 and json.loads(capsys.readouterr().out) == {"lines": 0, "errors": []}
    assert list(tmp_path.iterdir()) == []
    rc = experiment.main(DataOnly(), ["--n", "2", "--json", "--jobs", "1"])
    res = json.loads(capsys.readouterr().out)
    assert rc == 0 and res["lines"] == 2 and "sweep" in res


def test_an_app_that_keeps_no_results_by_default(tmp_path, capsys, monkeypatch):
    """keeps_results False: without --results the records go to a temporary file (nothing
    left behind); with --results they are kept and resumed."""
    class Temporary(Probe):
        keeps_results = False

    monkeypatch.chdir(tmp_path)
    assert "default: a temporary file" in " ".join(
        experiment.parser(Temporary()).format_help().split())
    rc = experiment.main(Temporary(), ["--n", "2", "--json", "--jobs", "1"])
    res = json.loads(capsys.readouterr().out)
    assert rc == 0 and res["seeds"] == [0, 1] and res["sweep"]["results_file"] is None
    assert list(tmp_path.iterdir()) == []
    experiment.main(Temporary(), ["--n", "2", "--jobs", "1", "--results", "r.jsonl"])
    capsys.readouterr()
    assert len((tmp_path / "r.jsonl").read_text().splitlines()) == 2
    # the apps that keep them write <name>_results.jsonl in the current folder
    experiment.main(Probe(), ["--n", "1", "--jobs", "1"])
    assert (tmp_path / "probe_experiments_results.jsonl").exists()
