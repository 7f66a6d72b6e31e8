"""Bad input at the command line: one-line errors that name the flag or file, exit status 2
before any computation; failed runs counted, never silently dropped.

The apps' main(argv) is called in-process (no subprocess) wherever possible."""

import json
import math
from pathlib import Path

import numpy as np
import pytest
from conftest import bad_usage as _bad
from conftest import run_main as _exit

DATA = Path(__file__).parent / "data"
EXAMPLE = Path(__file__).resolve().parents[1] / "apps" / "examples" / "two_drawer_cabinet.csv"


@pytest.fixture(scope="module")
def prior_db(tmp_path_factory):
    """A small valid prior database (JSON dict) learned from two simulated tracks."""
    from mmlearn.models.articulation.priors import PriorDatabase
    from mmlearn.models.articulation.sim import simulate_link

    rng = np.random.default_rng(0)
    db = PriorDatabase()
    for k in range(2):
        db.add(simulate_link("revolute", 20, rng=rng).Z[:, :3], f"t{k}", rng=rng)
    return db.to_dict()


def _write(tmp_path, name, d):
    p = tmp_path / name
    p.write_text(json.dumps(d))
    return p


# --------------------------------------------------------------------------- shared types
def test_common_parser_aliases_and_one_line_errors(capsys):
    from mmlearn.apps.common.cli import ArgumentParser, name_list, nonneg_int, pos_float

    ap = ArgumentParser(prog="x")
    ap.add_argument("--out-dir", default="d")
    ap.add_argument("--seed", type=nonneg_int, default=0)
    ap.add_argument("--max-time", type=pos_float, default=1.0)
    ap.add_argument("--objects", type=name_list(["a", "b"]), default=["a"])
    assert ap.parse_args(["--out_dir", "q"]).out_dir == "q"  # hidden alias
    assert ap.parse_args([]).out_dir == "d"
    assert "--out_dir" not in ap.format_help() and "--out-dir" in ap.format_help()
    for argv, msg in ((["--seed", "-1"], "--seed: expected a non-negative integer"),
                      (["--seed", "x"], "--seed: expected a non-negative integer"),
                      (["--max-time", "inf"], "--max-time: expected a finite number > 0"),
                      (["--max-time", "nan"], "--max-time: expected a finite number > 0"),
                      (["--objects", ","], "--objects: expected a comma-separated list"),
                      (["--objects", "a,c"], "--objects: unknown 'c'")):
        with pytest.raises(SystemExit) as e:
            ap.parse_args(argv)
        assert e.value.code == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and msg in err, err


def test_output_path_checks(tmp_path):
    from mmlearn.apps.common.cli import UsageError, check_out_dir, check_out_file

    f = tmp_path / "file.txt"
    f.write_text("x")
    with pytest.raises(UsageError, match="--plot: folder .*missing does not exist"):
        check_out_file("--plot", tmp_path / "missing" / "a.png")
    with pytest.raises(UsageError, match="--plot: .* is a folder"):
        check_out_file("--plot", tmp_path)
    check_out_file("--plot", tmp_path / "a.png")  # fine
    with pytest.raises(UsageError, match="--out-dir: .* is a file"):
        check_out_dir("--out-dir", f)
    with pytest.raises(UsageError, match="--out-dir: folder .* does not exist"):
        check_out_dir("--out-dir", tmp_path / "a" / "b")
    check_out_dir("--out-dir", tmp_path / "new")
    assert (tmp_path / "new").is_dir()


# --------------------------------------------------------------------------- open_cabinet
def test_open_cabinet_bad_input(tmp_path, capsys, prior_db):
    from mmlearn.apps.open_cabinet import main

    _bad(main, ["--max-time", "inf"], capsys, "--max-time", "finite")
    _bad(main, ["--seed", "-1"], capsys, "--seed: expected a non-negative integer")
    _bad(main, ["--sigma-pos", "0"], capsys, "--sigma-pos")
    nocfg = dict(prior_db)
    del nocfg["config"]
    _bad(main, ["--priors", str(_write(tmp_path, "nocfg.json", nocfg))], capsys,
         "--priors", "missing key 'config'")
    nan = json.loads(json.dumps(prior_db))
    nan["clusters"][0]["data"][0][1][2] = math.nan
    _bad(main, ["--priors", str(_write(tmp_path, "nan.json", nan))], capsys,
         "--priors", "non-finite value clusters[0].data[0][1][2]")
    _bad(main, ["--priors", str(tmp_path / "none.json")], capsys, "--priors", "not found")
    _bad(main, ["--html-out", str(tmp_path / "no" / "x.html")], capsys, "--html-out",
         "does not exist")
    _bad(main, ["--html_out", str(tmp_path)], capsys, "--html-out", "is a folder")
    _bad(main, ["--save-track", str(tmp_path)], capsys, "--save-track", "is a folder")


def test_open_cabinet_failed_trial_exits_1_and_says_nothing_saved(tmp_path, capsys):
    from mmlearn.apps.open_cabinet import main

    track = tmp_path / "track.log"
    rc, out, err = _exit(main, ["--object", "drawer", "--max-time", "0.5", "--save-track",
                                str(track)], capsys)
    assert rc == 1 and "FAILED" in out
    assert "--save-track: nothing written" in err and not track.exists()
    assert "Meshcat" not in err  # no URL without --meshcat


def test_make_meshcat_announces_only_a_live_view(capsys):
    from mmlearn.apps.common.cli import make_meshcat

    make_meshcat(announce=False)
    assert "http" not in capsys.readouterr().err


# --------------------------------------------------------------------------- operate_trials
def test_operate_trials_bad_input(tmp_path, capsys, prior_db):
    from mmlearn.apps.operate_trials import main

    _bad(main, ["--objects", ","], capsys, "--objects: expected a comma-separated list")
    _bad(main, ["--objects", "left_door,door"], capsys, "--objects: unknown 'door'")
    _bad(main, ["--jobs", "0"], capsys, "--jobs: expected a positive integer")
    _bad(main, ["--max-time", "inf"], capsys, "--max-time")
    _bad(main, ["--trials", "0"], capsys, "--trials")
    _bad(main, ["--save-tracks", str(tmp_path / "a" / "b")], capsys, "--save-tracks")
    nocfg = dict(prior_db)
    del nocfg["config"]
    _bad(main, ["--priors", str(_write(tmp_path, "nocfg.json", nocfg))], capsys,
         "--priors", "missing key 'config'")


def test_operate_trials_counts_a_crashed_trial_as_an_error(monkeypatch, capsys, tmp_path):
    import mmlearn.diagrams.articulation.trials as trials
    from mmlearn.apps.operate_trials import main

    def boom(**kw):
        raise RuntimeError("simulated crash")

    monkeypatch.setattr(trials, "open_mechanism", boom)  # --jobs 1 runs the trials in this process
    rc, out, err = _exit(main, ["--objects", "drawer", "--trials", "2", "--jobs", "1",
                                "--json", "--results", str(tmp_path / "r.jsonl")], capsys)
    assert "drawer seed 0, drawer seed 1" in err  # the failed trials are named
    assert rc == 1 and "raised an error" in err
    res = json.loads(out)
    assert res["errors"] == 2 and res["total"] == 0 and res["success_rate"] is None
    row = res["per_object"]["drawer"]
    assert row["errors"] == 2 and row["trials"] == 0 and row["mean_opened"] is None
    assert "simulated crash" in res["trials"][0]["error"]


def test_operate_trials_table_reports_errors_beside_the_means():
    from mmlearn.apps.operate_trials import format_table
    from mmlearn.models.articulation.evaluation import summarize_operate as summarize

    ok = {"object": "drawer", "seed": 0, "success": True, "opened": 0.35, "unit": "m",
          "outcome": "done", "learned_model": "prismatic", "radius_error_m": None,
          "axis_error_deg": 2.0, "right_model_at": 0.1}
    bad = {"object": "drawer", "seed": 1, "success": False, "opened": None, "unit": "m",
           "outcome": "error: RuntimeError: x", "error": "RuntimeError: x",
           "learned_model": None, "radius_error_m": None, "axis_error_deg": None}
    table = summarize([ok, bad])
    assert table["drawer"]["trials"] == 1 and table["drawer"]["errors"] == 1
    assert table["drawer"]["mean_opened"] == pytest.approx(0.35)
    assert table["drawer"]["axis_runs"] == 1 and table["drawer"]["radius_runs"] == 0
    text = format_table({"trials": [ok, bad], "per_object": table, "successes": 1,
                         "total": 1, "errors": 1, "success_rate": 1.0, "wall_seconds": 1})
    assert "errors" in text.splitlines()[0] and "error:  drawer seed 1" in text
    assert "1 trial(s) raised an error" in text


# --------------------------------------------------------------------------- fit_articulation
def test_fit_articulation_bad_input(tmp_path, capsys):
    from mmlearn.apps.fit_articulation import main

    (tmp_path / "empty").mkdir()
    _bad(main, [str(tmp_path / "empty")], capsys, "no track files", "empty")
    logs = str(DATA / "articulation_logs")
    _bad(main, [logs, "--plot", str(tmp_path / "no" / "f.png")], capsys, "--plot",
         "does not exist")
    _bad(main, [logs, "--plot", str(tmp_path)], capsys, "--plot", "is a folder")
    _bad(main, [logs, "--models", ","], capsys, "--models")
    _bad(main, [logs, "--models", "rigid,screw"], capsys, "--models", "screw")
    _bad(main, [logs, "--sigma-pos", "nan"], capsys, "--sigma-pos")


# --------------------------------------------------------------------------- fit_structure
def test_fit_structure_example_and_bad_paths(tmp_path, capsys):
    from mmlearn.apps.fit_structure import main

    rc, out, err = _exit(main, [str(EXAMPLE), "--json"], capsys)
    assert rc == 0, err
    r = json.loads(out)
    assert r["parts"] == ["cabinet", "upper_drawer", "lower_drawer"] and r["dof"] == 2
    assert {(e["a"], e["b"], e["model"]) for e in r["edges"]} == {
        ("cabinet", "upper_drawer", "prismatic"), ("cabinet", "lower_drawer", "prismatic")}
    _bad(main, [str(EXAMPLE), "--plot", str(tmp_path)], capsys, "--plot", "is a folder")
    _bad(main, [str(tmp_path / "none.csv")], capsys, "not found")
    _bad(main, [str(EXAMPLE), "--seed", "-2"], capsys, "--seed")


# --------------------------------------------------------------------------- learn_priors
def test_learn_priors_prints_tracks_to_clusters_and_checks_paths(tmp_path, capsys, prior_db):
    from mmlearn.apps.learn_priors import main

    tracks = sorted((DATA / "articulation_priors").rglob("*.log"))[:3]
    rc, out, err = _exit(main, [*map(str, tracks), "--no-progress"], capsys)
    assert rc == 0, err
    assert out.splitlines()[0].startswith("3 tracks -> ") and "clusters" in out
    _bad(main, [str(tracks[0]), "--save", str(tmp_path / "no" / "db.json")], capsys,
         "--save", "does not exist")
    nocfg = dict(prior_db)
    del nocfg["config"]
    _bad(main, [str(tracks[0]), "--load", str(_write(tmp_path, "n.json", nocfg))], capsys,
         "missing key 'config'")
    (tmp_path / "empty").mkdir()
    _bad(main, [str(tmp_path / "empty")], capsys, "no track files")
    _bad(main, [str(tracks[0]), "--evaluate", "--fractions", "0,2"], capsys, "--fractions")


# --------------------------------------------------------------------------- experiments
def test_experiment_apps_check_the_output_folder_first(tmp_path, capsys):
    from mmlearn.apps import articulation_experiments, body_schema_experiments
    from mmlearn.apps import structure_experiments

    f = tmp_path / "file"
    f.write_text("x")
    _bad(articulation_experiments.main, ["--quick", "--out-dir", str(f)], capsys,
         "--out-dir", "is a file")
    _bad(articulation_experiments.main, ["--only", "noise,nose"], capsys, "--only", "nose")
    _bad(body_schema_experiments.main, ["--quick", "--out-dir", str(f)], capsys,
         "--out-dir", "is a file")
    _bad(body_schema_experiments.main, ["--quick", "--out_dir", str(tmp_path / "a" / "b")],
         capsys, "--out-dir", "does not exist")
    _bad(body_schema_experiments.main, ["--drake_runs", "0"], capsys, "--drake_runs",
         "positive integer")
    _bad(structure_experiments.main, ["--quick", "--out", str(f)], capsys, "--out-dir",
         "is a file")


def test_articulation_experiments_count_failed_runs(monkeypatch, capsys):
    import mmlearn.apps.articulation_experiments as ae
    import mmlearn.models.articulation.evaluation as ev

    real = ev._fit_err

    def flaky(model_name, *a, **k):
        if model_name == "gp":
            raise ValueError("gp: too few samples")
        return real(model_name, *a, **k)

    monkeypatch.setattr(ev, "_fit_err", flaky)
    # one job, no shared inputs: the sweep runs its trials in this process (the patch holds)
    res = ae.run(runs=2, quick=True, only=["size"], out_dir=None, progress=False, jobs=1)
    assert res["errors"] == []
    res = res["size"]
    assert res["failed"]["gp"] == [2, 2, 2, 2] and res["error_mean"]["gp"] == [None] * 4
    assert res["failed"]["rigid"] == [0, 0, 0, 0]
    ae._print({"size": res})
    out = capsys.readouterr().out
    assert "failed" in out and "(gp: runs left out of the mean, of 2)" in out


def test_body_schema_experiments_count_failed_runs(monkeypatch):
    import mmlearn.diagrams.body_schema.trials as bst
    from mmlearn.models.body_schema.evaluation import average_runs, recovery_summary

    # a Drake run that raises is a failed run, not a crash and not silently dropped
    def recovery(failure, n_block, seed, n_first=30, show=False):
        if seed == 1:
            raise RuntimeError("solver diverged")
        return dict(first=2, restore=1, second=3)

    monkeypatch.setattr(bst, "drake_recovery", recovery)
    rs = [bst.body_schema_trial(seed=s, block="table_3_1_drake", run=s,
                    kwargs=dict(failure="joint", n_block=5, n_first=30)) for s in range(3)]
    r = recovery_summary(rs, drake=True)
    assert r["failed_runs"] == 1 and r["mean"] == [2.0, 1.0, 3.0] and r["runs"] == 3
    assert "solver diverged" in r["failures"][0]
    # Fig. 3.10 over runs: a run without a complete schema is counted as left out
    rows = [dict(n=10, correct=True, pred_error_m=0.02, pred_error_deg=1.0)]
    left = [dict(n=10, correct=False, error="singular")]
    base = dict(obs_noise_m=0.04, online_converged_at=10, update_ms_median=1.0, seconds=1.0)
    avg = average_runs([dict(base, rows=rows), dict(base, rows=left)])
    assert avg["rows"][0]["runs_in_mean"] == 1 and avg["rows"][0]["runs_left_out"] == 1
    assert avg["rows"][0]["pred_error_m"] == pytest.approx(0.02)


# --------------------------------------------------------------------------- configs, models
def test_view_scene_config_errors_name_the_key(tmp_path, capsys):
    from mmlearn.apps.view_scene import main

    cases = {"sensor: 5\n": "sensor: expected a mapping",
             "arm: [\n": "not valid YAML",
             "sensor:\n  sigma_pos: abc\n": "sensor.sigma_pos: expected a number",
             "cabinet: 3\n": "cabinet: expected true or false",
             "cabnet: false\n": "cabnet"}
    for k, (text, msg) in enumerate(cases.items()):
        p = tmp_path / f"c{k}.yaml"
        p.write_text(text)
        _bad(main, ["--config", str(p)], capsys, "--config", msg)
    _bad(main, ["--config", str(tmp_path / "none.yaml")], capsys, "--config", "not found")
    _bad(main, ["--html_out", str(tmp_path / "x" / "y.html")], capsys, "--html-out")
    _bad(main, ["--duration", "inf"], capsys, "--duration")


def test_learn_body_schema_flag_names(tmp_path, capsys):
    from mmlearn.apps.learn_body_schema import main

    _bad(main, ["--n_test", "0"], capsys, "--n_test: expected a positive integer")
    _bad(main, ["--n-control", "-1"], capsys, "--n-control")
    _bad(main, ["--html-out", str(tmp_path)], capsys, "--html-out", "is a folder")


def test_load_model_errors_are_value_errors(tmp_path):
    from mmlearn.models.articulation.io import load_model, save_model
    from mmlearn.models.articulation.sim import simulate_link
    from mmlearn.models.articulation.structure import select_link_model

    m = select_link_model(simulate_link("revolute", 20, rng=np.random.default_rng(1)).Z,
                          models=["revolute"], rng=0).best
    save_model(m, tmp_path / "m.json")
    d = json.loads((tmp_path / "m.json").read_text())
    del d["link"]["theta"]
    (tmp_path / "k.json").write_text(json.dumps(d))
    with pytest.raises(ValueError, match=r"k\.json: link: missing key\(s\) theta"):
        load_model(tmp_path / "k.json")
    (tmp_path / "bad.yaml").write_text("format: [\n")
    with pytest.raises(ValueError, match=r"bad\.yaml: not valid YAML"):
        load_model(tmp_path / "bad.yaml")
    (tmp_path / "bad.json").write_text("{")
    with pytest.raises(ValueError, match=r"bad\.json: not valid JSON"):
        load_model(tmp_path / "bad.json")
    d = json.loads((tmp_path / "m.json").read_text())
    d["link"]["theta"][0] = float("nan")
    (tmp_path / "n.json").write_text(json.dumps(d))
    with pytest.raises(ValueError, match="non-finite value link.theta"):
        load_model(tmp_path / "n.json")
    d = json.loads((tmp_path / "m.json").read_text())
    d["kind"] = "object"
    (tmp_path / "o.json").write_text(json.dumps(d))
    with pytest.raises(ValueError, match="object: missing"):
        load_model(tmp_path / "o.json")


def test_readable_reprs():
    from mmlearn.models.articulation.link import make_model
    from mmlearn.models.articulation.sim import simulate_link
    from mmlearn.models.articulation.structure import (ArticulatedObject, LinkEdge,
                                                       select_link_model)

    assert repr(make_model("revolute")) == "RevoluteModel(not fitted, sigma_pos=0.01 m)"
    m = select_link_model(simulate_link("revolute", 20, rng=np.random.default_rng(1)).Z,
                          models=["revolute"], rng=0).best
    r = repr(m)
    assert r.startswith("RevoluteModel(n=20, gamma=") and "radius_m=" in r and "<" not in r
    o = ArticulatedObject(["frame", "door"], 0, [LinkEdge(0, 1, m, {})])
    assert repr(o) == ("ArticulatedObject(parts=['frame', 'door'], root='frame', dof=1, "
                       "links=[frame-door: revolute])")
