"""Reading articulation track files (the format of the ROS articulation stack's logs, e.g. tests/data/articulation_logs).

Format: whitespace-separated text, one observation per line, ``#`` starts a comment (whole
line or trailing). Every data line has the same number of columns:

- 3 columns ``x y z``: position only (metres); orientation unknown.
- 7 columns ``x y z qx qy qz qw``: full pose (scalar-last quaternion).
- 9 columns ``x y z qx qy qz qw width height``: pose of a perceived rectangle plus its size
  (metres); the size is kept in :attr:`Track.extra`.

Errors (missing file, wrong column count, non-numeric or NaN values, fewer than
``min_observations`` observations, zero quaternion, positions beyond 1e6 m) raise :class:`TrackFileError` (a
ValueError) whose message names the file and, where applicable, the line number.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mmlearn.models.common.se3 import MAX_COORDINATE

__all__ = ["Track", "TrackFileError", "read_track", "find_track_files"]

TRACK_SUFFIXES = (".log", ".txt", ".dat", ".track")


class TrackFileError(ValueError):
    """A track file that cannot be used; the message names the file (and line)."""


@dataclass
class Track:
    """One observed track.

    Attributes:
        path: source file.
        poses: (n, 7) ``x y z qx qy qz qw`` or (n, 3) positions (metres).
        extra: (n, 2) rectangle width/height for 9-column files, else None.
        line_numbers: 1-based line number of every observation in the file.
    """

    path: str
    poses: np.ndarray
    extra: np.ndarray | None = None
    line_numbers: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))

    @property
    def n(self) -> int:
        return int(self.poses.shape[0])

    @property
    def has_orientation(self) -> bool:
        return self.poses.shape[1] == 7


def read_track(path, *, min_observations: int = 3) -> Track:
    """Read one track file. Raises TrackFileError naming the file and line on bad input."""
    p = Path(path)
    if not p.exists():
        raise TrackFileError(f"{p}: file not found")
    if not p.is_file():
        raise TrackFileError(f"{p}: not a regular file")
    try:
        text = p.read_text()
    except (OSError, UnicodeDecodeError) as e:
        raise TrackFileError(f"{p}: cannot read ({e})") from None
    rows: list[list[float]] = []
    lines: list[int] = []
    ncol = None
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        tok = line.split()
        if len(tok) not in (3, 7, 9):
            raise TrackFileError(
                f"{p}:{lineno}: expected 3, 7 or 9 columns (x y z [qx qy qz qw [w h]]), "
                f"got {len(tok)}"
            )
        if ncol is None:
            ncol = len(tok)
        elif len(tok) != ncol:
            raise TrackFileError(
                f"{p}:{lineno}: {len(tok)} columns, but earlier lines have {ncol}"
            )
        try:
            vals = [float(t) for t in tok]
        except ValueError:
            raise TrackFileError(f"{p}:{lineno}: non-numeric value in {line!r}") from None
        if not all(np.isfinite(vals)):
            raise TrackFileError(f"{p}:{lineno}: NaN or infinite value in {line!r}")
        if max(abs(v) for v in vals[:3]) > MAX_COORDINATE:
            raise TrackFileError(f"{p}:{lineno}: position beyond {MAX_COORDINATE:g} m "
                                 f"(positions must be in metres)")
        if ncol >= 7 and sum(v * v for v in vals[3:7]) < 1e-12:
            raise TrackFileError(f"{p}:{lineno}: zero quaternion")
        if ncol >= 7 and not sum(v * v for v in vals[3:7]) < 1e300:
            raise TrackFileError(f"{p}:{lineno}: quaternion too long to normalise")
        rows.append(vals)
        lines.append(lineno)
    if len(rows) < min_observations:
        raise TrackFileError(
            f"{p}: only {len(rows)} observation(s); at least {min_observations} are needed"
        )
    a = np.asarray(rows, dtype=float)
    extra = None
    if ncol == 9:
        extra = a[:, 7:9].copy()
        a = a[:, :7]
    if ncol >= 7:
        a[:, 3:7] /= np.linalg.norm(a[:, 3:7], axis=1, keepdims=True)
    return Track(path=str(p), poses=a, extra=extra, line_numbers=np.asarray(lines, dtype=int))


def find_track_files(paths) -> list[str]:
    """Expand files and folders (recursively, files ending in .log/.txt/.dat/.track, sorted)
    into a list of file paths. Paths that do not exist are kept so that the reader reports
    them."""
    out: list[str] = []
    for path in paths:
        p = Path(path)
        if p.is_dir():
            found = sorted(
                str(f)
                for f in p.rglob("*")
                if f.is_file() and f.suffix.lower() in TRACK_SUFFIXES
                and not f.name.lower().startswith("readme")
            )
            out.extend(found)
        else:
            out.append(os.fspath(p))
    return out
