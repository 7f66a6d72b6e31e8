"""Property-based tests of results files and the sweep runner: a results file cut or damaged
anywhere reads as its intact lines and names the rest; a sweep interrupted at any point and
run again records every trial exactly once."""

import json
import tempfile
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mmlearn.apps.common.sweep import TrialSpec, probe_trial, read_results, run_sweep

N_TRIALS = 5
_SETTINGS = dict(deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


def _specs():
    return [TrialSpec(fn=probe_trial, seed=i, params={"payload": i}, label=f"probe {i}")
            for i in range(N_TRIALS)]


def _sound_text() -> bytes:
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "r.jsonl"
        run_sweep(_specs(), results=p, jobs=1, show_progress=False)
        return p.read_bytes()


SOUND = _sound_text()
SOUND_LINES = SOUND.decode().splitlines()


def _read(data: bytes):
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "r.jsonl"
        p.write_bytes(data)
        return read_results(p, trials=(probe_trial,))


STARTS = [0] + [i + 1 for i, b in enumerate(SOUND) if b == ord("\n")]


@settings(max_examples=600, **_SETTINGS)
@given(cut=st.integers(0, len(SOUND)), junk=st.binary(max_size=40),
       where=st.integers(0, N_TRIALS))
def test_a_damaged_file_reads_as_its_intact_lines(cut, junk, where):
    """Cut the file anywhere (a killed writer) and splice bytes in at a line's start (a
    foreign or broken write): every line read is one of the original lines, byte for byte;
    every other line is named with a reason; never the same trial twice. (An edit inside a
    line that leaves valid JSON of the right shape is not detected: lines carry no
    checksum.)"""
    at = min(STARTS[where], cut)
    data = SOUND[:at] + junk + SOUND[at:cut]
    good, bad = _read(data)
    originals = {json.dumps(json.loads(x)) for x in SOUND_LINES}
    for ln in good:
        assert json.dumps(ln) in originals
    assert len(good) + len(bad) <= len(data.splitlines())
    assert all(isinstance(i, int) and isinstance(why, str) and why for i, why in bad)
    intact = SOUND[:at].count(b"\n") + max(0, SOUND[at:cut].count(b"\n") - 1)
    assert len(good) >= min(intact, N_TRIALS)
    assert len({ln["key"] for ln in good}) == len(good)


@settings(max_examples=400, **_SETTINGS)
@given(cut=st.integers(0, len(SOUND)))
def test_an_interrupted_sweep_resumes_to_every_trial_once(cut):
    """A sweep killed at any byte of its results file and run again records each trial
    exactly once, with the record of a complete run."""
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "r.jsonl"
        p.write_bytes(SOUND[:cut])
        run_sweep(_specs(), results=p, jobs=1, show_progress=False)
        good, _ = read_results(p, trials=(probe_trial,))
    assert sorted(ln["spec"]["seed"] for ln in good) == list(range(N_TRIALS))
    for ln in good:
        assert ln["error"] is None and ln["record"]["payload"] == list(range(ln["spec"]["seed"]))
