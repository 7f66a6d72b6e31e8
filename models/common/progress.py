"""Progress bars on stderr (tqdm), for long loops in trials, apps and benchmarks."""

from __future__ import annotations

import sys

__all__ = ["progress", "progress_bar"]


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
