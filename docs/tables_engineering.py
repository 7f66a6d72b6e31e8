"""The generated blocks of the engineering pages (docs/operating_accuracy.md,
docs/user_models.md, docs/teaching.md, docs/performance_articulation.md) and of the capability
pages' measured lines, and the results files they are made from.

Imported by docs/make_tables.py, which merges :data:`COMMANDS` into its own and writes the
blocks of :func:`page_blocks` between ``<!-- generated:NAME -->`` and
``<!-- /generated:NAME -->`` of each page. Every function here takes ``load`` (a results
file's name -> its JSON, None when missing) and ``cmd`` (a results file's name -> its
command), so the figures come from the files alone.
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from tables_common import fmt as _f, missing as _missing, table as _table

#: results file -> the command (from the repository root) that writes it
COMMANDS = {
    # where the door radius' error comes from (docs/operating_accuracy.md), about 15 CPU
    # minutes for the four: the split by cause with the default base localisation (the
    # robot in its odometry frame), the same doors in the localisation's map frame, the
    # exact base pose, and a knob
    "radius_error_causes.json": "python benchmarks/radius_error_causes.py --objects "
                                "left_door,right_door,dishwasher --seeds 0,1,2,3,4 "
                                "--base-noise 1 --json docs/results/radius_error_causes.json",
    "radius_error_causes_map.json": "python benchmarks/radius_error_causes.py --objects "
                                    "left_door,right_door --seeds 0,1,2,3,4 --base-noise 1 "
                                    "--frame map --json docs/results/radius_error_causes_map.json",
    "radius_error_causes_exact.json": "python benchmarks/radius_error_causes.py --objects "
                                      "left_door,right_door,dishwasher --seeds 0,1,2,3 "
                                      "--base-noise 0 "
                                      "--json docs/results/radius_error_causes_exact.json",
    "radius_error_causes_knob.json": "python benchmarks/radius_error_causes.py --model "
                                     "tests/data/user_models/wardrobe.sdf --joint left_wing "
                                     "--seeds 0,1,2,3,4 --base-noise 1 "
                                     "--json docs/results/radius_error_causes_knob.json",
    # the four test models of tests/data/user_models, SDFormat and URDF, 5 trials each, on
    # two seed sets (about 5 CPU minutes each)
    "user_models_seed10.json": "python docs/make_tables.py --user-models 10",
    "user_models_seed20.json": "python docs/make_tables.py --user-models 20",
    # link-model estimation against ripl-articulation (its interpreter: an environment with
    # ripl-articulation installed; without it the peer's columns say why)
    "peer_ripl.json": "python benchmarks/bench_peer_ripl.py --peer-python "
                      "/tmp/peer_ripl/bin/python --seeds 10 --json docs/results/peer_ripl.json",
    # what two demonstrations teach about the place spot, with and without the prior
    "teaching_prior.json": "python benchmarks/bench_teaching_prior.py --seeds 200-209 "
                           "--priors 0,1,2,4 --json docs/results/teaching_prior.json",
    # the impact force of the pure force controller against the switching one (Fig. 7.5-7.6)
    "grasp_controller.json": "python benchmarks/bench_grasp_controller.py "
                             "--json docs/results/grasp_controller.json",
    # informed (expected information gain) against random grasp heights (ch. 6)
    "tactile_informed.json": "python -m mmlearn.apps.tactile_recognition --grasps-per-class 8 "
                             "--informed --informed-trials 100 --seed 1 --jobs 1 --results "
                             "build/tactile_informed.jsonl --create-dirs --json",
    # the model selected by n and by the assumed noise (Fig. 4.25-4.26), 2 runs per point
    "articulation_bic.json": "python -m mmlearn.apps.articulation_experiments --only "
                             "bic_n,bic_noise --runs 2 --seed 0 --jobs 1 --create-dirs "
                             "--out-dir build/articulation_bic "
                             "--results build/articulation_bic/results.jsonl --json",
}

#: the results files here whose figures change with the door-radius, user-model and teaching
#: work (make_tables.py adds them to its own list)
VOLATILE = ("radius_error_causes", "radius_error_causes_map", "radius_error_causes_exact",
            "radius_error_causes_knob", "user_models_seed10", "user_models_seed20")

#: the test models of tests/data/user_models: (file stem, joint, handle)
USER_MODELS = [("wall_cabinet", "door_hinge", "bar"), ("wardrobe", "left_wing", "knob"),
               ("drawer", "slide", "bar"), ("light_door", "hinge", "thin rod")]
USER_MODEL_TRIALS = 5


# ------------------------------------------------------------------------------ helpers

def _mean(xs):
    xs = [x for x in xs if x is not None]
    return statistics.fmean(xs) if xs else None


def _range(xs, digits=3, unit=" m") -> str:
    xs = [x for x in xs if x is not None]
    return "-" if not xs else f"{min(xs):.{digits}f}-{max(xs):.{digits}f}{unit}"


def _seeds(rows) -> str:
    s = sorted({r["seed"] for r in rows})
    return (f"{s[0]}-{s[-1]}" if s == list(range(s[0], s[-1] + 1)) else
            ", ".join(map(str, s))) if s else "-"


# ------------------------------------------------------------ docs/operating_accuracy.md

PARTS = ("metric_m", "contact_m", "drift_m", "fit_m")


def _split_rows(d) -> list:
    return [r for r in (d or {}).get("rows", []) if "error_m" in r]


def radius_split(load, cmd) -> str:
    """The split of every trial of radius_error_causes.json and the mean of each part."""
    d = load("radius_error_causes.json")
    if not d:
        return _missing("radius_error_causes.json")
    done = _split_rows(d)
    rows = [[r["object"], r["seed"], _f(r["opened_deg"], 0), _f(r["true_radius_m"]),
             _f(r["radius_m"]), _f(r["error_m"], sign=True)]
            + [_f(r[p], sign=True) for p in PARTS] + [_f(r["axis_error_deg"], 1)]
            for r in done]
    left = [r for r in d["rows"] if "error_m" not in r]
    rows += [[r["object"], r["seed"], _f(r["opened_deg"], 0), "-", "-",
              f"no revolute model ({r['learned_model']})", "", "", "", "", ""] for r in left]
    mean = ["mean", "", "", "", "", _f(_mean(r["error_m"] for r in done), sign=True)] + \
        [_f(_mean(r[p] for r in done), sign=True) for p in PARTS] + [""]
    absm = ["mean abs.", "", "", "", "", _f(_mean(abs(r["error_m"]) for r in done))] + \
        [_f(_mean(abs(r[p]) for r in done)) for p in PARTS] + \
        [_f(_mean(r["axis_error_deg"] for r in done), 1)]
    n = len(d["rows"])
    return (_table(["object", "seed", "opened (deg)", "true r (m)", "learned r (m)", "error",
                    "metric", "contact", "drift", "fit", "axis error (deg)"],
                   rows + [mean, absm])
            + f"\n\n{n} trials ({len(done)} with a revolute model; seeds {_seeds(d['rows'])}, "
              "default base localisation, the robot in its odometry frame, sigma_pos "
              f"0.05 m); radii and errors in m. Made by `{cmd('radius_error_causes.json')}`.")


def radius_frames(load, cmd) -> str:
    """The same doors in the odometry frame (the default) and in the map frame."""
    a, b = load("radius_error_causes.json"), load("radius_error_causes_map.json")
    if not a or not b:
        return _missing("radius_error_causes_map.json" if a else "radius_error_causes.json")
    odo = {(r["object"], r["seed"]): r for r in a["rows"]}
    rows, pairs = [], []
    for r in b["rows"]:
        o = odo.get((r["object"], r["seed"]))
        if o is None:
            continue
        pairs.append((o, r))

        def cell(x, p):
            return _f(x[p], sign=True) if p in x else f"({x['learned_model']})"
        rows.append([r["object"], r["seed"], cell(o, "error_m"), cell(o, "drift_m"),
                     cell(r, "error_m"), cell(r, "drift_m")])

    def mabs(side, p):
        return _mean(abs(x[side][p]) for x in pairs if p in x[side])
    n_odo = sum("error_m" in o for o, _ in pairs)
    n_map = sum("error_m" in m for _, m in pairs)
    rows.append(["mean abs.", "", _f(mabs(0, "error_m")), _f(mabs(0, "drift_m")),
                 _f(mabs(1, "error_m")), _f(mabs(1, "drift_m"))])
    return (_table(["object", "seed", "error, odometry frame", "drift, odometry frame",
                    "error, map frame", "drift, map frame"], rows)
            + f"\n\n{len(pairs)} door trials, the same seeds in both frames ({n_odo} with a "
              f"revolute model in the odometry frame, {n_map} in the map frame); m. Made by "
              f"`{cmd('radius_error_causes_map.json')}` beside the run above.")


def radius_exact(load, cmd) -> str:
    """The split with the exact base pose: contact and fit alone."""
    d = load("radius_error_causes_exact.json")
    if not d:
        return _missing("radius_error_causes_exact.json")
    done = _split_rows(d)
    by = {}
    for r in done:
        by.setdefault(r["object"], []).append(r)
    rows = [[obj, len(rs), _f(_mean(abs(r["error_m"]) for r in rs)),
             _f(max(abs(r["error_m"]) for r in rs)),
             _f(_mean(r["contact_m"] for r in rs), sign=True),
             _f(_mean(abs(r["drift_m"]) for r in rs)), _f(_mean(abs(r["fit_m"]) for r in rs)),
             _f(_mean(r["axis_error_deg"] for r in rs), 1)] for obj, rs in by.items()]
    rows.append(["all", len(done), _f(_mean(abs(r["error_m"]) for r in done)),
                 _f(max((abs(r["error_m"]) for r in done), default=None)),
                 _f(_mean(r["contact_m"] for r in done), sign=True),
                 _f(_mean(abs(r["drift_m"]) for r in done)),
                 _f(_mean(abs(r["fit_m"]) for r in done)),
                 _f(_mean(r["axis_error_deg"] for r in done), 1)])
    return (_table(["object", "trials", "mean abs. error (m)", "max abs. error (m)",
                    "contact (mean, m)", "drift (mean abs., m)", "fit (mean abs., m)",
                    "axis error (mean, deg)"], rows)
            + f"\n\nSeeds {_seeds(d['rows'])}, `--base-noise 0` (the robot knows its base "
              f"pose exactly). Made by `{cmd('radius_error_causes_exact.json')}`.")


def radius_knob(load, cmd) -> str:
    """A knob held at the finger's tip: the split on the wardrobe."""
    d = load("radius_error_causes_knob.json")
    if not d:
        return _missing("radius_error_causes_knob.json")
    done = _split_rows(d)
    rows = [[r["seed"], _f(r["opened_deg"], 0), _f(r["true_radius_m"]), _f(r["radius_m"]),
             _f(r["error_m"], sign=True)] + [_f(r[p], sign=True) for p in PARTS[1:]]
            for r in done]
    rows += [[r["seed"], _f(r["opened_deg"], 0), "-", "-",
              f"no revolute model ({r['learned_model']})", "", "", ""]
             for r in d["rows"] if "error_m" not in r]
    return (_table(["seed", "opened (deg)", "true r (m)", "learned r (m)", "error", "contact",
                    "drift", "fit"], rows)
            + f"\n\nThe wardrobe's knob (a 22 mm ball on an 8 mm stem), {len(d['rows'])} trials, "
              f"mean abs. error {_f(_mean(abs(r['error_m']) for r in done))} m, default base "
              f"localisation. Made by `{cmd('radius_error_causes_knob.json')}`.")


def _operate_door_errors(d) -> list:
    return [t["radius_error_m"] for t in (d or {}).get("trials", [])
            if t.get("radius_error_m") is not None]


def sweep_lines(path: Path) -> list:
    """The parsed lines of a sweep's JSON Lines file (unreadable lines skipped; [] when the
    file is missing)."""
    if not path.is_file():
        return []
    out = []
    for line in path.read_text().splitlines():
        try:
            out.append(json.loads(line))
        except json.JSONDecodeError:
            continue
    return out


def operate_trial_records(name: str, results_dir: Path) -> list:
    """The trial records of an operate_trials JSON Lines file (the sweep's lines)."""
    recs = (r.get("record") if isinstance(r, dict) and "record" in r else r
            for r in sweep_lines(results_dir / name))
    return [rec for rec in recs if isinstance(rec, dict) and rec.get("object")]


def radius_targets(load, cmd) -> str:
    """Status against the targets: opened, right kind, radius errors (operate_trials.json,
    radius_error_causes_exact.json, the user-model files)."""
    rows = []
    op = load("operate_trials.json")
    if op:
        errs = [e for o in op["per_object"].values() if o.get("radius_runs")
                for e in [o["mean_radius_error_m"]] * o["radius_runs"]]
        mx = max((o["max_radius_error_m"] for o in op["per_object"].values()
                  if o.get("max_radius_error_m") is not None), default=None)
        rows.append(["`operate_trials --trials 8`: >= 38/40 opened, right kind >= 38/40",
                     f"{op['successes']}/{op['total']} opened, {op['right_kind']}/{op['total']} "
                     "right kind", "met" if min(op["successes"], op["right_kind"]) >= 38
                     else "not met"])
        m = _mean(errs)
        rows.append(["mean door radius error < 0.02 m, default base localisation",
                     f"{_f(m)} m mean, {_f(mx)} m max ({len(errs)} revolute trials)",
                     "met" if m is not None and m < 0.02 else "not met"])
    ex = _split_rows(load("radius_error_causes_exact.json"))
    if ex:
        m = _mean(abs(r["error_m"]) for r in ex)
        rows.append(["mean <= 0.01 m with `--base-noise 0`",
                     f"{_f(m)} m mean, {_f(max(abs(r['error_m']) for r in ex))} m max "
                     f"({len(ex)} trials)", "met" if m <= 0.01 else "not met"])
    sets = [load(f"user_models_seed{s}.json") for s in (10, 20)]
    sets = [s for s in sets if s]
    if sets:
        ms = [m for s in sets for m in s["models"]]
        opened = sum(m["successes"] for m in ms)
        right = sum(m["right_kind"] for m in ms)
        total = sum(m["trials"] for m in ms)
        means = [m["mean_radius_error_m"] for m in ms if m.get("mean_radius_error_m") is not None]
        mx = max((m["max_radius_error_m"] for m in ms
                  if m.get("max_radius_error_m") is not None), default=None)
        ok = opened == right == total and means and max(means) <= 0.02
        rows.append(["user models ({doc}`user_models`): all opened, right kind, radius "
                     "<= 0.02 m", f"{opened}/{total} opened, {right}/{total} right kind; mean "
                     f"radius error per model and format {_range(means)} (max {_f(mx)} m)",
                     "met on the mean" if ok else "not met"])
    if not rows:
        return _missing("operate_trials.json")
    return _table(["target", "measured", "status"], rows) + \
        f"\n\nMade by `{cmd('operate_trials.json')}` and the runs above."


def dishwasher_axis(load, cmd) -> str:
    """The dishwasher's axis error against the doors' (operate_trials.json, the exact run)."""
    op = load("operate_trials.json")
    if not op:
        return _missing("operate_trials.json")
    per = op["per_object"]
    parts = [f"{obj} {_f(per[obj].get('mean_axis_error_deg'), 1)} deg"
             for obj in ("left_door", "right_door", "dishwasher") if obj in per]
    ex = [r for r in _split_rows(load("radius_error_causes_exact.json"))
          if r["object"] == "dishwasher"]
    extra = (f"; with the exact base pose the dishwasher's is "
             f"{_range([r['axis_error_deg'] for r in ex], 1, ' deg')} over seeds "
             f"{_seeds(ex)}") if ex else ""
    return (f"Mean axis error over the thesis' experiment (`{cmd('operate_trials.json')}`): "
            + ", ".join(parts) + extra + ".")


# ------------------------------------------------------------------ docs/user_models.md

def run_user_models(seed: int, root: Path) -> dict:
    """Run ``operate_trials`` on every test model of tests/data/user_models, SDFormat and
    URDF, :data:`USER_MODEL_TRIALS` trials from ``seed``; per model and format the sweep's
    summary and how often the hook held the handle at its seat or its finger's tip."""
    out = []
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
    with tempfile.TemporaryDirectory(prefix="mmlearn_user_models_") as tmp:
        for stem, joint, handle in USER_MODELS:
            for fmt in ("sdf", "urdf"):
                results = Path(tmp) / f"{stem}_{fmt}.jsonl"
                argv = [sys.executable, "-m", "mmlearn.apps.operate_trials", "--model",
                        f"tests/data/user_models/{stem}.{fmt}", "--joint", joint, "--trials",
                        str(USER_MODEL_TRIALS), "--seed", str(seed), "--jobs", "1",
                        "--results", str(results), "--json"]
                p = subprocess.run(argv, cwd=root, env=env, capture_output=True, text=True)
                try:
                    d = json.loads(p.stdout)
                except json.JSONDecodeError:
                    out.append({"model": stem, "format": fmt, "joint": joint, "handle": handle,
                                "error": (p.stderr.strip().splitlines() or ["no output"])[-1]})
                    continue
                (o,) = d["per_object"].values()
                grips = {}
                for t in d["trials"]:
                    grips[t.get("hook_grip") or "-"] = grips.get(t.get("hook_grip") or "-", 0) + 1
                out.append({"model": stem, "format": fmt, "joint": joint, "handle": handle,
                            "trials": o["trials"], "successes": o["successes"],
                            "right_kind": o["right_kind"], "unit": o.get("unit"),
                            "mean_opened": o.get("mean_opened"),
                            "mean_radius_error_m": o.get("mean_radius_error_m"),
                            "max_radius_error_m": o.get("max_radius_error_m"),
                            "mean_axis_error_deg": o.get("mean_axis_error_deg"),
                            "hook_grip": grips,
                            "cpu_seconds": sum(t.get("cpu_seconds") or 0 for t in d["trials"])})
    return {"seed": seed, "seeds": f"{seed}-{seed + USER_MODEL_TRIALS - 1}",
            "base_noise": 1.0, "sigma_pos": 0.05, "models": out}


def user_models_table(load, cmd) -> str:
    """Per test model: opened and right kind (SDF / URDF) and radius errors, per seed set."""
    sets = [(s, load(f"user_models_seed{s}.json")) for s in (10, 20)]
    sets = [(s, d) for s, d in sets if d]
    if not sets:
        return _missing("user_models_seed10.json")
    head = ["model (joint)", "handle"]
    for s, d in sets:
        head += [f"opened, seeds {d['seeds']} (SDF / URDF)", "right kind (SDF / URDF)",
                 "radius error mean / max (SDF; URDF)"]
    rows = []

    def pair(ms, key):
        return " / ".join("-" if ms.get(f) is None or "error" in ms[f] else
                          f"{ms[f][key]}/{ms[f]['trials']}" for f in ("sdf", "urdf"))

    def radius(m):
        if m is None or "error" in m:
            return "-"
        if m.get("mean_radius_error_m") is None:
            return ("-" if m.get("mean_opened") is None else
                    f"- (opened {m['mean_opened']:.3f} {m.get('unit') or 'm'})")
        return f"{m['mean_radius_error_m']:.3f} / {m['max_radius_error_m']:.3f} m"
    for stem, joint, handle in USER_MODELS:
        row = [f"{stem} ({joint})", handle]
        for _, d in sets:
            ms = {m["format"]: m for m in d["models"] if m["model"] == stem}
            row += [pair(ms, "successes"), pair(ms, "right_kind"),
                    "; ".join(radius(ms.get(f)) for f in ("sdf", "urdf"))]
        rows.append(row)
    for _, d in sets:
        ok = [m for m in d["models"] if "error" not in m]
        n = sum(m["trials"] for m in ok)
        rows_all = [f"{sum(m['successes'] for m in ok)}/{n}", f"{sum(m['right_kind'] for m in ok)}/{n}", ""]
        if len(rows) == len(USER_MODELS):
            rows.append(["all", ""])
        rows[-1] += rows_all
    notes = []
    for s, d in sets:
        tip = [m for m in d["models"] if m.get("hook_grip", {}).get("tip")]
        grips = ", ".join(f"{m['model']}.{m['format']} {m['hook_grip']['tip']} of {m['trials']}"
                          for m in tip) or "none"
        cpu = sum(m.get("cpu_seconds") or 0 for m in d["models"])
        notes.append(f"seeds {d['seeds']}: the hook held the handle at its finger's tip "
                     f"(`hook_grip` \"tip\") in {grips}, at its seat otherwise; "
                     f"{cpu:.0f} s of simulation CPU; made by "
                     f"`{cmd(f'user_models_seed{s}.json')}`")
    return (_table(head, rows) + "\n\nDefault base localisation (the robot in its odometry "
            "frame), sigma_pos 0.05 m, click perception, "
            f"{USER_MODEL_TRIALS} trials per model, format and seed set. "
            + "; ".join(notes) + ".")


# ---------------------------------------------------------------------- docs/teaching.md

def teaching_prior(load, cmd) -> str:
    """bench_teaching_prior.py's table: the place target's error and table A's x spread,
    ranges over the seeds per pair of demonstrations and prior weight."""
    d = load("teaching_prior.json")
    if not d:
        return _missing("teaching_prior.json")
    groups = {}
    for r in d.get("rows", []):
        groups.setdefault((r["pair"], r["prior"]), []).append(r)
    rows = []
    for (pair, prior), rs in groups.items():
        e = [r["place_target_error_mm"] for r in rs]
        rows.append([pair, f"{prior:g}", _range(e, 1, " mm"), f"{sum(x > 15 for x in e)}/{len(e)}",
                     _range([r["table_a_x_sd_mm"] for r in rs], 0, " mm")])
    return (_table(["pair", "prior weight", "place target error (range)",
                    "seeds with error > 15 mm", "table A x sd (range)"], rows)
            + f"\n\nSeeds {_seeds(d['rows'])}, no simulation of the robot (the learned model "
              f"only). Made by `{cmd('teaching_prior.json')}`.")


def _teach_runs(load_runs):
    runs = load_runs("teaching.jsonl")
    inter = sorted((r for r in runs if r["fn"].startswith("imitation.teach")),
                   key=lambda r: r["seed"])
    batch = {}
    for r in runs:
        if r["fn"].startswith("imitation.reproduce"):
            key = (r["params"].get("demos"), bool(r["params"].get("isotropic_prior")))
            batch.setdefault(key, {})[r["seed"]] = r
    return inter, batch


def teaching_findings(load_runs, cmd) -> str:
    """What the interactive-against-batch sweep shows, from teaching.jsonl's records."""
    inter, batch = _teach_runs(load_runs)
    if not inter:
        return _missing("teaching.json")
    n = len(inter)
    seeds = _seeds(inter)
    ok = [r for r in inter if r.get("success")]
    counts = {}
    for r in ok:
        counts[r["demos_used"]] = counts.get(r["demos_used"], 0) + 1
    by_count = ", ".join(f"{c} on {k} seed{'s' if k > 1 else ''}"
                         for c, k in sorted(counts.items()))
    second_failed = [r["seed"] for r in inter if len(r.get("rounds", [])) > 1
                     and r["rounds"][1]["outcome"] != "success"]
    b2 = batch.get((2, False), {})
    b2p = batch.get((2, True), {})
    b1 = batch.get((1, False), {})
    test_fail = [r for r in inter if r.get("test_success") is False]
    first = [r["rounds"][0] for r in inter if r.get("rounds")]
    first_flag = [x for x in first if x["outcome"] == "unsure"]
    later = [x for r in inter for x in r.get("rounds", [])[1:]]
    later_fail = [x for x in later if x["outcome"] == "failed"]
    succ_rounds = [x for r in inter for x in r.get("rounds", []) if x["outcome"] == "success"]

    def ratio(xs):
        v = [x["confidence"]["peak_ratio"] for x in xs if x.get("confidence")]

        def num(x):
            return f"{x:,.0f}" if x >= 100 else f"{x:.1f}"
        if not v:
            return "-"
        return num(v[0]) if len(v) == 1 else f"{num(min(v))}-{num(max(v))}"

    def fails(d):
        bad = sorted((s, r) for s, r in d.items() if not r.get("success"))
        return ", ".join(f"{s}: {_f(r.get('place_error_m'))} m" for s, r in bad) or "none"
    thr = (first[0].get("confidence") or {}).get("threshold") if first else None
    lines = [
        f"interactive teaching ended with a success on {len(ok)} of {n} seeds (seeds {seeds}) "
        f"with **{_f(_mean(r['demos_used'] for r in ok), 1)} demonstrations on average** "
        f"({by_count}); a second round missed on {len(second_failed)} of {n} seeds"
        + (f" ({', '.join(map(str, second_failed))})" if second_failed else ""),
        f"batch learning (the thesis' learner) succeeded on {sum(r.get('success') for r in b2.values())} "
        f"of {len(b2)} from 2 demonstrations, on {sum(r.get('success') for r in b1.values())} of "
        f"{len(b1)} from 1",
        f"in batch's own test situations the taught robot succeeded on "
        f"{sum(bool(r.get('test_success')) for r in inter)} of {n} seeds (misses, place error: "
        + (", ".join(f"{r['seed']}: {_f((r.get('test') or {}).get('place_error_m'))} m"
                     for r in test_fail) or "none")
        + f"; tolerance 0.02 m); batch from 2 demonstrations with the prior on "
        f"{sum(r.get('success') for r in b2p.values())} of {len(b2p)} (misses: {fails(b2p)})",
        f"the robot asked after the first demonstration on {len(first_flag)} of {len(first)} "
        f"seeds (peak surprise {ratio(first_flag)} times the reference, threshold "
        f"{'-' if thr is None else f'{thr:g}'}); {len(later_fail)} later round(s) failed "
        f"while sure (peak {ratio(later_fail)} times); the successful rounds peaked at "
        f"{ratio(succ_rounds)} times",
    ]
    return "\n".join(f"* {x};" if i < len(lines) - 1 else f"* {x}." for i, x in
                     enumerate(lines)) + f"\n\nFrom `docs/results/teaching.jsonl` (`{cmd('teaching.json')}`)."


# ------------------------------------------------------ docs/performance_articulation.md

def _speed(load, name):
    d = load("speed.json")
    for b in (d or {}).get("benchmarks", []):
        if b["name"] == name and not b.get("error"):
            return b, d
    return None, d


def demo_speed(load, cmd) -> str:
    """The README demo's simulation speed (speed.json's bench_demo) against the 6x target."""
    b, d = _speed(load, "bench_demo")
    if not b:
        return _missing("speed.json")
    f = b["figures"]
    rtf = f["realtime_factor_cpu"]
    return (f"The README's demo (`open_cabinet --object left_door --seed 1`): "
            f"{f['simulated_s']:.2f} s simulated in {f['simulation_cpu_s']:.2f} s of simulation "
            f"CPU, {rtf:.2f}x real time on the CPU clock (target >= 6x: "
            f"{'met' if rtf >= 6 else 'not met'}; load {b['load_start']:.1f}-{b['load_end']:.1f}; "
            f"`benchmarks/bench_demo.py --quick`, made by `{cmd('speed.json')}`). From run to "
            "run on a shared machine this figure moves by several per cent either way.")


def selection_speed(load, cmd) -> str:
    """Link-model selection's CPU time (speed.json's bench_articulation) against the targets."""
    b, d = _speed(load, "bench_articulation")
    if not b:
        return _missing("speed.json")
    f = b["figures"]
    rows = []
    for track in ("microwave", "drawer"):
        for n, target in ((30, 10.0), (200, 30.0)):
            v = f.get(f"select_{track}_n{n}_cpu_ms")
            rows.append([f"{track}, n = {n}", _f(v, 1), f"< {target:g}",
                         "-" if v is None else ("met" if v < target else "not met")])
    return (_table(["track", "CPU ms per selection", "target", "status"], rows)
            + f"\n\nThe quick mode of `benchmarks/bench_articulation.py`, load "
              f"{b['load_start']:.1f}-{b['load_end']:.1f} on {d.get('cores')} cores "
              f"({d.get('date')}). Made by `{cmd('speed.json')}`.")


def peer_ripl(load, cmd) -> str:
    """mmlearn's link-model estimation against ripl-articulation on the same tracks."""
    d = load("peer_ripl.json")
    if not d:
        return _missing("peer_ripl.json")
    ours, peer = d["mmlearn"], d.get("ripl") or {}

    def cells(s):
        if not s:
            return ["-", "-", "-"]
        err = "-" if s["axis_err_mean_deg"] is None else \
            f"{s['axis_err_mean_deg']:.1f} / {s['axis_err_max_deg']:.1f}"
        return [f"{s['right']}/{s['tracks']}", err, _f(s["cpu_ms_median"], 1)]
    rows = [[k] + cells(s) + cells(peer.get(k)) for k, s in ours.items()]
    note = ("" if d.get("ripl") and not d.get("ripl_skipped") else
            f" The peer's columns are empty: {d.get('ripl_skipped') or 'not run'} (the "
            "benchmark needs an environment with ripl-articulation; mmlearn's side is "
            "measured without it).")
    return (_table(["tracks", "mmlearn: right type", "axis error mean / max (deg)",
                    "CPU ms (median)", "ripl: right type", "axis error mean / max (deg)",
                    "CPU ms (median)"], rows)
            + "\n\nAxis errors over the tracks whose type is right; CPU time per track." + note
            + f" Made by `{cmd('peer_ripl.json')}`.")


def opening_speed(load, cmd, results_dir: Path) -> str:
    """The opening trials' simulation cost: simulated s per CPU s (operate_trials.jsonl)."""
    recs = [r for r in operate_trial_records("operate_trials.jsonl", results_dir)
            if r.get("cpu_seconds") and r.get("sim_seconds")]
    if not recs:
        return _missing("operate_trials.json")
    by = {}
    for r in recs:
        by.setdefault(r["object"], []).append(r)
    rows = [[obj, len(rs), _f(_mean(r["sim_seconds"] for r in rs), 1),
             _f(_mean(r["cpu_seconds"] for r in rs), 1),
             _range([r["sim_seconds"] / r["cpu_seconds"] for r in rs], 1, "x")]
            for obj, rs in by.items()]
    allf = _mean(r["sim_seconds"] for r in recs) / _mean(r["cpu_seconds"] for r in recs)
    tour = {c["capability"]: c for c in (load("quick_tour.json") or {}).get("commands", [])}
    door = tour.get("operate a door")
    extra = (f" The README's door command (`{door['command']}`) took {door['cpu_s']:.0f} s "
             "of CPU as a whole process (imports, building and the recording included; "
             "`quick_tour.json`).") if door else ""
    return (_table(["object", "trials", "simulated s (mean)", "simulation CPU s (mean)",
                    "real-time factor on the CPU clock (range)"], rows)
            + f"\n\nOver all {len(recs)} trials: {allf:.1f}x on the CPU clock (`cpu_seconds` "
              f"and `sim_seconds` of each record in `docs/results/operate_trials.jsonl`, made "
              f"by `{cmd('operate_trials.json')}`, two trials at a time).{extra}")


# -------------------------------------------------------- the capability pages' lines

def learner_share(load, cmd) -> str:
    """The body-schema learner's share of the 7-DOF simulation's CPU time."""
    b, _ = _speed(load, "bench_learner_cost")
    if not b:
        return _missing("speed.json")
    f = b["figures"]
    return (f"- The learner takes {100 * f['learner_share']:.1f} % of the 7-DOF simulation's "
            f"CPU time ({f['learner_updates_cpu_s']:.3f} of {f['simulation_cpu_s']:.2f} s; "
            f"{f['realtime_factor_cpu']:.1f}x real time on the CPU clock; "
            f"`benchmarks/bench_learner_cost.py --quick`, made by `{cmd('speed.json')}`).")


def imitation_cost(load, cmd) -> str:
    """An incremental step's, learning's and a global plan's CPU time (bench_imitation)."""
    b, _ = _speed(load, "bench_imitation")
    if not b:
        return _missing("speed.json")
    f = b["figures"]
    return (f"- An incremental step costs {f['step_cpu_ms']:.2f} ms CPU ({f['step_obstacle_cpu_ms']:.2f} "
            f"with an obstacle); learning {f['learn_cpu_s'] * 1e3:.0f} ms; a global plan "
            f"{f['plan_global_cpu_s']:.2f} s (`benchmarks/bench_imitation.py --quick`, made by "
            f"`{cmd('speed.json')}`).")


def tactile_cost(load, cmd) -> str:
    """A taxel frame's CPU time and a grasp's real-time factor (bench_tactile_sim)."""
    b, _ = _speed(load, "bench_tactile_sim")
    if not b:
        return _missing("speed.json")
    f = b["figures"]
    return (f"- A taxel frame costs {f['frame_block_cpu_ms']:.1f} ms CPU on two 14 x 6 pads "
            f"({f['frame_container_cpu_ms']:.1f} ms on a container); one grasp simulates "
            f"{f['grasp_realtime_factor_wall']:.1f}x faster than real time on the wall clock "
            f"(`benchmarks/bench_tactile_sim.py --quick`, made by `{cmd('speed.json')}`).")


def revolute_from(load, cmd) -> str:
    """How far a door opens before its model turns revolute (operate_trials.json)."""
    op = load("operate_trials.json")
    if not op:
        return _missing("operate_trials.json")
    per = op["per_object"]
    parts = [f"{obj} {per[obj]['mean_right_model_at']:.0f} deg on average (at most "
             f"{per[obj]['max_right_model_at']:.0f})" for obj in ("left_door", "right_door",
                                                                 "dishwasher")
             if per.get(obj, {}).get("mean_right_model_at") is not None]
    return ("- At sigma_pos 0.05 m a door's model turns revolute only well into the opening: "
            + ", ".join(parts) + f" (`{cmd('operate_trials.json')}`).")


def page_blocks(load, cmd, load_runs, results_dir) -> dict:
    """docs page -> {block name -> function of no arguments giving its text}."""
    def b(fn, *extra):
        return lambda: fn(load, cmd, *extra)
    return {
        "docs/operating_accuracy.md": {
            "radius_split": b(radius_split), "radius_frames": b(radius_frames),
            "radius_exact": b(radius_exact), "radius_knob": b(radius_knob),
            "radius_targets": b(radius_targets), "dishwasher_axis": b(dishwasher_axis)},
        "docs/user_models.md": {"user_models": b(user_models_table)},
        "docs/teaching.md": {"teaching_prior": b(teaching_prior),
                             "teaching_findings": lambda: teaching_findings(load_runs, cmd)},
        "docs/performance_articulation.md": {
            "selection_speed": b(selection_speed), "peer_ripl": b(peer_ripl),
            "opening_speed": lambda: opening_speed(load, cmd, results_dir()),
            "demo_speed": b(demo_speed)},
        "docs/body_schema.md": {"learner_share": b(learner_share)},
        "docs/imitation.md": {"imitation_cost": b(imitation_cost)},
        "docs/performance.md": {"peer_ripl_table": b(peer_ripl), "peer_gp": b(peer_gp)},
        "docs/articulation.md": {"revolute_from": b(revolute_from),
                                 "selection_by_n_and_noise": b(selection_by_n_and_noise)},
        "docs/perception.md": {"detector_speed": b(detector_speed)},
        "docs/tactile.md": {"tactile_cost": b(tactile_cost), "tactile_impact": b(tactile_impact),
                            "tactile_state_given": b(tactile_state_given),
                            "icub_classifiers": b(icub_classifiers),
                            "tactile_informed": b(tactile_informed)},
    }


def detector_speed(load, cmd) -> str:
    """The front detector's CPU time per stage (speed.json's bench_front_detector) against
    the targets."""
    b, d = _speed(load, "bench_front_detector")
    if not b:
        return _missing("speed.json")
    f = b["figures"]
    rows = []
    for stage, key, target in (("`planes`", "planes_cpu_ms", 5.0), ("`masks`", "masks_cpu_ms", 10.0),
                               ("`sampling`", "sampling_cpu_ms", None),
                               ("`optimisation`", "optimisation_cpu_ms", None),
                               ("`check`", "check_cpu_ms", None),
                               ("whole", "total_cpu_ms", 33.0)):
        v = f.get(key)
        rows.append([stage, _f(v, 1), "" if target is None else f"< {target:g}",
                     "" if target is None or v is None else ("met" if v < target else "not met")])
    return (_table(["stage", "CPU ms per frame", "target", "status"], rows)
            + f"\n\nThe quick mode of `benchmarks/bench_front_detector.py` (synthetic 640 x 480 "
              f"frames), detection rate {_f(f.get('detection_rate'), 2)}, load "
              f"{b['load_start']:.1f}-{b['load_end']:.1f} on {d.get('cores')} cores; the whole "
              "target is the camera's 30 Hz. Made by "
              f"`{cmd('speed.json')}`.")


def tactile_impact(load, cmd) -> str:
    """The peak contact force above f_target, pure force control against switching."""
    d = load("grasp_controller.json")
    if not d:
        return _missing("grasp_controller.json")
    f = d["f_target_n"]
    by = {}
    for r in d["rows"]:
        by.setdefault(r["object"], {})[r["controller"]] = 100 * (r["peak_n"] / f - 1)
    parts = [f"{obj}: {_f(c.get('force'), 1, ' %', sign=True)} with pure force control, "
             f"{_f(c.get('switching'), 1, ' %', sign=True)} with the switching controller"
             for obj, c in by.items()]
    return (f"- The switching controller has no impact spike: the peak contact force above "
            f"f_target ({f:g} N) on the " + "; on the ".join(parts) + f" (`{cmd('grasp_controller.json')}`).")


def tactile_state_given(load, cmd) -> str:
    """The state rate given the container, simulated, against the thesis' bottles."""
    d = load("tactile_state_sim.json")
    if not d:
        return _missing("tactile_state_sim.json")
    r = d.get("state_rate_by_container", {})
    here = ", ".join(f"{c} {_f(r.get(c), 2)}" for c in ("naked", "water") if c in r)
    return ("- State given the container: the flimsy bottles' buckling is not modelled, so the "
            f"Naked and water bottles' states are easier here ({here}; thesis 0.58 / 0.33; "
            f"{d['settings']['trials']} grasps per state at {d['f_target']:g} N, "
            f"`{cmd('tactile_state_sim.json')}`).")


def _runs_of(xs, labels, unit: str = "") -> str:
    """'prismatic at 3-12, revolute at 15-21, ...': the selected model over a grid, as runs."""
    out, start = [], 0
    for i in range(1, len(labels) + 1):
        if i == len(labels) or labels[i] != labels[start]:
            a, b = xs[start], xs[i - 1]
            out.append(f"{labels[start]} at {a:g}{unit}" if a == b else
                       f"{labels[start]} at {a:g}-{b:g}{unit}")
            start = i
    return ", ".join(out)


def selection_by_n_and_noise(load, cmd) -> str:
    """Fig. 4.25 (the model selected by n) and Fig. 4.26 (by the assumed noise)."""
    d = load("articulation_bic.json")
    if not d:
        return _missing("articulation_bic.json")
    a, b = d["bic_n"], d["bic_noise"]
    return ("- Configuration prior: Eq. 4.26's integral along the path instead of `n^-d`. "
            f"Fig. 4.25 (the roll-up door, sigma {a['sigma_pos']:g} m), the model selected "
            f"by n: {_runs_of(a['n'], a['selected'])} (thesis: revolute from n = 24-28). "
            f"Fig. 4.26 (n = {b['n']}, true noise {b['true_sigma_pos']:g} m), by the assumed "
            f"noise: {_runs_of(b['assumed_sigma_pos'], b['selected'], ' m')} (thesis: GP up to "
            f"0.02 m, rigid above 0.2 m). {d['runs']} runs per point; "
            f"`{cmd('articulation_bic.json')}`.")


def icub_classifiers(load, cmd) -> str:
    """The classifiers on the real iCub grasps shipped with the tests (icub_state.json)."""
    d = load("icub_state.json")
    if not d:
        return _missing("icub_state.json")
    rates = dict(d.get("compare", {}), **{d["classifier"]: d["rate"]})
    return ("- Real iCub grasps: a random forest on the six features of Table 7.1 beside the "
            "thesis' decision tree (thesis: 0.888 on the full data set); on the sample grasps "
            f"of `tests/data/icub_grasp` ({d['n_test']} grasps, {d['evaluation']}): "
            + ", ".join(f"{k} {_f(v, 3)}" for k, v in sorted(rates.items()))
            + f" (`{cmd('icub_state.json')}`).")


def tactile_informed(load, cmd) -> str:
    """Informed against random grasp heights (tactile_informed.json)."""
    d = load("tactile_informed.json")
    if not d:
        return ("- Informed grasp heights against random ones (thesis: +5.0 % on all objects, "
                "+9.5 % on the industrial parts): " + _missing("tactile_informed.json"))
    names = {"all": "all objects", "industrial": "the industrial parts"}
    parts = []
    for subset, what in names.items():
        pt = ((d.get("informed") or {}).get(subset) or {}).get("paired_t", {}).get("informed")
        if pt:
            parts.append(f"{100 * pt['mean_difference']:+.1f} % on {what} (paired t p = "
                         f"{pt['p']:.2g})")
    return ("- Informed grasp heights against random ones (thesis: +5.0 % on all objects, "
            f"+9.5 % on the industrial parts): {', '.join(parts) or 'not measured'}; "
            f"{d['settings'].get('grasps_per_class')} grasps per class, "
            f"{d['settings'].get('informed_trials')} recognitions per fold and strategy "
            f"({d.get('n_grasps')} grasps; `{cmd('tactile_informed.json')}`).")


def peer_gp(load, cmd) -> str:
    """mmlearn's GP against scikit-learn's on the same data (speed.json's bench_peer_gp)."""
    b, d = _speed(load, "bench_peer_gp")
    if not b:
        return _missing("speed.json")
    f = b["figures"]
    return (_table(["", "CPU ms per fit (12 outputs, n = 30)"],
                   [["mmlearn `GaussianProcess`", _f(f["gp_ms"], 1)],
                    ["scikit-learn, one regressor per output", _f(f["sklearn_ms"], 1)]])
            + f"\n\n{f['speedup']:.1f}x faster; the log marginal likelihoods reached differ by at "
              f"most {f['lml_max_diff']:.1g} per output (`benchmarks/bench_peer_gp.py --quick`, "
              f"load {b['load_start']:.1f}; made by `{cmd('speed.json')}`).")
