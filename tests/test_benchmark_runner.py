"""benchmarks/run_speed.py: the speed benchmarks' quick mode, their figures and the table."""

import json
import subprocess
import sys
from pathlib import Path

BENCH = Path(__file__).resolve().parents[1] / "benchmarks"


def test_run_speed_lists_every_speed_benchmark():
    out = subprocess.run([sys.executable, str(BENCH / "run_speed.py"), "--list"],
                         capture_output=True, text=True, check=True).stdout.split()
    assert all((BENCH / f"{name}.py").is_file() for name in out) and len(out) >= 14


def test_run_speed_runs_a_benchmark_quick_and_writes_its_figures(tmp_path):
    f = tmp_path / "speed.json"
    r = subprocess.run([sys.executable, str(BENCH / "run_speed.py"), "--only", "depth_filter",
                        "--json", str(f)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    (row,) = json.loads(f.read_text())["benchmarks"]
    assert row["name"] == "bench_depth_filter" and row["error"] is None
    assert row["figures"]["filter_cpu_ms"] > 0 and row["load_start"] >= 0
    assert "filter_cpu_ms" in r.stdout and "load" in r.stdout
    bad = subprocess.run([sys.executable, str(BENCH / "run_speed.py"), "--only", "nope"],
                         capture_output=True, text=True)
    assert bad.returncode == 2 and "not a speed benchmark" in bad.stderr
