"""Command-line pieces shared by the benchmarks: ``--json [FILE]`` and ``--quick``.

``--json FILE`` writes the benchmark's figures as one JSON document to FILE and the table is
printed as usual; ``--json`` alone (or ``--json -``) prints the JSON document instead of the
table. A speed benchmark's document holds ``figures``: a flat ``{name: number}`` of its
headline figures (the name carries the unit), read by ``run_speed.py``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np


def add_output_arguments(ap, *, quick: str | None = None) -> None:
    """Add ``--json [FILE]`` to the argparse parser ``ap``, and ``--quick`` (``store_true``,
    help ``quick``) when ``quick`` is given."""
    ap.add_argument("--json", nargs="?", const="-", default=None, metavar="FILE", type=_json_file,
                    help="also write the figures as JSON to FILE; without FILE (or '-'), print "
                         "the JSON instead of the table")
    if quick is not None:
        ap.add_argument("--quick", action="store_true", help=quick)


def _json_file(text: str) -> str:
    """argparse type of ``--json``: ``-`` or a file that can be written (checked at once by a
    probe write, not after the benchmark ran)."""
    import argparse

    from mmlearn.models.common.fileio import OutputPathError, check_output_file

    if text != "-":
        try:
            check_output_file(text)
        except OutputPathError as e:
            raise argparse.ArgumentTypeError(str(e)) from None
    return text


def _plain(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (Path, set, frozenset)):
        return str(o) if isinstance(o, Path) else sorted(o)
    return str(o)


def _finite(o):
    """JSON has no NaN or infinity: they become null."""
    if isinstance(o, float) and not math.isfinite(o):
        return None
    if isinstance(o, dict):
        return {str(k): _finite(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_finite(v) for v in o]
    return o


def emit_json(path: str | None, doc) -> bool:
    """Write ``doc`` as JSON to ``path`` (nothing when None; standard output when ``'-'``).
    Returns True when the JSON went to standard output (the caller then skips its table)."""
    if path is None:
        return False
    text = json.dumps(_finite(json.loads(json.dumps(doc, default=_plain))), indent=1)
    if path == "-":
        print(text)
        return True
    from mmlearn.models.common.fileio import atomic_write_text

    atomic_write_text(path, text + "\n")
    return False
