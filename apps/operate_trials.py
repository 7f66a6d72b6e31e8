"""The thesis' experiment 4.4.2: five mechanisms x eight trials of opening while learning.

    python -m mmlearn.apps.operate_trials --trials 8 --json

Trials are independent and run in parallel processes (``--jobs``, default: all cores).
"""

import argparse
import json
import os
import sys
import time
from pathlib import Path
from concurrent.futures import ProcessPoolExecutor, as_completed

import numpy as np

from mmlearn.apps._common import progress
from mmlearn.sdf.mechanisms import KINDS


def _one(args):
    kind, seed, max_time, sigma_pos, priors, mechanism_seed, tracks, base_noise = args
    from mmlearn.apps.open_cabinet import run

    try:
        return run(kind=kind, seed=seed, max_time=max_time, sigma_pos=sigma_pos,
                   priors=priors, mechanism_seed=mechanism_seed, show_progress=False,
                   save_track=str(Path(tracks) / f"{kind}_{seed:03d}.log") if tracks else "",
                   base_noise=base_noise)
    except Exception as e:  # a crashed trial is a failed trial, reported with its reason
        revolute = kind in ("left_door", "right_door", "dishwasher")
        return {"object": kind, "seed": seed, "success": False, "opened": 0.0,
                "unit": "deg" if revolute else "m",
                "outcome": f"error: {type(e).__name__}: {e}", "learned_model": None,
                "radius_error_m": None, "axis_error_deg": None, "right_kind": False,
                "right_model_at": None, "true_kind": "revolute" if revolute else "prismatic",
                "model_log": [], "sim_seconds": 0.0, "wall_seconds": 0.0}


def summarize(trials: list[dict]) -> dict:
    """Per-object success rate, mean opening, radius and axis errors, and how many trials
    ended with the right kind of model (and the mean opening from which it held)."""
    table = {}
    for kind in dict.fromkeys(t["object"] for t in trials):
        ts = [t for t in trials if t["object"] == kind]
        radius = [t["radius_error_m"] for t in ts if t.get("radius_error_m") is not None]
        right_at = [t["right_model_at"] for t in ts if t.get("right_model_at") is not None]
        axis = [t["axis_error_deg"] for t in ts if t.get("axis_error_deg") is not None]
        table[kind] = {
            "trials": len(ts),
            "successes": sum(t["success"] for t in ts),
            "mean_opened": float(np.mean([t["opened"] for t in ts])),
            "unit": ts[0]["unit"],
            "mean_radius_error_m": float(np.mean(radius)) if radius else None,
            "max_radius_error_m": float(np.max(radius)) if radius else None,
            "mean_axis_error_deg": float(np.mean(axis)) if axis else None,
            "right_kind": sum(bool(t.get("right_kind")) for t in ts),
            "success_and_right_kind": sum(bool(t["success"] and t.get("right_kind"))
                                          for t in ts),
            "mean_right_model_at": float(np.mean(right_at)) if right_at else None,
            "max_right_model_at": float(np.max(right_at)) if right_at else None,
            "models": {m: sum(t["learned_model"] == m for t in ts)
                       for m in dict.fromkeys(t["learned_model"] for t in ts)},
        }
    return table


def run(*, objects=KINDS, trials: int = 8, seed: int = 0, jobs: int | None = None,
        max_time: float = 60.0, sigma_pos: float | None = None, priors: str = "",
        mechanism_seed: int | None = None, save_tracks: str = "",
        show_progress: bool = True, base_noise: float | None = None) -> dict:
    """Run the trials; ``mechanism_seed`` fixes each object's geometry (the trials then
    differ in the handle click and the start), ``save_tracks`` writes every trial's hook
    trajectory into that folder, ``priors`` uses a prior database, ``base_noise`` scales
    the base-localisation error (None: 1, 0: the base pose is known exactly),
    ``sigma_pos`` is the noise the estimator assumes (None: 0.05 m)."""
    for k in objects:
        if k not in KINDS:
            raise ValueError(f"unknown object {k!r}; choose from {', '.join(KINDS)}")
    if trials < 1:
        raise ValueError("trials must be >= 1")
    jobs = jobs or os.cpu_count() or 1
    if save_tracks:
        Path(save_tracks).mkdir(parents=True, exist_ok=True)
    work = [(k, seed + i, max_time, sigma_pos, priors, mechanism_seed, save_tracks, base_noise)
            for k in objects for i in range(trials)]
    t0 = time.perf_counter()
    results = []
    with ProcessPoolExecutor(max_workers=jobs) as pool:
        futures = [pool.submit(_one, w) for w in work]
        for f in progress(as_completed(futures), desc="trials", unit="trial",
                          enabled=show_progress, total=len(futures)):
            results.append(f.result())
    order = {(w[0], w[1]): i for i, w in enumerate(work)}
    results.sort(key=lambda r: order[(r["object"], r["seed"])])
    n_ok = sum(r["success"] for r in results)
    n_kind = sum(bool(r.get("right_kind")) for r in results)
    first = next((r for r in results if "sigma_pos" in r), {})
    return {"trials": results, "success_rate": n_ok / len(results), "successes": n_ok,
            "right_kind": n_kind, "right_kind_rate": n_kind / len(results),
            "total": len(results), "per_object": summarize(results),
            "sigma_pos": first.get("sigma_pos", sigma_pos),
            "base_noise": first.get("base_noise", base_noise),
            "wall_seconds": round(time.perf_counter() - t0, 1)}


def format_table(res: dict) -> str:
    lines = [f"{'object':13s} {'success':>8s} {'right kind':>10s} {'from (mean/max)':>17s} "
             f"{'mean opened':>12s} {'radius err (mean/max)':>22s} {'axis err':>9s}  "
             f"final models"]
    for kind, row in res["per_object"].items():
        op = f"{row['mean_opened']:.1f} {row['unit']}" if row["unit"] == "deg" else \
            f"{row['mean_opened']:.3f} m"
        rad = (f"{row['mean_radius_error_m']:.4f}/{row['max_radius_error_m']:.4f} m"
               if row["mean_radius_error_m"] is not None else "-")
        ax = (f"{row['mean_axis_error_deg']:.1f} deg"
              if row["mean_axis_error_deg"] is not None else "-")
        models = ", ".join(f"{m}:{c}" for m, c in row["models"].items())
        ra, rm = row.get("mean_right_model_at"), row.get("max_right_model_at")
        ra = "-" if ra is None else (f"{ra:.0f}/{rm:.0f} deg" if row["unit"] == "deg"
                                     else f"{ra:.2f}/{rm:.2f} m")
        rk = f"{row.get('right_kind', 0)}/{row['trials']}"
        lines.append(f"{kind:13s} {row['successes']:>3d}/{row['trials']:<4d} {rk:>10s} "
                     f"{ra:>17s} {op:>12s} {rad:>22s} {ax:>9s}  {models}")
    n_kind = res.get("right_kind", sum(bool(t.get("right_kind")) for t in res["trials"]))
    lines.append(f"overall: {res['successes']}/{res['total']} successes "
                 f"({100 * res['success_rate']:.1f}%), right kind {n_kind}/{res['total']} "
                 f"in {res['wall_seconds']} s")
    if res.get("sigma_pos") is not None or res.get("base_noise") is not None:
        lines.append(f"(sigma_pos {res.get('sigma_pos')} m, base noise x{res.get('base_noise')})")
    for t in res["trials"]:
        if t["success"] and t.get("right_kind"):
            continue
        what = ("failed" if not t["success"] else "wrong kind") + (
            ", wrong kind" if not t["success"] and not t.get("right_kind") else "")
        lines.append(f"  {what}: {t['object']} seed {t['seed']}: opened {t['opened']:.2f} "
                     f"{t['unit']} ({t['outcome']}), final model {t.get('learned_model')}")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m mmlearn.apps.operate_trials",
                                 description="Five mechanisms x N trials of opening while "
                                             "learning (thesis 4.4.2).")
    ap.add_argument("--trials", type=int, default=8, help="trials per object")
    ap.add_argument("--objects", default=",".join(KINDS),
                    help="comma-separated objects (default: all five)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the first trial")
    ap.add_argument("--jobs", type=int, default=None, help="parallel processes")
    ap.add_argument("--max-time", type=float, default=60.0)
    ap.add_argument("--sigma-pos", type=float, default=None,
                    help="position noise the estimator assumes, m (default 0.05, the "
                         "thesis' value)")
    ap.add_argument("--base-noise", type=float, default=None,
                    help="scale of the robot's base-localisation and odometry error (default "
                         "1: 0.05 m RMS, 1.1 deg, drifting; 0: base pose known exactly)")
    ap.add_argument("--mechanism-seed", type=int, default=None,
                    help="the same mechanism per object in every trial (trials differ in "
                         "the handle click and the robot's start)")
    ap.add_argument("--save-tracks", default="",
                    help="folder to write each trial's hook trajectory to (for learn_priors)")
    ap.add_argument("--priors", default="", help="prior database to use (from learn_priors)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    try:
        res = run(objects=[o for o in args.objects.split(",") if o], trials=args.trials,
                  seed=args.seed, jobs=args.jobs, max_time=args.max_time,
                  sigma_pos=args.sigma_pos, priors=args.priors,
                  mechanism_seed=args.mechanism_seed, save_tracks=args.save_tracks,
                  show_progress=not args.json, base_noise=args.base_noise)
    except ValueError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(res))
    else:
        print(format_table(res))
    return 0


if __name__ == "__main__":
    sys.exit(main())
