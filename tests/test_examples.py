"""The runnable examples under examples/ run and print what their docstrings promise."""

import ast
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _run(name: str) -> str:
    r = subprocess.run([sys.executable, str(EXAMPLES / name)], capture_output=True, text=True,
                       timeout=600, env={**os.environ, "OPENBLAS_NUM_THREADS": "1"})
    assert r.returncode == 0, r.stderr[-2000:]
    return r.stdout


def test_every_example_is_short_documented_and_listed():
    page = (EXAMPLES.parent / "docs" / "examples.md").read_text()
    names = sorted(p.name for p in EXAMPLES.glob("*.py"))
    assert len(names) >= 5
    for name in names:
        text = (EXAMPLES / name).read_text()
        doc = ast.get_docstring(ast.parse(text))
        assert doc and f"python examples/{name}" in doc, name
        code = [ln for ln in text[text.index(doc.splitlines()[-1]) + 1:].splitlines()
                if ln.strip() and not ln.lstrip().startswith("#")]
        assert len(code) <= 40, (name, len(code))
        assert f"examples/{name}" in page, f"{name} is not in docs/examples.md"


def test_fit_link_model(capsys):
    import runpy

    runpy.run_path(str(EXAMPLES / "fit_link_model.py"), run_name="__main__")  # no Drake
    out = capsys.readouterr().out
    m = re.search(r"selected revolute: radius ([0-9.]+) m", out)
    assert m and abs(float(m.group(1)) - 0.45) < 0.02, out


@pytest.mark.slow
def test_door_markers():
    m = re.search(r"door: revolute, radius ([0-9.]+) m", _run("door_markers.py"))
    assert m and abs(float(m.group(1)) - 0.336) < 0.02  # the handle's distance to the hinge


@pytest.mark.slow
def test_detect_fronts():
    sizes = [tuple(map(float, s)) for s in
             re.findall(r"([0-9.]+) x ([0-9.]+) m", _run("detect_fronts.py"))]
    # the two doors of cabinet.sdf (0.4 x 0.7 m each) are among the rectangles
    assert sum(abs(w - 0.4) < 0.03 and abs(h - 0.69) < 0.03 for w, h in sizes) >= 2, sizes


@pytest.mark.slow
def test_tactile_grasp():
    out = _run("tactile_grasp.py")
    forces = [float(f) for f in re.search(r"pad forces \[\s*([0-9.]+)\s+([0-9.]+)\]",
                                          out).groups()]
    assert all(abs(f - 10.0) < 1.5 for f in forces), out
    assert "left pad readings" in out and "right pad readings" in out


@pytest.mark.slow
def test_imitate_reach():
    out = _run("imitate_reach.py")
    assert re.search(r"learned \d+ slices of \['obj:target'", out), out
    mm = float(re.search(r"(\d+) mm apart in x-y", out).group(1))
    assert mm < 40, out
