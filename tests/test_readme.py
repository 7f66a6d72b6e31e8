"""The README's promises: its first two commands and its reuse example."""

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()


def test_first_lines_are_the_two_commands():
    block = re.search(r"```bash\n(.*?)```", README, re.S).group(1).splitlines()
    assert block[0].startswith("# 1. set up and run the main demo")
    assert "python -m mmlearn.apps." in block[1] and "venv" in block[1]
    assert block[2].startswith("# 2. set up and run the test suite")
    assert "pytest" in block[3] and "venv" in block[3]
    # .ci/run runs exactly that second command
    assert "set up and run the test suite" in (ROOT / ".ci" / "run").read_text()


@pytest.mark.slow
def test_reuse_example_runs(tmp_path):
    code = re.search(r"## Reusing a system.*?```python\n(.*?)```", README, re.S).group(1)
    script = tmp_path / "example.py"
    script.write_text(code)
    r = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "['x1', 'x2', 'x3']" in r.stdout


def test_reuse_example_observes_the_falling_arm():
    code = re.search(r"## Reusing a system.*?```python\n(.*?)```", README, re.S).group(1)
    ns: dict = {}
    exec(compile(code.replace("print(", "(lambda *a: None)("), "README", "exec"), ns)
    obs = ns["obs"]
    assert obs.time > 0.9
    arr = obs.as_array()
    # the base marker does not move; noise 0.01 m
    assert np.all(np.isnan(arr[~obs.visible]))
    assert arr.shape == (3, 7)


def test_readme_is_short_and_points_at_the_docs():
    lines = README.splitlines()
    assert len(lines) <= 300
    assert max(len(line) for line in lines) <= 250
    assert "../" + "shared" not in README
    # every docs page the README links to exists
    for page in re.findall(r"\]\((docs/[\w/]+\.md)\)", README):
        assert (ROOT / page).is_file(), page
    assert "chromium" in README.split("## Quick tour")[0]
