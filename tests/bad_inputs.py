"""A bad-input harness for every app: bad values for every flag (found from each app's own
argument parser), bad files for every input flag (missing, empty, binary, truncated, NaN,
another format, a folder), unknown flags and choices, and inputs whose result would be
meaningless. Each case runs the app's ``main(argv)`` in the test process and is classified:

* ``clean``: exit status 2 and one line on stderr saying ``error`` (no traceback);
* ``traceback``: an exception escaped ``main``;
* ``multiline``: exit 2, but more than one error line;
* ``accepted``: exit 0 (or 1) or the work started (silent nonsense for these inputs);
* ``status``: another exit status.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import io
import math
import os
import signal
from dataclasses import dataclass, field
from pathlib import Path

APPS = ("articulation_experiments", "body_schema_experiments", "fit_articulation",
        "fit_structure", "imitate", "imitate_lasa", "imitation_experiments",
        "learn_body_schema", "learn_priors", "liquid_detection", "open_cabinet",
        "operate_trials", "perception_experiments", "record_demos", "render_fronts",
        "structure_experiments", "tactile_recognition", "tactile_state", "track_fronts",
        "view_scene")

DATA = Path(__file__).parent / "data"
TRACK = DATA / "articulation_logs" / "left_door_001.log"

_INT_TYPES = {"pos_int", "_pos_int", "nonneg_int", "int"}
_FLOAT_TYPES = {"pos_float", "nonneg_float", "_finite_float", "float"}
#: flags that take an input file (or folder) the app reads
_INPUT_FLAGS = {"--demos-file": "demos", "--priors": "priors", "--load": "priors",
                "--config": "config", "--train": "folder", "--test": "folder",
                "--tracks": "folder"}
#: positional inputs: app -> kind
_POSITIONAL = {"fit_articulation": "track", "learn_priors": "track", "fit_structure": "parts"}
#: flags some apps need besides the bad one (so the bad one is what fails)
_BASE = {"fit_articulation": [str(TRACK)], "learn_priors": [str(TRACK)],
         "fit_structure": [str(DATA.parent.parent / "apps" / "examples" / "two_drawer_cabinet.csv")]}


@dataclass
class Case:
    app: str
    argv: list
    what: str


@dataclass
class Outcome:
    case: Case
    kind: str
    status: object = None
    stderr: str = ""
    detail: str = ""


@dataclass
class Files:
    """The bad files the cases use (made by :func:`make_files`)."""
    folder: Path
    paths: dict = field(default_factory=dict)

    def __getitem__(self, k):
        return str(self.paths[k])


class _Started(Exception):
    """The case ran past its time limit: the app accepted the input and started working."""


def parser_of(app: str) -> argparse.ArgumentParser:
    """The app's ArgumentParser, caught when ``main`` asks it to parse."""
    mod = importlib.import_module(f"mmlearn.apps.{app}")

    class Got(Exception):
        pass

    def grab(self, *a, **k):
        raise Got(self)

    orig = argparse.ArgumentParser.parse_args
    argparse.ArgumentParser.parse_args = grab
    try:
        mod.main([])
    except Got as g:
        return g.args[0]
    finally:
        argparse.ArgumentParser.parse_args = orig
    raise RuntimeError(f"{app}: main did not parse arguments")


def make_files(folder) -> Files:
    """Bad input files of every kind in ``folder``."""
    import sys

    sys.path.insert(0, str(Path(__file__).parent))
    from saved_files import write_saved_files

    folder = Path(folder)
    f = Files(folder)
    p = f.paths
    saved = write_saved_files(folder / "saved")
    p["missing"] = folder / "missing.json"
    p["empty"] = folder / "empty.json"
    p["empty"].write_text("")
    p["binary"] = folder / "binary.json"
    p["binary"].write_bytes(bytes(range(256)) * 8)
    p["folder"] = folder / "a_folder"
    p["folder"].mkdir()
    for name in ("priors.json", "demos.json", "link.yaml"):
        src = saved[name][0]
        text = src.read_bytes()
        p[f"truncated_{name}"] = folder / f"truncated_{name}"
        p[f"truncated_{name}"].write_bytes(text[: len(text) // 2])
        p[f"edited_{name}"] = folder / f"edited_{name}"
        p[f"edited_{name}"].write_bytes(text.replace(b"0.", b"0.9", 1))
        p[name] = src
    p["nan_json"] = folder / "nan.json"
    p["nan_json"].write_text('{"format": "mmlearn.articulation_priors", "version": 2, '
                             '"config": NaN}')
    p["list_json"] = folder / "list.json"
    p["list_json"].write_text("[1, 2, 3]")
    # YAML configs
    for k, text in {"cfg_toaster": "front: toaster\n", "cfg_nan": "kp_revolute: .nan\n",
                    "cfg_unknown": "toaster: 1\n", "cfg_list": "- 1\n- 2\n",
                    "cfg_type": "front: [1, 2]\n", "cfg_bad_yaml": "front: [\n",
                    "cfg_nested_nan": "camera:\n  fov_x_deg: .nan\n",
                    "cfg_time_step": "time_step: 10.0\n", "cfg_empty": "# nothing\n",
                    "cfg_neg": "noise:\n  max_range: -1\n"}.items():
        p[k] = folder / f"{k}.yaml"
        p[k].write_text(text)
    p["cfg_binary"] = folder / "cfg_binary.yaml"
    p["cfg_binary"].write_bytes(b"\xff\xfe\x00\x01" * 64)
    # tracks
    lines = TRACK.read_text().splitlines()
    for k, text in {"track_empty": "", "track_nan": "nan nan nan\n" * 20,
                    "track_inf": "0 0 inf\n" * 20,
                    "track_short": "0 0 0\n1 1 1\n",
                    "track_cols": "0 0 0\n0 1\n1 1 1\n",
                    "track_words": "a b c\n" * 5,
                    "track_truncated": "\n".join(lines[:2]) + "\n" + lines[2][:5],
                    "track_scaled": "".join(
                        " ".join(f"{float(x) * 1e6:.9g}" for x in ln.split()) + "\n"
                        for ln in lines if ln.strip())}.items():
        p[k] = folder / f"{k}.log"
        p[k].write_text(text)
    p["track_binary"] = folder / "track_binary.log"
    p["track_binary"].write_bytes(bytes(range(256)) * 4)
    # parts CSV
    for k, text in {"parts_empty": "", "parts_header": "t,part,x\n",
                    "parts_nan": "t,part,x,y,z,qx,qy,qz,qw\n" + "0,a,nan,0,0,0,0,0,1\n" * 5,
                    "parts_words": "hello\nworld\n"}.items():
        p[k] = folder / f"{k}.csv"
        p[k].write_text(text)
    p["parts_binary"] = folder / "parts_binary.csv"
    p["parts_binary"].write_bytes(bytes(range(256)) * 4)
    p["empty_folder"] = folder / "empty_folder"
    p["empty_folder"].mkdir()
    return f


def _values(action) -> list:
    """Bad values for one flag of the given argparse action."""
    t = getattr(action.type, "__name__", None)
    out = []
    if action.choices is not None:
        out += ["toaster"]
    if t in _INT_TYPES:
        out += ["-1", "abc", "2.5", "1e999", ""]
        if t in ("pos_int", "_pos_int"):
            out += ["0"]
    elif t in _FLOAT_TYPES:
        out += ["nan", "inf", "abc", "-inf"]
        if t in ("pos_float", "nonneg_float"):
            out += ["-1"]
        if t == "pos_float":
            out += ["0"]
    elif t == "float_list":
        out += ["nan", "1,abc", ",", "inf,1"]
    elif t == "list":
        out += ["toaster", ","]
    return out


def _file_values(kind: str, files: Files) -> list:
    common = ["missing", "binary", "empty", "folder", "list_json", "nan_json"]
    if kind == "priors":
        return common + ["truncated_priors.json", "edited_priors.json", "link.yaml",
                         "demos.json"]
    if kind == "demos":
        return common + ["truncated_demos.json", "edited_demos.json", "priors.json"]
    if kind == "config":
        return ["missing", "folder", "cfg_toaster", "cfg_nan", "cfg_unknown", "cfg_list",
                "cfg_type", "cfg_bad_yaml", "cfg_nested_nan", "cfg_binary", "cfg_empty",
                "cfg_neg"]
    if kind == "folder":
        return ["missing", "binary", "empty_folder"]
    if kind == "track":
        return ["missing", "track_empty", "track_nan", "track_inf", "track_short",
                "track_cols", "track_words", "track_binary", "track_truncated",
                "track_scaled", "empty_folder"]
    if kind == "parts":
        return ["missing", "parts_empty", "parts_header", "parts_nan", "parts_words",
                "parts_binary", "folder"]
    return []


#: inputs whose result would be meaningless (the app must refuse them), app -> argv lists
SEMANTIC = {
    "render_fronts": [["--distance", "1e6"], ["--front", "toaster"]],
    "track_fronts": [["--distance", "1e6"], ["--camera-rate", "-5"]],
    "view_scene": [["--duration", "0.0001"]],
    "learn_body_schema": [["--noise", "1e6"]],
    "imitate_lasa": [["--dt", "1e6", "--shapes", "Angle"], ["--shapes", "toaster"],
                     ["--folds", "toaster"], ["--gain", "5"]],
    "tactile_state": [["--train", str(DATA / "icub_grasp"), "--contact-level", "1e9"],
                      ["--f-target", "20", "--contact-level", "5"],
                      ["--train", str(DATA / "icub_grasp"), "--f-target", "20"]],
    "fit_articulation": [[str(TRACK), "--models", "toaster"], [str(TRACK), "--expect", "x"],
                         [str(TRACK), "--sigma-pos", "1e-9"]],
    "learn_priors": [[str(TRACK), "--models", "toaster"]],
    "perception_experiments": [["--only", "toaster"]],
    "structure_experiments": [["--only", "toaster"]],
}


def build_cases(files: Files) -> list[Case]:
    """Every case, over all apps."""
    cases = []
    for app in APPS:
        ap = parser_of(app)
        base = list(_BASE.get(app, []))
        cases.append(Case(app, base + ["--toaster"], "unknown flag"))
        cases.append(Case(app, base + ["--seed"], "flag without its value"))
        for a in ap._actions:
            if not a.option_strings or a.help == argparse.SUPPRESS:
                continue
            flag = a.option_strings[0]
            for v in _values(a):
                cases.append(Case(app, base + [flag, v], f"{flag} {v!r}"))
            kind = _INPUT_FLAGS.get(flag)
            if kind:
                for k in _file_values(kind, files):
                    cases.append(Case(app, base + [flag, files[k]], f"{flag} {k}"))
        pos = _POSITIONAL.get(app)
        if pos:
            for k in _file_values(pos, files):
                cases.append(Case(app, [files[k]], f"input {k}"))
        if app == "view_scene":
            cases.append(Case(app, ["--config", files["cfg_time_step"], "--duration", "0.5"],
                              "time step 10 s for a 0.5 s run"))
        for argv in SEMANTIC.get(app, []):
            cases.append(Case(app, list(argv), "meaningless: " + " ".join(argv)))
    if files.paths:
        cases.append(Case("imitate", ["--demos-file", files["demos.json"],
                                      "--task", "whiteboard"], "another task's demonstrations"))
    return cases


def run_case(case: Case, *, limit_s: float = 20.0) -> Outcome:
    """Run one case in this process (stdout / stderr captured; at most ``limit_s`` s)."""
    mod = importlib.import_module(f"mmlearn.apps.{case.app}")
    out, err = io.StringIO(), io.StringIO()

    def alarm(signum, frame):
        raise _Started()

    old = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, limit_s)
    status = None
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                status = mod.main(list(case.argv))
            except SystemExit as e:
                status = e.code
    except _Started:
        return Outcome(case, "accepted", None, err.getvalue(), f"still running after {limit_s} s")
    except BaseException as e:  # noqa: BLE001 - the harness counts it
        return Outcome(case, "traceback", None, err.getvalue(), f"{type(e).__name__}: {e}")
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
    text = err.getvalue()
    lines = [ln for ln in text.splitlines() if "error" in ln.lower()]
    if "Traceback (most recent call last)" in text:
        return Outcome(case, "traceback", status, text)
    if status in (0, 1, None):
        return Outcome(case, "accepted", status, text, out.getvalue()[-300:])
    if status != 2:
        return Outcome(case, "status", status, text)
    if len(lines) != 1:
        return Outcome(case, "multiline", status, text)
    return Outcome(case, "clean", status, text)


def summary(outcomes) -> dict:
    """Counts per kind, and the number of apps covered."""
    counts = {}
    for o in outcomes:
        counts[o.kind] = counts.get(o.kind, 0) + 1
    return {"cases": len(outcomes), "apps": len({o.case.app for o in outcomes}), **counts}


def main() -> None:  # pragma: no cover - the figures of docs/reliability_inputs.md
    import json
    import sys
    import tempfile
    import time

    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    with tempfile.TemporaryDirectory() as d:
        files = make_files(d)
        cases = build_cases(files)
        t0 = time.perf_counter()
        outs = [run_case(c) for c in cases]
        s = summary(outs)
        s["seconds"] = round(time.perf_counter() - t0, 1)
        print(json.dumps(s))
        for o in outs:
            if o.kind != "clean":
                print(o.kind, o.case.app, o.case.what, o.status, o.detail[:200],
                      o.stderr.strip()[-300:].replace("\n", " | "), file=sys.stderr)
    _ = math


if __name__ == "__main__":  # pragma: no cover
    main()
