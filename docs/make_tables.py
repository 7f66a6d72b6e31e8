"""Generate every measured figure of the README and the docs from the results files in
docs/results/.

    python docs/make_tables.py                 # results/*.json -> results/tables/<page>.md and
                                               # the generated blocks of README.md
    python docs/make_tables.py --run           # first re-run every experiment that makes a file
    python docs/make_tables.py --run --only operate_trials,teaching   # only some of them
    python docs/make_tables.py --check         # exit 1 if a table or a README block differs
                                               # from what the results files give

Every number comes from a results file; the thesis' numbers beside them are the reference
values of the thesis (chapter and figure named beside them). Each table names the command that
produced its file, so a reader can re-run it. The small runs take minutes on two cores and
show what a user gets from those commands; the larger runs (``operate_trials``,
``body_schema_7dof``, ...) are the sizes that fit about 10-15 CPU minutes each, and every line
that quotes them states that size and the command. In README.md the generated parts sit
between ``<!-- generated:NAME -->`` and ``<!-- /generated:NAME -->``; do not edit them by hand.
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

#: results file -> the command (run from the repository root) that writes it: to stdout, or,
#: when the command names the file after ``--json``, itself. The name given to ``--only`` is
#: the file's stem (``operate_trials``) or the file name.
COMMANDS = {
    "fit_articulation_sigma001.json": "python -m mmlearn.apps.fit_articulation tests/data/articulation_logs "
                                      "--sigma-pos 0.01 --seed 1 --json --no-progress",
    "fit_articulation_sigma002.json": "python -m mmlearn.apps.fit_articulation tests/data/articulation_logs "
                                      "--sigma-pos 0.02 --seed 1 --json --no-progress",
    "fit_articulation_sigma005.json": "python -m mmlearn.apps.fit_articulation tests/data/articulation_logs "
                                      "--sigma-pos 0.05 --seed 1 --json --no-progress",
    "operate.json": "python -m mmlearn.apps.operate_trials --trials 1 --objects left_door,drawer "
                    "--seed 1 --jobs 1 --results docs/results/operate.jsonl --json",
    # the five objects of Sec. 4.4.2, 8 trials each as in the thesis (about 10 CPU minutes)
    "operate_trials.json": "python -m mmlearn.apps.operate_trials --trials 8 --seed 0 --jobs 2 "
                           "--results docs/results/operate_trials.jsonl --json",
    "user_models.json": "python -m mmlearn.apps.operate_trials --model "
                        "tests/data/user_models/wall_cabinet.sdf --joint door_hinge --trials 5 "
                        "--seed 0 --jobs 1 --results docs/results/user_models.jsonl --json",
    "mechanism_damping.json": "python benchmarks/bench_mechanism.py --only damping --seed 900 "
                              "--results docs/results/mechanism_damping.jsonl "
                              "--json docs/results/mechanism_damping.json",
    # the same on a second set of doors and drawers
    "mechanism_damping_950.json": "python benchmarks/bench_mechanism.py --only damping --seed 950 "
                                  "--results docs/results/mechanism_damping_950.jsonl "
                                  "--json docs/results/mechanism_damping_950.json",
    # and on a third
    "mechanism_damping_980.json": "python benchmarks/bench_mechanism.py --only damping --seed 980 "
                                  "--results docs/results/mechanism_damping_980.jsonl "
                                  "--json docs/results/mechanism_damping_980.json",
    # and on a fourth
    "mechanism_damping_1010.json": "python benchmarks/bench_mechanism.py --only damping "
                                   "--seed 1010 --results docs/results/mechanism_damping_1010.jsonl "
                                   "--json docs/results/mechanism_damping_1010.json",
    # jams at 5 positions, latches and sticky mechanisms, doors and drawers (about 30 CPU minutes)
    "mechanism_faults.json": "python benchmarks/bench_mechanism.py --only jam,locked,sticky "
                             "--kinds left_door,drawer --trials 2 --repeats 5 --seed 700 --jobs 2 "
                             "--results docs/results/mechanism_faults.jsonl "
                             "--json docs/results/mechanism_faults.json",
    # single trials quoted on docs/mechanism_dynamics.md (about 1 CPU minute each)
    "drawer_spring.json": "python -m mmlearn.apps.open_cabinet --object drawer --seed 8 "
                          "--damping 20 --spring 10 --save-model build/drawer8.sdf --json",
    "drawer_locked.json": "python -m mmlearn.apps.open_cabinet --object drawer --seed 7 --locked "
                          "--json",
    # where a door's damping goes: the torque followed through one trial (a few CPU minutes each)
    "door_torque_map.json": "python benchmarks/bench_door_torque.py --seeds 710 --damping 3 "
                            "--frame map --json docs/results/door_torque_map.json",
    "door_torque_exact.json": "python benchmarks/bench_door_torque.py --seeds 710 --damping 3 "
                              "--base-noise 0 --frame map --json docs/results/door_torque_exact.json",
    "body_schema.json": "python -m mmlearn.apps.learn_body_schema --arm 2dof --samples 50 --seed 1 --json",
    "body_schema_7dof.json": "python benchmarks/bench_body_schema_7dof.py --sigmas 0.044 --seeds 1-5 "
                             "--extra --jobs 1 --results docs/results/body_schema_7dof.jsonl "
                             "--json docs/results/body_schema_7dof.json",
    "fronts.json": "python -m mmlearn.apps.track_fronts --object drawer --seed 1 --json",
    "perception_distance.json": "python -m mmlearn.apps.perception_experiments --only distance "
                                "--objects drawer --distances 2.2 --seeds 3 --frames 60 --seed 1 "
                                "--jobs 1 --no-progress --out-dir build/perception "
                                "--results docs/results/perception_distance.jsonl --json",
    "icub_state.json": "python -m mmlearn.apps.tactile_state --train tests/data/icub_grasp --folds 3 "
                       "--seed 1 --json",
    "tactile_state_sim.json": "python -m mmlearn.apps.tactile_state --f-target 20 --trials 4 --seed 1 "
                              "--jobs 1 --results docs/results/tactile_state_sim.jsonl --json",
    "tactile_recognition.json": "python -m mmlearn.apps.tactile_recognition --grasps-per-class 4 "
                                "--seed 1 --jobs 1 --results docs/results/tactile_recognition.jsonl "
                                "--json",
    "lasa.json": "python -m mmlearn.apps.imitate_lasa --shapes Sshape,Leaf_1,GShape --json",
    "lasa_held_back.json": "python -m mmlearn.apps.imitate_lasa --shapes held-back --json",
    "imitate.json": "python -m mmlearn.apps.imitate --task pick_place --seed 1 --json",
    "imitation_experiments.json": "python -m mmlearn.apps.imitation_experiments --experiments "
                                  "swap,u_obstacle --seeds 4 --seed 1 --jobs 1 "
                                  "--results docs/results/imitation_experiments.jsonl "
                                  "--out-dir build/imitation --json",
    # about an hour on two cores
    "teaching.json": "python -m mmlearn.apps.imitation_experiments --experiments teaching --seeds 10 "
                     "--seed 100 --jobs 1 --results docs/results/teaching.jsonl "
                     "--out-dir build/teaching --json",
    "structure_prior.json": "python benchmarks/bench_structure_prior.py --seeds 11-20 --json",
    # the CPU time of every quick-tour command of the README (about 3 CPU minutes)
    "quick_tour.json": "python docs/make_tables.py --time-tour",
    # every program of examples/: its CPU time and what it printed (about 2 CPU minutes)
    "examples.json": "python docs/make_tables.py --time-examples",
    # every speed benchmark in its quick mode (detector, link selection, ...): the tables of
    # docs/performance.md between its speed-table markers (about 15 CPU minutes); the peers'
    # columns need MMLEARN_PEER_PYTHON set to the interpreter of an environment with
    # ripl-articulation (benchmarks/bench_peer_ripl.py), else they stay empty
    "speed.json": "python benchmarks/run_speed.py --json docs/results/speed.json",
}


def _tables_module(name: str):
    """docs/<name>.py (the engineering pages' blocks, or the design notes' measured lines,
    and their results files)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(name, DOCS / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod  # (the other docs/ modules import docs/tables_common.py by name)
    spec.loader.exec_module(mod)
    return mod


COMMON = _tables_module("tables_common")
_fmt, _table, _missing = COMMON.fmt, COMMON.table, COMMON.missing
ENGINEERING = _tables_module("tables_engineering")
NOTES = _tables_module("tables_notes")
COMMANDS.update(ENGINEERING.COMMANDS)
COMMANDS.update(NOTES.COMMANDS)

#: the results files whose figures change with the door-radius, user-model, detector,
#: mechanism-dynamics and teaching work: re-run them after such changes
#: (``--run --only <stem>,...``)
VOLATILE = ("operate", "operate_trials", "user_models", "mechanism_damping",
            "mechanism_damping_950", "mechanism_damping_980", "mechanism_damping_1010",
            "mechanism_faults", "door_damping_sources", "fronts",
            "perception_distance", "teaching", "imitate", "quick_tour", "speed")
VOLATILE += ENGINEERING.VOLATILE + NOTES.VOLATILE


def _load(name: str):
    path = RESULTS / name
    if not path.is_file():
        return None
    return json.loads(path.read_text())


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
            + "\n\n" + _teaching_per_seed() + "\n\n" + _source("teaching.json"))


def _teaching_runs(name: str = "teaching.jsonl") -> list[dict]:
    """The records of a sweep's JSON Lines file that finished without an error, each with its
    ``fn`` (``imitation.teach@...`` / ``imitation.reproduce@...``), ``params`` and ``seed``."""
    return [dict(r["record"], fn=r["spec"]["fn"], params=r["spec"]["params"],
                 seed=r["spec"]["seed"])
            for r in ENGINEERING.sweep_lines(RESULTS / name)
            if r.get("error") is None and r.get("record")]


def teaching_per_seed(runs: list[dict]) -> dict:
    """Per seed: the fewest demonstrations (1-4) from which batch learning (the thesis'
    learner) succeeded, None when none did, and the demonstrations interactive teaching used
    (None when it did not end with a success); and the comparison over the seeds."""
    batch, inter = {}, {}
    for r in runs:
        if r["fn"].startswith("imitation.teach"):
            inter[r["seed"]] = r.get("demos_used") if r.get("success") else None
        elif not r["params"].get("isotropic_prior") and r.get("success"):
            n = r["params"].get("demos")
            if n is not None and 1 <= n <= 4:
                batch[r["seed"]] = min(n, batch.get(r["seed"], n))
    seeds = sorted(inter)
    fewest = {s: batch.get(s) for s in seeds}
    with_batch = [s for s in seeds if fewest[s] is not None]
    return {"seeds": seeds, "interactive": inter, "batch_fewest": fewest,
            "no_more": sum(inter[s] is not None and inter[s] <= fewest[s] for s in with_batch),
            "batch_never": [s for s in seeds if fewest[s] is None],
            "mean_batch_fewest": (sum(fewest[s] for s in with_batch) / len(with_batch)
                                  if with_batch else None),
            "mean_interactive": (sum(inter[s] for s in with_batch if inter[s] is not None) /
                                 max(1, sum(inter[s] is not None for s in with_batch)))}


def _teaching_per_seed() -> str:
    c = teaching_per_seed(_teaching_runs())
    if not c["seeds"]:
        return "(no interactive runs in `docs/results/teaching.jsonl`)"
    rows = [[s, "-" if c["interactive"][s] is None else c["interactive"][s],
             "never (1-4)" if c["batch_fewest"][s] is None else c["batch_fewest"][s]]
            for s in c["seeds"]]
    n = len(c["seeds"])
    never = (f"; batch learning never succeeded with 1-4 demonstrations on seed(s) "
             f"{', '.join(map(str, c['batch_never']))} (left out of the means and counted as "
             "not compared)" if c["batch_never"] else "")
    return ("**Per seed: interactive teaching against batch's fewest successful "
            "demonstrations** (batch: the thesis' learner with 1, 2, 3, 4 demonstrations)\n\n"
            + _table(["seed", "interactive: demonstrations used", "batch: fewest that succeed"],
                     rows)
            + f"\n\nInteractive teaching used no more demonstrations than batch's fewest "
              f"successful in {c['no_more']}/{n} seeds; mean of batch's fewest "
              f"{_fmt(c['mean_batch_fewest'], 1)} against interactive's "
              f"{_fmt(c['mean_interactive'], 1)}{never}.")


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


# ----------------------------------------------------------------- the larger runs, headlines

def _wrap(text: str) -> str:
    """A paragraph broken into lines of at most 100 characters (README lines stay short)."""
    import textwrap

    return textwrap.fill(text, 100, break_long_words=False, break_on_hyphens=False)


def _cmd(name: str) -> str:
    return f"`{COMMANDS[name]}`"


def _real_tracks(d) -> tuple[int, int]:
    """(right, total) over the recorded real tracks of a fit_articulation file (the synthetic
    cosine tracks left out)."""
    real = [t for t in d["tracks"] if "cosine" not in Path(t["path"]).name]
    return sum(t["selected"] == _expected_kind(t["path"]) for t in real), len(real)


def _operate_stats(d) -> dict:
    """Opened, trials and the doors' mean radius error of an operate_trials file."""
    per = d.get("per_object", {})
    err = [(o["mean_radius_error_m"], o["radius_runs"]) for o in per.values()
           if o.get("mean_radius_error_m") is not None and o.get("radius_runs")]
    n = sum(k for _, k in err)
    return {"opened": d.get("successes"), "total": d.get("total"),
            "right_kind": d.get("right_kind"),
            "radius_error_m": sum(e * k for e, k in err) / n if n else None}


def _swap_row(d):
    for r in d.get("conditions", []):
        if r["condition"] == "pick_place 4 demos, swapped tables":
            return r
    return None


def _lasa_gain(d) -> float | None:
    """How far the method's mean rmse is below the baseline's, %."""
    b = d.get("baseline", {}).get("mean_rmse_mm")
    m = d.get("mean_rmse_mm")
    return None if not b or m is None else 100.0 * (1.0 - m / b)


def _seven_dof(d):
    return d["sets"][0] if d and d.get("sets") else None


def _eligible_at(d, obj="drawer"):
    """The distance experiment's row of ``obj`` (the first distance run)."""
    for key in ("distance", "rows", "table"):
        rows = d.get(key)
        if isinstance(rows, dict):
            rows = rows.get(obj, rows.get("rows"))
        if isinstance(rows, list):
            for r in rows:
                if r.get("object", obj) == obj:
                    return r
    return None


def _container_rate(d):
    for key in ("container_rate", "rate_container"):
        if d.get(key) is not None:
            return d[key]
    return (d.get("rates") or {}).get("container")


def _objects_rate(d):
    if d.get("recognition_rate") is not None:
        return d["recognition_rate"]
    r = (d.get("rates") or {}).get("all")
    if isinstance(r, dict):
        return r.get("rate", r.get("mean"))
    return r if r is not None else d.get("recognition_rate")


def articulation_larger() -> str:
    out = []
    d = _load("operate_trials.json")
    if d:
        st = _operate_stats(d)
        rows = []
        for obj, o in d.get("per_object", {}).items():
            unit = o.get("unit", "")
            rows.append([obj, f"{o['successes']}/{o['trials']}", f"{o['right_kind']}/{o['trials']}",
                         _fmt(o.get("mean_opened"), 1 if unit == "deg" else 3, f" {unit}"),
                         _fmt(o.get("mean_radius_error_m"), 3, " m"),
                         _fmt(o.get("mean_axis_error_deg"), 1, " deg")])
        out.append("**The operating experiment of Sec. 4.4.2**: five objects x "
                   f"{max(o['trials'] for o in d['per_object'].values())} trials, drifting base "
                   f"localisation (x{d.get('base_noise')}), sigma_pos {d.get('sigma_pos')} m "
                   f"(thesis: 37 of 40 opened; door radii within 0.02 m)\n\n" +
                   _table(["object", "opened", "right kind", "opening (mean)", "radius error (mean)",
                           "axis error (mean)"], rows) +
                   f"\n\nOpened {st['opened']}/{st['total']}; doors' mean radius error "
                   f"{_fmt(st['radius_error_m'], 3, ' m')}. Made by {_cmd('operate_trials.json')}.")
    else:
        out.append(_missing("operate_trials.json"))
    fits = [(s, _load(f"fit_articulation_sigma{s}.json")) for s in ("001", "002", "005")]
    if all(f for _, f in fits):
        right = ", ".join(f"{a}/{n} at {int(s) / 100:g} m" for s, f in fits
                          for a, n in [_real_tracks(f)])
        out.append(f"Model selection on the five recorded real tracks: right kind {right} "
                   "(thesis: right on every real track); made by `fit_articulation` as in the "
                   "table above, and at 0.05 m by " + _cmd("fit_articulation_sigma005.json") + ".")
    return "\n\n".join(out)


def body_schema_larger() -> str:
    s = _seven_dof(_load("body_schema_7dof.json"))
    if not s:
        return _missing("body_schema_7dof.json")
    conv = ", ".join("-" if c is None else str(c) for c in s["converged_at"])
    return ("**7-DOF arm, x4 occluded, 50 samples** (Sec. 3.4, Fig. 3.10; thesis: the structure "
            f"right after about 10 samples): at marker noise {s['sigma']:g} m the structure was "
            f"right within 12 samples in {s['within_12']} of {s['runs']} runs (seeds "
            f"{s['label']}; right from sample {conv}); prediction error "
            f"{_fmt(s['mean_pred_error_m'], 4, ' m')} against an observation noise of "
            f"{_fmt(s['mean_obs_noise_m'], 4, ' m')}. Made by {_cmd('body_schema_7dof.json')}.")


def perception_larger() -> str:
    d = _load("perception_distance.json")
    r = _eligible_at(d) if d else None
    if not r:
        return _missing("perception_distance.json")
    return ("**The distance experiment at 2.2 m** (Sec. 5.2, Fig. 5.8; thesis: > 0.75 up to "
            f"2.2 m, position error < 0.015 m): the drawer found in "
            f"{_fmt(r.get('detection_rate_eligible'), 2)} of the frames where it is wholly in view "
            f"({_fmt(r.get('detection_rate'), 2)} of all frames), position error "
            f"{_fmt(r.get('pos_error_m'), 4, ' m')}. Made by {_cmd('perception_distance.json')}.")


def tactile_larger() -> str:
    out = []
    d = _load("tactile_state_sim.json")
    if d:
        out.append("**Simulated grasps, containers x states at 20 N** (Sec. 7.2; thesis: "
                   f"container 0.939): container recognised {_fmt(_container_rate(d), 3)}, "
                   f"class and state together {_fmt(d.get('combined_rate'), 3)} "
                   f"({d.get('n_grasps')} grasps, 10-fold CV). "
                   f"Made by {_cmd('tactile_state_sim.json')}.")
    else:
        out.append(_missing("tactile_state_sim.json"))
    d = _load("tactile_recognition.json")
    if d:
        per = sorted((d.get("grasps_per_class") or {"-": None}).values(), key=str)[0]
        out.append(f"**Objects by touch, {len(d.get('classes', []))} classes** (ch. 6; thesis "
                   f"84.6 % with 40 grasps per class): recognised "
                   f"{_fmt(100 * _objects_rate(d), 1, ' %')} with {per} grasps per class "
                   f"({d.get('n_grasps')} grasps, 2-fold CV). "
                   f"Made by {_cmd('tactile_recognition.json')}.")
    else:
        out.append(_missing("tactile_recognition.json"))
    return "\n\n".join(out)


def imitation_larger() -> str:
    out = []
    d = _load("imitation_experiments.json")
    if d:
        rows = [[r["condition"], f"{r['successes']}/{r['trials']}",
                 _fmt(r.get("median_place_error_m"), 3, " m")] for r in d["conditions"]]
        out.append("**Reproduction in changed scenes** (Sec. 8.4; thesis: pick-and-place "
                   "succeeds with swapped tables; the U obstacle needs the global plan)\n\n" +
                   _table(["condition", "success", "median place error"], rows) +
                   f"\n\nMade by {_cmd('imitation_experiments.json')}.")
    else:
        out.append(_missing("imitation_experiments.json"))
    d = _load("lasa_held_back.json")
    if d:
        out.append(f"**LASA, the {d.get('n_shapes')} held-back shapes**: mean rmse "
                   f"{_fmt(d.get('mean_rmse_mm'), 3, ' mm')} against the baseline's "
                   f"{_fmt(d.get('baseline', {}).get('mean_rmse_mm'), 3, ' mm')} "
                   f"({_fmt(_lasa_gain(d), 1, ' %')} below). Made by {_cmd('lasa_held_back.json')}.")
    else:
        out.append(_missing("lasa_held_back.json"))
    return "\n\n".join(out)


LARGER = {"articulation": articulation_larger, "body_schema": body_schema_larger,
          "perception": perception_larger, "tactile": tactile_larger,
          "imitation": imitation_larger}


def _or(value, name: str, text) -> str:
    return text(value) if value is not None else f"(run `--only {Path(name).stem}`)"


def headlines() -> dict[str, str]:
    """Capability -> its headline result against the thesis (thesis value in brackets)."""
    h = {}
    fits = [_load(f"fit_articulation_sigma{s}.json") for s in ("001", "002", "005")]
    if all(fits):
        counts = [_real_tracks(f) for f in fits]
        h["articulation"] = ("right kind on " + ", ".join(f"{a}/{n}" for a, n in counts) +
                             " real tracks at sigma 0.01, 0.02, 0.05 m (all)")
    op = _load("operate_trials.json")
    if op:
        st = _operate_stats(op)
        h["operating"] = (f"{st['opened']}/{st['total']} opened with base noise (37/40); door "
                          f"radius error {_fmt(st['radius_error_m'], 3, ' m')} (< 0.02 m)")
    s = _seven_dof(_load("body_schema_7dof.json"))
    if s:
        h["body_schema"] = (f"7-DOF structure within 12 samples in {s['within_12']}/{s['runs']} "
                            "runs (about 10 samples)")
    d = _load("perception_distance.json")
    r = _eligible_at(d) if d else None
    if r:
        h["perception"] = (f"drawer found in {_fmt(r.get('detection_rate_eligible'), 2)} of its "
                           "frames at 2.2 m (> 0.75)")
    a, b = _load("tactile_state_sim.json"), _load("tactile_recognition.json")
    parts = ([f"container recognised {_fmt(_container_rate(a), 3)} (0.939)"] if a else []) + \
        ([f"objects {_fmt(100 * _objects_rate(b), 1, ' %')} (84.6 %)"] if b else [])
    if parts:
        h["tactile"] = ", ".join(parts)
    a, b = _load("imitation_experiments.json"), _load("lasa_held_back.json")
    r = _swap_row(a) if a else None
    if r and b:
        h["imitation"] = (f"pick-and-place with swapped tables {r['successes']}/{r['trials']} "
                          f"(succeeds); LASA {_fmt(_lasa_gain(b), 1, ' %')} below a baseline")
    return h


#: capability table: (key, capability, thesis chapter, docs page, results files)
CAPABILITIES = [
    ("articulation", "Articulated objects: rigid / prismatic / revolute / GP links, MLESAC, BIC, "
                     "trees, priors", "ch. 4.1-4.2", "articulation",
     "fit_articulation_sigma005"),
    ("operating", "Operating doors and drawers: hook, EPC along the learned model, drifting "
                  "base localisation", "ch. 4.3-4.4", "articulation", "operate_trials"),
    ("body_schema", "Body schema: local GP models, structure search, prediction, control, "
                    "adaptation to failures", "ch. 3", "body_schema", "body_schema_7dof"),
    ("perception", "Cabinet fronts in depth images: planes, rectangles, tracking, "
                   "articulation", "ch. 5", "perception", "perception_distance"),
    ("tactile", "Tactile recognition and state: tactile images, bag of features, grasp "
                "dynamics, liquid", "ch. 6-7", "tactile", "tactile_state_sim,tactile_recognition"),
    ("imitation", "Imitation learning: a DBN of constraints, incremental and global "
                  "reproduction", "ch. 8", "imitation", "imitation_experiments,lasa_held_back"),
]


def capability_table() -> str:
    h = headlines()
    rows = []
    for key, what, chapter, page, files in CAPABILITIES:
        cell = h.get(key) or f"(run `python docs/make_tables.py --run --only {files}`)"
        rows.append([what, chapter, cell, f"[{page.replace('_', ' ')}](docs/{page}.md)"])
    return (_table(["capability", "thesis", "headline result (thesis)", "docs"], rows) +
            "\n\n" + _wrap("Each result comes from a results file under `docs/results/`; the capability's "
            "page names the command and the size of its run (most are smaller than the thesis' "
            "experiments, to fit minutes of CPU)."))


def _beyond_results() -> dict[str, str]:
    r = {}
    d = _load("user_models.json")
    if d:
        st = _operate_stats(d)
        r["user_models"] = f"a wall cabinet's door (SDFormat) opened {st['opened']}/{st['total']}"
    sets = [x for x in (_load("user_models_seed10.json"), _load("user_models_seed20.json")) if x]
    ms = [m for x in sets for m in x["models"] if "error" not in m]
    if ms:
        r["user_models"] = (f"four test models, SDFormat and URDF, opened "
                            f"{sum(m['successes'] for m in ms)}/{sum(m['trials'] for m in ms)}")
    figs = [(x or {}).get("summary", x or {}) for x in map(_load, _MECH_DAMPING)]
    if all(f.get("damping_drawer") and f.get("damping_left_door") for f in figs):
        def _total(key):
            return (f"{sum(f[key]['within_25pct'] for f in figs)}/"
                    f"{sum(f[key]['trials'] for f in figs)}")
        r["mechanism_dynamics"] = (f"damping within 25 %: drawers {_total('damping_drawer')}, "
                                   f"doors {_total('damping_left_door')}")
        src = (_load("door_damping_sources.json") or {}).get("summary", {})
        lt, hv = src.get("robot_light"), src.get("robot_heavier")
        if lt and hv:  # the doors of the source-by-source benchmark, as the robot learns them
            r["mechanism_dynamics"] += (
                f" and {hv['within_25pct'] + lt['within_25pct']}/"
                f"{hv['doors'] + lt['doors']} more (lightest {lt['within_25pct']}/{lt['doors']})")
    d = _load("teaching.json")
    if d:
        by = {c["condition"]: c for c in d["conditions"]}
        i = by.get("pick_place interactive, swapped tables")
        b = by.get("pick_place 2 demos, swapped tables")
        if i and b:
            c = teaching_per_seed(_teaching_runs())
            r["teaching"] = (f"swapped tables {i['successes']}/{i['trials']} with "
                             f"{i['mean_demos']:.1f} demonstrations (batch of 2: "
                             f"{b['successes']}/{b['trials']})")
            if c["seeds"] and c["mean_batch_fewest"] is not None:
                r["teaching"] += (f"; <= batch's fewest on {c['no_more']}/"
                                  f"{len(c['seeds'])} seeds")
    d = _load("structure_prior.json")
    if d:
        n = len(d["seeds"]) * len(d["rows"])
        r["structure_prior"] = (f"right structure {sum(x['right_with_prior'] for x in d['rows'])}/{n}"
                                f" (BIC alone {sum(x['right_bic_alone'] for x in d['rows'])}/{n})")
    return r


BEYOND = [
    ("user_models", "open your own SDFormat / URDF furniture",
     "python -m mmlearn.apps.open_cabinet --model FILE --joint NAME", "user_models"),
    ("mechanism_dynamics", "dynamics learned while opening; jams, latches",
     "python -m mmlearn.apps.open_cabinet --object drawer --damping 20 --save-model d.sdf",
     "mechanism_damping"),
    ("teaching", "interactive teaching, asking where unsure",
     "python -m mmlearn.apps.imitate --task pick_place --interactive --swap-tables", "teaching"),
    ("structure_prior", "structure that knows furniture",
     "python -m mmlearn.apps.fit_structure apps/examples/two_drawers_pulled_together.csv "
     "--furniture-prior", "structure_prior"),
]


def beyond_table() -> str:
    res = _beyond_results()
    rows = []
    for key, what, cmd, name in BEYOND:
        rows.append([f"[{what}](docs/{key}.md)", res.get(key) or f"(run `--only {name}`)",
                     f"`{cmd}`"])
    return _table(["feature (docs)", "measured", "command"], rows)


#: the README's quick tour: (capability, command, what you see); ``{out}`` is where the
#: command's file goes (the file name itself in the README)
TOUR = [
    ("operate a door", "python -m mmlearn.apps.open_cabinet --object left_door --seed 1 --html-out {out}door.html",
     "`door.html`: the robot hooks and opens the door; learned axis, circle and range drawn in"),
    ("operate a drawer", "python -m mmlearn.apps.open_cabinet --object drawer --seed 1 --html-out {out}drawer.html",
     "`drawer.html`: the drawer pulled open along the learned prismatic axis"),
    ("structure of a cabinet", "python -m mmlearn.apps.fit_structure apps/examples/two_drawer_cabinet.csv",
     "the kinematic tree of a two-drawer cabinet and its degrees of freedom, printed"),
    ("body schema", "python -m mmlearn.apps.learn_body_schema --arm 2dof --seed 1 --html-out {out}body_schema.html",
     "an arm babbles, learns its kinematic structure from markers, then reaches targets with it"),
    ("cabinet fronts in depth", "python -m mmlearn.apps.track_fronts --object drawer --seed 1 --html-out {out}fronts.html",
     "a drawer detected as a rectangle in noisy depth images while it opens; its learned model"),
    ("tactile state", "python -m mmlearn.apps.tactile_state --f-target 20 --trials 2 --containers odwalla "
                      "--seed 1 --plot {out}tactile.png",
     "grasps of a bottle, empty or full, and the classifier's rates; `tactile.png` the grasp profiles"),
    ("imitation", "python -m mmlearn.apps.imitate --task pick_place --seed 1 --html-out {out}imitation.html",
     "a teacher demonstrates pick-and-place four times; the arm reproduces it from the learned DBN"),
    ("handwriting", "python -m mmlearn.apps.imitate_lasa --shapes Sshape --plot {out}lasa.png",
     "LASA human handwriting demonstrations and their reproductions, scored against a baseline"),
]


def time_tour() -> dict:
    """Run every quick-tour command (outputs into a temporary folder); the CPU time (user +
    sys of the process and its children) and wall time of each, s."""
    import resource
    import tempfile
    import time

    out = []
    with tempfile.TemporaryDirectory(prefix="mmlearn_tour_") as tmp:
        for what, cmd, _ in TOUR:
            argv = [sys.executable] + cmd.format(out=tmp + os.sep).split()[1:]
            t0 = time.perf_counter()
            p = subprocess.Popen(argv, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                 text=True, env=dict(os.environ, OPENBLAS_NUM_THREADS="1"))
            _, err = p.communicate()
            wall = time.perf_counter() - t0
            ru = resource.getrusage(resource.RUSAGE_CHILDREN)  # cumulative: take differences
            out.append({"capability": what, "command": cmd.format(out=""), "exit": p.returncode,
                        "cpu_total_s": ru.ru_utime + ru.ru_stime, "wall_s": round(wall, 1),
                        "stderr_tail": err.strip().splitlines()[-1:] if p.returncode else []})
    prev = 0.0
    for r in out:
        r["cpu_s"] = round(r.pop("cpu_total_s") - prev, 1)
        prev += r["cpu_s"]
    return {"commands": out, "load_1min": round(os.getloadavg()[0], 1)}


def tour_table() -> str:
    d = _load("quick_tour.json")
    cpu = {r["command"]: r for r in (d or {}).get("commands", [])}
    rows = []
    for what, cmd, see in TOUR:
        r = cpu.get(cmd.format(out=""))
        t = "-" if r is None else f"{r['cpu_s']:.0f} s" + ("" if r["exit"] in (0, 1) else " (failed)")
        rows.append([what, f"`{cmd.format(out='')}`", see, t])
    if d:
        note = (f"CPU time: user + sys of the whole run, Drake's start-up included (`python "
                f"docs/make_tables.py --run --only quick_tour`; the 1-minute load average was "
                f"{d.get('load_1min')} at the end). On a shared machine the wall-clock time is "
                "several times longer.")
    else:
        note = ("CPU time: not measured in this checkout (`python docs/make_tables.py --run "
                "--only quick_tour` measures it).")
    return _table(["capability", "command", "what you see", "CPU time"], rows) + "\n\n" + \
        _wrap(note)


#: the programs of examples/: (file, capability, what it uses, the start of its result line)
EXAMPLES = [
    ("fit_link_model.py", "articulation (ch. 4)", "`select_link_model`, `ObservationModel`",
     "selected"),
    ("door_markers.py", "articulation (ch. 4)", "`MarkerSensor`, `ArticulationEstimator`",
     "door:"),
    ("detect_fronts.py", "perception (ch. 5)", "`AddDepthCamera`, `FrontDetector`", "front at"),
    ("tactile_grasp.py", "tactile (ch. 6-7)", "`MakeTactileGraspDiagram`, `TactileSensor`",
     "pad forces"),
    ("imitate_reach.py", "imitation (ch. 8)", "`record_demonstrations`, `learn_task`, "
     "`MakeImitationDiagram` (`DbnReproducer`)", "hand"),
]


def _run_timed(argv: list[str]) -> dict:
    """Run ``argv`` from the repository root; its CPU time (user + sys, s), wall time, exit
    status and standard output."""
    import resource
    import time

    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    p = subprocess.run(argv, cwd=ROOT, capture_output=True, text=True,
                       env=dict(os.environ, OPENBLAS_NUM_THREADS="1"))
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return {"exit": p.returncode, "cpu_s": round(cpu, 1), "wall_s": round(wall, 1),
            "stdout": p.stdout, "stderr_tail": p.stderr.strip().splitlines()[-1:]}


def time_examples() -> dict:
    """Run every program of examples/; CPU time and output of each."""
    out = []
    for name, *_ in EXAMPLES:
        r = _run_timed([sys.executable, f"examples/{name}"])
        out.append(dict(r, example=name))
    return {"examples": out, "load_1min": round(os.getloadavg()[0], 1)}


def examples_table() -> str:
    d = _load("examples.json")
    by = {r["example"]: r for r in (d or {}).get("examples", [])}
    rows = []
    for name, cap, uses, prefix in EXAMPLES:
        r = by.get(name)
        if r is None:
            rows.append([f"`examples/{name}`", cap, uses, "-", "-"])
            continue
        lines = [ln.strip() for ln in r["stdout"].splitlines() if ln.strip().startswith(prefix)]
        said = "; ".join(f"`{ln}`" for ln in lines[:2]) or f"(exit {r['exit']})"
        rows.append([f"`examples/{name}`", cap, uses, f"{r['cpu_s']:.0f} s", said])
    note = "" if d else (" (no `docs/results/examples.json` yet: `python docs/make_tables.py "
                         "--run --only examples`)")
    return (_table(["example", "capability", "what it uses", "CPU time", "what it printed"],
                   rows) + "\n\n" +
            _wrap("CPU time: user + sys of `python examples/<name>.py`, most of it importing "
                  "Drake and building the diagram; made by `python docs/make_tables.py --run "
                  f"--only examples`{note}."))


# ------------------------------------------------- docs/mechanism_dynamics.md's generated blocks
_MECH_KINDS = (("left_door", "door", "N m s/rad", "deg", 5.0),
               ("drawer", "drawer", "N s/m", "m", 0.03))


def _mech_rows(d, group: str, kind: str) -> list[dict]:
    return [r for r in (d or {}).get("rows", []) if r["group"] == group and r["kind"] == kind]


def _mech_damping_figures(d) -> dict:
    """kind -> (within 25 %, trials, mean and max relative error) of the damping rows."""
    out = {}
    for kind, *_ in _MECH_KINDS:
        errs = [r["learned"]["damping"] / r["value"] - 1 for r in _mech_rows(d, "damping", kind)
                if r["learned"]["damping"] is not None]
        n = len(_mech_rows(d, "damping", kind))
        if n:
            out[kind] = (sum(abs(e) <= 0.25 for e in errs), n,
                         max(map(abs, errs), default=None),
                         sum(map(abs, errs)) / len(errs) if errs else None)
    return out


_NUMBERS = {2: "two", 3: "three", 4: "four"}

#: the damping sweeps: one results file per set of seeds
_MECH_DAMPING = ("mechanism_damping.json", "mechanism_damping_950.json",
                 "mechanism_damping_980.json", "mechanism_damping_1010.json")


def _mech_damping_table(file: str) -> str:
    """One damping sweep's rows and figures (``file``: its results file)."""
    d = _load(file)
    if not d:
        return _missing(file)
    rows = []
    for kind, name, unit, _, _ in _MECH_KINDS:
        for r in _mech_rows(d, "damping", kind):
            b, sd = r["learned"]["damping"], r["learned"]["damping_std"]
            rows.append([name, r["seed"], f"{r['value']:g} {unit}",
                         "-" if b is None else f"{b:.3g} +- {sd:.2g}",
                         "-" if b is None else f"{100 * (b / r['value'] - 1):+.0f} %",
                         f"{r['true']['friction']:.2f}", r["outcome"]])
    fig = _mech_damping_figures(d)
    said = "; ".join(f"{name}s {fig[k][0]}/{fig[k][1]} within 25 % (mean error "
                     f"{100 * fig[k][3]:.0f} %, max {100 * fig[k][2]:.0f} %)"
                     for k, name, *_ in _MECH_KINDS if k in fig and fig[k][2] is not None)
    return (f"**Damping, seeds {d['seed']}-{d['seed'] + 4}** (`docs/results/{file}`; one "
            "trial per value, each value on its own door or drawer; `friction` is the "
            "mechanism's drawn Coulomb friction, N m or N)\n\n" +
            _table(["mechanism", "seed", "true damping", "learned", "error", "friction",
                    "outcome"], rows) + "\n\n" + _wrap(said + "."))


def mechanism_examples() -> str:
    """docs/mechanism_dynamics.md's single trials: a drawer with a spring (its learned
    dynamics against the true ones) and a latched drawer (drawer_spring.json,
    drawer_locked.json)."""
    out = []
    d = _load("drawer_spring.json")
    if d:
        dyn = d.get("dynamics") or {}
        true, units = dyn.get("true", {}), dyn.get("units", {})
        rows = [[k, f"{_fmt(dyn.get(k))} +- {_fmt(dyn.get(k + '_std'), 2)}",
                 _fmt(true.get(k, 0.0)), units.get(k, "")]
                for k in ("damping", "friction", "stiffness") if dyn.get(k) is not None]
        out.append(f"**One drawer with a spring** (`{COMMANDS['drawer_spring.json']}`; "
                   f"outcome: {d.get('outcome', '-')})\n\n"
                   + _table(["", "learned", "true", "unit"], rows))
    else:
        out.append(_missing("drawer_spring.json"))
    d = _load("drawer_locked.json")
    if d:
        force = d.get("peak_force_N")
        out.append(f"**A latched drawer** (`{COMMANDS['drawer_locked.json']}`): outcome "
                   f"`{d.get('outcome', '-')}`, the robot stopped pulling at a held wrist force "
                   f"of {_fmt(force, 2, ' N')}.")
    else:
        out.append(_missing("drawer_locked.json"))
    return "\n\n".join(out)


def door_torque() -> str:
    """The torque on one door followed through a trial, fitted with the dynamics regression
    from each source (door_torque_map.json, door_torque_exact.json)."""
    cols = [("contact", "contact torques"), ("generalized_contact_force", "generalised force"),
            ("wrist_true_geometry", "wrist force, true lever and rate"),
            ("wrist_true_q_local_rate", "wrist force, rates from local fits"),
            ("pipeline", "the robot's estimate"), ("learned_radius_m", "learned radius (m)"),
            ("true_radius_m", "true radius (m)"),
            ("pipeline_over_radius_factor", "estimate / (learned radius / true radius)^2")]
    rows = []
    for name, label in (("door_torque_map.json", "base localisation as in the trials"),
                        ("door_torque_exact.json", "exact base pose")):
        d = _load(name)
        if not d:
            return _missing(name)
        for r in d["results"]:
            rows.append([label, r["seed"], _fmt(d["damping"])]
                        + [_fmt(r.get(k)) for k, _ in cols]
                        + [", ".join(r.get("bodies_touching_door", []))])
    return ("Damping fitted from each source, N m s/rad (the hook tracked in the map frame)\n\n"
            + _table(["run", "seed", "true"] + [lbl for _, lbl in cols] + ["bodies on the door"],
                     rows)
            + "\n\nMade by `" + COMMANDS["door_torque_map.json"] + "` and `"
            + COMMANDS["door_torque_exact.json"] + "`.")


def mechanism_measured() -> str:
    """docs/mechanism_dynamics.md's measured figures: the damping sweeps
    (mechanism_damping*.json) and the jams, latches and sticky mechanisms
    (mechanism_faults.json), one row per trial."""
    parts = [_mech_damping_table(name) for name in _MECH_DAMPING]
    f = _load("mechanism_faults.json")
    if f:
        s = f["summary"]
        for kind, name, _, punit, tol in _MECH_KINDS:
            rs = _mech_rows(f, "jam", kind)
            if not rs:
                continue
            rows = [[f"{r['value']:g} {punit}", r["seed"], r["outcome"],
                     _fmt(r["jammed_at"], 1 if punit == "deg" else 3),
                     "-" if r["jammed_at"] is None else
                     _fmt(abs(r["jammed_at"] - r["value"]), 1 if punit == "deg" else 3),
                     _fmt(r["peak_force_N"], 1), _fmt(r["block_force_N"], 1)] for r in rs]
            j = s[f"jam_{kind}"]
            err = "-" if j["max_position_error"] is None else \
                f"{j['mean_position_error']:.{1 if punit == 'deg' else 3}f} / " \
                f"{j['max_position_error']:.{1 if punit == 'deg' else 3}f} {punit}"
            parts.append(
                f"**Jammed {name}s** (`jammed_at` and its error in {punit}; `peak`: the largest "
                "wrist force held for 0.1 s over the trial, `block`: the same from where the "
                "block began, N)\n\n" +
                _table(["jam at", "seed", "outcome", "jammed_at", "error", "peak", "block"],
                       rows) + "\n\n" +
                _wrap(f"{j['recognised']}/{j['trials']} recognised, {j['within_tolerance']}/"
                      f"{j['trials']} within {tol:g} {punit} (mean / max error {err}), the "
                      f"held force at most {_fmt(j['max_peak_force_N'], 1)} N (the controller's "
                      f"limit is 35 N); the impact spike of a moving handle hitting the stop "
                      f"reached {_fmt(j['max_impact_force_N'], 0)} N for a few ms."))
        rows = []
        for kind, name, unit, *_ in _MECH_KINDS:
            lk, st = s.get(f"locked_{kind}"), s.get(f"sticky_{kind}")
            if lk and lk["trials"]:
                rows.append([f"latched {name}", f"{lk['recognised']}/{lk['trials']} called "
                             "locked", ", ".join(lk["outcomes"]),
                             f"{_fmt(lk['max_peak_force_N'], 1)} N", "-"])
            srs = _mech_rows(f, "sticky", kind)
            if st and st["trials"] and srs:
                bs = [r["learned"]["damping"] for r in srs if r["learned"]["damping"] is not None]
                drawn = [r["true"]["damping"] for r in srs]
                rng = f"{min(bs):.3g}-{max(bs):.3g} (drawn {min(drawn):.2g}-{max(drawn):.2g}) " \
                      f"{unit}" if bs else "-"
                rows.append([f"sticky {name} ({srs[0]['value']:g} {unit.split()[0]}"
                             f"{' m' if kind == 'left_door' else ''} of friction)",
                             f"{st['opened']}/{st['trials']} opened, {st['called_blocked']} "
                             "called blocked", ", ".join(st["outcomes"]),
                             f"{_fmt(max(r['peak_force_N'] for r in srs), 1)} N", rng])
        if rows:
            parts.append("**Latched and sticky mechanisms** (`peak`: the largest wrist force "
                         "held for 0.1 s; a sticky drawer's peak is its end stop)\n\n" +
                         _table(["mechanism", "result", "outcomes", "peak", "learned damping"],
                                rows))
    else:
        parts.append(_missing("mechanism_faults.json"))
    return "\n\n".join(parts + [_source(*_MECH_DAMPING, "mechanism_faults.json")])


def mechanism_status() -> str:
    """docs/mechanism_dynamics.md's table of the targets against the results files."""
    f = _load("mechanism_faults.json")
    sets = [(_load(n), n) for n in _MECH_DAMPING]
    rows = []
    for kind, name, *_ in _MECH_KINDS:
        said, met = [], 0
        for d, file in sets:
            fig = _mech_damping_figures(d)
            if kind not in fig:
                said.append(_missing(file))
                continue
            ok, n, mx, mean = fig[kind]
            said.append(f"{ok}/{n} on seeds {d['seed']}-{d['seed'] + n - 1} (mean error "
                        f"{100 * mean:.0f} %, max {100 * mx:.0f} %)")
            met += n >= 5 and ok == n
        rows.append([f"{name} damping within 25 %, 5 values over 10x", "; ".join(said),
                     "met" if met == len(sets) else f"met on {met} of {len(sets)} seed sets"])
    s = (f or {}).get("summary", {})
    for g, what in (("jam", "jams recognised >= 9/10, `jammed_at` within 5 deg / 0.03 m, "
                           "force below 35 N"),
                    ("locked", "latches recognised >= 9/10, force below 35 N"),
                    ("sticky", "sticky free mechanisms opened >= 9/10, never called blocked")):
        said, met = [], bool(s)
        for kind, name, _, punit, tol in _MECH_KINDS:
            x = s.get(f"{g}_{kind}")
            if not x or not x["trials"]:
                met = False
                continue
            n = x["trials"]
            if g == "sticky":
                said.append(f"{name}s {x['opened']}/{n} opened, {x['called_blocked']} called "
                            "blocked")
                met &= x["opened"] >= 0.9 * n and x["called_blocked"] == 0
                continue
            within = f", {x['within_tolerance']}/{n} within {tol:g} {punit}" if g == "jam" else ""
            said.append(f"{name}s {x['recognised']}/{n}{within}, <= "
                        f"{_fmt(x['max_peak_force_N'], 1)} N")
            met &= (x["recognised"] >= 0.9 * n and x["below_limit"] == n
                    and (g != "jam" or x["within_tolerance"] >= 0.9 * n))
        rows.append([what, "; ".join(said) or _missing("mechanism_faults.json"),
                     "met" if met else "not met"])
    return _table(["target", "measured", "status"], rows)


#: generated blocks of README.md: name -> text
README_BLOCKS = {"tour": tour_table, "capabilities": capability_table, "beyond": beyond_table}
#: generated blocks of the docs pages: page -> {name -> text}
PAGE_BLOCKS = {"docs/examples.md": {"examples": examples_table},
               "docs/mechanism_dynamics.md": {"mechanism_measured": mechanism_measured,
                                              "mechanism_status": mechanism_status,
                                              "mechanism_examples": mechanism_examples,
                                              "door_torque": door_torque}}


PAGES = {"articulation": articulation, "body_schema": body_schema, "perception": perception,
         "tactile": tactile, "imitation": imitation, "teaching": teaching,
         "structure_prior": structure_prior}

#: the engineering pages' blocks and the capability pages' measured lines
#: (docs/tables_engineering.py), and the measured lines of the design notes and deviation
#: lists (docs/tables_notes.py)
for _page, _named in (*ENGINEERING.page_blocks(_load, lambda name: COMMANDS[name], _teaching_runs,
                                               lambda: RESULTS).items(),
                      *NOTES.page_blocks(_load, lambda name: COMMANDS[name]).items()):
    PAGE_BLOCKS.setdefault(_page, {}).update(_named)


def render() -> dict[str, str]:
    """Page name -> the generated markdown: the small runs' tables, then the larger runs."""
    head = "<!-- generated by docs/make_tables.py from docs/results/; do not edit -->\n\n"
    out = {}
    for page, fn in PAGES.items():
        text = fn()
        if page in LARGER:
            text += "\n\n**Larger runs**\n\n" + LARGER[page]()
        out[page] = head + text + "\n"
    return out


def _blocks(text: str) -> dict[str, tuple[int, int]]:
    """name -> (start, end) of the body of every generated block in ``text``."""
    import re

    out = {}
    for m in re.finditer(r"<!-- generated:(\w+) -->\n", text):
        end = text.find(f"<!-- /generated:{m.group(1)} -->", m.end())
        if end < 0:
            raise ValueError(f"<!-- generated:{m.group(1)} --> has no closing marker")
        out[m.group(1)] = (m.end(), end)
    return out


def render_blocks(text: str, blocks: dict, where: str = "README.md") -> str:
    """``text`` with every generated block rewritten by ``blocks`` (name -> function)."""
    spans = _blocks(text)
    unknown = sorted(set(spans) - set(blocks))
    if unknown:
        raise ValueError(f"{where}: unknown generated block(s) {', '.join(unknown)}")
    for name in sorted(spans, key=lambda n: -spans[n][0]):  # from the end: offsets stay valid
        a, b = spans[name]
        text = text[:a] + blocks[name]() + "\n" + text[b:]
    return text


def render_readme(text: str) -> str:
    """``text`` (README.md) with every generated block rewritten from the results files."""
    return render_blocks(text, README_BLOCKS)


def render_performance(text: str) -> str:
    """docs/performance.md's ``text`` with its speed tables rewritten from
    docs/results/speed.json (by benchmarks/make_performance_doc.py); unchanged without it."""
    import importlib.util

    doc = _load("speed.json")
    if doc is None:
        return text
    spec = importlib.util.spec_from_file_location(
        "make_performance_doc", ROOT / "benchmarks" / "make_performance_doc.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    head, rest = text.split(mod.START)
    _, tail = rest.split(mod.END)
    return f"{head}{mod.START}\n{mod.tables(doc)}\n{mod.END}{tail}"  # as that script writes it


def _atomic_write(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    tmp.replace(path)


def resolve(only: list[str]) -> list[str]:
    """Results file names of ``--only`` (stems or file names); ValueError for unknown ones."""
    names = [n if n.endswith(".json") else n + ".json" for n in only]
    unknown = sorted(n for n in names if n not in COMMANDS)
    if unknown:
        raise ValueError(f"unknown results file(s) {', '.join(unknown)}; choose from "
                         f"{', '.join(Path(c).stem for c in COMMANDS)}")
    return names


def run_experiments(only=None) -> None:
    """Re-run every command of COMMANDS (or the results files named in ``only``) and write
    its JSON output to docs/results/ (a command that names its file after ``--json`` writes
    it itself)."""
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
    for name, cmd in COMMANDS.items():
        if only and name not in only:
            continue
        argv = [sys.executable] + cmd.split()[1:]
        if "--results" in argv:  # a fresh sweep: an old results file would only be resumed
            (ROOT / argv[argv.index("--results") + 1]).unlink(missing_ok=True)
        itself = "--json" in argv and argv.index("--json") + 1 < len(argv) and \
            argv[argv.index("--json") + 1].endswith(".json")
        print(f"+ {cmd}", flush=True)
        r = subprocess.run(argv, cwd=ROOT, env=env, capture_output=True, text=True)
        text = (ROOT / argv[argv.index("--json") + 1]).read_text() if itself and \
            (ROOT / argv[argv.index("--json") + 1]).is_file() else r.stdout
        try:
            json.loads(text)
        except json.JSONDecodeError:
            sys.exit(f"make_tables: {cmd!r} gave no JSON (exit {r.returncode}): "
                     f"{r.stderr.strip().splitlines()[-1:]} ")
        if not itself:
            _atomic_write(RESULTS / name, text)


def main(argv=None) -> int:
    stems = ", ".join(Path(c).stem for c in COMMANDS)
    ap = argparse.ArgumentParser(
        prog="python docs/make_tables.py", description=__doc__.split("\n\n")[0],
        epilog=f"Results files (--only names): {stems}. After changes to the door-radius "
               f"estimate, user models, the front detector, mechanism dynamics or interactive "
               f"teaching re-run: --run --only {','.join(VOLATILE)}. The speed figures of the "
               "performance pages come from benchmarks/run_speed.py and "
               "benchmarks/make_performance_doc.py.")
    ap.add_argument("--run", action="store_true", help="re-run the experiments first")
    ap.add_argument("--only", default="", metavar="NAMES",
                    help="with --run: only these results files (comma-separated stems, e.g. "
                         "operate_trials,fronts)")
    ap.add_argument("--check", action="store_true",
                    help="only compare the committed tables and README blocks with the results "
                         "files; exit 1 if any differs")
    ap.add_argument("--time-tour", action="store_true",
                    help="run the README's quick-tour commands and print their CPU times as JSON")
    ap.add_argument("--time-examples", action="store_true",
                    help="run the programs of examples/ and print their CPU times and output "
                         "as JSON")
    ap.add_argument("--user-models", type=int, default=None, metavar="SEED",
                    help="open every test model of tests/data/user_models (SDFormat and URDF, "
                         "5 trials from SEED) and print the summary as JSON")
    args = ap.parse_args(argv)
    if args.user_models is not None:
        print(json.dumps(ENGINEERING.run_user_models(args.user_models, ROOT), indent=1))
        return 0
    if args.time_tour:
        print(json.dumps(time_tour(), indent=1))
        return 0
    if args.time_examples:
        print(json.dumps(time_examples(), indent=1))
        return 0
    try:
        only = resolve([x.strip() for x in args.only.split(",") if x.strip()])
    except ValueError as e:
        ap.error(f"--only: {e}")
    if args.run:
        run_experiments(only)
    tables = render()
    readme_path = ROOT / "README.md"
    readme = readme_path.read_text()
    try:
        new_readme = render_readme(readme)
    except ValueError as e:
        print(f"make_tables: {e}", file=sys.stderr)
        return 2
    pages = {}  # path -> (old text, new text) of the pages with generated blocks
    for rel, blocks in PAGE_BLOCKS.items():
        path = ROOT / rel
        if path.is_file() and rel != "docs/performance.md":  # (below, with its speed tables)
            old_text = path.read_text()
            try:
                pages[path] = (old_text, render_blocks(old_text, blocks, rel))
            except ValueError as e:
                print(f"make_tables: {e}", file=sys.stderr)
                return 2
    perf_path = ROOT / "docs" / "performance.md"
    perf = perf_path.read_text() if perf_path.is_file() else None
    try:
        new_perf = None if perf is None else render_performance(
            render_blocks(perf, PAGE_BLOCKS.get("docs/performance.md", {}), "docs/performance.md"))
    except ValueError as e:
        print(f"make_tables: {e}", file=sys.stderr)
        return 2
    if args.check:
        stale = [f"docs/results/tables/{p}.md" for p, text in tables.items()
                 if not (TABLES / f"{p}.md").is_file() or (TABLES / f"{p}.md").read_text() != text]
        if new_readme != readme:
            stale.append("README.md")
        if new_perf != perf:
            stale.append("docs/performance.md")
        stale += [str(path.relative_to(ROOT)) for path, (a, b) in pages.items() if a != b]
        if stale:
            print("make_tables: out of date with docs/results/ (run python docs/make_tables.py): "
                  + ", ".join(stale), file=sys.stderr)
            return 1
        return 0
    TABLES.mkdir(parents=True, exist_ok=True)
    for page, text in tables.items():
        _atomic_write(TABLES / f"{page}.md", text)
        print(f"wrote {TABLES / page}.md")
    if new_readme != readme:
        _atomic_write(readme_path, new_readme)
        print(f"wrote {readme_path}")
    if new_perf != perf:
        _atomic_write(perf_path, new_perf)
        print(f"wrote {perf_path}")
    for path, (a, b) in pages.items():
        if a != b:
            _atomic_write(path, b)
            print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
