"""Generate the results tables of the docs from the results files in docs/results/.

    python docs/make_tables.py          # results/*.json -> results/tables/<capability>.md
    python docs/make_tables.py --run    # first re-run the experiments that make the files
    python docs/make_tables.py --run --only operate.json   # only some of them
    python docs/make_tables.py --check  # exit 1 if a committed table differs from its file

Every number in a table comes from a results file; the thesis' numbers beside them are the
reference values of the thesis (chapter and figure named in the row). Each table names the
command that produced its file, so a reader can re-run it. The runs are small (minutes on
two cores), so the tables show what a user gets from those commands, not the full-size
experiments that the pages name separately.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
RESULTS = DOCS / "results"
TABLES = RESULTS / "tables"

#: results file -> the command (run from the repository root) that writes it to stdout
COMMANDS = {
    "fit_articulation_sigma001.json": "python -m mmlearn.apps.fit_articulation tests/data/articulation_logs "
                                      "--sigma-pos 0.01 --seed 1 --json --no-progress",
    "fit_articulation_sigma002.json": "python -m mmlearn.apps.fit_articulation tests/data/articulation_logs "
                                      "--sigma-pos 0.02 --seed 1 --json --no-progress",
    "operate.json": "python -m mmlearn.apps.operate_trials --trials 1 --objects left_door,drawer "
                    "--seed 1 --jobs 1 --results docs/results/operate.jsonl --json",
    "body_schema.json": "python -m mmlearn.apps.learn_body_schema --arm 2dof --samples 50 --seed 1 --json",
    "fronts.json": "python -m mmlearn.apps.track_fronts --object drawer --seed 1 --json",
    "icub_state.json": "python -m mmlearn.apps.tactile_state --train tests/data/icub_grasp --folds 3 "
                       "--seed 1 --json",
    "lasa.json": "python -m mmlearn.apps.imitate_lasa --shapes Sshape,Leaf_1,GShape --json",
    "imitate.json": "python -m mmlearn.apps.imitate --task pick_place --seed 1 --json",
    # about an hour on two cores
    "teaching.json": "python -m mmlearn.apps.imitation_experiments --experiments teaching --seeds 10 "
                     "--seed 100 --jobs 1 --results docs/results/teaching.jsonl "
                     "--out-dir build/teaching --json",
    "structure_prior.json": "python benchmarks/bench_structure_prior.py --seeds 11-20 --json",
}


def _load(name: str):
    path = RESULTS / name
    if not path.is_file():
        return None
    return json.loads(path.read_text())


def _fmt(x, digits: int = 3, unit: str = "") -> str:
    if x is None:
        return "-"
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, int):
        return f"{x}{unit}"
    if isinstance(x, float):
        return f"{x:.{digits}f}{unit}"
    return str(x)


def _table(header: list[str], rows: list[list[str]]) -> str:
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(out)


def _source(*names: str) -> str:
    lines = []
    for n in names:
        state = "" if (RESULTS / n).is_file() else " (file missing: run `python docs/make_tables.py --run`)"
        lines.append(f"- `docs/results/{n}`{state}: `{COMMANDS[n]}`")
    return "Produced by (results files under `docs/results/`):\n\n" + "\n".join(lines)


def _expected_kind(path: str) -> str:
    name = Path(path).name
    for key, kind in (("drawer", "prismatic"), ("door", "revolute"), ("dishwasher", "revolute"),
                      ("cosine", "gp")):
        if key in name:
            return kind
    return "-"


def articulation() -> str:
    parts = []
    a, b = _load("fit_articulation_sigma001.json"), _load("fit_articulation_sigma002.json")
    if a and b:
        by_b = {t["path"]: t for t in b["tracks"]}
        rows = []
        for t in a["tracks"]:
            u = by_b.get(t["path"], {})
            rows.append([f"`{Path(t['path']).name}`", t["n"], _expected_kind(t["path"]),
                         t["selected"], u.get("selected", "-"),
                         _fmt(t["avg_pos_error_m"], 4, " m")])
        right = sum(r[2] == r[3] for r in rows)
        parts.append("**Model selection on recorded tracks** (Sec. 4.1; thesis: the right model "
                     "on every real track)\n\n" +
                     _table(["track", "n", "true kind", "selected at sigma 0.01 m",
                             "at 0.02 m", "position error (0.01 m)"], rows) +
                     f"\n\nRight at sigma 0.01 m: {right} of {len(rows)} tracks; at 0.02 m: "
                     f"{sum(r[2] == r[4] for r in rows)} of {len(rows)}" +
                     ("" if all(r[2] == r[4] for r in rows) else
                      " (a curve whose bow is below the assumed noise is taken as prismatic)") +
                     ".")
    op = _load("operate.json")
    if op:
        rows = []
        for t in op.get("trials", []):
            unit = t.get("unit", "")
            rows.append([t.get("object", "-"), t.get("seed", "-"), _fmt(t.get("success")),
                         t.get("learned_model", "-"), _fmt(t.get("right_kind")),
                         _fmt(t.get("opened"), 1 if unit == "deg" else 3, f" {unit}"),
                         _fmt(t.get("radius_error_m"), 3, " m"),
                         _fmt(t.get("axis_error_deg"), 1, " deg")])
        parts.append("**Opening doors and drawers** (Sec. 4.4.2; thesis: 37 of 40 opened)\n\n" +
                     _table(["object", "seed", "opened", "learned model", "right kind",
                             "opening", "radius error", "axis error"], rows) +
                     f"\n\nsigma_pos {op.get('sigma_pos')} m, base-localisation noise x"
                     f"{op.get('base_noise')}; thesis: door radii within 0.02 m.")
    return "\n\n".join(parts + [_source("fit_articulation_sigma001.json",
                                        "fit_articulation_sigma002.json", "operate.json")])


def body_schema() -> str:
    d = _load("body_schema.json")
    parts = []
    if d:
        rows = [["structure right", _fmt(d.get("structure_correct")), "yes"],
                ["samples until the structure was right", _fmt(d.get("converged_at"), 0), "about 10 (7-DOF)"],
                ["prediction error", _fmt(d.get("pred_error_m"), 4, " m"), "below the observation noise"],
                ["observation noise", _fmt(d.get("obs_noise_m"), 4, " m"), "-"],
                ["control error", _fmt(d.get("ctrl_error_m"), 4, " m"), "-"]]
        parts.append("**2-DOF arm, 50 babbling samples, marker noise 0.044 m** (Sec. 3.4)\n\n" +
                     _table(["measure", "here", "thesis"], rows))
    return "\n\n".join(parts + [_source("body_schema.json")])


def perception() -> str:
    d = _load("fronts.json")
    parts = []
    if d:
        rows = [["detection rate (front wholly in view, < 70 deg incidence)",
                 _fmt(d.get("detection_rate_eligible"), 2), "> 0.75 up to 2.2 m (Fig. 5.8)"],
                ["position error of the found front", _fmt(d.get("pos_error_m"), 4, " m"),
                 "< 0.015 m (Fig. 5.8)"],
                ["orientation error", _fmt(d.get("orient_error_deg"), 2, " deg"), "-"],
                ["model of the moving front's track", _fmt(d.get("selected_model")), "prismatic"],
                ["right from observation n", _fmt(d.get("model_right_from")), "-"]]
        parts.append("**A drawer opening in front of the depth camera**" +
                     (f" ({d['distance_m']} m away, {d.get('frames')} frames)" if "distance_m" in d else "") + " (Sec. 5.2)\n\n" +
                     _table(["measure", "here", "thesis"], rows))
    return "\n\n".join(parts + [_source("fronts.json")])


def tactile() -> str:
    d = _load("icub_state.json")
    parts = []
    if d:
        rows = [[d["classifier"] + " (six features of Table 7.1)", _fmt(d["rate"], 3)]]
        rows += [[name, _fmt(rate, 3)] for name, rate in sorted(d.get("compare", {}).items())]
        parts.append(f"**Real iCub grasps**: {d['evaluation']} on the sample files of "
                     f"`tests/data/icub_grasp` ({len(d['labels'])} classes, {d['n_test']} grasps; "
                     "the full data set has 10 objects x 10 trials)\n\n" +
                     _table(["classifier", "rate"], rows))
    return "\n\n".join(parts + [_source("icub_state.json")])


def imitation() -> str:
    parts = []
    d = _load("lasa.json")
    if d:
        rows = [[s["name"], _fmt(s["rmse_mm"], 3, " mm"), _fmt(s["baseline_rmse_mm"], 3, " mm"),
                 _fmt(s["end_error_mm"], 3, " mm")] for s in d["shapes"]]
        rows.append(["mean", _fmt(d["mean_rmse_mm"], 3, " mm"),
                     _fmt(d["baseline"]["mean_rmse_mm"], 3, " mm"),
                     _fmt(d["mean_end_error_mm"], 3, " mm")])
        parts.append("**LASA handwriting, leave-one-out** (ch. 8 method on human demonstrations; "
                     "the baseline is the mean demonstration shifted to the start)\n\n" +
                     _table(["shape", "rmse", "baseline rmse", "end error"], rows))
    r = _load("imitate.json")
    if r:
        rows = [["success", _fmt(r.get("success"))],
                ["place error", _fmt(r.get("place_error_m"), 3, " m")],
                ["cup upright on table B", _fmt(r.get("cup_on_table_b"))],
                ["learning time (4 demonstrations)", _fmt(r.get("learn_seconds"), 3, " s")]]
        parts.append("**Pick-and-place from 4 demonstrations** (Sec. 8.4; thesis: succeeds "
                     "from 4 demonstrations, also with swapped tables)\n\n" +
                     _table(["measure", "here"], rows))
    return "\n\n".join(parts + [_source("lasa.json", "imitate.json")])


def teaching() -> str:
    d = _load("teaching.json")
    if not d:
        return _source("teaching.json")
    order = ["pick_place 1 demo, swapped tables", "pick_place 2 demos, swapped tables",
             "pick_place 3 demos, swapped tables", "pick_place 4 demos, swapped tables",
             "pick_place 2 demos, swapped tables, isotropic prior",
             "pick_place interactive, swapped tables"]
    rows = []
    for r in sorted(d["conditions"], key=lambda r: order.index(r["condition"])
                    if r["condition"] in order else len(order)):
        counts = r.get("demos_counts") or {}
        per_seed = ", ".join(f"{n} x{c}" for n, c in counts.items()) if len(counts) > 1 else ""
        rows.append([r["condition"].replace("pick_place ", "").replace(", swapped tables", ""),
                     f"{r['successes']}/{r['trials']}",
                     f"{r.get('test_successes', r['successes'])}/{r['trials']}",
                     _fmt(r.get("mean_demos"), 1) + (f" ({per_seed})" if per_seed else ""),
                     str(r.get("asked_before_failing", 0)), str(r.get("failed_unflagged", 0)),
                     _fmt(r.get("median_place_error_m"), 3, " m")])
    return ("**Pick-and-place with swapped tables: batch against interactive teaching** "
            "(Sec. 9.1's outlook; the thesis: 4 demonstrations). *success*: the last "
            "reproduction (interactive: the round that ended teaching); *in batch's "
            "situation*: the reproduction in the situation batch learning is tested in for "
            "the same seed (interactive: a final test there after teaching)\n\n"
            + _table(["learning", "success", "in batch's situation", "demonstrations (mean)",
                      "rounds asked before failing", "rounds failed unasked",
                      "median place error"], rows)
            + "\n\n" + _source("teaching.json"))


def structure_prior() -> str:
    d = _load("structure_prior.json")
    if not d:
        return _source("structure_prior.json")
    n = len(d["seeds"])
    rows = [[r["case"], f"{r['right_bic_alone']}/{n}", f"{r['right_with_prior']}/{n}"]
            for r in d["rows"]]
    return ("**Right structure, the BIC alone against BIC + furniture prior** (Sec. 9.1's "
            "outlook)\n\n" + _table(["case", "BIC alone", "BIC + prior"], rows)
            + "\n\n" + _source("structure_prior.json"))


PAGES = {"articulation": articulation, "body_schema": body_schema, "perception": perception,
         "tactile": tactile, "imitation": imitation, "teaching": teaching,
         "structure_prior": structure_prior}


def render() -> dict[str, str]:
    """Page name -> the generated markdown table(s)."""
    head = "<!-- generated by docs/make_tables.py from docs/results/; do not edit -->\n\n"
    return {page: head + fn() + "\n" for page, fn in PAGES.items()}


def run_experiments(only=None) -> None:
    """Re-run every command of COMMANDS (or the results files named in ``only``) and write
    its JSON output to docs/results/."""
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
    for name, cmd in COMMANDS.items():
        if only and name not in only:
            continue
        argv = [sys.executable] + cmd.split()[1:]
        if "--results" in argv:  # a fresh sweep: an old results file would only be resumed
            (ROOT / argv[argv.index("--results") + 1]).unlink(missing_ok=True)
        print(f"+ {cmd}", flush=True)
        r = subprocess.run(argv, cwd=ROOT, env=env, capture_output=True, text=True)
        try:
            json.loads(r.stdout)
        except json.JSONDecodeError:
            sys.exit(f"make_tables: {cmd!r} printed no JSON (exit {r.returncode}): "
                     f"{r.stderr.strip().splitlines()[-1:]} ")
        tmp = RESULTS / (name + ".tmp")
        tmp.write_text(r.stdout)
        tmp.replace(RESULTS / name)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--run", action="store_true", help="re-run the experiments first")
    ap.add_argument("--only", default="", metavar="FILES",
                    help="with --run: only these results files (comma-separated, e.g. "
                         "operate.json,fronts.json)")
    ap.add_argument("--check", action="store_true",
                    help="only compare the committed tables with the results files")
    args = ap.parse_args(argv)
    only = [x.strip() for x in args.only.split(",") if x.strip()]
    unknown = sorted(set(only) - set(COMMANDS))
    if unknown:
        ap.error(f"--only: unknown results file(s) {', '.join(unknown)}; choose from "
                 f"{', '.join(COMMANDS)}")
    if args.run:
        run_experiments(only)
    tables = render()
    if args.check:
        stale = [p for p, text in tables.items()
                 if not (TABLES / f"{p}.md").is_file() or (TABLES / f"{p}.md").read_text() != text]
        if stale:
            print("make_tables: stale tables: " + ", ".join(stale), file=sys.stderr)
            return 1
        return 0
    TABLES.mkdir(parents=True, exist_ok=True)
    for page, text in tables.items():
        tmp = TABLES / f"{page}.md.tmp"
        tmp.write_text(text)
        tmp.replace(TABLES / f"{page}.md")
        print(f"wrote {TABLES / page}.md")
    return 0


if __name__ == "__main__":
    sys.exit(main())
