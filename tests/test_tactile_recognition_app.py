"""The tactile_recognition app (thesis ch. 6): a short run, --report-only, the recording of
one grasp and bad arguments."""

import json

import pytest
from conftest import bad_usage, run_main


# ------------------------------------------------------------------ the app
@pytest.mark.slow
def test_app_short_run_and_report_only(tmp_path, capsys):
    from mmlearn.apps.tactile_recognition import main

    res = tmp_path / "g.jsonl"
    argv = ["--classes", "soft_ball,tennis_ball,round_bar,stepped_shaft", "--grasps-per-class",
            "2", "--k", "4", "--T", "2", "--recognitions", "40", "--cv-repeats", "2", "--jobs", "1",
            "--results",
            str(res), "--seed", "3", "--json"]
    rc, out, err = run_main(main, argv, capsys)
    assert rc == 0, err
    d = json.loads(out)
    assert d["n_grasps"] == 8 and not d["errors"] and not d["no_contact"]
    assert set(d["rates"]) == {"all", "household", "industrial", "soft_vs_tennis"}
    for r in d["rates"].values():
        assert 0.0 <= r["rate"] <= 1.0 and r["recognitions"] == 160
    assert d["rates"]["all"]["n_classes"] == 4 and d["thesis"]["rates"]["all"] == 0.846
    assert d["rates"]["all"]["k_used"] == [2]  # half of the 4 training grasps
    lines = [json.loads(x) for x in res.read_text().splitlines()]
    assert len(lines) == 8 and all(ln["error"] is None for ln in lines)
    png = tmp_path / "rec.png"
    rc, out2, err = run_main(main, ["--report-only", str(res), "--k", "4", "--T", "2",
                                    "--recognitions", "40", "--cv-repeats", "2", "--seed", "3",
                                    "--plot", str(png), "--json"], capsys)
    assert rc == 0, err
    d2 = json.loads(out2)
    assert d2["rates"] == d["rates"]  # the same figures from the file alone
    assert set(d2["example_images"]) == {"soft_ball", "tennis_ball", "round_bar",
                                         "stepped_shaft"}
    assert png.stat().st_size > 10_000


@pytest.mark.slow
def test_one_grasp_recorded_as_meshcat_html(tmp_path, monkeypatch):
    import numpy as np

    import mmlearn.systems.common.meshcat_view as view
    from mmlearn.apps.common.cli import make_meshcat
    from mmlearn.apps.tactile_recognition import _show_one

    framed = []
    original = view.frame_camera
    monkeypatch.setattr(view, "frame_camera",
                        lambda mc, pts, **kw: framed.append(np.asarray(pts)) or original(mc, pts, **kw))
    html = tmp_path / "grasp.html"
    rec = _show_one("round_bar", seed=0, meshcat=make_meshcat(announce=False), html_out=html)
    assert rec["contact"] and html.stat().st_size > 100_000
    import base64
    import re
    msgs = b"".join(base64.b64decode(m) for m in
                    re.findall(r'base64,([A-Za-z0-9+/=]+)"', html.read_text()))
    # a legend naming what is drawn, with the grasp's numbers, and a framing camera
    assert b"# mmlearn legend: Tactile grasp for recognition: round_bar" in msgs
    assert b"# taxel cell reading 0" in msgs and b"largest reading" in msgs
    assert f"finger distance {1000 * rec['width']:.1f} mm".encode() in msgs
    # the camera frames the gripper around the grasped part: the grasp height is in view
    assert len(framed) == 1 and framed[0][:, 2].min() <= rec["height"] <= framed[0][:, 2].max()


@pytest.mark.parametrize("argv, needles", [
    (["--alpha", "2"], ["--alpha", "[0, 1]"]),
    (["--classes", "jar"], ["--classes", "jar"]),
    (["--grasps-per-class", "1"], ["grasps_per_class", "at least 2"]),
    (["--k", "0"], ["--k"]),
    (["--report-only", "/nonexistent/x.jsonl"], ["--report-only", "no results file"]),
    (["--report-only", "x.jsonl", "--html-out", "y.html"], ["--report-only simulates nothing"]),
])
def test_app_bad_arguments(argv, needles, capsys):
    from mmlearn.apps.tactile_recognition import main

    bad_usage(main, argv, capsys, *needles)


def test_app_help(capsys):
    from mmlearn.apps.tactile_recognition import main

    rc, out, _ = run_main(main, ["--help"], capsys)
    assert rc == 0 and "--grasps-per-class" in out and "--report-only" in out
