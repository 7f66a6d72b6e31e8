"""The body-schema apps: --help and short runs as subprocesses."""

import json
import subprocess

import pytest

from conftest import PYTHON


def _run(args, cwd, timeout=300):
    return subprocess.run([PYTHON, "-m", *args], capture_output=True, text=True, cwd=cwd,
                          timeout=timeout)


def test_learn_body_schema_help(tmp_path):
    r = _run(["mmlearn.apps.learn_body_schema", "--help"], tmp_path)
    assert r.returncode == 0 and "--occlude" in r.stdout and "--json" in r.stdout


@pytest.mark.slow
def test_learn_body_schema_short_run_json(tmp_path):
    r = _run(["mmlearn.apps.learn_body_schema", "--arm", "2dof", "--samples", "24",
              "--noise", "0.01", "--n-test", "30", "--n-control", "1", "--seed", "1",
              "--json"], tmp_path)
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    for k in ("structure", "converged_at", "pred_error_m", "pred_error_deg", "obs_noise_m",
              "ctrl_error_m", "seconds"):
        assert k in d
    # seed 1: the search on the first 10 samples calls x1-x2 rigid (x2 seen only 7 times);
    # the tree turns invalid and the re-search on the later samples corrects it
    assert d["structure_correct"] and d["converged_at"] <= 24
    assert {tuple(sorted((e["a"], e["b"]))) for e in d["structure"]} == \
        {("x1", "x2"), ("x2", "x3"), ("x3", "x4")}
    assert d["pred_error_m"] < 0.05 and d["ctrl_error_m"] < 0.1


@pytest.mark.slow
def test_learn_body_schema_bad_args(tmp_path):
    r = _run(["mmlearn.apps.learn_body_schema", "--samples", "0"], tmp_path)
    assert r.returncode == 2 and "samples" in r.stderr
    r = _run(["mmlearn.apps.learn_body_schema", "--occlude", "x99", "--samples", "3"], tmp_path)
    assert r.returncode == 2 and "x99" in r.stderr


def test_body_schema_experiments_help(tmp_path):
    r = _run(["mmlearn.apps.body_schema_experiments", "--help"], tmp_path)
    assert r.returncode == 0 and "--quick" in r.stdout and "numpy" in r.stdout


@pytest.mark.slow
def test_body_schema_experiments_quick(tmp_path):
    r = _run(["mmlearn.apps.body_schema_experiments", "--quick", "--json", "--out-dir",
              str(tmp_path / "out")], tmp_path, timeout=600)
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert (tmp_path / "out" / "fig_3_10.png").stat().st_size > 1000
    assert (tmp_path / "out" / "body_schema_experiments.json").is_file()
    assert d["where"]["fig_3_10"] == "drake"
    rows = {r["n"]: r for r in d["fig_3_10"]["rows"]}
    assert rows[20]["correct"] and rows[20]["pred_error_m"] < 0.06
    assert d["noise_free"]["rows"][0]["pred_error_m"] < 0.01  # 20 noise-free samples
    t = d["table_3_2_drake"]
    assert t["bent_static"] > 0.1 and t["bent_adaptive"] < 0.05  # adaptation helps
    st = d["7dof_structure"]
    assert len(st) == 1 and [r["n"] for r in st[0]["rows"]] == [8, 10, 12]
    assert st[0]["noise"] == 0.044 and st[0]["occluded"] == ["x4"]
    for f in ("joint", "tool"):
        assert d["table_3_1_drake"][f]["first"] > 0  # the failure is noticed
        assert d["table_3_1_drake"][f]["runs"] == 1
        assert len(d["table_3_1_numpy"][f]["mean"]) == 3
    # the tables, the plot and the JSON come from the results file: --report-only on it
    # reproduces them without running anything
    from mmlearn.apps.body_schema_experiments import format_report

    res = tmp_path / "out" / "body_schema_experiments_results.jsonl"
    assert len(res.read_text().splitlines()) == 10  # one line per run
    ro = _run(["mmlearn.apps.body_schema_experiments", "--report-only", str(res),
               "--out-dir", str(tmp_path / "ro")], tmp_path)
    assert ro.returncode == 0, ro.stderr
    table = ro.stdout.rsplit("\nplots:", 1)[0]
    assert "Table 3.1" in table and "Table 3.2" in table and "Fig. 3.10" in table
    assert table == format_report(d).rsplit("\nplots:", 1)[0]
    assert (tmp_path / "ro" / "fig_3_10.png").stat().st_size > 1000
    ro_json = json.loads((tmp_path / "ro" / "body_schema_experiments.json").read_text())
    for k in ("fig_3_10", "noise_free", "7dof_structure", "table_3_1_drake", "table_3_2_numpy"):
        assert json.dumps(ro_json[k]) == json.dumps(d[k])
