"""The tactile_state app (thesis Sec. 7.1-7.2): real iCub grasps (tests/data/icub_grasp) and
the simulation mode, results, plots, recordings and bad arguments."""

import base64
import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import run_main

from mmlearn.apps.tactile_state import main

DATA = Path(__file__).parent / "data" / "icub_grasp"


# --------------------------------------------------------------------------- real grasps
def _main(argv, capsys):
    return run_main(main, argv, capsys)


@pytest.mark.parametrize("argv, needle", [
    ([], "--train DIR is required"),
    (["--f-target", "20", "--train", str(DATA)], "--f-target applies to simulation mode only"),
    (["--train", "/nonexistent/dir"], "--train: /nonexistent/dir: folder not found"),
    (["--train", str(DATA), "--classifier", "svm"], "--classifier"),
    (["--train", str(DATA), "--folds", "0"], "--folds"),
    (["--train", str(DATA), "--plot", "/nonexistent/x.png"], "--plot: folder"),
    (["--train", str(DATA), "--folds", "10"], "needs at least 10 instances per class"),
    (["--train", str(DATA), "--meshcat"], "--meshcat: real-data mode has no 3-D scene"),
    (["--train", str(DATA), "--report-only", "r.jsonl"], "--report-only applies to simulation"),
])
def test_cli_errors_exit_2_with_one_line(argv, needle, capsys):
    rc, out, err = _main(argv, capsys)
    assert rc == 2, (rc, out, err)
    assert needle in err.strip().splitlines()[-1], err
    assert "Traceback" not in err


def test_cli_bad_file_in_folder_names_it(tmp_path, capsys):
    for n in ("book_1.txt", "book_2.txt", "none_1.txt", "none_2.txt"):
        shutil.copy(DATA / n, tmp_path / n)
    p = tmp_path / "book_2.txt"
    p.write_text("\n".join(p.read_text().splitlines()[:-2]))
    rc, out, err = _main(["--train", str(tmp_path), "--folds", "2"], capsys)
    assert rc == 2 and "book_2.txt" in err and "truncated" in err


def test_cli_test_classes_must_be_trained(tmp_path, capsys):
    tr, te = tmp_path / "tr", tmp_path / "te"
    tr.mkdir()
    te.mkdir()
    for n in ("book_1.txt", "none_1.txt", "book_2.txt", "none_2.txt"):
        shutil.copy(DATA / n, tr / n)
    shutil.copy(DATA / "med_coke_1.txt", te / "med_coke_1.txt")
    rc, out, err = _main(["--train", str(tr), "--test", str(te)], capsys)
    assert rc == 2 and "classes that --train lacks: med_coke" in err


@pytest.mark.slow
def test_cli_quick_runs_cv_and_split(tmp_path, capsys):
    plot = tmp_path / "conf.png"
    rc, out, err = _main(["--train", str(DATA), "--folds", "4", "--seed", "3", "--json",
                          "--classifier", "tree", "--plot", str(plot)], capsys)
    assert rc == 0, err
    d = json.loads(out)
    assert d["evaluation"] == "4-fold CV" and d["n_train"] == 16
    assert d["labels"] == ["blue_bear", "book", "med_coke", "none"]
    assert np.array(d["confusion"]).sum() == 16
    assert 0.0 <= d["rate"] <= 1.0 and set(d["per_class"]) == set(d["labels"])
    assert set(d["compare"]) == {"forest", "boost"} and d["no_contact"]["none"] == 4
    assert plot.stat().st_size > 10_000
    # train on trials 1-2, test on 3-4
    tr, te = tmp_path / "tr", tmp_path / "te"
    tr.mkdir()
    te.mkdir()
    for f in DATA.glob("*_[1-4].txt"):
        if f.name.startswith("full_coke"):
            continue
        shutil.copy(f, (tr if f.stem.endswith(("_1", "_2")) else te) / f.name)
    rc, out, err = _main(["--train", str(tr), "--test", str(te), "--json"], capsys)
    assert rc == 0, err
    d = json.loads(out)
    assert d["evaluation"] == "test" and d["n_train"] == 8 and d["n_test"] == 8
    assert d["classifier"] == "forest" and d["rate"] >= 0.5  # 4 classes: chance is 0.25


def test_app_help_as_subprocess():
    r = subprocess.run([sys.executable, "-m", "mmlearn.apps.tactile_state", "--help"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and "--include-full-coke" in r.stdout and "--train" in r.stdout


# --------------------------------------------------------------------------- simulation
@pytest.mark.slow
def test_simulation_mode_small_run(tmp_path, capsys):
    """The app's simulation mode end to end on 6 short grasps (cans: 3 states x 2)."""
    res = tmp_path / "grasps.jsonl"
    png, html = tmp_path / "sim.png", tmp_path / "grasp.html"
    rc = main(["--f-target", "20", "--containers", "can", "--trials", "2", "--folds", "2",
               "--jobs", "1", "--results", str(res), "--seed", "3", "--json",
               "--plot", str(png), "--html-out", str(html)])
    out, err = capsys.readouterr()
    assert rc == 0, err
    d = json.loads(out)
    # the plot (profiles, impact, tactile images) and the Meshcat recording of one grasp
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 20_000
    text = html.read_text()
    assert text.lstrip().lower().startswith("<!doctype html")
    msgs = [base64.b64decode(m) for m in re.findall(r'base64,([A-Za-z0-9+/=]+)"', text)]
    anim = [m for m in msgs if b"set_animation" in m]
    # the recording animates the taxel cells (colour and height) along with the scene
    assert anim and b"taxels/left/r00c00" in anim[0] and b"scale" in anim[0]
    # its legend: the grasped container and state, the taxel colours, the controller
    legend = b"".join(msgs)
    assert b"# mmlearn legend: Tactile grasp of can/" in legend
    assert b"# controller: switching, 20 N per finger" in legend
    # the colour scale is fitted to the grasp's readings (far below saturation) and stated
    scale = float(re.search(rb"colour scale 0-([0-9.]+)", legend).group(1))
    assert 0.05 <= scale < 1.0
    assert d["demo_grasp"]["container"] == "can" and d["demo_grasp"]["f_max_N"] > 20.0
    peaks = d["demo_grasp"]["impact_peak_N"]  # Fig. 7.5 vs 7.6 at 10 N
    assert peaks["switching"] < 10.5 < 12.0 < peaks["force"], peaks
    assert d["mode"] == "simulation" and d["n_grasps"] == 6 and d["no_contact"] == 0
    assert set(d["state_rate_by_container"]) == {"can"}
    assert 0.0 <= d["state_rate_by_container"]["can"] <= 1.0
    assert 0.0 <= d["combined_rate"] <= 1.0
    recs = [json.loads(ln) for ln in res.read_text().splitlines()]
    assert len(recs) == 6 and all(r["error"] is None for r in recs)
    # the readings carry no label: a record's series are numbers only
    assert all(isinstance(v, float) for v in recs[0]["record"]["p"])
    # --report-only recomputes the same report from the grasps file without simulating
    rc = main(["--f-target", "20", "--containers", "can", "--trials", "2", "--folds", "2",
               "--seed", "3", "--json", "--report-only", str(res)])
    again = json.loads(capsys.readouterr().out)
    for k in ("wall_seconds", "resumed", "demo_grasp"):
        d.pop(k)
    assert rc == 0 and again == d


@pytest.mark.parametrize("argv, needle", [
    (["--f-target", "20", "--containers", "jar"], "--containers"),
    (["--f-target", "20", "--test", "x"], "--test applies to real-data mode only"),
    (["--train", "no_such_dir", "--meshcat"], "--meshcat"),
    (["--train", "no_such_dir", "--html-out", "x.html"], "--html-out"),
    (["--f-target", "20", "--html-out", "/no/such/dir/x.html"], "--html-out"),
])
def test_simulation_bad_flags(argv, needle, capsys):
    rc, _, err = run_main(main, argv, capsys)
    assert rc == 2 and needle in err and "Traceback" not in err
