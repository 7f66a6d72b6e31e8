"""Write the measured tables of docs/performance.md from ``run_speed.py``'s JSON.

    python benchmarks/run_speed.py --json speed.json
    python benchmarks/make_performance_doc.py speed.json [--doc docs/performance.md]

Replaces what lies between the lines ``<!-- speed-table:start -->`` and
``<!-- speed-table:end -->`` of the page (the rest is left as it is) with two markdown tables:
the anchored figures (value, anchor, ratio, target, load) and every benchmark's headline
figures with its wall time and load. Exit status 2 on a missing or malformed JSON or page.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

START, END = "<!-- speed-table:start -->", "<!-- speed-table:end -->"
DOC = Path(__file__).resolve().parents[1] / "docs" / "performance.md"


def _fmt(v) -> str:
    if v is None:
        return "-"
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return str(v)
    return f"{v:.4g}"


def tables(doc: dict) -> str:
    """The markdown of the two tables for run_speed's JSON document ``doc``."""
    out = [f"Measured {doc.get('date', '')} on {doc.get('cores', '?')} cores, every benchmark "
           "in its quick mode, one BLAS thread (`python benchmarks/run_speed.py --json FILE`; "
           "load: the 1-minute load average at the benchmark's start and end).", ""]
    if doc.get("anchors"):
        out += ["| figure | value | anchor | ratio | target | met | load |",
                "|---|---|---|---|---|---|---|"]
        for a in doc["anchors"]:
            met = "-" if a["met"] is None else ("yes" if a["met"] else "no")
            out.append(f"| {a['benchmark'].removeprefix('bench_')}: `{a['figure']}` | "
                       f"{_fmt(a['value'])} | {a['anchor']}: {_fmt(a['anchor_value'])} | "
                       f"{_fmt(a['ratio'])} | {a['target'] or '-'} | {met} | {a['load']} |")
        out.append("")
    out += ["| benchmark | figure | value | wall s | load |", "|---|---|---|---|---|"]
    for r in doc["benchmarks"]:
        items = list(r["figures"].items()) or [(f"error: {r['error']}", None)]
        for k, (fig, v) in enumerate(items):
            head = (r["name"].removeprefix("bench_"), f"{r['wall_s']:.1f}",
                    f"{r['load_start']:.1f}-{r['load_end']:.1f}") if k == 0 else ("", "", "")
            out.append(f"| {head[0]} | `{fig}` | {_fmt(v)} | {head[1]} | {head[2]} |")
    return "\n".join(out)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("json", help="run_speed.py's --json output")
    ap.add_argument("--doc", default=str(DOC), help="the page to update")
    a = ap.parse_args(argv)
    try:
        doc = json.loads(Path(a.json).read_text())
        doc["benchmarks"]  # noqa: B018 - the one key the tables need
        page = Path(a.doc).read_text()
    except (OSError, ValueError, KeyError, TypeError) as e:
        print(f"make_performance_doc: cannot read the JSON or the page ({e})", file=sys.stderr)
        return 2
    if page.count(START) != 1 or page.count(END) != 1 or page.index(START) > page.index(END):
        print(f"make_performance_doc: {a.doc} needs one {START} ... {END} block",
              file=sys.stderr)
        return 2
    head, rest = page.split(START)
    _, tail = rest.split(END)
    new = f"{head}{START}\n{tables(doc)}\n{END}{tail}"
    tmp = Path(a.doc).with_name(Path(a.doc).name + ".tmp")
    tmp.write_text(new)
    tmp.replace(a.doc)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
