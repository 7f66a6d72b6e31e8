"""Apps fit_structure, learn_priors, structure_experiments: --help, short runs, bad input."""

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

from conftest import PYTHON

DATA = Path(__file__).parent / "data" / "articulation_priors"


def _run(*args, cwd=None):
    return subprocess.run([PYTHON, "-m", *args], capture_output=True, text=True, cwd=cwd,
                          timeout=300)


@pytest.mark.parametrize("app", ["fit_structure", "learn_priors", "structure_experiments"])
def test_help(app):
    r = _run(f"mmlearn.apps.{app}", "--help")
    assert r.returncode == 0 and "usage" in r.stdout.lower()


@pytest.fixture(scope="module")
def closed_csv(tmp_path_factory):
    from mmlearn.diagrams.common.object_tracks import yardstick_scenario
    from mmlearn.models.articulation.graph import write_parts_csv

    tr = yardstick_scenario(True, 60, rng=5)
    Y = tr.poses.copy()
    Y[3, 7] = np.nan  # one missing observation
    p = tmp_path_factory.mktemp("csv") / "closed.csv"
    write_parts_csv(p, tr.parts, np.arange(60) * 0.1, Y)
    return p


@pytest.mark.slow
def test_fit_structure_closed_yardstick(closed_csv, tmp_path):
    png = tmp_path / "s.png"
    r = _run("mmlearn.apps.fit_structure", str(closed_csv), "--search", "local",
             "--reduce-dofs", "--sigma-pos", "0.005", "--sigma-orient", "0.05",
             "--models", "rigid,prismatic,revolute", "--json", "--plot", str(png), cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert set(out) == {"parts", "edges", "dof", "has_loop", "bic", "seconds"}
    assert out["parts"] == ["seg1", "seg2", "seg3", "seg4"]
    assert out["dof"] == 1 and out["has_loop"] is True
    assert len(out["edges"]) == 4
    assert all(set(e) == {"a", "b", "model", "bic"} for e in out["edges"])
    assert all(e["model"] == "revolute" for e in out["edges"])
    assert png.stat().st_size > 1000


@pytest.mark.slow
def test_fit_structure_bad_input(tmp_path, closed_csv):
    bad = tmp_path / "bad.csv"
    bad.write_text("time,part,x,y,z,qx,qy,qz,qw\n")
    r = _run("mmlearn.apps.fit_structure", str(bad))
    assert r.returncode == 2 and "bad header" in r.stderr
    r = _run("mmlearn.apps.fit_structure", str(tmp_path / "none.csv"))
    assert r.returncode == 2 and "not found" in r.stderr
    r = _run("mmlearn.apps.fit_structure", str(closed_csv), "--models", "rigid,screw")
    assert r.returncode == 2 and "screw" in r.stderr
    r = _run("mmlearn.apps.fit_structure", str(closed_csv), "--search", "bfs")
    assert r.returncode == 2


@pytest.mark.slow
def test_learn_priors_clusters_real_tracks(tmp_path):
    db = tmp_path / "db.json"
    r = _run("mmlearn.apps.learn_priors", str(DATA), "--json", "--save", str(db),
             "--no-progress", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert len(out["clusters"]) == 4 and len(out["models"]) == 4
    for c in out["clusters"]:
        assert len({Path(p).name.rsplit("_", 1)[0] for p in c}) == 1
    assert json.loads(db.read_text())["format"] == "mmlearn.articulation_priors"


@pytest.mark.slow
def test_learn_priors_evaluate(tmp_path):
    files = [str(DATA / f) for f in ("drawer_001.log", "right_door_001.log", "drawer_002.log",
                                     "right_door_002.log")]
    png = tmp_path / "e.png"
    r = _run("mmlearn.apps.learn_priors", *files, "--evaluate", "--fractions", "0.5",
             "--json", "--plot", str(png), "--no-progress")
    assert r.returncode == 0, r.stderr
    ev = json.loads(r.stdout)["evaluation"]
    assert ev["fractions"] == [0.5]
    assert ev["ratio"][0] > 3
    assert png.stat().st_size > 1000


@pytest.mark.slow
def test_learn_priors_bad_input(tmp_path):
    r = _run("mmlearn.apps.learn_priors", str(tmp_path / "missing.log"))
    assert r.returncode == 2 and "not found" in r.stderr
    bad = tmp_path / "bad.log"
    bad.write_text("0 0\n1 1\n")
    r = _run("mmlearn.apps.learn_priors", str(bad))
    assert r.returncode == 2 and "bad.log" in r.stderr
    r = _run("mmlearn.apps.learn_priors", str(DATA), "--fractions", "half", "--evaluate")
    assert r.returncode == 2 and "fractions" in r.stderr


@pytest.mark.slow
def test_structure_experiments_quick(tmp_path):
    r = _run("mmlearn.apps.structure_experiments", "--quick", "--only", "fig48,fig416,garage", "--seeds", "1",
             "--json", "--out-dir", str(tmp_path), "--no-progress")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    s = out["fig416"]["summary"]
    assert s["open"]["right_dof"] == s["open"]["runs"]
    assert s["closed"]["right_dof"] == s["closed"]["runs"]
    assert s["closed"]["max_gap_local_pct"] < 5
    for key in ("open", "closed"):  # CPU times are reported; the local search visits fewer graphs
        assert s[key]["search_cpu_seconds_local"] > 0 and s[key]["pair_fit_cpu_seconds"] > 0
        assert s[key]["graphs_local_mean"] < s[key]["graphs_exhaustive_mean"] == 38
    assert out["garage"]["selected"].startswith("gp")
    last = out["fig48"]["rows"][-1]
    assert sorted(m for _, _, m in last["edges"]) == ["prismatic", "prismatic"]
    r = _run("mmlearn.apps.structure_experiments", "--only", "fig99")
    assert r.returncode == 2 and "fig99" in r.stderr


@pytest.mark.slow
def test_structure_experiments_report_only_reproduces_the_tables(tmp_path):
    """The tables and plots come from the results file: --report-only on the file of a
    quick run prints the same tables; a trial that raised is named and exits 1."""
    args = ["--quick", "--only", "garage,fig411,fig49", "--no-progress", "--jobs", "1"]
    r = _run("mmlearn.apps.structure_experiments", *args, "--out-dir", str(tmp_path / "a"))
    assert r.returncode == 0, r.stderr
    res = tmp_path / "a" / "structure_experiments_results.jsonl"
    lines = [json.loads(x) for x in res.read_text().splitlines()]
    assert sorted(ln["spec"]["label"] for ln in lines) == ["fig411", "fig49", "garage"]
    assert "Roll-up garage door: selected gp" in r.stdout and "Fig. 4.11" in r.stdout
    ro = _run("mmlearn.apps.structure_experiments", "--report-only", str(res), "--only",
              "garage,fig411,fig49", "--out-dir", str(tmp_path / "b"))
    assert ro.returncode == 0, ro.stderr
    assert ro.stdout.split("plots:")[0] == r.stdout.split("plots:")[0]
    assert (tmp_path / "b" / "fig49_table.png").stat().st_size > 1000
    # the same command again runs nothing (every trial is in the file)
    again = _run("mmlearn.apps.structure_experiments", *args, "--out-dir", str(tmp_path / "a"))
    assert again.returncode == 0 and again.stdout == r.stdout
    assert len(res.read_text().splitlines()) == 3
    # a trial that raised: recorded with its error, left out of the tables, named, exit 1
    bad = dict(lines[0], record=None, error="RuntimeError: boom", traceback="...")
    (tmp_path / "bad.jsonl").write_text(json.dumps(bad) + "\n" + json.dumps(lines[1]) + "\n")
    ro = _run("mmlearn.apps.structure_experiments", "--report-only", str(tmp_path / "bad.jsonl"))
    assert ro.returncode == 1 and "raised an error: " + lines[0]["spec"]["label"] in ro.stderr
    assert "RuntimeError: boom" in ro.stdout
    ro = _run("mmlearn.apps.structure_experiments", "--report-only", str(tmp_path / "none.jsonl"))
    assert ro.returncode == 2 and "none.jsonl" in ro.stderr
