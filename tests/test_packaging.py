"""The wheel maps the folders onto the mmlearn namespace and ships the SDF files."""

import subprocess
import sys
import zipfile

import pytest

from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_wheel_contents(tmp_path):
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation",
                        "-q", "-w", str(tmp_path), str(ROOT)], capture_output=True, text=True,
                       timeout=600)
    if r.returncode != 0 and "No module named" in r.stderr:
        pytest.skip(f"cannot build a wheel here: {r.stderr.strip()[-200:]}")
    assert r.returncode == 0, r.stderr
    wheel = next(tmp_path.glob("mmlearn-*.whl"))
    names = set(zipfile.ZipFile(wheel).namelist())
    for must in ("mmlearn/__init__.py", "mmlearn/systems/common/marker_sensor.py",
                 "mmlearn/models/__init__.py", "mmlearn/models/perception/__init__.py",
                 "mmlearn/diagrams/common/scene.py",
                 "mmlearn/apps/view_scene.py", "mmlearn/sdf/package.xml",
                 "mmlearn/sdf/arm_7dof.sdf", "mmlearn/sdf/cabinet.sdf"):
        assert must in names, must
    # generic top-level names never land in site-packages
    assert not any(n.split("/")[0] in ("models", "systems", "apps", "diagrams", "sdf", "tests")
                   for n in names)
