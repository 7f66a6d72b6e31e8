"""Results files: every line validated when read, --report-only names and counts what it
skips, one sweep per file (advisory lock), workers that die with their sweep."""

import json
import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest

from mmlearn.apps.common.cli import UsageError
from mmlearn.apps.common.sweep import (ResultsLock, TrialSpec, load_results, probe_trial,
                                       read_results, report_lines, run_sweep)
from mmlearn.models.common.trials import check_record


def _specs(n, **params):
    return [TrialSpec(fn=probe_trial, seed=i, params=dict(params), label=f"probe {i}")
            for i in range(n)]


def _sound_file(tmp_path, n=3):
    path = tmp_path / "r.jsonl"
    run_sweep(_specs(n), results=path, jobs=1, show_progress=False)
    return path, path.read_text().splitlines()


def test_check_record_names_the_missing_or_mistyped_key():
    good = {"seed": 1, "pid": 2, "ray_worker": False, "shared_len": 0, "payload": []}
    assert check_record(probe_trial, good) is None
    assert check_record("sweep.probe@1", dict(good, seed=1.5)) == \
        "the record's 'seed' is 1.5, expected an integer"
    assert check_record(probe_trial, {k: v for k, v in good.items() if k != "pid"}) == \
        "the record lacks 'pid'"
    assert "expected a mapping" in check_record(probe_trial, [1, 2])
    assert check_record("unknown.trial@1", {}) is None  # no schema known: any mapping


def test_read_results_names_every_skipped_line(tmp_path):
    path, lines = _sound_file(tmp_path)
    other = json.loads(lines[0])
    other["spec"]["fn"] = "articulation.operate@1"
    wrong = json.loads(lines[1])
    del wrong["record"]["payload"]
    text = "\n".join([lines[0], "[1, 2]", json.dumps(wrong), lines[1], lines[0],
                      json.dumps(dict(json.loads(lines[2]), format=1)), json.dumps(other),
                      lines[2][:40]])
    path.write_text(text)  # the last line cut short, without its newline
    good, bad = read_results(path, trials=(probe_trial,))
    assert [ln["spec"]["seed"] for ln in good] == [0, 1]
    why = dict(bad)
    assert sorted(why) == [2, 3, 5, 6, 7, 8]
    assert why[2] == "not a results line (no 'key' and 'spec')"
    assert why[3] == "the record lacks 'payload'"
    assert why[5] == "the same trial as line 1"
    assert why[6].startswith("an older results format")
    assert why[7].startswith("a record of another experiment's trial (articulation.operate@1")
    assert why[8] == "cut short (the last line, without its end)"


def test_report_only_counts_skipped_lines_and_refuses_a_file_without_a_record(tmp_path,
                                                                             capsys):
    path, lines = _sound_file(tmp_path)
    path.write_text("\n".join(lines) + "\n" + lines[0][:30])
    assert len(report_lines(path, trials=(probe_trial,))) == 3
    err = capsys.readouterr().err.strip()
    assert err == (f"--report-only: {path}: skipped 1 of 4 line(s): line 4: cut short (the "
                   "last line, without its end)")
    bad = tmp_path / "bad.jsonl"
    bad.write_text("{\"key\": 1}\nnot json\n")
    with pytest.raises(UsageError, match=r"holds no valid trial record \(2 line\(s\) skipped: "
                                         r"line 1: not a results line"):
        report_lines(bad)
    (tmp_path / "empty.jsonl").write_text("")
    with pytest.raises(UsageError, match="holds no valid trial record \\(it is empty\\)"):
        report_lines(tmp_path / "empty.jsonl")


def test_a_sweep_drops_malformed_lines_and_runs_their_trials_again(tmp_path, capsys):
    path, lines = _sound_file(tmp_path)
    wrong = json.loads(lines[1])
    wrong["record"]["seed"] = "one"
    path.write_text("\n".join([lines[0], json.dumps(wrong), lines[2]]) + "\n")
    res = run_sweep(_specs(3), results=path, jobs=1, show_progress=False)
    assert (res.resumed, res.ran) == (2, 1)
    assert "line 2: the record's 'seed' is 'one', expected an integer" in capsys.readouterr().err
    assert sorted(load_results(path)) == sorted(s.key for s in _specs(3))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.jsonl"]  # no temporary, no lock


def test_a_second_sweep_on_a_locked_file_refuses(tmp_path):
    path = tmp_path / "r.jsonl"
    lock = ResultsLock(path).acquire()
    try:
        with pytest.raises(UsageError, match=f"^--results: {path} is being written by another "
                                             f"sweep \\(process {os.getpid()} on "):
            run_sweep(_specs(1), results=path, jobs=1, show_progress=False)
    finally:
        lock.release()
    assert not path.exists()
    run_sweep(_specs(1), results=path, jobs=1, show_progress=False)
    assert len(load_results(path)) == 1


def test_a_results_file_in_a_missing_folder_is_refused_unless_asked(tmp_path):
    with pytest.raises(UsageError, match="folder .*no does not exist .*--create-dirs"):
        run_sweep(_specs(1), results=tmp_path / "no" / "r.jsonl", show_progress=False)
    assert not (tmp_path / "no").exists()
    run_sweep(_specs(1), results=tmp_path / "no" / "r.jsonl", show_progress=False,
              create_dirs=True)
    assert len(load_results(tmp_path / "no" / "r.jsonl")) == 1


_SCRIPT = textwrap.dedent("""
    import sys
    from mmlearn.apps.common.cli import UsageError
    from mmlearn.apps.common.sweep import TrialSpec, probe_trial, run_sweep
    specs = [TrialSpec(fn=probe_trial, seed=i, params={"sleep_s": float(sys.argv[3])})
             for i in range(int(sys.argv[4]))]
    if __name__ == "__main__":
        try:
            run_sweep(specs, results=sys.argv[1], jobs=2, show_progress=False,
                      executor=sys.argv[2])
        except UsageError as e:
            print(e, file=sys.stderr)
            sys.exit(2)
""")


def _children(pid):
    """The live child processes of ``pid`` (Linux /proc)."""
    out = set()
    try:
        for tid in os.listdir(f"/proc/{pid}/task"):
            with open(f"/proc/{pid}/task/{tid}/children") as f:
                out |= {int(x) for x in f.read().split()}
    except OSError:
        pass
    return out


def _descendants(pid):
    todo, seen = [pid], set()
    while todo:
        for c in _children(todo.pop()):
            if c not in seen:
                seen.add(c)
                todo.append(c)
    return seen


def _read(path):
    try:
        with open(path, "rb") as f:
            return f.read()
    except OSError:
        return b""


def _alive(pid):
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split(")")[-1].split()[0] != "Z"
    except OSError:
        return False


@pytest.mark.slow
def test_two_sweeps_on_one_file_record_each_trial_once(tmp_path):
    script = tmp_path / "sweep.py"
    script.write_text(_SCRIPT)
    path = tmp_path / "r.jsonl"
    cmd = [sys.executable, str(script), str(path), "local", "0.5", "8"]
    first = subprocess.Popen(cmd, stderr=subprocess.PIPE, text=True)
    t0 = time.time()
    while time.time() - t0 < 60 and not path.exists():
        time.sleep(0.05)
    second = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert first.wait(timeout=120) == 0
    assert second.returncode == 2
    assert "is being written by another sweep (process" in second.stderr
    seeds = [json.loads(x)["spec"]["seed"] for x in path.read_text().splitlines()]
    assert sorted(seeds) == list(range(8))


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
@pytest.mark.parametrize("executor", ["local", "ray"])
def test_sigkill_of_a_sweep_leaves_no_process_behind(tmp_path, executor):
    if executor == "ray":
        pytest.importorskip("ray")
    script = tmp_path / "sweep.py"
    script.write_text(_SCRIPT)
    p = subprocess.Popen([sys.executable, str(script), str(tmp_path / "r.jsonl"), executor,
                          "30", "4"], start_new_session=True)
    # wait until the trials run: two trial processes asleep in their trial
    t0, procs = time.time(), set()
    while time.time() - t0 < 180:
        procs = _descendants(p.pid)
        if sum(b"spawn_main" in _read(f"/proc/{c}/cmdline")
               and b"nanosleep" in _read(f"/proc/{c}/wchan") for c in procs) >= 2:
            break
        time.sleep(0.2)
    else:
        pytest.fail("the sweep's trials did not start")
    procs = _descendants(p.pid)
    os.kill(p.pid, signal.SIGKILL)  # the parent only, not its process group
    p.wait(timeout=10)
    time.sleep(5.0)
    left = [c for c in procs if _alive(c)]
    names = [_read(f"/proc/{c}/cmdline")[:120] for c in left]
    for c in left:  # leave nothing behind even when the test fails
        try:
            os.kill(c, signal.SIGKILL)
        except OSError:
            pass
    assert names == []


UNWRITABLE = next((d for d in ("/sys/kernel", "/proc") if os.path.isdir(d)
                   and os.access(d, os.W_OK)), None)


def test_create_dirs_flag_of_every_app_parser(tmp_path):
    from mmlearn.apps.common.cli import ArgumentParser, check_out_file

    ap = ArgumentParser(prog="app")
    ap.add_argument("--plot")
    ap.parse_args(["--plot", "x"])
    with pytest.raises(UsageError, match="^--plot: folder .*a does not exist .*--create-dirs"):
        check_out_file("--plot", tmp_path / "a" / "p.png")
    ap.parse_args(["--plot", "x", "--create-dirs"])
    check_out_file("--plot", tmp_path / "a" / "p.png")
    assert (tmp_path / "a").is_dir()
    ap.parse_args([])  # later checks in this process are strict again


def test_an_experiments_app_refuses_bad_results_paths_before_running(tmp_path, capsys):
    from mmlearn.apps import operate_trials

    base = ["--trials", "1", "--objects", "drawer", "--jobs", "1"]
    assert operate_trials.main(base + ["--results", str(tmp_path / "no" / "r.jsonl")]) == 2
    assert not (tmp_path / "no").exists()
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"python -m mmlearn.apps.operate_trials: error: --results: folder "
                   f"{tmp_path / 'no'} does not exist (create it, or pass --create-dirs)"]
    if UNWRITABLE:
        assert operate_trials.main(base + ["--results", f"{UNWRITABLE}/r.jsonl"]) == 2
        assert capsys.readouterr().err.strip().startswith(
            f"python -m mmlearn.apps.operate_trials: error: --results: cannot write in folder "
            f"{UNWRITABLE} (")


def test_report_only_of_another_experiments_file_is_one_line(tmp_path, capsys):
    from mmlearn.apps import operate_trials

    path, lines = _sound_file(tmp_path)
    assert operate_trials.main(["--report-only", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert err[0].startswith(f"python -m mmlearn.apps.operate_trials: error: --report-only: "
                             f"{path} holds no valid trial record (3 line(s) skipped: line 1: "
                             "a record of another experiment's trial (sweep.probe@1")
