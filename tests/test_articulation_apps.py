"""Subprocess tests of the articulation apps."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

DATA = Path(__file__).parent / "data" / "articulation_logs"
ENV = {**os.environ, "DRAKE_ALLOW_NETWORK": "meshcat", "OPENBLAS_NUM_THREADS": "1"}


def _run(args, cwd):
    return subprocess.run([sys.executable, "-m", *args], capture_output=True, text=True,
                          cwd=cwd, env=ENV, timeout=300)


@pytest.mark.slow
def test_fit_articulation_help(tmp_path):
    r = _run(["mmlearn.apps.fit_articulation", "--help"], tmp_path)
    assert r.returncode == 0 and "--sigma-pos" in r.stdout and "--json" in r.stdout


@pytest.mark.slow
def test_fit_articulation_json_real_tracks_and_bad_files(tmp_path):
    bad1 = tmp_path / "bad_cols.log"
    bad1.write_text("0 0 0\n0 1 0\n1 2\n0 0 1\n")
    bad2 = tmp_path / "short.log"
    bad2.write_text("0 0 0\n1 1 1\n")
    missing = tmp_path / "missing.log"
    plot = tmp_path / "fit.png"
    r = _run(["mmlearn.apps.fit_articulation", str(DATA), str(missing)], tmp_path)
    assert r.returncode == 2 and "missing.log: file or folder not found" in r.stderr
    r = _run(["mmlearn.apps.fit_articulation", str(bad1), str(bad2)], tmp_path)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1  # nothing fitted
    assert "bad_cols.log:3" in r.stderr and "and 1 more file" in r.stderr
    r = _run(["mmlearn.apps.fit_articulation", str(DATA), str(bad1), str(bad2),
              "--json", "--seed", "1", "--plot", str(plot)], tmp_path)
    assert r.returncode == 1  # some files failed
    out = json.loads(r.stdout)
    by = {Path(t["path"]).name: t for t in out["tracks"]}
    assert by["drawer_001.log"]["selected"] == "prismatic"
    assert by["left_door_001.log"]["selected"] == "revolute"
    p = by["left_door_001.log"]["params"]
    assert 0.3 < p["radius_m"] < 0.4 and len(p["axis"]) == 3 and len(p["center"]) == 3
    assert by["dishwasher_005.log"]["selected"] == "revolute"
    assert by["left_door_001.log"]["avg_orient_error_rad"] is None
    assert by["rectangle_drawer.txt"]["avg_orient_error_rad"] is not None
    for t in out["tracks"]:
        assert set(t) >= {"path", "n", "selected", "bic", "gamma", "avg_pos_error_m",
                          "avg_orient_error_rad", "params", "fit_seconds"}
    assert "bad_cols.log:3: expected 3, 7 or 9 columns" in r.stderr
    assert "short.log: only 2 observation" in r.stderr
    assert len(out["errors"]) == 2
    assert plot.exists() and plot.stat().st_size > 1000


@pytest.mark.slow
def test_articulation_experiments_quick(tmp_path):
    r = _run(["mmlearn.apps.articulation_experiments", "--quick", "--json", "--seed", "0",
              "--out-dir", str(tmp_path / "plots")], tmp_path)
    assert r.returncode == 0, r.stderr
    res = json.loads(r.stdout)
    out = res["outliers"]
    for m in ("rigid", "prismatic", "revolute"):
        # MLESAC estimators stay below the noise level at gamma = 0.5 and estimate gamma
        assert out["error_mean"][m][out["gamma"].index(0.5)] < out["sigma_pos"]
        assert max(out["gamma_abs_dev_mean"][m]) < 0.05
        assert out["unidentifiable_runs_pct"][m][out["gamma"].index(0.0)] == 0.0
        assert out["error_mean_identifiable"][m][0] == pytest.approx(out["error_mean"][m][0])
        assert out["error_median"][m][out["gamma"].index(0.5)] < out["sigma_pos"]
    tab = res["table"]
    assert tab["microwave"]["selected_counts"] == {"revolute": 3}
    assert tab["drawer"]["selected_counts"] == {"prismatic": 3}
    assert tab["microwave"]["models"]["revolute"]["pos_true"] < 0.002
    assert res["bic_n"]["selected"][0] == "prismatic" and res["bic_n"]["selected"][-1] == "gp"
    assert len(res["plots"]) == 7
    assert all(Path(p).exists() for p in res["plots"])


def test_articulation_experiments_help(tmp_path):
    r = _run(["mmlearn.apps.articulation_experiments", "--help"], tmp_path)
    assert r.returncode == 0 and "--runs" in r.stdout and "--quick" in r.stdout


@pytest.mark.slow
def test_articulation_experiments_report_only_reproduces_the_tables(tmp_path):
    """--report-only on the results file of a quick run prints the same tables and JSON and
    redraws the plots; every trial has its own random stream, so one or two jobs give the
    same numbers."""
    args = ["mmlearn.apps.articulation_experiments", "--quick", "--only", "size,table,bic_n"]
    r = _run([*args, "--jobs", "1", "--out-dir", "a"], tmp_path)
    assert r.returncode == 0, r.stderr
    res = tmp_path / "a" / "articulation_experiments_results.jsonl"
    n = len(res.read_text().splitlines())
    assert n == 4 * 4 + 5 + 1  # (model, n) points of size, Table 4.2 objects, bic_n runs
    ro = _run(["mmlearn.apps.articulation_experiments", "--report-only", str(res),
               "--out-dir", "b"], tmp_path)
    assert ro.returncode == 0, ro.stderr
    assert ro.stdout.split("plots:")[0] == r.stdout.split("plots:")[0]
    assert "Fig. 4.23" in ro.stdout and "Table 4.2" in ro.stdout and "Fig. 4.25" in ro.stdout
    assert sorted(p.name for p in (tmp_path / "b").glob("*.png")) == [
        "fig4_23_size.png", "fig4_25_bic_n.png"]
    two = _run([*args, "--jobs", "2", "--out-dir", "", "--results", "two.jsonl", "--json"],
               tmp_path)
    assert two.returncode == 0, two.stderr
    one = _run(["mmlearn.apps.articulation_experiments", "--report-only", str(res), "--json",
                "--out-dir", ""], tmp_path)
    d1, d2 = json.loads(one.stdout), json.loads(two.stdout)
    for k in ("size", "table", "bic_n"):
        assert d1[k] == d2[k]
    # a results file holding two settings (here: --runs 2 and 3) is not averaged together
    lines = res.read_text().splitlines()
    other = json.loads(lines[0])
    other["spec"]["params"]["runs"], other["key"] = 3, "x" * 20
    mixed = tmp_path / "mixed.jsonl"
    mixed.write_text("\n".join(lines) + "\n" + json.dumps(other) + "\n")
    r = _run(["mmlearn.apps.articulation_experiments", "--report-only", str(mixed),
              "--out-dir", ""], tmp_path)
    assert r.returncode == 2 and "mixes settings" in r.stderr and "mixed.jsonl" in r.stderr
