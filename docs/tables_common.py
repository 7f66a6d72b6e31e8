"""The formatting shared by the generated blocks of docs/make_tables.py,
docs/tables_engineering.py and docs/tables_notes.py: a figure as text, a markdown table, and
the line that stands in for a results file not yet made."""

from __future__ import annotations

from pathlib import Path


def fmt(x, digits: int = 3, unit: str = "", sign: bool = False) -> str:
    """A figure as text: ``-`` for None, yes/no for a bool, an int as it is, a float with
    ``digits`` decimals (never ``-0.000``; a leading ``+`` when ``sign``), anything else as
    ``str``; ``unit`` follows a number."""
    if x is None:
        return "-"
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, int):
        return f"{x}{unit}"
    if not isinstance(x, float):
        return str(x)
    if abs(x) < 0.5 * 10.0 ** -digits:
        return f"{0.0:.{digits}f}{unit}"
    return f"{x:+.{digits}f}{unit}" if sign else f"{x:.{digits}f}{unit}"


def table(header, rows) -> str:
    """A markdown table of ``header`` and ``rows`` (each cell as ``str``)."""
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(out)


def missing(name: str) -> str:
    """The line of a block whose results file ``docs/results/<name>`` is not there."""
    return (f"(no `docs/results/{name}` in this checkout: `python docs/make_tables.py --run "
            f"--only {Path(name).stem}` makes it)")
