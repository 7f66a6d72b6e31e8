"""Pieces shared by the benchmarks: ``--json [FILE]``, ``--quick`` and ``--baseline REV``
(:func:`import_revision`).

``--json FILE`` writes the benchmark's figures as one JSON document to FILE and the table is
printed as usual; ``--json`` alone (or ``--json -``) prints the JSON document instead of the
table. A speed benchmark's document holds ``figures``: a flat ``{name: number}`` of its
headline figures (the name carries the unit), read by ``run_speed.py``.
"""

from __future__ import annotations

import atexit
import importlib
import io
import json
import math
import shutil
import subprocess
import sys
import tarfile
import tempfile
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


REPO = Path(__file__).resolve().parent.parent


def import_revision(rev: str, paths: list[str], package_dir: str, name: str,
                    rewrite: tuple[str, str]):
    """Import ``package_dir`` of git revision ``rev`` of this repository as the top-level
    package ``name``, for a side-by-side comparison with the checkout's code: ``paths``
    (directories under the repository) are extracted into a temporary directory (removed at
    exit), ``package_dir`` is renamed ``name`` (given an empty ``__init__.py`` when it has
    none), and ``rewrite`` = (old, new) replaces the absolute imports of its modules. Raises
    SystemExit with a one-line message when the revision cannot be extracted."""
    try:
        tar = subprocess.run(["git", "-C", str(REPO), "archive", rev, *paths],
                             capture_output=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError) as e:
        raise SystemExit(f"--baseline: cannot extract {' '.join(paths)} at {rev!r} ({e})")
    root = Path(tempfile.mkdtemp(prefix=f"baseline{name}_"))
    atexit.register(shutil.rmtree, root, ignore_errors=True)
    with tarfile.open(fileobj=io.BytesIO(tar)) as t:
        t.extractall(root, filter="data")
    pkg = root / name
    (root / package_dir).rename(pkg)
    if not (pkg / "__init__.py").is_file():
        (pkg / "__init__.py").write_text("")
    for f in pkg.rglob("*.py"):
        f.write_text(f.read_text().replace(*rewrite))
    sys.path.insert(0, str(root))
    return importlib.import_module(name)
