"""One trial runner for the experiments apps: a local process pool or Ray, results streamed
to a JSON Lines file, resumable.

An experiment is a list of :class:`TrialSpec` (a pure trial function registered with
:func:`mmlearn.models.common.trials.register_trial`, its keyword parameters and a seed); a trial
function returns a JSON-able ``dict``. The runner
executes the specs that are not yet in the results file and appends one line per finished
trial, flushed and synced at once::

    {"key": "...", "format": 2, "spec": {"fn": "articulation.operate@1", "params": {...},
     "seed": 3, "label": "..."},
     "record": {...} | null, "error": "ValueError: ..." | null, "traceback": "..." | null,
     "wall_s": 12.3, "cpu_s": 12.1, "host": "...", "finished": "2026-11-22T18:00:00+00:00"}

(``wall_s``: the trial's wall time, ``cpu_s``: the CPU time of the process running it
meanwhile, both in seconds, measured where the trial ran.)

``key`` is a hash of (the trial's name and version, params, seed): re-running the same command with the same results
file skips every trial already recorded (resume), so an interrupted sweep (Ctrl-C, a killed
process or machine) loses at most the trials that were running. A line that cannot be read
(a sweep killed while writing it) is dropped when the file is next opened and its trial runs
again; nothing else in the file changes. A trial that raises is recorded with its error and
traceback (an error of the code, not a failure of the robot) and the sweep goes on. A results
file written by another version of a trial (or in an older format) is refused with a message
naming the file; start a new file for it.

Executors:

* ``local`` (default): a process pool of ``jobs`` workers (default: all cores) started with
  ``spawn`` (each worker builds its own Drake diagrams), with a progress bar and an ETA.
* ``ray``: the same trial functions as Ray tasks (one CPU each) on an existing cluster
  (``ray_address``, e.g. ``ray://head:10001`` or ``auto``) or on a local Ray instance of
  ``jobs`` CPUs when no address is given. Ray is an optional extra
  (``pip install 'mmlearn[ray]'``) and is imported only when chosen. The workers of a cluster
  need mmlearn installed (the same version as the driver). Each Ray worker runs its trials in
  a plain child process of its own (started once, ``spawn``): inside the Ray worker process
  the same trial took 8-14 % more CPU time (measured, see :func:`_ray_execute`).

Large inputs that every trial needs (a prior database, track files) go in ``shared``: they
are sent once per worker (local) or put once in Ray's object store, not once per trial; the
trial function then gets them as its ``shared`` keyword argument.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import json
import os
import signal
import socket
import sys
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path

from mmlearn.apps.common.cli import UsageError, check_out_file, json_clean, progress_bar
from mmlearn.models.common.fileio import OutputPathError, atomic_write_text, check_output_file
from mmlearn.models.common.trials import check_record, register_trial, trial_id

EXECUTORS = ("local", "ray")
#: the format of a results-file line (``"format"``); older files are refused
RESULTS_FORMAT = 2

__all__ = ["TrialSpec", "SweepResult", "run_sweep", "load_results", "read_results", "ResultsLock",
           "die_with_parent", "add_sweep_args",
           "sweep_kwargs", "exit_status", "EXECUTORS"]


@dataclass(frozen=True)
class TrialSpec:
    """One trial: ``fn`` (a function registered with ``register_trial``) called as
    ``fn(seed=seed, **params)`` (plus ``shared=...`` when the sweep has shared inputs).
    ``params`` must be JSON-able; ``label`` names the trial in progress and error messages
    (not part of its identity)."""

    fn: object
    params: dict = field(default_factory=dict)
    seed: int = 0
    label: str = ""

    def __post_init__(self):
        trial_id(self.fn)  # raises unless fn is a registered trial function
        try:
            json.dumps(self.params, sort_keys=True)
        except TypeError as e:
            raise ValueError(f"TrialSpec.params must be JSON-able: {e}") from None

    @property
    def key(self) -> str:
        ident = json.dumps({"fn": trial_id(self.fn), "params": self.params,
                            "seed": int(self.seed)},
                           sort_keys=True)
        return hashlib.sha1(ident.encode()).hexdigest()[:20]

    def name(self) -> str:
        return self.label or f"{self.fn.trial_name} seed {self.seed}"


@dataclass
class SweepResult:
    """What a sweep produced. ``lines`` holds the results-file line of every spec that has
    one, in the order of the specs (resumed and new alike); ``missing`` the specs without
    one (only after an interruption)."""

    lines: list[dict]
    resumed: int
    ran: int
    missing: list[TrialSpec]
    interrupted: bool
    wall_s: float
    results: Path | None

    @property
    def records(self) -> list[dict]:
        return [ln["record"] for ln in self.lines if ln.get("error") is None]

    @property
    def errors(self) -> list[dict]:
        return [ln for ln in self.lines if ln.get("error") is not None]

    def summary(self) -> dict:
        """What the apps put in their JSON about the sweep itself."""
        return {"results_file": str(self.results) if self.results else None,
                "resumed": self.resumed, "interrupted": self.interrupted,
                "wall_seconds": round(self.wall_s, 1),
                "trial_seconds": round(sum(ln.get("wall_s") or 0.0 for ln in self.lines), 1),
                "not_run": [s.label for s in self.missing]}

    def error_summary(self) -> str:
        return "; ".join(f"{ln['spec'].get('label') or ln['key']}: {ln['error']}"
                         for ln in self.errors)


# ---------------------------------------------------------------------------- results file

def load_results(path: str | Path, *, repair: bool = False) -> dict[str, dict]:
    """The lines of a results file by key (first occurrence wins). Lines that are not a JSON
    object with a ``key`` and a ``spec``, and format-2 lines whose record does not match its
    trial's schema (:func:`~mmlearn.models.common.trials.check_record`), are skipped; with
    ``repair`` the file is rewritten without them (atomically: a uniquely named temporary
    file, fsync, rename, fsync of the folder), so appending after a truncated last line
    cannot glue two records together, and the dropped lines are named on stderr. A missing
    file is an empty result."""
    p = Path(path)
    if not p.exists():
        return {}
    if p.is_dir():
        raise ValueError(f"results file {p} is a directory")
    out: dict[str, dict] = {}
    good: list[str] = []
    bad: list[tuple[int, str]] = []
    raw = p.read_bytes()
    for i, line, d, why in _parse_lines(raw):
        if why is None and d.get("format") == RESULTS_FORMAT:
            why = _line_problem(d)
        if why is not None:
            bad.append((i, why))
            continue
        good.append(line)
        out.setdefault(d["key"], d)
    if repair and (bad or (raw and not raw.endswith(b"\n"))):
        atomic_write_text(p, "".join(g + "\n" for g in good))
        if bad:
            print(f"{p}: dropped {len(bad)} unreadable line(s) ({_problems(bad)}); their "
                  "trials run again", file=sys.stderr)
    return out


def _parse_lines(raw: bytes):
    """``(line number, text, parsed object or None, problem or None)`` per non-blank line."""
    text = raw.decode("utf-8", errors="replace")
    lines = text.split("\n")
    last = len(lines) - 1 if not text.endswith("\n") else -1
    for i, line in enumerate(lines):
        if not line.strip():
            continue
        try:
            d = json.loads(line)
        except json.JSONDecodeError:
            yield i + 1, line, None, ("cut short (the last line, without its end)" if i == last
                                      else "not valid JSON")
            continue
        if not isinstance(d, dict) or "key" not in d or not isinstance(d.get("spec"), dict):
            yield i + 1, line, None, "not a results line (no 'key' and 'spec')"
            continue
        yield i + 1, line, d, None


def _line_problem(d: dict, *, schema: bool = True) -> str | None:
    """Why a format-2 results line is malformed (None: it is sound): its fields, and (with
    ``schema``) its record against the schema of its trial."""
    spec = d["spec"]
    if not isinstance(d["key"], str):
        return "'key' is not a string"
    if not isinstance(spec.get("fn"), str) or not isinstance(spec.get("params"), dict):
        return "'spec' lacks the trial's name ('fn') or its parameters ('params')"
    if isinstance(spec.get("seed"), bool) or not isinstance(spec.get("seed"), int):
        return "'spec' lacks an integer 'seed'"
    if "record" not in d or "error" not in d:
        return "lacks 'record' or 'error'"
    if d["error"] is not None:
        return None if isinstance(d["error"], str) else "'error' is not a string"
    return check_record(spec["fn"], d["record"], spec["params"]) if schema else None


def _problems(bad: list[tuple[int, str]], most: int = 4) -> str:
    text = "; ".join(f"line {i}: {why}" for i, why in bad[:most])
    return text + (f"; and {len(bad) - most} more" if len(bad) > most else "")


def read_results(path: str | Path, *, trials=()) -> tuple[list[dict], list[tuple[int, str]]]:
    """Every sound line of a results file, validated, and the skipped ones as ``(line
    number, reason)``: lines that are not JSON (a last line cut short by a killed sweep),
    not results lines, of an older format, of a trial not among ``trials`` (registered
    trial functions; empty: any), of another version of one of them, whose record does not
    match its trial's schema, or a repeat of a trial already read."""
    p = Path(path)
    ours = {t.trial_name: trial_id(t) for t in trials}
    lines: list[dict] = []
    bad: list[tuple[int, str]] = []
    seen: dict[str, int] = {}
    for i, _line, d, why in _parse_lines(p.read_bytes()):
        if why is None and d.get("format") != RESULTS_FORMAT:
            why = f"an older results format ({d.get('format')!r}, this version reads " \
                  f"{RESULTS_FORMAT})"
        if why is None:
            why = _line_problem(d, schema=False)
        if why is None and ours:
            fn = d["spec"]["fn"]
            name = fn.split("@", 1)[0]
            if name not in ours:
                why = f"a record of another experiment's trial ({fn}; this one reads " \
                      f"{', '.join(ours.values())})"
            elif fn != ours[name]:
                why = f"written by {fn}, this version reads {ours[name]}"
        if why is None:
            why = _line_problem(d)
        if why is None and d["key"] in seen:
            why = f"the same trial as line {seen[d['key']]}"
        if why is not None:
            bad.append((i, why))
            continue
        seen[d["key"]] = i
        lines.append(d)
    return lines, bad


class _Appender:
    def __init__(self, path: Path):
        self.f = open(path, "a", encoding="utf-8")

    def write(self, line: dict) -> None:
        self.f.write(json.dumps(line, allow_nan=False) + "\n")
        self.f.flush()
        os.fsync(self.f.fileno())

    def close(self) -> None:
        self.f.close()


class ResultsLock:
    """An advisory lock (``flock``) on a results file, held by the sweep writing it: a
    second sweep on the same file refuses at once with a message naming the file and the
    process holding it. The lock lives in a hidden file beside the results
    (``.<name>.lock``, removed on release); reading a results file (``--report-only``)
    needs no lock. Linux and macOS (``fcntl``); elsewhere no lock is taken."""

    def __init__(self, path: Path):
        self.results = path
        self.path = path.with_name(f".{path.name}.lock")
        self.fd: int | None = None

    def acquire(self) -> "ResultsLock":
        try:
            import fcntl
        except ImportError:  # pragma: no cover - Windows: no advisory lock
            return self
        while True:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o666)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                holder = os.read(fd, 200).decode(errors="replace").strip() or "unknown"
                os.close(fd)
                raise UsageError(f"--results: {self.results} is "
                                 f"being written by another sweep ({holder}); wait for it "
                                 "to finish or use another results file") from None
            try:  # the holder before us may have removed the file: lock the current one
                same = os.path.samestat(os.fstat(fd), os.stat(self.path))
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)
        os.ftruncate(fd, 0)
        os.write(fd, f"process {os.getpid()} on {socket.gethostname()}\n".encode())
        self.fd = fd
        return self

    def release(self) -> None:
        if self.fd is None:
            return
        try:
            self.path.unlink(missing_ok=True)
        finally:
            os.close(self.fd)  # closing drops the flock
            self.fd = None


# ---------------------------------------------------------------------------- trial execution

_SHARED = None  # a worker's copy of the sweep's shared inputs (set once per worker process)


def _watch_parent(parent: int, period_s: float = 0.5) -> None:
    """End this process at once when its parent is gone (reparented: ``getppid`` changes)."""
    while os.getppid() == parent:
        time.sleep(period_s)
    os._exit(1)


def die_with_parent(parent: int) -> None:
    """Make this process end when ``parent`` (the process that started it) dies, so a sweep
    killed with SIGKILL leaves no worker behind. On Linux the kernel sends SIGKILL on the
    parent's death (``prctl(PR_SET_PDEATHSIG)``: it works while the worker is busy in
    compiled code that holds the GIL); elsewhere a thread watches ``getppid``. A parent that
    died before this call ends the process at once."""
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            libc = ctypes.CDLL(None, use_errno=True)
            ok = libc.prctl(1, int(signal.SIGKILL), 0, 0, 0) == 0  # 1: PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            ok = False
        if ok:
            if os.getppid() != parent:
                os._exit(1)
            return
    import threading

    threading.Thread(target=_watch_parent, args=(parent,), daemon=True,
                     name="mmlearn-watch-parent").start()
    if os.getppid() != parent:
        os._exit(1)


def _init_worker(shared, parent: int | None = None) -> None:
    global _SHARED
    _SHARED = shared
    if parent is not None:
        die_with_parent(parent)
    # Ctrl-C goes to the whole process group: the parent stops the pool, the workers must not
    # each print a traceback of the interrupted trial
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _line(spec: dict, record, error, tb, wall_s: float, cpu_s: float | None) -> dict:
    return {"key": spec["key"], "format": RESULTS_FORMAT,
            "spec": dict({k: spec[k] for k in ("params", "seed", "label")}, fn=spec["trial"]),
            "record": record, "error": error, "traceback": tb,
            "wall_s": round(wall_s, 3), "cpu_s": None if cpu_s is None else round(cpu_s, 3),
            "host": socket.gethostname(),
            "finished": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")}


def _execute(spec: dict, shared) -> dict:
    """Run one trial; exceptions become the line's ``error`` (never raised). ``wall_s``: the
    trial's wall time [s]; ``cpu_s``: the CPU time [s] the process running it spent meanwhile
    (``time.process_time``: all its threads, user + system)."""
    t0, c0 = time.perf_counter(), time.process_time()
    record, error, tb = None, None, None
    try:
        func = spec["fn"]
        kw = dict(spec["params"])
        if shared is not None:
            kw["shared"] = shared
        record = func(seed=spec["seed"], **kw)
        if not isinstance(record, dict):
            raise TypeError(f"trial function {spec['trial']} returned {type(record).__name__}, "
                            "expected a dict")
        record = json_clean(record)
        json.dumps(record, allow_nan=False)
    except Exception as e:  # noqa: BLE001 - a crashed trial is data
        record, error, tb = None, f"{type(e).__name__}: {e}", traceback.format_exc()
    return _line(spec, record, error, tb, time.perf_counter() - t0,
                 time.process_time() - c0)


def _local_worker(spec: dict) -> dict:
    return _execute(spec, _SHARED)


def _run_local(todo: list[dict], *, jobs: int, shared):
    """Run ``todo`` in a spawn process pool of ``jobs`` workers, yielding each trial's line.

    A worker that dies (a crash in compiled code, the OOM killer) breaks the pool; the trials
    that were running then are run again one at a time, each in a fresh process, so the one
    that kills its process is recorded as that trial's error and the others run normally; the
    sweep then continues in a new pool."""
    import multiprocessing as mp
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
    from concurrent.futures.process import BrokenProcessPool

    if jobs == 1 and shared is None:  # no pool: cheaper, and debuggers / profilers see the trial
        for s in todo:
            yield _execute(s, None)
        return
    ctx = mp.get_context("spawn")
    n = min(jobs, len(todo))
    active: list = []  # the executor whose workers run now (killed on Ctrl-C)

    def pool(workers: int):
        ex = ProcessPoolExecutor(max_workers=workers, mp_context=ctx,
                                 initializer=_init_worker, initargs=(shared, os.getpid()))
        active[:] = [ex]
        return ex

    queue = list(reversed(todo))
    running: dict = {}  # future -> (spec, start time)
    ex = pool(n)
    try:
        while queue or running:
            broken = False
            while queue and len(running) < n:
                s = queue.pop()
                try:
                    running[ex.submit(_local_worker, s)] = (s, time.perf_counter())
                except BrokenProcessPool:  # a worker died since the last wait
                    queue.append(s)
                    broken = True
                    break
            if not broken:
                done, _ = wait(running, return_when=FIRST_COMPLETED)
                broken = any(f.exception() is not None for f in done)
                if not broken:
                    for f in done:
                        yield f.result()
                        running.pop(f)
                    continue
            # the pool is broken: keep what finished, re-run the rest one at a time
            wait(running)
            suspects = []
            for f, (s, _t0) in running.items():
                try:
                    yield f.result()
                except BrokenProcessPool:
                    suspects.append(s)
            running.clear()
            ex.shutdown(wait=True)
            for s in suspects:  # one at a time: the trial that dies is the crashed one
                one, t0 = pool(1), time.perf_counter()
                try:
                    yield one.submit(_local_worker, s).result()
                except BrokenProcessPool as e:
                    yield _line(s, None, f"BrokenProcessPool: the trial process died ({e})",
                                traceback.format_exc(), time.perf_counter() - t0, None)
                finally:
                    one.shutdown(wait=True)
            ex = pool(n)
    except BaseException:
        # stop the running trials now (the executor has no public terminate)
        for proc in list((getattr(active[0], "_processes", None) or {}).values()):
            proc.terminate()
        raise
    finally:
        active[0].shutdown(wait=True, cancel_futures=True)


# A Ray task runs its trial in a plain child process of the Ray worker (one per worker, kept for
# the worker's next trials), not in the Ray worker process itself. Measured (operate_trials
# drawer trials, each run alternately in a spawn-pool worker, in a Ray worker and in a child of
# a Ray worker): the trial's own CPU time was 8-14 % higher inside the Ray worker process and
# equal (-3 % .. +4 %) in its child, with the same niceness (15, Ray's worker_niceness), the
# same environment and imports; see docs/sweeps.md.
_RAY_CHILD: dict = {}  # this Ray worker's trial process: {"key": shared ref, "pool": executor}


def _ray_child_pool(shared_box: list):
    """This Ray worker's trial process (made on first use, or anew for other shared inputs or
    after the previous one died)."""
    from concurrent.futures import ProcessPoolExecutor
    import multiprocessing as mp

    key = shared_box[0].hex() if shared_box else None
    if _RAY_CHILD.get("pool") is not None and _RAY_CHILD.get("key") != key:
        _RAY_CHILD.pop("pool").shutdown(wait=True, cancel_futures=True)
    if _RAY_CHILD.get("pool") is None:
        shared = None
        if shared_box:
            import ray

            shared = ray.get(shared_box[0])
        _RAY_CHILD["pool"] = ProcessPoolExecutor(
            max_workers=1, mp_context=mp.get_context("spawn"), initializer=_init_worker,
            initargs=(shared, os.getpid()))
        _RAY_CHILD["key"] = key
    return _RAY_CHILD["pool"]


def _ray_execute(spec: dict, shared_box: list, in_child: bool = True) -> dict:
    """A Ray task: one trial, in this worker's trial process (``in_child``) or in the Ray
    worker itself. A trial process that dies (a crash in compiled code) is an error of that
    trial; the next trial gets a new process."""
    if not in_child:
        import ray

        return _execute(spec, ray.get(shared_box[0]) if shared_box else None)
    from concurrent.futures.process import BrokenProcessPool

    t0 = time.perf_counter()
    try:
        return _ray_child_pool(shared_box).submit(_local_worker, spec).result()
    except BrokenProcessPool as e:
        _RAY_CHILD.pop("pool", None)
        return _line(spec, None, f"BrokenProcessPool: the trial process died ({e})",
                     traceback.format_exc(), time.perf_counter() - t0, None)


# A local Ray instance started by a sweep is a tree of processes under the sweep (GCS, raylet,
# agents, workers). If the sweep is killed (SIGKILL), the raylet and the workers follow it, but
# Ray's dashboard and runtime-env agents stay. A small guard process notes the sweep's
# descendants while Ray runs and, when the sweep dies without shutting Ray down, kills those
# still alive (the same process: pid and start time), then ends. Linux only (/proc).
_GUARD = r"""
import os, signal, sys, time
driver = int(sys.argv[1])
me = os.getpid()
def start(pid):
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[19]
    except (OSError, IndexError):
        return None
def children(pid):
    out = []
    try:
        for t in os.listdir(f"/proc/{pid}/task"):
            with open(f"/proc/{pid}/task/{t}/children") as f:
                out += [int(x) for x in f.read().split()]
    except OSError:
        pass
    return out
known = {}
while os.getppid() == driver:
    todo = [driver]
    while todo:
        for c in children(todo.pop()):
            if c != me and c not in known:
                st = start(c)
                if st is not None:
                    known[c] = st
            todo.append(c)
    time.sleep(0.5)
time.sleep(1.0)  # what dies with the sweep by itself goes first
for pid, st in known.items():
    if start(pid) == st:
        try:
            os.kill(pid, signal.SIGKILL)
        except OSError:
            pass
"""


def _start_ray_guard():
    """The guard process of a local Ray instance (None off Linux); stop it with
    :func:`_stop_ray_guard` after ``ray.shutdown``."""
    if not sys.platform.startswith("linux"):
        return None
    import subprocess

    return subprocess.Popen([sys.executable, "-c", _GUARD, str(os.getpid())],
                            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)


def _stop_ray_guard(guard) -> None:
    if guard is not None:
        guard.kill()
        guard.wait()


def _run_ray(todo: list[dict], *, jobs: int, address: str | None, shared,
             in_child: bool = True):
    try:
        import ray
    except ImportError:
        raise UsageError("--executor ray needs Ray, an optional extra: "
                         "pip install 'mmlearn[ray]'") from None
    started, guard = False, None
    if not ray.is_initialized():
        if address:
            ray.init(address=address, log_to_driver=False)
        else:
            guard = _start_ray_guard()
            try:
                ray.init(num_cpus=jobs, include_dashboard=False, log_to_driver=False)
            except BaseException:
                _stop_ray_guard(guard)
                raise
        started = True
    try:
        task = ray.remote(num_cpus=1, max_retries=0)(_ray_execute)
        # the reference goes in a list so that Ray hands the task the reference, not the
        # value: a worker fetches the shared inputs once (when it starts its trial process)
        shared_box = [ray.put(shared)] if shared is not None else []
        pending = [task.remote(s, shared_box, in_child) for s in todo]
        try:
            while pending:
                done, pending = ray.wait(pending, num_returns=1)
                for ref in done:
                    yield ray.get(ref)
        except BaseException:
            # A local instance's workers end with ``ray.shutdown`` below. A forced cancel of a
            # task that is finishing at that moment crashes Ray's task manager (a failed check,
            # exit status 1), so tasks are cancelled only on a cluster, where they would outlive
            # the sweep, and there without force (the worker gets a KeyboardInterrupt).
            if not started:
                for ref in pending:
                    ray.cancel(ref, force=False)
            raise
    finally:
        if started:
            ray.shutdown()
        _stop_ray_guard(guard)


# ---------------------------------------------------------------------------- the runner

def run_sweep(specs: list[TrialSpec], *, results: str | Path | None = None,
              executor: str = "local", jobs: int | None = None, ray_address: str | None = None,
              shared=None, show_progress: bool = True, desc: str = "trials",
              ray_in_child: bool = True, create_dirs: bool = False) -> SweepResult:
    """Run every spec that ``results`` does not hold yet and stream its line to the file.

    ``results``: the JSON Lines file (created; its folder must exist unless
    ``create_dirs``; ``None``: a temporary file, removed afterwards, nothing to resume).
    While the sweep runs it holds an advisory lock on the file (:class:`ResultsLock`): a
    second sweep on the same file refuses with a :class:`UsageError`. ``jobs``: parallel trials (default: all cores).
    ``ray_in_child``: with the Ray executor, run each worker's trials in a plain child process
    of the Ray worker (default; a trial runs as fast as in the local pool, see
    :func:`_ray_execute`) or, False, in the Ray worker process itself.
    Returns a :class:`SweepResult`. On Ctrl-C the pool is stopped, the result says
    ``interrupted`` and names the missing specs; records already written stay in the file.
    """
    if executor not in EXECUTORS:
        raise ValueError(f"executor must be one of {', '.join(EXECUTORS)}, got {executor!r}")
    if jobs is not None and jobs < 1:
        raise ValueError(f"jobs must be >= 1, got {jobs}")
    specs = list(specs)
    keys = [s.key for s in specs]
    if len(set(keys)) != len(keys):
        raise ValueError("two trial specs are identical (same function, parameters and seed)")
    jobs = jobs or os.cpu_count() or 1
    temporary = results is None
    if temporary:
        import tempfile

        fd, name = tempfile.mkstemp(prefix="mmlearn-sweep-", suffix=".jsonl")
        os.close(fd)
        path = Path(name)
    else:
        path = Path(results)
        try:
            check_output_file(path, what="--results", create_dirs=create_dirs,
                              flag_hint="--create-dirs")
        except OutputPathError as e:
            raise UsageError(str(e)) from None
    t0 = time.perf_counter()
    lock = None if temporary else ResultsLock(path).acquire()
    try:
        done = load_results(path, repair=True)
        _check_format(path, done, specs)
        todo = [dict(vars(s), key=k, trial=trial_id(s.fn)) for s, k in zip(specs, keys)
                if k not in done]
        resumed = len(specs) - len(todo)
        if resumed and show_progress:
            print(f"{path}: {resumed} of {len(specs)} trials already recorded, running "
                  f"{len(todo)}", file=sys.stderr)
        new: dict[str, dict] = {}
        interrupted = False
        if todo:
            bar = progress_bar(len(specs), desc, unit="trial", enabled=show_progress)
            bar.update(resumed)
            out = _Appender(path)
            run = (_run_local(todo, jobs=jobs, shared=shared) if executor == "local" else
                   _run_ray(todo, jobs=jobs, address=ray_address, shared=shared,
                            in_child=ray_in_child))
            try:
                for line in run:
                    out.write(line)
                    new[line["key"]] = line
                    bar.update(1)
                    if line["error"] and show_progress:
                        bar.write(f"error in {line['spec']['label'] or line['key']}: "
                                  f"{line['error']}", file=sys.stderr)
            except KeyboardInterrupt:
                interrupted = True
            finally:
                out.close()
                bar.close()
        lines, missing = [], []
        for s, k in zip(specs, keys):
            ln = done.get(k) or new.get(k)
            (lines.append(ln) if ln is not None else missing.append(s))
        if interrupted:
            print(f"interrupted: {len(lines)} of {len(specs)} trials recorded in {path}; "
                  "run the same command again to resume", file=sys.stderr)
        return SweepResult(lines=lines, resumed=resumed, ran=len(new), missing=missing,
                           interrupted=interrupted, wall_s=time.perf_counter() - t0,
                           results=None if temporary else path)
    finally:
        if temporary:
            path.unlink(missing_ok=True)
        if lock is not None:
            lock.release()


def _check_format(path: Path, done: dict[str, dict], specs: list[TrialSpec]) -> None:
    """Refuse a results file written in an older format or by another version of a trial."""
    ours = {s.fn.trial_name: trial_id(s.fn) for s in specs}
    for line in done.values():
        fn = str(line["spec"].get("fn"))
        if line.get("format") != RESULTS_FORMAT:
            raise UsageError(f"{path}: written in an older results format (trial {fn!r}); "
                             "start a new results file (or delete this one)")
        name = fn.split("@", 1)[0]
        if name in ours and fn != ours[name]:
            raise UsageError(f"{path}: holds results of {fn}, this run is {ours[name]}; start a "
                             "new results file (or delete this one)")


# ---------------------------------------------------------------------------- probe trial

@register_trial("sweep.probe", record={"seed": int, "pid": int, "ray_worker": bool,
                                        "shared_len": int, "payload": list})
def probe_trial(*, seed: int, sleep_s: float = 0.0, fail_seeds=(), crash_seeds=(),
                payload: int = 0, shared=None) -> dict:
    """The runner's own trial, for its tests and for measuring its overhead: sleeps
    ``sleep_s`` seconds, raises ``RuntimeError`` for a seed in ``fail_seeds``, ends its process
    at once (``os._exit``, as a crash in compiled code would) for a seed in ``crash_seeds``,
    returns the seed, the process id, whether that process is a Ray worker, the length of
    ``shared`` and a list of ``payload`` numbers."""
    if sleep_s > 0:
        time.sleep(sleep_s)
    if seed in set(fail_seeds):
        raise RuntimeError(f"probe trial {seed} fails on purpose")
    if seed in set(crash_seeds):
        os._exit(3)
    ray = sys.modules.get("ray")
    return {"seed": seed, "pid": os.getpid(),
            "ray_worker": bool(ray is not None and ray.is_initialized()),
            "shared_len": len(shared) if shared else 0, "payload": list(range(payload))}


# ---------------------------------------------------------------------------- command line

def add_sweep_args(ap, *, app: str, keeps_results: bool = True) -> None:
    """``--results``, ``--executor``, ``--ray-address``, ``--jobs``, ``--report-only``
    (``keeps_results``: without ``--results`` the records go to ``<app>_results.jsonl``, else
    to a temporary file)."""
    default = (f"{app}_results.jsonl in the output folder / current folder" if keeps_results
               else "a temporary file, removed after the run")
    ap.add_argument("--results", default=None,
                    help=f"JSON Lines file of the trials' records (default: {default}); "
                         "re-running the same command with it skips the trials already "
                         "recorded")
    ap.add_argument("--executor", choices=EXECUTORS, default="local",
                    help="local process pool (default) or Ray tasks (pip install 'mmlearn[ray]')")
    ap.add_argument("--ray-address", default=None,
                    help="address of a running Ray cluster (default: start a local Ray "
                         "instance with --jobs CPUs)")
    ap.add_argument("--jobs", type=_pos_int, default=None,
                    help="parallel trials (default: all cores)")
    ap.add_argument("--report-only", default=None, metavar="RESULTS.jsonl",
                    help="redraw the tables / plots from a results file without running anything")


def _pos_int(text):
    from mmlearn.apps.common.cli import pos_int

    return pos_int(text)


def sweep_kwargs(args, *, app: str, out_dir: str | Path | None = ".") -> dict:
    """The runner's keyword arguments from parsed ``add_sweep_args`` flags (checks them);
    ``out_dir`` None: no default results file (a temporary one)."""
    if args.ray_address and args.executor != "ray":
        raise UsageError("--ray-address needs --executor ray")
    results = args.results or (None if out_dir is None
                               else str(Path(out_dir) / f"{app}_results.jsonl"))
    if results is not None and Path(results).is_dir():
        raise UsageError(f"--results: {Path(results)} is a directory")
    check_out_file("--results", results)
    return {"results": results, "executor": args.executor, "jobs": args.jobs,
            "ray_address": args.ray_address}



def apply_sweep_args(cfg, args, *, app: str, out_dir: str | Path = ".") -> None:
    """Set ``cfg.results``, ``cfg.executor``, ``cfg.jobs`` and ``cfg.ray_address`` of an
    experiments app's config from its parsed ``add_sweep_args`` flags (checked as in
    :func:`sweep_kwargs`)."""
    sw = sweep_kwargs(args, app=app, out_dir=out_dir)
    cfg.results, cfg.executor, cfg.jobs = sw["results"], sw["executor"], sw["jobs"]
    cfg.ray_address = sw["ray_address"]

def exit_status(prog: str, res: dict) -> int:
    """An experiments app's exit status from its result (``res["errors"]``: the trials that
    raised, each with a ``"trial"`` name; ``res["sweep"]``: :meth:`SweepResult.summary`): 1
    with the failed trials named on stderr when a trial raised, 130 when the sweep was
    interrupted, else 0."""
    if res["errors"]:
        print(f"{prog}: {len(res['errors'])} trial(s) raised an error: "
              + ", ".join(e["trial"] for e in res["errors"]), file=sys.stderr)
        return 1
    if res.get("sweep", {}).get("interrupted"):
        return 130
    return 0


def report_only_lines(args, *, simulates: str, trials=()) -> list[dict] | None:
    """``--report-only RESULTS``: the results file's lines, or None without the flag. The
    viewing flags (``--meshcat`` / ``--html-out``) simulate ``simulates`` (e.g. "a roll"), so
    they are a usage error beside it."""
    path = getattr(args, "report_only", None)
    if not path:
        return None
    if getattr(args, "meshcat", False) or getattr(args, "html_out", None):
        raise UsageError(f"--meshcat / --html-out simulate {simulates}; --report-only "
                         "simulates nothing")
    return report_lines(path, trials=trials)


def report_only_result(res: dict, path: str | Path) -> dict:
    """A report recomputed by ``--report-only`` from ``path``: JSON-clean, marked as such."""
    res = json_clean(res)
    res["sweep"] = {"results_file": str(path), "report_only": True}
    return res


_SAID: set = set()


def report_lines(path: str | Path, *, trials=()) -> list[dict]:
    """The sound lines of a results file, for ``--report-only`` (:func:`read_results`,
    ``trials``: the experiment's trial functions, empty: any). Every skipped line is named
    and counted on stderr; a missing file, or one without a single valid record, is a
    :class:`UsageError` saying why."""
    p = Path(path)
    if not p.is_file():
        raise UsageError(f"--report-only: no results file {p}")
    try:
        lines, bad = read_results(p, trials=trials)
    except OSError as e:
        raise UsageError(f"--report-only: {p}: cannot read it ({e.strerror or e})") from None
    if not lines:
        raise UsageError(f"--report-only: {p} holds no valid trial record"
                         + (f" ({len(bad)} line(s) skipped: {_problems(bad, 2)})" if bad
                            else " (it is empty)"))
    said = (str(p.resolve()), tuple(sorted(trial_id(t) for t in trials)))
    if bad and said not in _SAID:  # once per file and process (an app may read it twice)
        _SAID.add(said)
        print(f"--report-only: {p}: skipped {len(bad)} of {len(bad) + len(lines)} line(s): "
              f"{_problems(bad)}", file=sys.stderr)
    return lines
