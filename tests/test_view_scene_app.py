import base64
import json
import re
import subprocess
import sys

import numpy as np
import pytest

from headless_browser import chromium, screenshot_or_skip
from mmlearn.apps import view_scene


def _run(args, cwd):
    return subprocess.run([sys.executable, "-m", "mmlearn.apps.view_scene", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=300)


@pytest.mark.slow
def test_help(tmp_path):
    r = _run(["--help"], tmp_path)
    assert r.returncode == 0
    assert "--html-out" in r.stdout and "--meshcat" in r.stdout


@pytest.mark.slow
def test_json_run_with_html_recording(tmp_path):
    out = tmp_path / "rec" / "scene.html"
    out.parent.mkdir()  # an output path into a missing folder is bad input (test_cli.py)
    # run from an unrelated working directory: the app finds its models by itself
    r = _run(["--arm", "7dof", "--duration", "1", "--seed", "3", "--json", "--html-out",
              str(out)], tmp_path)
    assert r.returncode == 0, r.stderr
    res = json.loads(r.stdout)
    assert res["frames"] == 10 and res["markers"] == 10
    assert res["marker_observations"] == 100
    assert 0 < res["visible"] <= 100
    assert res["html_out"] == str(out)
    # the recording embeds Meshcat's commands as base64 msgpack; they name the scene's
    # objects: the robot's parts and the cabinet's
    blobs = re.findall(r"base64,([A-Za-z0-9+/=]+)", out.read_text())
    decoded = b"".join(base64.b64decode(b) for b in blobs)
    for name in (b"robot", b"x10", b"cabinet", b"left_door", b"drawer"):
        assert name in decoded, name


def test_same_seed_same_counts():
    cfg = lambda: view_scene.ViewSceneConfig(duration=0.5, seed=5)  # noqa: E731
    a = view_scene.run(config=cfg(), show_progress=False)
    b = view_scene.run(config=cfg(), show_progress=False)
    assert a["visible"] == b["visible"] and a["frames"] == b["frames"] == 5


@pytest.mark.slow
def test_bad_arguments_give_clear_errors(tmp_path):
    r = _run(["--duration", "-1"], tmp_path)
    assert r.returncode == 2 and "--duration: expected a finite number > 0" in r.stderr
    bad = tmp_path / "bad.yaml"
    bad.write_text("arm: 2dof\ncabinett: false\n")
    r = _run(["--config", str(bad)], tmp_path)
    assert r.returncode == 2 and "cabinett" in r.stderr
    r = _run(["--config", str(tmp_path / "missing.yaml")], tmp_path)
    assert r.returncode == 2 and "not found" in r.stderr


def test_recording_renders_in_a_headless_browser(tmp_path):
    """Open the exported HTML in a real browser; the screenshot must show the arm (orange)
    and the cabinet (light wood), not a blank page."""
    browser = chromium()
    if browser is None:
        pytest.skip("no chromium on this machine (.ci/run installs Debian's chromium)")
    cv2 = pytest.importorskip("cv2")
    html = tmp_path / "scene.html"
    view_scene.run(config=view_scene.ViewSceneConfig(duration=0.5, html_out=str(html)),
                   show_progress=False)
    png = tmp_path / "shot.png"
    screenshot_or_skip(browser, html, png)
    img = cv2.imread(str(png))
    assert img is not None, "the browser wrote no screenshot"
    b, g, r = (img[..., i].astype(int) for i in range(3))
    orange = (r > 170) & (g > 80) & (g < 190) & (b < 80) & (r - g > 50)
    wood = (r > 180) & (g > 150) & (b > 90) & (b < 200) & (r - b > 40)
    assert orange.sum() > 150, f"arm not visible ({orange.sum()} orange pixels)"
    assert wood.sum() > 1000, f"cabinet not visible ({wood.sum()} wood pixels)"
    assert np.std(img) > 10
