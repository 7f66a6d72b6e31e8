"""benchmarks/run_speed.py: the speed benchmarks' quick mode, their figures and the table."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

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


def _load(name):
    import importlib.util

    spec = importlib.util.spec_from_file_location(name, BENCH / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_anchored_figures_get_their_ratio_and_target():
    rs = _load("run_speed")
    rows = [dict(name="bench_front_detector", wall_s=1.0, load_start=1.0, load_end=2.0,
                 figures={"total_cpu_ms": 66.6, "planes_cpu_ms": 4.0}, error=None),
            dict(name="bench_peer_gp", wall_s=1.0, load_start=0.5, load_end=0.5,
                 figures={"gp_ms": 10.0, "sklearn_ms": 50.0, "speedup": 5.0}, error=None)]
    got = {(a["benchmark"], a["figure"]): a for a in rs.anchor_rows(rows)}
    total = got[("bench_front_detector", "total_cpu_ms")]
    assert total["ratio"] == pytest.approx(2.0, rel=1e-2) and total["met"] is False
    assert got[("bench_front_detector", "planes_cpu_ms")]["met"] is True
    assert got[("bench_front_detector", "masks_cpu_ms")]["value"] is None  # not measured
    gp = got[("bench_peer_gp", "gp_ms")]
    assert gp["anchor_value"] == 50.0 and gp["ratio"] == pytest.approx(0.2)
    assert not any(b == "bench_articulation" for b, _ in got)  # did not run: no row


def test_performance_page_tables_come_from_the_json(tmp_path):
    js, page = tmp_path / "speed.json", tmp_path / "performance.md"
    js.write_text(json.dumps(dict(cores=2, date="today", benchmarks=[dict(
        name="bench_depth_filter", wall_s=3.0, load_start=1.0, load_end=1.5,
        figures={"filter_cpu_ms": 4.25}, error=None)], anchors=[])))
    page.write_text("# P\n\nkept\n<!-- speed-table:start -->\nold\n<!-- speed-table:end -->\ntail\n")
    r = subprocess.run([sys.executable, str(BENCH / "make_performance_doc.py"), str(js),
                        "--doc", str(page)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    text = page.read_text()
    assert "kept" in text and text.endswith("tail\n") and "old" not in text
    assert "| depth_filter | `filter_cpu_ms` | 4.25 | 3.0 | 1.0-1.5 |" in text
    page.write_text("no markers\n")
    bad = subprocess.run([sys.executable, str(BENCH / "make_performance_doc.py"), str(js),
                          "--doc", str(page)], capture_output=True, text=True)
    assert bad.returncode == 2 and "speed-table" in bad.stderr


def test_demo_benchmark_refuses_no_runs():
    r = subprocess.run([sys.executable, str(BENCH / "bench_demo.py"), "--runs", "0"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "--runs must be >= 1" in r.stderr


def test_demo_benchmark_refuses_a_missing_baseline_interpreter(tmp_path):
    r = subprocess.run([sys.executable, str(BENCH / "bench_demo.py"), "--baseline-python",
                        str(tmp_path / "no_python")], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "--baseline-python: no interpreter" in r.stderr


def test_demo_benchmark_plant_only_runs_on_its_own():
    r = subprocess.run([sys.executable, str(BENCH / "bench_demo.py"), "--plant-only", "--quick"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "--plant-only runs on its own" in r.stderr


@pytest.mark.slow
def test_demo_benchmark_times_the_plant_alone_on_the_trials_commands(tmp_path):
    f = tmp_path / "plant.json"
    r = subprocess.run([sys.executable, str(BENCH / "bench_demo.py"), "--plant-only", "--runs",
                        "1", "--max-time", "2", "--json", str(f)],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stdout + r.stderr
    fig = json.loads(f.read_text())["figures"]
    # the replay follows the trial; both figures are of the same simulated span
    assert fig["replay_opening_difference"] < 1e-6
    assert fig["plant_only_cpu_s"] > 0 and fig["trial_cpu_s"] > 0
    assert fig["plant_only_realtime_factor_cpu"] * fig["plant_only_cpu_s"] == pytest.approx(
        fig["realtime_factor_cpu"] * fig["trial_cpu_s"])
    assert "the plant alone" in r.stdout and "not the plant" in r.stdout


@pytest.mark.slow
def test_demo_benchmark_runs_two_interpreters_in_turn(tmp_path):
    f = tmp_path / "side.json"
    r = subprocess.run([sys.executable, str(BENCH / "bench_demo.py"), "--baseline-python",
                        sys.executable, "--runs", "1", "--max-time", "3", "--json", str(f)],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stdout + r.stderr
    doc = json.loads(f.read_text())
    assert len(doc["runs_this"]) == len(doc["runs_baseline"]) == 1
    this, base = doc["runs_this"][0], doc["runs_baseline"][0]
    assert this["sim_seconds"] == base["sim_seconds"] == pytest.approx(3.0)
    fig = doc["figures"]
    assert fig["speedup_vs_baseline"] == pytest.approx(
        (base["cpu_seconds"] / base["sim_seconds"]) / (this["cpu_seconds"] / this["sim_seconds"]))
    assert "this checkout" in r.stdout and "baseline / this checkout" in r.stdout


@pytest.mark.slow
def test_demo_benchmark_times_the_readme_demo(tmp_path):
    f = tmp_path / "demo.json"
    r = subprocess.run([sys.executable, str(BENCH / "bench_demo.py"), "--quick", "--json", str(f)],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stdout + r.stderr
    doc = json.loads(f.read_text())
    fig = doc["figures"]
    assert doc["runs"] == 1 and fig["success"] == 1.0
    assert fig["simulated_s"] > 5 and fig["simulation_cpu_s"] > 0
    assert abs(fig["realtime_factor_cpu"] - fig["simulated_s"] / fig["simulation_cpu_s"]) < 1e-9
