"""benchmarks/bench_body_schema_7dof.py: its report and target judgement on a results file
that already holds every trial (nothing is simulated: the sweep resumes all of them)."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "benchmarks" / "bench_body_schema_7dof.py"


@pytest.fixture(scope="module")
def bench():
    spec = importlib.util.spec_from_file_location("bench_body_schema_7dof", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    sys.modules["bench_body_schema_7dof"] = mod
    spec.loader.exec_module(mod)
    yield mod
    sys.modules.pop("bench_body_schema_7dof", None)


def _write(mod, path, sigma, seeds, conv, pe, on):
    from mmlearn.apps.common.sweep import RESULTS_FORMAT, TrialSpec
    from mmlearn.models.common.trials import trial_id

    with open(path, "a") as f:
        for n, c, p, o in zip(seeds, conv, pe, on):
            s = TrialSpec(fn=mod.trial, seed=n,
                          params={"noise": sigma, "samples": 50})
            rec = {"converged_at": c, "pred_error_m": p, "obs_noise_m": o,
                   "structure_correct": c is not None}
            f.write(json.dumps({"key": s.key, "format": RESULTS_FORMAT,
                                "spec": {"fn": trial_id(s.fn), "params": s.params,
                                                       "seed": n, "label": ""},
                                "record": rec, "error": None, "traceback": None,
                                "wall_s": 1.0, "cpu_s": 1.0}) + "\n")


def test_report_counts_and_targets(bench, tmp_path, capsys):
    res, out = tmp_path / "r.jsonl", tmp_path / "s.json"
    seeds = list(range(1, 11))
    # 7 of 10 within 12 samples (13, 20 and never are not), mean error above the noise
    conv = [5, 12, 13, 8, None, 9, 10, 20, 11, 7]
    pe = [0.008] * 5 + [0.012] * 5
    on = [0.009] * 10
    _write(bench, res, 0.01, seeds, conv, pe, on)
    rc = bench.main(["--sigmas", "0.01", "--seeds", "1-10", "--extra", "--results", str(res),
                     "--json", str(out)])
    assert rc == 0
    s = json.loads(out.read_text())
    (row,) = s["sets"]
    assert row["within_12"] == 7 and row["runs_below_noise"] == 5
    assert row["mean_pred_error_m"] == pytest.approx(0.010)
    assert s["targets"]["structure_within_12_in_8_of_10_every_set"] is False
    assert s["targets"]["mean_pred_error_below_obs_noise_at_0.01"] == {"1-10": False}
    assert "within 12 samples: 7/10" in capsys.readouterr().out

    # one more seed set that meets both: the structure target still fails on the first set
    seeds2 = list(range(101, 111))
    _write(bench, res, 0.01, seeds2, [6] * 9 + [None], [0.007] * 10, [0.009] * 10)
    rc = bench.main(["--sigmas", "0.01", "--seeds", "1-10", "101-110", "--extra",
                     "--results", str(res), "--json", str(out)])
    s = json.loads(out.read_text())
    assert [r["within_12"] for r in s["sets"]] == [7, 9]
    assert s["targets"]["mean_pred_error_below_obs_noise_at_0.01"] == {"1-10": False,
                                                                       "101-110": True}
    assert s["targets"]["structure_within_12_in_8_of_10_every_set"] is False
