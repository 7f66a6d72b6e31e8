"""Helpers shared by the apps: progress bars, Meshcat, config files, atomic writes."""

from __future__ import annotations

import sys
from pathlib import Path

from mmlearn.models.fileio import atomic_write_text


def progress(iterable, *, desc: str = "", unit: str = "it", enabled: bool = True,
             total: int | None = None):
    """A tqdm progress bar on stderr (only when stderr is a terminal and ``enabled``)."""
    if not enabled:
        return iterable
    from tqdm import tqdm

    return tqdm(iterable, desc=desc, unit=unit, total=total, file=sys.stderr,
                disable=None, leave=False)


def progress_bar(total: int, desc: str = "", *, unit: str = "it", enabled: bool = True):
    """A manual tqdm bar on stderr (``update``, ``set_postfix_str``, ``close``); when not
    ``enabled`` (or stderr is no terminal) the same calls do nothing."""
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit=unit, file=sys.stderr, leave=False,
                disable=True if not enabled else None)


def make_meshcat():
    """Start a Meshcat server (local only) and print its URL to stderr."""
    from pydrake.geometry import StartMeshcat

    meshcat = StartMeshcat()
    print(f"Meshcat: open {meshcat.web_url()} in a browser", file=sys.stderr)
    return meshcat


def save_html(meshcat, path: str | Path) -> Path:
    """Write Meshcat's current scene (with its published recording) as standalone HTML."""
    return atomic_write_text(path, meshcat.StaticHtml())


def load_config(path: str | Path, cls):
    """Load a dataclass config from YAML with Drake's typed loader (misspelled keys are
    errors naming the key)."""
    from pydrake.common.yaml import yaml_load_typed

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"config file not found: {path}")
    try:
        return yaml_load_typed(schema=cls, filename=str(path))
    except RuntimeError as e:
        raise ValueError(f"{path}: {e}") from None


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
