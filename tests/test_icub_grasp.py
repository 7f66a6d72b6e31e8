"""The iCub grasp dataset reader and the tactile_state app on real grasps (tests/data/icub_grasp:
trials 1-4 of four objects + one full_coke file, see PROVENANCE.md there)."""

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import run_main

from mmlearn.models.tactile.icub_grasp import (CONTACT_LEVEL, REST_VELOCITY, ICubFileError,
                                               load_icub_dir, read_icub_trial)

DATA = Path(__file__).parent / "data" / "icub_grasp"


def test_reads_the_real_files():
    tr = read_icub_trial(DATA / "blue_bear_1.txt")
    assert (tr.label, tr.trial, tr.n) == ("blue_bear", 1, 12)
    assert tr.encoders.shape == (12, 9) and tr.taxels.shape == (12, 5, 12)
    assert tr.encoders[0, 0] == pytest.approx(20.7273)  # first value after the header
    assert tr.taxels[0, 0, 0] == 242.0 and tr.taxels[0, 4, 11] == 245.0
    assert tr.line_numbers[0] == 2 and tr.line_numbers[1] == 9
    g = tr.to_grasp()
    assert g.n == 12 and np.all(g.f > 0) and g.finger_force.shape == (12, 5)
    np.testing.assert_allclose(g.f, (255 - tr.taxels).sum(axis=(1, 2)))
    # per-finger maxima in the file agree with the taxels within a few counts
    assert np.max(np.abs(tr.finger_max - (255 - tr.taxels).max(axis=2))) <= 3


def test_directory_skips_full_coke_by_default_and_filters_trials():
    trials, errors = load_icub_dir(DATA)
    labels = sorted({t.label for t in trials})
    assert labels == ["blue_bear", "book", "med_coke", "none"] and not errors
    assert len(trials) == 16
    with_coke, _ = load_icub_dir(DATA, include_unreliable=True)
    assert len(with_coke) == 17
    few, _ = load_icub_dir(DATA, trials={1, 2})
    assert len(few) == 8 and {t.trial for t in few} == {1, 2}


def _copy(tmp_path, name="book_1.txt", new=None):
    dst = tmp_path / (new or name)
    shutil.copy(DATA / name, dst)
    return dst


def _lines(p):
    return p.read_text().splitlines()


@pytest.mark.parametrize("case", ["truncated", "nan", "negative", "above255", "label",
                                  "short_line", "header", "one_slice", "text"])
def test_bad_files_give_errors_naming_file_and_line(tmp_path, case):
    p = _copy(tmp_path)
    L = _lines(p)
    if case == "truncated":  # the last time slice lost its last 3 lines
        p.write_text("\n".join(L[:-3]) + "\n")
        match = r"book_1\.txt:\d+: the last time slice is truncated"
    elif case == "nan":
        L[10] = L[10].replace("242.0", "nan", 1) if "242.0" in L[10] else "nan " + L[10].split(" ", 1)[1]
        p.write_text("\n".join(L))
        match = r"book_1\.txt:11: NaN"
    elif case == "negative":
        tok = L[4].split()
        tok[3] = "-5.0"
        L[4] = " ".join(tok)
        p.write_text("\n".join(L))
        match = r"book_1\.txt:5: negative index taxel reading"
    elif case == "above255":
        tok = L[5].split()
        tok[0] = "300"
        L[5] = " ".join(tok)
        p.write_text("\n".join(L))
        match = r"book_1\.txt:6: middle taxel reading above 255"
    elif case == "label":
        p = _copy(tmp_path, new="teapot_3.txt")
        match = r"teapot_3\.txt: unknown object label 'teapot'"
    elif case == "short_line":
        L[3] = " ".join(L[3].split()[:7])
        p.write_text("\n".join(L))
        match = r"book_1\.txt:4: time slice 1 is truncated or malformed: expected 12 thumb"
    elif case == "header":
        p.write_text("\n".join(L[1:]))
        match = r"book_1\.txt:1: expected the header line '-10000'"
    elif case == "one_slice":
        p.write_text("\n".join(L[:8]))
        match = r"book_1\.txt: 1 time slice\(s\); at least 2"
    elif case == "text":
        L[2] = L[2].replace("1", "x", 1)
        p.write_text("\n".join(L))
        match = r"book_1\.txt:3: non-numeric"
    with pytest.raises(ICubFileError, match=match):
        read_icub_trial(p)


def test_directory_errors(tmp_path):
    with pytest.raises(ICubFileError, match="folder not found"):
        load_icub_dir(tmp_path / "nope")
    with pytest.raises(ICubFileError, match="no trial files"):
        load_icub_dir(tmp_path)
    _copy(tmp_path)
    (tmp_path / "mystery_1.txt").write_text("-10000\n")
    with pytest.raises(ICubFileError, match="unknown object label 'mystery'"):
        load_icub_dir(tmp_path)
    trials, errors = load_icub_dir(tmp_path, strict=False)
    assert len(trials) == 1 and len(errors) == 1 and "mystery_1.txt" in errors[0]


def test_features_on_real_grasps_find_contact_where_fingers_press():
    from mmlearn.models.tactile.state import feature_matrix

    trials, _ = load_icub_dir(DATA)
    X, feats = feature_matrix([t.to_grasp() for t in trials], contact_force=CONTACT_LEVEL,
                              rest_velocity=REST_VELOCITY)
    assert X.shape == (16, 6) and np.all(np.isfinite(X))
    contact = {t.label: [] for t in trials}
    for t, f in zip(trials, feats):
        contact[t.label].append(f.contact)
    # the can is squeezed by several fingers; the empty hand touches nothing
    assert all(contact["med_coke"]) and not any(contact["none"])


# --------------------------------------------------------------------------- app
def _main(argv, capsys):
    from mmlearn.apps.tactile_state import main

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
])
def test_cli_errors_exit_2_with_one_line(argv, needle, capsys):
    rc, out, err = _main(argv, capsys)
    assert rc == 2, (rc, out, err)
    assert needle in err.strip().splitlines()[-1], err
    assert "Traceback" not in err


def test_cli_bad_file_in_folder_names_it(tmp_path, capsys):
    for n in ("book_1.txt", "book_2.txt", "none_1.txt", "none_2.txt"):
        _copy(tmp_path, n)
    p = tmp_path / "book_2.txt"
    p.write_text("\n".join(_lines(p)[:-2]))
    rc, out, err = _main(["--train", str(tmp_path), "--folds", "2"], capsys)
    assert rc == 2 and "book_2.txt" in err and "truncated" in err


def test_cli_test_classes_must_be_trained(tmp_path, capsys):
    tr, te = tmp_path / "tr", tmp_path / "te"
    tr.mkdir()
    te.mkdir()
    for n in ("book_1.txt", "none_1.txt", "book_2.txt", "none_2.txt"):
        _copy(tr, n)
    _copy(te, "med_coke_1.txt")
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
        _copy(tr if f.stem.endswith(("_1", "_2")) else te, f.name)
    rc, out, err = _main(["--train", str(tr), "--test", str(te), "--json"], capsys)
    assert rc == 0, err
    d = json.loads(out)
    assert d["evaluation"] == "test" and d["n_train"] == 8 and d["n_test"] == 8
    assert d["classifier"] == "forest" and d["rate"] >= 0.5  # 4 classes: chance is 0.25


def test_app_help_as_subprocess():
    r = subprocess.run([sys.executable, "-m", "mmlearn.apps.tactile_state", "--help"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and "--include-full-coke" in r.stdout and "--train" in r.stdout
