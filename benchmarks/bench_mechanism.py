"""Benchmark: mechanism dynamics learned while opening, and jammed / locked / sticky
mechanisms (Drake trials of ``open_cabinet``; prints a table, never fails on a figure).

    python benchmarks/bench_mechanism.py [--only damping,jam,locked,sticky]
        [--kinds left_door,drawer] [--seed 100]
        [--trials 1] [--repeats 5] [--jobs 1] [--base-noise S] [--results FILE.jsonl]
        [--json [FILE]]

Groups: ``damping`` (a door at 0.5-5 N m s/rad, a drawer at 5-50 N s/m: the learned damping
against the true, in joint units and as the handle's N s/m, which does not depend on the
learned radius), ``jam`` (a door jammed at 15-55 deg, a drawer at 0.05-0.25 m: recognised,
``jammed_at`` error, peak wrist force), ``locked`` (latched door and drawer) and ``sticky``
(free but with 5-10 times the usual friction: must be opened). ``--trials`` trials per
setting, each setting on its own seeds (``--seed`` on: a door's damping values on different
doors, so one door's learned radius does not bias them all alike); locked and sticky:
``--repeats`` settings per kind. ``--jobs`` trials run at once. Each finished trial is
appended to ``--results`` (default ``bench_mechanism_results.jsonl``); a rerun skips the
trials already there.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

from _common import add_output_arguments, emit_json

GROUPS = ("damping", "jam", "locked", "sticky")
KINDS = ("left_door", "drawer")
DAMPING = {"left_door": (0.5, 1.0, 2.0, 3.0, 5.0), "drawer": (5.0, 10.0, 20.0, 30.0, 50.0)}
JAMS = {"left_door": (15.0, 25.0, 35.0, 45.0, 55.0), "drawer": (0.05, 0.10, 0.15, 0.20, 0.25)}
STICKY = {"left_door": 2.5, "drawer": 10.0}
LIMIT_N = 35.0  # the controller's force limit (EpcConfig.stop_force)
JAM_TOL = {"left_door": 5.0, "drawer": 0.03}


def trials(groups, seed: int, n: int, repeats: int = 5,
           base_noise: float | None = None, kinds=KINDS) -> list[dict]:
    """The trials of the chosen groups and kinds: label, group, kind, seed, options, value
    (and the base-localisation error's scale, None = the default)."""
    out = []
    for g in groups:
        for kind in kinds:
            rev = kind == "left_door"
            if g == "damping":
                settings = [({"damping": v}, v) for v in DAMPING[kind]]
            elif g == "jam":
                settings = [({"jam_at": math.radians(v) if rev else v}, v) for v in JAMS[kind]]
            elif g == "locked":
                settings = [({"locked": True}, None)] * repeats
            else:
                settings = [({"friction": STICKY[kind]}, STICKY[kind])] * repeats
            for j, (opts, v) in enumerate(settings):
                for i in range(n):
                    s = seed + j * n + i  # every setting on its own mechanisms and starts
                    noise = "" if base_noise is None else f" base noise {base_noise:g}"
                    out.append({"label": f"{g} {kind} {v} seed {s}{noise}", "group": g,
                                "kind": kind, "seed": s, "options": opts, "value": v,
                                "base_noise": base_noise})
    return out


def run_trial(t: dict) -> dict:
    from mmlearn.diagrams.articulation.trials import open_mechanism

    t0 = time.perf_counter()
    r = open_mechanism(kind=t["kind"], seed=t["seed"], show_progress=False,
                       mechanism_options=t["options"], base_noise=t.get("base_noise"))
    d = r.get("dynamics") or {}
    learned = d if d.get("learned") else {}
    return {**{k: t[k] for k in ("label", "group", "kind", "seed", "value")},
            "outcome": r["outcome"], "success": r["success"], "opened": r["opened"],
            "jammed_at": r.get("jammed_at"), "peak_force_N": r.get("peak_force_N"),
            "peak_force_impact_N": r.get("peak_force_impact_N"),
            "block_force_N": r.get("block_force_N"),
            "true": r["dynamics"]["true"],
            "learned": {k: learned.get(k) for k in ("damping", "damping_std", "friction",
                                                     "friction_std", "stiffness",
                                                     "stiffness_std", "radius")},
            "prediction": learned.get("prediction"),
            "radius_m": r.get("radius_m"), "true_radius_m": r.get("true_radius_m"),
            "wall_s": round(time.perf_counter() - t0, 1)}


def summary(rows: list[dict]) -> dict:
    """The figures of each group (see the module docstring)."""
    out = {}
    dmp = [r for r in rows if r["group"] == "damping"]
    for kind in ("left_door", "drawer"):
        rs = [r for r in dmp if r["kind"] == kind]
        errs, handle = [], []
        for r in rs:
            b = r["learned"]["damping"]
            if b is None:
                errs.append(None)
                continue
            errs.append(b / r["value"] - 1)
            if kind == "left_door" and r["learned"]["radius"] and r["true_radius_m"]:
                handle.append(b / r["learned"]["radius"] ** 2
                              / (r["value"] / r["true_radius_m"] ** 2) - 1)
        ok = [e for e in errs if e is not None]
        out[f"damping_{kind}"] = {
            "trials": len(rs), "learned": sum(e is not None for e in errs),
            "within_25pct": sum(abs(e) <= 0.25 for e in ok),
            "mean_abs_rel_error": float(np.mean(np.abs(ok))) if ok else None,
            "max_abs_rel_error": float(np.max(np.abs(ok))) if ok else None,
            "handle_mean_abs_rel_error": float(np.mean(np.abs(handle))) if handle else None}
    for g, want in (("jam", "jammed"), ("locked", "locked")):
        for kind in ("left_door", "drawer"):
            rs = [r for r in rows if r["group"] == g and r["kind"] == kind]
            hit = [r for r in rs if r["outcome"] == want]
            within = [r for r in hit if g == "locked" or (
                r["jammed_at"] is not None
                and abs(r["jammed_at"] - r["value"]) <= JAM_TOL[kind])]
            errs = [abs(r["jammed_at"] - r["value"]) for r in hit
                    if g == "jam" and r["jammed_at"] is not None]
            peaks = [r["peak_force_N"] for r in rs if r["peak_force_N"] is not None]
            out[f"{g}_{kind}"] = {
                "trials": len(rs), "recognised": len(hit), "within_tolerance": len(within),
                "mean_position_error": float(np.mean(errs)) if errs else None,
                "max_position_error": float(np.max(errs)) if errs else None,
                "below_limit": sum(p < LIMIT_N for p in peaks),
                "max_peak_force_N": float(max(peaks)) if peaks else None,
                "block_below_limit": sum(r.get("block_force_N") is not None
                                         and r["block_force_N"] < LIMIT_N for r in hit),
                "max_block_force_N": max((r["block_force_N"] for r in hit
                                          if r.get("block_force_N") is not None),
                                         default=None),
                "max_impact_force_N": max((r["peak_force_impact_N"] for r in rs
                                           if r.get("peak_force_impact_N") is not None),
                                          default=None),
                "outcomes": sorted({r["outcome"] for r in rs})}
    for kind in ("left_door", "drawer"):
        rs = [r for r in rows if r["group"] == "sticky" and r["kind"] == kind]
        out[f"sticky_{kind}"] = {"trials": len(rs),
                                 "opened": sum(bool(r["success"]) for r in rs),
                                 "called_blocked": sum(r["outcome"] in ("jammed", "locked")
                                                       for r in rs),
                                 "outcomes": sorted({r["outcome"] for r in rs})}
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", default=",".join(GROUPS), help="groups, comma-separated")
    ap.add_argument("--seed", type=int, default=100)
    ap.add_argument("--trials", type=int, default=1, help="trials per setting")
    ap.add_argument("--repeats", type=int, default=5,
                    help="locked and sticky trials per mechanism kind (x --trials)")
    ap.add_argument("--kinds", default=",".join(KINDS), help="mechanisms, comma-separated")
    ap.add_argument("--jobs", type=int, default=1, help="trials run at once")
    ap.add_argument("--base-noise", type=float, default=None,
                    help="scale of the base-localisation error (0: the exact base pose; "
                         "default: open_cabinet's)")
    ap.add_argument("--results", default="bench_mechanism_results.jsonl")
    add_output_arguments(ap)
    a = ap.parse_args(argv)
    groups = [g for g in a.only.split(",") if g]
    kinds = [k for k in a.kinds.split(",") if k]
    bad = [g for g in groups if g not in GROUPS]
    if not kinds or any(k not in KINDS for k in kinds):
        ap.error(f"--kinds: choose from {', '.join(KINDS)}")
    if bad or a.trials < 1 or a.jobs < 1:
        ap.error(f"--only: choose from {', '.join(GROUPS)}" if bad
                 else "--trials and --jobs must be >= 1")
    table = a.json != "-"
    path = Path(a.results)
    done = {}
    if path.exists():
        for line in path.read_text().splitlines():
            if line.strip():
                r = json.loads(line)
                done[r["label"]] = r
    todo = trials(groups, a.seed, a.trials, a.repeats, a.base_noise, kinds)
    new = [t for t in todo if t["label"] not in done]
    if a.jobs > 1 and len(new) > 1:
        from concurrent.futures import ProcessPoolExecutor, as_completed

        with ProcessPoolExecutor(min(a.jobs, len(new))) as pool:
            for fut in as_completed([pool.submit(run_trial, t) for t in new]):
                r = fut.result()
                done[r["label"]] = r
                with path.open("a") as f:
                    f.write(json.dumps(r) + "\n")
    rows = []
    for t in todo:
        r = done.get(t["label"])
        if r is None:
            r = run_trial(t)
            with path.open("a") as f:
                f.write(json.dumps(r) + "\n")
        rows.append(r)
        if table:
            lr = r["learned"]
            dm = "" if lr["damping"] is None else \
                f" damping {lr['damping']:.3g}+-{lr['damping_std']:.2g}"
            ja = "" if r["jammed_at"] is None else f" jammed_at {r['jammed_at']:.3g}"
            pk = "" if r["peak_force_N"] is None else f" peak {r['peak_force_N']:.1f} N"
            if r.get("block_force_N") is not None:
                pk += f" block {r['block_force_N']:.1f} N"
            print(f"{r['label']:36s} {r['outcome']:30s}{dm}{ja}{pk}", flush=True)
    s = summary(rows)
    if table:
        for k, v in s.items():
            print(k, json.dumps(v))
    emit_json(a.json, {"groups": groups, "seed": a.seed, "trials": a.trials,
                       "base_noise": a.base_noise, "summary": s,
                       "rows": rows})


if __name__ == "__main__":
    main()
