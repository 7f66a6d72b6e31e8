"""Progress on stderr for long loops in trials, apps and benchmarks.

In a terminal this is a tqdm bar (with its rate and estimated time left). When stderr is not
a terminal (a log file, a pipe, a batch job) a bar would fill the log with carriage returns,
so a long run instead prints a plain line now and then::

    simulating: 1200/100000 step (1.2%), 0:00:30 elapsed, about 0:41:10 left

The first line comes after ``MMLEARN_PROGRESS_SECONDS`` seconds (default 30), then one per
that interval, so short runs stay quiet and a big run (``--trials 100000``) shows how far it
is and when it will end.
"""

from __future__ import annotations

import os
import sys
import time

__all__ = ["progress", "progress_bar", "LineProgress"]


def _interval() -> float:
    try:
        return max(float(os.environ.get("MMLEARN_PROGRESS_SECONDS", "30")), 0.0)
    except ValueError:
        return 30.0


def _hms(seconds: float) -> str:
    seconds = int(round(seconds))
    return f"{seconds // 3600}:{seconds // 60 % 60:02d}:{seconds % 60:02d}"


class LineProgress:
    """A progress bar for a stderr that is no terminal: plain lines at most every
    ``interval`` seconds with the count, the fraction done, the elapsed time and the estimated
    time left. Offers the tqdm calls the code uses (iteration, ``update``,
    ``set_postfix_str``, ``write``, ``close``, a context manager)."""

    def __init__(self, iterable=None, *, total=None, desc: str = "", unit: str = "it",
                 interval: float | None = None, file=None, clock=time.monotonic):
        if total is None and iterable is not None:
            try:
                total = len(iterable)
            except TypeError:
                total = None
        self.iterable, self.total, self.desc, self.unit = iterable, total, desc, unit
        self.n = 0
        self.postfix = ""
        self._clock = clock
        self._interval = _interval() if interval is None else interval
        self._start = clock()
        self._next = self._start + self._interval
        self._file = file if file is not None else sys.stderr
        self.lines = 0

    def __iter__(self):
        for x in self.iterable:
            yield x
            self.update(1)

    def __len__(self):
        return self.total or 0

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def update(self, n=1) -> None:
        self.n += n
        now = self._clock()
        if now >= self._next:
            self._report(now)
            self._next = now + self._interval

    def line(self, now=None) -> str:
        """The progress line as of ``now`` (the clock's time)."""
        now = self._clock() if now is None else now
        elapsed = now - self._start
        head = f"{self.desc}: " if self.desc else ""
        text = f"{head}{self.n}"
        if self.total:
            text += f"/{self.total} {self.unit} ({100.0 * self.n / self.total:.1f}%)"
        else:
            text += f" {self.unit}"
        text += f", {_hms(elapsed)} elapsed"
        if self.total and self.n > 0:
            left = elapsed * (self.total - self.n) / self.n
            text += f", about {_hms(left)} left"
        if self.postfix:
            text += f" [{self.postfix}]"
        return text

    def _report(self, now) -> None:
        print(self.line(now), file=self._file, flush=True)
        self.lines += 1

    def set_postfix_str(self, s: str = "", refresh: bool = True) -> None:
        self.postfix = str(s)

    def set_description(self, desc: str = "", refresh: bool = True) -> None:
        self.desc = str(desc)

    def write(self, s: str, file=None) -> None:
        print(s, file=file if file is not None else self._file)

    def refresh(self) -> None:
        pass

    def close(self) -> None:
        pass


def _terminal() -> bool:
    try:
        return sys.stderr.isatty()
    except (AttributeError, ValueError):
        return False


def progress(iterable, *, desc: str = "", unit: str = "it", enabled: bool = True,
             total: int | None = None):
    """``iterable`` with progress on stderr when ``enabled``: a tqdm bar in a terminal,
    else a :class:`LineProgress` (a line every 30 s of a long run)."""
    if not enabled:
        return iterable
    if not _terminal():
        return LineProgress(iterable, total=total, desc=desc, unit=unit)
    from tqdm import tqdm

    return tqdm(iterable, desc=desc, unit=unit, total=total, file=sys.stderr,
                disable=None, leave=False)


def progress_bar(total: int, desc: str = "", *, unit: str = "it", enabled: bool = True):
    """A manual progress bar on stderr (``update``, ``set_postfix_str``, ``close``): tqdm in
    a terminal, else a :class:`LineProgress`; when not ``enabled`` the same calls do
    nothing."""
    from tqdm import tqdm

    if enabled and not _terminal():
        return LineProgress(total=total, desc=desc, unit=unit)
    return tqdm(total=total, desc=desc, unit=unit, file=sys.stderr, leave=False,
                disable=True if not enabled else None)
