"""The sweep runner (apps/common/sweep.py): executors, resume, errors, corrupt results files."""

import json
import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest

from mmlearn.apps.common.sweep import TrialSpec, load_results, probe_trial, run_sweep

PROBE = probe_trial


def _specs(n, **params):
    return [TrialSpec(fn=PROBE, seed=i, params=dict(params), label=f"probe {i}")
            for i in range(n)]


def _lines(path):
    return [json.loads(x) for x in path.read_text().splitlines()]


def test_local_pool_records_every_trial_once_in_spec_order(tmp_path):
    # each trial sleeps long enough that the second worker, started while the first already
    # runs, gets its share on a loaded machine
    res = run_sweep(_specs(6, sleep_s=0.4), results=tmp_path / "r.jsonl", jobs=2,
                    shared="abc", show_progress=False)
    assert [r["seed"] for r in res.records] == list(range(6))
    assert res.ran == 6 and res.resumed == 0 and not res.errors and not res.missing
    assert all(r["shared_len"] == 3 for r in res.records)  # shared inputs reach the workers
    assert len({r["pid"] for r in res.records}) == 2       # two worker processes
    lines = _lines(tmp_path / "r.jsonl")
    assert sorted(ln["spec"]["seed"] for ln in lines) == list(range(6))
    assert all(ln["wall_s"] >= 0.4 and ln["error"] is None for ln in lines)


def test_resume_runs_only_the_missing_trials_and_keeps_the_first_records(tmp_path):
    path = tmp_path / "r.jsonl"
    specs = _specs(5)
    run_sweep(specs[:3], results=path, jobs=1, show_progress=False)
    before = path.read_bytes()
    res = run_sweep(specs, results=path, jobs=1, show_progress=False)
    assert res.resumed == 3 and res.ran == 2
    assert path.read_bytes().startswith(before)
    assert sorted(ln["spec"]["seed"] for ln in _lines(path)) == list(range(5))
    # other parameters are other trials
    res = run_sweep(_specs(2, payload=1), results=path, jobs=1, show_progress=False)
    assert res.resumed == 0 and res.ran == 2 and len(_lines(path)) == 7


def test_a_raising_trial_is_recorded_and_the_sweep_goes_on(tmp_path):
    res = run_sweep(_specs(4, fail_seeds=[1, 2]), results=tmp_path / "r.jsonl", jobs=2,
                    show_progress=False)
    assert [r["seed"] for r in res.records] == [0, 3]
    assert [e["spec"]["seed"] for e in res.errors] == [1, 2]
    assert "fails on purpose" in res.errors[0]["error"]
    assert "Traceback" in res.errors[0]["traceback"]
    assert "probe 1: RuntimeError" in res.error_summary()


def test_a_corrupt_last_line_is_dropped_and_its_trial_runs_again(tmp_path):
    path = tmp_path / "r.jsonl"
    run_sweep(_specs(3), results=path, jobs=1, show_progress=False)
    raw = path.read_bytes()
    path.write_bytes(raw[: raw.rstrip(b"\n").rfind(b"\n") + 1] + b'{"key": "abc", "spe')
    res = run_sweep(_specs(3), results=path, jobs=1, show_progress=False)
    assert res.resumed == 2 and res.ran == 1
    lines = _lines(path)  # every line parses again
    assert sorted(ln["spec"]["seed"] for ln in lines) == [0, 1, 2]
    assert path.read_bytes().startswith(raw[: raw.rstrip(b"\n").rfind(b"\n") + 1])
    assert load_results(path).keys() == {s.key for s in _specs(3)}


def test_bad_specs_and_arguments_are_refused(tmp_path):
    with pytest.raises(ValueError, match="not a registered trial"):
        TrialSpec(fn="mmlearn.apps.common.sweep:probe_trial")
    with pytest.raises(ValueError, match="not a registered trial"):
        TrialSpec(fn=len)
    with pytest.raises(ValueError, match="JSON-able"):
        TrialSpec(fn=PROBE, params={"x": object()})
    with pytest.raises(ValueError, match="identical"):
        run_sweep(_specs(1) + _specs(1), show_progress=False)
    with pytest.raises(ValueError, match="executor"):
        run_sweep(_specs(1), executor="slurm", show_progress=False)
    (tmp_path / "d").mkdir()
    with pytest.raises(ValueError, match="is a folder"):
        run_sweep(_specs(1), results=tmp_path / "d", show_progress=False)


_SCRIPT = textwrap.dedent("""
    import signal, sys
    from mmlearn.apps.common.sweep import TrialSpec, probe_trial, run_sweep
    specs = [TrialSpec(fn=probe_trial, seed=i,
                       params={"sleep_s": 1.0}, label=f"probe {i}") for i in range(12)]
    if __name__ == "__main__":
        # Ctrl-C as in a terminal, also when this test runs under a parent that ignores SIGINT
        # (a background job), whose disposition the interpreter would otherwise inherit
        signal.signal(signal.SIGINT, signal.default_int_handler)
        res = run_sweep(specs, results=sys.argv[1], jobs=2, show_progress=False,
                        executor=sys.argv[2])
        sys.exit(130 if res.interrupted else 0)
""")


@pytest.mark.slow
@pytest.mark.parametrize("executor,sig", [("local", signal.SIGINT), ("local", signal.SIGKILL),
                                          ("ray", signal.SIGINT)])
def test_an_interrupted_sweep_completes_when_run_again(tmp_path, executor, sig):
    if executor == "ray":
        pytest.importorskip("ray")
    script = tmp_path / "sweep.py"
    script.write_text(_SCRIPT)
    path = tmp_path / "r.jsonl"
    p = subprocess.Popen([sys.executable, str(script), str(path), executor],
                         start_new_session=True)
    t0 = time.time()
    while time.time() - t0 < 90 and (not path.exists() or len(path.read_text().splitlines()) < 5):
        time.sleep(0.05)
    os.killpg(p.pid, sig) if sig == signal.SIGKILL else p.send_signal(sig)
    rc = p.wait(timeout=60)
    assert rc == (130 if sig == signal.SIGINT else -9)
    first = path.read_bytes()
    n_first = len(first.splitlines())
    assert 5 <= n_first < 12
    assert subprocess.run([sys.executable, str(script), str(path), executor],
                          timeout=180).returncode == 0
    assert path.read_bytes().startswith(first)
    seeds = [ln["spec"]["seed"] for ln in _lines(path)]
    assert sorted(seeds) == list(range(12))  # every trial exactly once


@pytest.mark.slow
def test_ray_executor_gives_the_local_records(tmp_path):
    pytest.importorskip("ray")
    specs = _specs(4, fail_seeds=[2])
    res = run_sweep(specs, results=tmp_path / "r.jsonl", executor="ray", jobs=2,
                    shared="xyz", show_progress=False)
    assert [r["seed"] for r in res.records] == [0, 1, 3]
    assert all(r["shared_len"] == 3 for r in res.records)
    assert [e["spec"]["seed"] for e in res.errors] == [2]
    res2 = run_sweep(specs, results=tmp_path / "r.jsonl", executor="ray", jobs=2,
                     show_progress=False)
    assert res2.ran == 0 and res2.resumed == 4


@pytest.mark.slow
def test_ray_trials_run_in_a_plain_child_process_of_each_worker(tmp_path):
    """A Ray task runs its trial in a child process of the Ray worker (the trial is slower
    inside the Ray worker process itself, see apps/common/sweep._ray_execute); the shared inputs reach
    it, other shared inputs get a new child, and a child that dies is that trial's error."""
    ray = pytest.importorskip("ray")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        res = run_sweep(_specs(4), executor="ray", jobs=2, shared="abc", show_progress=False)
        assert [r["seed"] for r in res.records] == [0, 1, 2, 3]
        assert not any(r["ray_worker"] for r in res.records)  # not the Ray worker itself
        assert all(r["shared_len"] == 3 for r in res.records)
        assert len({r["pid"] for r in res.records}) <= 2        # one trial process per worker
        assert all(ln["cpu_s"] is not None and ln["cpu_s"] >= 0 for ln in res.lines)
        res = run_sweep(_specs(4), executor="ray", jobs=2, shared="wxyz", show_progress=False)
        assert all(r["shared_len"] == 4 for r in res.records)
        res = run_sweep(_specs(4, crash_seeds=[1]), executor="ray", jobs=2,
                        show_progress=False)
        assert [r["seed"] for r in res.records] == [0, 2, 3]
        assert [e["spec"]["seed"] for e in res.errors] == [1]
        assert "trial process died" in res.errors[0]["error"]
        res = run_sweep(_specs(2, payload=1), executor="ray", jobs=2, show_progress=False,
                        ray_in_child=False)
        assert all(r["ray_worker"] for r in res.records)      # the Ray worker itself
    finally:
        ray.shutdown()


@pytest.mark.slow
def test_a_trial_that_kills_its_local_worker_is_its_error_and_the_sweep_goes_on(tmp_path):
    """A crash in compiled code ends the worker process: the local pool must not hang; the
    trial is recorded as an error, every other trial (also those running beside it) runs."""
    specs = [TrialSpec(fn=PROBE, seed=i, params={"sleep_s": 0.2, "crash_seeds": [2]},
                       label=f"probe {i}") for i in range(6)]
    res = run_sweep(specs, results=tmp_path / "r.jsonl", jobs=2, shared="abc",
                    show_progress=False)
    assert sorted(r["seed"] for r in res.records) == [0, 1, 3, 4, 5]
    assert [e["spec"]["seed"] for e in res.errors] == [2]
    assert "died" in res.errors[0]["error"]
    seeds = [ln["spec"]["seed"] for ln in _lines(tmp_path / "r.jsonl")]
    assert sorted(seeds) == list(range(6))  # every trial exactly once


@pytest.mark.slow
def test_a_results_file_of_another_format_or_trial_version_is_refused(tmp_path):
    path = tmp_path / "r.jsonl"
    run_sweep(_specs(2), results=path, show_progress=False)
    lines = _lines(path)
    assert {ln["spec"]["fn"] for ln in lines} == {"sweep.probe@1"}
    old = dict(lines[0], spec=dict(lines[0]["spec"], fn="mmlearn.apps._sweep:probe_trial"))
    old.pop("format")
    path.write_text(json.dumps(old) + "\n")
    with pytest.raises(ValueError, match="older results format"):
        run_sweep(_specs(2), results=path, show_progress=False)
    newer = dict(lines[0], spec=dict(lines[0]["spec"], fn="sweep.probe@2"))
    path.write_text(json.dumps(newer) + "\n")
    with pytest.raises(ValueError, match="holds results of sweep.probe@2"):
        run_sweep(_specs(2), results=path, show_progress=False)
