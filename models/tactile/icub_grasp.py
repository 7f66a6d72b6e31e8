"""Reader for the iCub grasp dataset (H. Soh, 2012), real tactile grasps for thesis ch. 7.

File format (``README.txt`` of the data set): one file ``<label>_<trial>.txt`` per grasp; the
first line ``-10000`` is a header; then every time slice is 7 lines:

1. 9 encoder values of the iCub hand, joints 7-15, degrees (7 finger adduction, 8 thumb
   opposition, 9-10 thumb proximal / distal flexion, 11-12 index, 13-14 middle, 15 ring and
   little finger together);
2. 5 values, per finger: ``max(255 - reading)``;
3.-7. 12 raw taxel readings of the thumb, index, middle, ring and little finger; 255 = no
   pressure, smaller = more pressure (untouched taxels read about 240-252).

Lines end in CRLF in the original files; blank lines are ignored. Any deviation is an
:class:`ICubFileError` (a ValueError) whose message names the file and line: a truncated time
slice, a wrong number of values, non-numeric / NaN / infinite values, negative or > 255 taxel
readings, encoder values beyond +-360 deg, a file name with an unknown object label, fewer
than 2 time slices.

From a trial to the quantities of ch. 7 (:meth:`ICubTrial.to_grasp`):

* p(t): the hand's **closure**, the mean of the 7 flexion encoders (joints 9-15), radians.
  It stands in for the gripper's finger distance; it *increases* as the hand closes (a
  gripper's distance decreases), which changes only signs in the features.
* f(t): the summed taxel pressure ``sum(255 - reading)`` over all 60 taxels, raw sensor counts
  (the data set has no force calibration and no reference reading without contact, so the
  sensor's no-load offset of ~650 counts stays in; it is the same for every class).
* finger contact: each finger's highest taxel pressure, counts. The ring and little fingers
  never touch anything in this data set; their highest taxel reads 11-14 counts in every slice
  of all 110 shared trials, so the contact threshold F defaults to :data:`CONTACT_LEVEL` =
  18 counts (that no-load maximum plus the 4-count spread of the no-load band; chosen from
  the untouched fingers, not from the class labels).
* time: the data set gives no sample rate; time is counted in **slices** (``t = 0, 1, 2, ...``
  at a nominal 1 Hz), so dt is in slices and the rates are per slice.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mmlearn.models.tactile.types import TactileGrasp

__all__ = ["ICubFileError", "ICubTrial", "read_icub_trial", "find_icub_files", "load_icub_dir",
           "KNOWN_LABELS", "UNRELIABLE_LABELS", "CONTACT_LEVEL", "REST_VELOCITY",
           "parse_icub_name"]

KNOWN_LABELS = ("blue_bear", "book", "empty_coke", "empty_vitamin_water", "full_coke",
                "full_vitamin_water", "lotion", "med_coke", "med_vitamin_water", "monkey_toy",
                "none")
"""Object labels of the data set (file name prefixes)."""

UNRELIABLE_LABELS = ("full_coke",)
"""Marked unreliable by the data set's author (README: problems during data collection)."""

CONTACT_LEVEL = 18.0
"""Default contact threshold F on a finger's highest taxel pressure, counts (no-load: 11-14)."""

REST_VELOCITY = float(np.deg2rad(0.25))
"""Default rest threshold V on the closure rate, rad per slice (0.25 deg: half the encoders'
0.5 deg resolution, averaged over 7 joints)."""

N_ENCODERS, N_FINGERS, N_TAXELS = 9, 5, 12
FLEXION = slice(2, 9)  # joints 9-15 within the 9 encoders (7-15)
FINGERS = ("thumb", "index", "middle", "ring", "little")
_LINE_COUNTS = (N_ENCODERS, N_FINGERS) + (N_TAXELS,) * N_FINGERS
_LINE_NAMES = ("encoder", "per-finger maximum") + tuple(f"{f} taxel" for f in FINGERS)
_NAME_RE = re.compile(r"^(?P<label>.+)_(?P<trial>\d+)\.txt$")


class ICubFileError(ValueError):
    """An iCub grasp file that cannot be used; the message names the file and line."""


@dataclass
class ICubTrial:
    """One grasp of the iCub data set.

    Attributes:
        path: source file.
        label: object label (one of :data:`KNOWN_LABELS`).
        trial: trial number from the file name.
        encoders: (T, 9) joints 7-15, degrees.
        finger_max: (T, 5) the file's per-finger ``max(255 - reading)``, counts.
        taxels: (T, 5, 12) raw readings (255 = no pressure), counts.
        line_numbers: (T,) 1-based line of each slice's first line.
    """

    path: str
    label: str
    trial: int
    encoders: np.ndarray
    finger_max: np.ndarray
    taxels: np.ndarray
    line_numbers: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))

    @property
    def n(self) -> int:
        return int(self.encoders.shape[0])

    @property
    def pressure(self) -> np.ndarray:
        """(T, 5, 12) taxel pressure ``255 - reading``, counts (>= 0)."""
        return 255.0 - self.taxels

    def closure(self) -> np.ndarray:
        """(T,) mean flexion of joints 9-15, radians (grows as the hand closes)."""
        return np.deg2rad(self.encoders[:, FLEXION].mean(axis=1))

    def to_grasp(self) -> TactileGrasp:
        """The trial as a :class:`TactileGrasp` (see the module docstring for the units):
        ``p`` closure (rad), ``f`` summed pressure (counts), ``finger_force`` each finger's
        highest taxel pressure (counts), ``t`` in slices."""
        P = self.pressure
        return TactileGrasp(t=np.arange(self.n, dtype=float), p=self.closure(),
                            f=P.sum(axis=(1, 2)), finger_force=P.max(axis=2),
                            label=self.label)


def parse_icub_name(path) -> tuple[str, int]:
    """``(label, trial)`` from a file name ``<label>_<trial>.txt``; ICubFileError when the name
    does not match or the label is unknown."""
    p = Path(path)
    m = _NAME_RE.match(p.name)
    if not m:
        raise ICubFileError(f"{p}: file name does not match <label>_<trial>.txt")
    label = m.group("label")
    if label not in KNOWN_LABELS:
        raise ICubFileError(f"{p}: unknown object label {label!r} (known: "
                            f"{', '.join(KNOWN_LABELS)})")
    return label, int(m.group("trial"))


def read_icub_trial(path) -> ICubTrial:
    """Read one trial file; raises :class:`ICubFileError` naming the file and line."""
    p = Path(path)
    label, trial = parse_icub_name(p)
    if not p.exists():
        raise ICubFileError(f"{p}: file not found")
    if not p.is_file():
        raise ICubFileError(f"{p}: not a regular file")
    try:
        text = p.read_text()
    except (OSError, UnicodeDecodeError) as e:
        raise ICubFileError(f"{p}: cannot read ({e})") from None
    lines = [(i, s.strip()) for i, s in enumerate(text.splitlines(), start=1) if s.strip()]
    if not lines:
        raise ICubFileError(f"{p}: empty file")
    if lines[0][1].split() == ["-10000"]:
        lines = lines[1:]
    else:
        raise ICubFileError(f"{p}:{lines[0][0]}: expected the header line '-10000', got "
                            f"{lines[0][1][:40]!r}")
    rows: list[list[float]] = []
    for k, (lineno, s) in enumerate(lines):
        kind = k % 7
        tok = s.split()
        if len(tok) != _LINE_COUNTS[kind]:
            raise ICubFileError(
                f"{p}:{lineno}: time slice {k // 7 + 1} is truncated or malformed: expected "
                f"{_LINE_COUNTS[kind]} {_LINE_NAMES[kind]} values, got {len(tok)}")
        try:
            vals = [float(x) for x in tok]
        except ValueError:
            raise ICubFileError(f"{p}:{lineno}: non-numeric value in {s[:60]!r}") from None
        a = np.asarray(vals)
        if not np.all(np.isfinite(a)):
            raise ICubFileError(f"{p}:{lineno}: NaN or infinite {_LINE_NAMES[kind]} value")
        if kind == 0 and np.any(np.abs(a) > 360):
            raise ICubFileError(f"{p}:{lineno}: encoder value beyond +-360 deg ({a[np.argmax(np.abs(a))]:g})")
        if kind >= 1 and np.any(a < 0):
            raise ICubFileError(f"{p}:{lineno}: negative {_LINE_NAMES[kind]} reading "
                                f"({a.min():g}); readings are 0-255")
        if kind >= 1 and np.any(a > 255):
            raise ICubFileError(f"{p}:{lineno}: {_LINE_NAMES[kind]} reading above 255 "
                                f"({a.max():g})")
        rows.append(vals)
    if len(rows) % 7:
        lineno = lines[-1][0]
        raise ICubFileError(f"{p}:{lineno}: the last time slice is truncated ({len(rows) % 7} "
                            f"of 7 lines)")
    T = len(rows) // 7
    if T < 2:
        raise ICubFileError(f"{p}: {T} time slice(s); at least 2 are needed")
    enc = np.array(rows[0::7], dtype=float)
    fmax = np.array(rows[1::7], dtype=float)
    tax = np.stack([np.array(rows[2 + j::7], dtype=float) for j in range(N_FINGERS)], axis=1)
    starts = np.array([lines[7 * i][0] for i in range(T)], dtype=int)
    return ICubTrial(str(p), label, trial, enc, fmax, tax, starts)


def find_icub_files(folder) -> list[Path]:
    """The ``*.txt`` trial files of a folder (not recursive; README files skipped), sorted by
    label and trial number."""
    d = Path(folder)
    if not d.exists():
        raise ICubFileError(f"{d}: folder not found")
    if not d.is_dir():
        raise ICubFileError(f"{d}: not a folder")
    files = [f for f in d.iterdir() if f.is_file() and f.suffix.lower() == ".txt"
             and not f.name.lower().startswith("readme")]

    def key(f):
        m = _NAME_RE.match(f.name)
        return (m.group("label"), int(m.group("trial"))) if m else (f.name, -1)

    return sorted(files, key=key)


def load_icub_dir(folder, *, include_unreliable: bool = False, trials=None,
                  strict: bool = True) -> tuple[list[ICubTrial], list[str]]:
    """Read every trial file of ``folder``.

    Args:
        include_unreliable: keep :data:`UNRELIABLE_LABELS` (``full_coke``); default skipped.
        trials: optional collection of trial numbers to keep (e.g. ``range(1, 6)``).
        strict: raise on the first bad file; otherwise collect its message and go on.

    Returns:
        (trials, errors): the trials read and one message per bad file (empty when strict).
    """
    out, errors = [], []
    files = find_icub_files(folder)
    if not files:
        raise ICubFileError(f"{folder}: no trial files (*.txt)")
    for f in files:
        try:
            label, num = parse_icub_name(f)
            if label in UNRELIABLE_LABELS and not include_unreliable:
                continue
            if trials is not None and num not in trials:
                continue
            out.append(read_icub_trial(f))
        except ICubFileError as e:
            if strict:
                raise
            errors.append(str(e))
    return out, errors
