"""Helpers shared by the apps: progress bars, Meshcat, config files, checked output paths and
atomic writes (through :mod:`mmlearn.models.common.fileio`)."""

from __future__ import annotations

import sys
from pathlib import Path

from mmlearn.models.common.fileio import (OutputPathError, atomic_output, atomic_write_text,
                                         check_output_dir, check_output_file)
from mmlearn.models.common.progress import progress, progress_bar  # noqa: F401 - for the apps


def make_meshcat(*, announce: bool = True):
    """Start a Meshcat server (local only) and, with ``announce`` (a live view), print its
    URL to stderr; for a recording only (``--html-out``) nobody needs the URL."""
    from pydrake.geometry import StartMeshcat

    meshcat = StartMeshcat()
    if announce:
        print(f"Meshcat: open {meshcat.web_url()} in a browser", file=sys.stderr)
    return meshcat


def frame_camera(meshcat, points, **kw):
    """:func:`mmlearn.systems.common.meshcat_view.frame_camera` (imported on first use)."""
    from mmlearn.systems.common.meshcat_view import frame_camera as frame

    return frame(meshcat, points, **kw)


def save_html(meshcat, path: str | Path) -> Path:
    """Write Meshcat's current scene (with its published recording) as standalone HTML.

    Meshcat's world-frame axes (red x, green y, blue z lines at the origin, which sits in
    the scene's furniture) are hidden first: they are not part of any drawing, and every
    recording's legend names only what the app draws."""
    meshcat.SetProperty("/Axes", "visible", False)
    return atomic_write_text(path, meshcat.StaticHtml())


def save_figure(fig, path, **kw) -> Path:
    """``fig.savefig`` written atomically (:func:`mmlearn.models.common.fileio.atomic_output`:
    a unique temporary file in the same folder, fsync, rename, fsync of the folder), so an
    interrupted run never leaves a half-written image. Returns the path."""
    path = Path(path)
    with atomic_output(path) as f:
        fig.savefig(f, format=path.suffix.lstrip(".").lower() or "png", **kw)
    return path


def load_config(path: str | Path, cls):
    """Load a dataclass config from YAML with Drake's typed loader (misspelled keys are
    errors naming the key) and check every value (:func:`validate_tree`: types, choices,
    bounds, finite numbers, nested configs). Raises ``ValueError("<path>: <key>: ...")``
    (``FileNotFoundError`` for a missing file)."""
    from pydrake.common.yaml import yaml_load_typed

    import yaml

    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"config file not found: {path}")
    if not path.is_file():
        raise ValueError(f"{path}: not a file")
    from mmlearn.models.common.config import validate_tree

    try:
        text = path.read_bytes().decode("utf-8")
    except UnicodeDecodeError as e:
        raise ValueError(f"{path}: not a text file (byte {e.start} is not UTF-8; binary or "
                         "damaged?)") from None
    try:
        doc = yaml.safe_load(text)
        if doc is None:
            raise ValueError("the file is empty (no key: value lines; leave --config out "
                             "for the defaults)")
        if not isinstance(doc, dict):
            raise ValueError(f"expected a mapping of {cls.__name__} keys to values, got "
                             f"{type(doc).__name__}")
        _check_config_types(doc, cls, "")
        # every field's allowed values (choices, bounds, finite), nested configs included:
        # an unknown value such as ``front: toaster`` is an error, never ignored
        return validate_tree(yaml_load_typed(schema=cls, filename=str(path)))
    except yaml.YAMLError as e:
        raise ValueError(f"{path}: not valid YAML ({' '.join(str(e).split())})") from None
    except AssertionError as e:
        # Drake's loader asserts that a nested config is a mapping (``sensor: 5``)
        raise ValueError(f"{path}: a nested config (such as 'sensor') must be a mapping of "
                         f"keys to values, got {str(e) or 'something else'!r}") from None
    except (RuntimeError, TypeError, ValueError) as e:
        raise ValueError(f"{path}: {' '.join(str(e).split())}") from None


def _check_config_types(d, cls, where: str) -> None:
    """Name the key whose YAML value has the wrong type for the dataclass ``cls`` (Drake's
    loader says only ``AssertionError: 5`` or ``could not convert string to float``)."""
    import dataclasses
    import typing

    if not isinstance(d, dict) or not dataclasses.is_dataclass(cls):
        return
    try:
        hints = typing.get_type_hints(cls)
    except Exception:  # noqa: BLE001 - unresolvable annotations: leave it to Drake
        return
    for f in dataclasses.fields(cls):
        if f.name not in d:
            continue
        v, t, key = d[f.name], hints.get(f.name), f"{where}{f.name}"
        if dataclasses.is_dataclass(t):
            if not isinstance(v, dict):
                raise ValueError(f"{key}: expected a mapping of {t.__name__} keys, got {v!r}")
            _check_config_types(v, t, key + ".")
        elif t is float and (isinstance(v, bool) or not isinstance(v, (int, float))):
            raise ValueError(f"{key}: expected a number, got {v!r}")
        elif t is int and (isinstance(v, bool) or not isinstance(v, int)):
            raise ValueError(f"{key}: expected an integer, got {v!r}")
        elif t is bool and not isinstance(v, bool):
            raise ValueError(f"{key}: expected true or false, got {v!r}")
        elif t is str and not isinstance(v, str):
            raise ValueError(f"{key}: expected a string, got {v!r}")


def finish_viewing(*, html_out, live: bool) -> None:
    """Tell where the recording went and, after a live Meshcat session in a terminal,
    keep the server up until the user presses Enter."""
    if html_out:
        print(f"Meshcat recording written to {html_out}")
    if live and sys.stdin.isatty():
        input("Meshcat is still serving the recording; press Enter to quit. ")


def json_clean(v):
    """Turn numpy scalars/arrays into plain Python and non-finite floats into None, so the
    value can be printed with ``json.dumps`` as strict JSON."""
    import math

    import numpy as np

    if isinstance(v, float):
        return v if math.isfinite(v) else None
    if isinstance(v, dict):
        return {str(k): json_clean(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [json_clean(x) for x in v]
    if isinstance(v, np.ndarray):
        return json_clean(v.tolist())
    if isinstance(v, np.generic):
        return json_clean(v.item())
    return v


# --------------------------------------------------------------------------- command lines
# One convention for every app: flags are spelled with hyphens (``--sigma-pos``; the old
# underscore spellings stay as hidden aliases), the output folder is ``--out-dir``, bad
# input exits with status 2 and a one-line message that names the flag.

import argparse as _argparse
import math as _math

BAD_INPUT = 2
"""Exit status for bad input (as argparse's own errors)."""

CREATE_DIRS_FLAG = "--create-dirs"
# ``--create-dirs`` of the command line parsed last in this process (every app parses one):
# the default of check_out_file / check_out_dir
_CREATE_DIRS = False


class UsageError(ValueError):
    """Bad input found by an app's checks; the message names the flag or file."""


class ArgumentParser(_argparse.ArgumentParser):
    """argparse with one-line errors (``prog: error: --seed: expected ...``, exit 2) and
    hidden underscore aliases: ``add_argument("--out-dir", ...)`` also accepts
    ``--out_dir`` without listing it in ``--help``."""

    def __init__(self, *a, **kw):
        super().__init__(*a, **kw)
        self.add_argument("--create-dirs", action="store_true",
                          help="create missing parent folders of the output paths (default: "
                               "a missing folder is an error)")

    def parse_known_args(self, args=None, namespace=None):
        ns, rest = super().parse_known_args(args, namespace)
        global _CREATE_DIRS
        _CREATE_DIRS = bool(getattr(ns, "create_dirs", False))
        return ns, rest

    def error(self, message):  # noqa: D401 - argparse API
        message = message.replace("argument ", "", 1) if message.startswith("argument ") \
            else message
        self.exit(BAD_INPUT, f"{self.prog}: error: {message} (see --help)\n")

    def add_argument(self, *names, **kw):
        action = super().add_argument(*names, **kw)
        aliases = ["--" + n[2:].replace("-", "_") for n in names
                   if n.startswith("--") and "-" in n[2:]]
        aliases = [a for a in aliases if a not in self._option_string_actions]
        if aliases:
            # the hidden spelling shares the action's dest, type and checks
            kw2 = {k: v for k, v in kw.items() if k not in ("help", "default", "required")}
            kw2["dest"] = action.dest
            super().add_argument(*aliases, help=_argparse.SUPPRESS,
                                 default=_argparse.SUPPRESS, **kw2)
        return action


def _number(kind, text, *, what):
    try:
        v = kind(text)
    except (TypeError, ValueError):
        raise _argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
    return v


def nonneg_int(text):
    """argparse type: an integer >= 0 (seeds, counts that may be 0)."""
    v = _number(int, text, what="a non-negative integer")
    if v < 0:
        raise _argparse.ArgumentTypeError(f"expected a non-negative integer, got {text!r}")
    return v


def pos_int(text):
    """argparse type: an integer >= 1."""
    v = _number(int, text, what="a positive integer")
    if v < 1:
        raise _argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return v


def pos_float(text):
    """argparse type: a finite number > 0 (noise levels, durations)."""
    v = _number(float, text, what="a finite number > 0")
    if not (_math.isfinite(v) and v > 0):
        raise _argparse.ArgumentTypeError(f"expected a finite number > 0, got {text!r}")
    return v


def nonneg_float(text):
    """argparse type: a finite number >= 0."""
    v = _number(float, text, what="a finite number >= 0")
    if not (_math.isfinite(v) and v >= 0):
        raise _argparse.ArgumentTypeError(f"expected a finite number >= 0, got {text!r}")
    return v


def name_list(choices=None):
    """argparse type: a comma-separated, non-empty list of names (optionally from
    ``choices``); returns a list."""
    def parse(text):
        names = [s.strip() for s in str(text).split(",") if s.strip()]
        if not names:
            raise _argparse.ArgumentTypeError(
                f"expected a comma-separated list{' of ' + ', '.join(choices) if choices else ''}"
                f", got {text!r}")
        if choices is not None:
            bad = [n for n in names if n not in choices]
            if bad:
                raise _argparse.ArgumentTypeError(
                    f"unknown {', '.join(map(repr, bad))}; choose from {', '.join(choices)}")
        return names
    parse.__name__ = "list"
    return parse


def float_list(text):
    """argparse type: a comma-separated, non-empty list of finite numbers; returns a list."""
    try:
        v = [float(x) for x in str(text).split(",") if x.strip()]
    except ValueError:
        raise _argparse.ArgumentTypeError(f"expected comma-separated numbers, got {text!r}") \
            from None
    if not v or not all(_math.isfinite(x) for x in v):
        raise _argparse.ArgumentTypeError(f"expected comma-separated finite numbers, got {text!r}")
    return v


def check_out_file(flag: str, path, *, create_dirs: bool | None = None) -> None:
    """Raise UsageError unless ``path`` can be written as a file, found by creating and
    removing a temporary file beside it (:func:`~mmlearn.models.common.fileio.check_output_file`):
    not a folder, its folder exists (missing folders are created with ``create_dirs``;
    None: the command line's ``--create-dirs``) and is writable. Call before any work."""
    try:
        check_output_file(path, what=flag, create_dirs=_create(create_dirs),
                          flag_hint=CREATE_DIRS_FLAG)
    except OutputPathError as e:
        raise UsageError(str(e)) from None


def check_out_dir(flag: str, path, *, create: bool = True,
                  create_dirs: bool | None = None) -> None:
    """Raise UsageError unless ``path`` is (or, with ``create``, can be made) a folder files
    can be written in, found by creating and removing a temporary file in it: an existing
    file there, or a missing parent folder (unless ``create_dirs``; None: the command
    line's ``--create-dirs``), is an error. Creates the folder when ``create``."""
    try:
        check_output_dir(path, what=flag, create=create, create_dirs=_create(create_dirs),
                         flag_hint=CREATE_DIRS_FLAG)
    except OutputPathError as e:
        raise UsageError(str(e)) from None


def _create(create_dirs: bool | None) -> bool:
    return _CREATE_DIRS if create_dirs is None else bool(create_dirs)


def check_in_file(flag: str, path) -> None:
    """Raise UsageError unless ``path`` is an existing regular file."""
    if path is None or str(path) == "":
        return
    p = Path(path)
    if not p.exists():
        raise UsageError(f"{flag}: {p}: file not found")
    if not p.is_file():
        raise UsageError(f"{flag}: {p} is not a file")


def fail(prog: str, message: str) -> int:
    """Print ``prog: error: message`` (one line) on stderr and return the bad-input status."""
    print(f"{prog}: error: {message}", file=sys.stderr)
    return BAD_INPUT
