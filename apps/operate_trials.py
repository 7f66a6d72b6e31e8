"""The thesis' experiment 4.4.2: five mechanisms x eight trials of opening while learning.

    python -m mmlearn.apps.operate_trials --trials 8 --json

Trials are independent and run through the sweep runner (``mmlearn.apps.common.sweep``): in
parallel processes (``--jobs``, default: all cores) or as Ray tasks (``--executor ray``),
streamed to ``--results`` (default ``operate_trials_results.jsonl``); re-running the same
command resumes, ``--report-only FILE`` redraws the table from a results file.
"""

import json
import math
import sys
from pathlib import Path

from mmlearn.apps.common import experiment
from mmlearn.apps.common.cli import UsageError, check_in_file, check_out_dir, name_list, nonneg_int, pos_int
from mmlearn.apps.common.experiment import Experiment
from mmlearn.apps.common.operate_args import add_model_args, add_trial_args, load_model_args
from mmlearn.diagrams.articulation.trials import operate_trial
from mmlearn.models.articulation.evaluation import operate_report
from mmlearn.sdf.mechanisms import KINDS


def _prior_text(priors: str) -> tuple[str | None, str]:
    """The prior database's text (sent once to every worker) and its SHA-1; a bad database
    is bad input, found here rather than in every trial."""
    import hashlib

    if not priors:
        return None, ""
    from mmlearn.models.articulation.priors import PriorDatabase

    PriorDatabase.load(priors)
    text = Path(priors).read_text()
    return text, hashlib.sha1(text.encode()).hexdigest()


def trial_specs(*, objects=KINDS, trials: int = 8, seed: int = 0, max_time: float = 60.0,
                sigma_pos: float | None = None, priors: str = "",
                mechanism_seed: int | None = None, save_tracks: str = "",
                base_noise: float | None = None, perception: str = "click",
                model: str = "", joint: str = "", model_pose: str | None = None,
                handle: str | None = None) -> list:
    """The sweep's trials, ``trials`` per object (checks the arguments, see :func:`run`);
    with ``model``, ``trials`` trials of its joint ``joint`` instead of the objects."""
    from mmlearn.apps.common.sweep import TrialSpec

    if model:
        objects = [None]

    objects = list(objects)
    if not objects:
        raise ValueError("objects: empty list; choose from " + ", ".join(KINDS))
    for k in objects:
        if k not in KINDS and not model:
            raise ValueError(f"unknown object {k!r}; choose from {', '.join(KINDS)}")
    if trials < 1:
        raise ValueError("trials must be >= 1")
    if perception not in ("click", "depth"):
        raise ValueError(f"perception must be click or depth, got {perception!r}")
    # a click trial's identity stays what it was before perception existed (results files
    # of earlier runs resume)
    extra = {} if perception == "click" else {"perception": perception}
    if not (max_time > 0 and math.isfinite(max_time)):
        raise ValueError(f"max_time must be a finite number of seconds > 0, got {max_time}")
    priors_sha1 = _prior_text(priors)[1]
    if save_tracks:
        Path(save_tracks).mkdir(parents=True, exist_ok=True)
    if model:
        # the file's absolute path, the joint and the flags' text name the trials
        extra.update(model=str(Path(model).resolve()), joint=joint, model_pose=model_pose,
                     handle=handle)
    name = f"{Path(model).name}:{joint}" if model else None
    return [TrialSpec(fn=operate_trial, seed=seed + i,
                      label=f"{k or name} seed {seed + i}",
                      params={"kind": k or "left_door", "max_time": max_time,
                              "sigma_pos": sigma_pos,
                              "mechanism_seed": mechanism_seed, "base_noise": base_noise,
                              "priors_sha1": priors_sha1,
                              "save_track": str(Path(save_tracks) / f"{k or Path(model).stem}_"
                                                f"{seed + i:03d}.log")
                              if save_tracks else "", **extra})
            for k in objects for i in range(trials)]


def _attach_sweep(res: dict, sweep) -> dict:
    res.update(wall_seconds=round(sweep.wall_s, 1), resumed=sweep.resumed,
               interrupted=sweep.interrupted, not_run=[s.label for s in sweep.missing],
               results_file=str(sweep.results) if sweep.results else None)
    return res


def run(*, objects=KINDS, trials: int = 8, seed: int = 0, jobs: int | None = None,
        max_time: float = 60.0, sigma_pos: float | None = None, priors: str = "",
        mechanism_seed: int | None = None, save_tracks: str = "",
        show_progress: bool = True, base_noise: float | None = None,
        results: str | None = None, executor: str = "local",
        ray_address: str | None = None, perception: str = "click", model: str = "",
        joint: str = "", model_pose: str | None = None, handle: str | None = None) -> dict:
    """Run the trials; ``mechanism_seed`` fixes each object's geometry (the trials then
    differ in the handle click and the start), ``save_tracks`` writes every trial's hook
    trajectory into that folder, ``priors`` uses a prior database, ``base_noise`` scales
    the base-localisation error (None: 1, 0: the base pose is known exactly),
    ``sigma_pos`` is the noise the estimator assumes (None: 0.05 m), ``perception`` where
    the handle comes from ("click" or "depth", see ``open_cabinet``); ``model`` and
    ``joint`` (with ``model_pose``, ``handle``): trials on that joint of a user's model file
    instead of ``objects`` (see ``open_cabinet --model``).

    The trials run through the sweep runner (``mmlearn.apps.common.sweep``): ``results`` is the
    JSON Lines file they are streamed to (None: a temporary one; with a file, trials already
    in it are not run again), ``executor`` ``"local"`` (a pool of ``jobs`` processes) or
    ``"ray"`` (``ray_address``: a cluster, None: a local Ray instance of ``jobs`` CPUs)."""
    from mmlearn.apps.common.sweep import run_sweep

    if jobs is not None and jobs < 1:
        raise ValueError(f"jobs must be >= 1 (or None for all cores), got {jobs}")
    specs = trial_specs(objects=objects, trials=trials, seed=seed, max_time=max_time,
                        sigma_pos=sigma_pos, priors=priors, mechanism_seed=mechanism_seed,
                        save_tracks=save_tracks, base_noise=base_noise, perception=perception,
                        model=model, joint=joint, model_pose=model_pose, handle=handle)
    sweep = run_sweep(specs, results=results, executor=executor, jobs=jobs,
                      ray_address=ray_address, shared=_prior_text(priors)[0],
                      show_progress=show_progress)
    return _attach_sweep(operate_report(sweep.lines), sweep)


def format_table(res: dict) -> str:
    lines = [f"{'object':13s} {'success':>8s} {'errors':>6s} {'right kind':>10s} "
             f"{'from (mean/max)':>17s} {'mean opened':>12s} {'radius err (mean/max)':>22s} "
             f"{'axis err':>9s}  final models"]
    for kind, row in res["per_object"].items():
        if row["mean_opened"] is None:
            op = "-"
        else:
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
        lines.append(f"{kind:13s} {row['successes']:>3d}/{row['trials']:<4d} "
                     f"{row.get('errors', 0):>6d} {rk:>10s} {ra:>17s} {op:>12s} {rad:>22s} "
                     f"{ax:>9s}  {models}")
    rate = "n/a" if res["success_rate"] is None else f"{100 * res['success_rate']:.1f}%"
    n_kind = res.get("right_kind", sum(bool(t.get("right_kind")) for t in res["trials"]
                                       if not t.get("error")))
    lines.append(f"overall: {res['successes']}/{res['total']} successes ({rate}), right kind "
                 f"{n_kind}/{res['total']}"
                 + (f" in {res['wall_seconds']} s" if res.get("wall_seconds") is not None
                    else "") + "; "
                 + f"{res.get('errors', 0)} trial(s) raised an error (not counted above)")
    if res.get("resumed"):
        lines.append(f"({res['resumed']} trial(s) read from {res.get('results_file')}, "
                     "not run again)")
    if res.get("not_run"):
        lines.append(f"interrupted: {len(res['not_run'])} trial(s) not run: "
                     + ", ".join(res["not_run"]))
    if res.get("perception") == "depth":
        lines.append("handle from the head depth camera: " + "; ".join(
            f"{k} {row.get('no_front', 0)} without a front, handle error mean/max "
            + (f"{row['mean_handle_error_m']:.4f}/{row['max_handle_error_m']:.4f} m"
               if row.get("mean_handle_error_m") is not None else "-")
            for k, row in res["per_object"].items()))
    if res.get("sigma_pos") is not None or res.get("base_noise") is not None:
        lines.append(f"(sigma_pos {res.get('sigma_pos')} m, base noise x{res.get('base_noise')})")
    lines.append("means are over the trials that ran; radius and axis errors over the trials "
                 "whose learned model had that parameter")
    for t in res["trials"]:
        if t.get("error"):
            lines.append(f"  error:  {t['object']} seed {t['seed']}: {t['error']}")
            continue
        if t["success"] and t.get("right_kind"):
            continue
        what = ("failed" if not t["success"] else "wrong kind") + (
            ", wrong kind" if not t["success"] and not t.get("right_kind") else "")
        lines.append(f"  {what}: {t['object']} seed {t['seed']}: opened {t['opened']:.2f} "
                     f"{t['unit']} ({t['outcome']}), final model {t.get('learned_model')}")
    return "\n".join(lines)


class OperateTrials(Experiment):
    name = "operate_trials"
    trials = (operate_trial,)
    description = ("Five mechanisms x N trials of opening while learning (thesis 4.4.2). Exit "
                   "status: 0 all trials ran (opened or not), 1 a trial raised an error, 2 bad "
                   "input.")
    seed_help = "seed of the first trial"
    json_help = None

    def add_arguments(self, ap):
        ap.add_argument("--trials", type=pos_int, default=8, help="trials per object")
        ap.add_argument("--objects", type=name_list(KINDS), default=list(KINDS),
                        help="comma-separated objects (default: all five)")
        add_trial_args(ap)
        ap.add_argument("--mechanism-seed", type=nonneg_int, default=None,
                        help="the same mechanism per object in every trial (trials differ in "
                             "the handle click and the robot's start)")
        ap.add_argument("--save-tracks", default="",
                        help="folder to write each trial's hook trajectory to (for "
                             "learn_priors)")
        ap.add_argument("--priors", default="",
                        help="prior database to use (from learn_priors)")
        add_model_args(ap)

    def check(self, args):
        if not args.report_only:
            check_out_dir("--save-tracks", args.save_tracks)
            check_in_file("--priors", args.priors)
            try:
                load_model_args(args)
            except ValueError as e:
                raise UsageError(str(e)) from None

    def specs(self, args):
        return trial_specs(objects=args.objects, trials=args.trials, seed=args.seed,
                           max_time=args.max_time, sigma_pos=args.sigma_pos,
                           priors=args.priors, mechanism_seed=args.mechanism_seed,
                           save_tracks=args.save_tracks, base_noise=args.base_noise,
                           perception=args.perception, model=args.model,
                           joint=args.joint, model_pose=args.model_pose, handle=args.handle)

    def shared(self, args):
        return _prior_text(args.priors)[0]

    def report(self, lines, args):
        return operate_report(lines)

    def attach_sweep(self, res, sweep, args):
        _attach_sweep(res, sweep)

    def print_table(self, res, args):
        print(format_table(res))

    def to_json(self, res):
        return json.dumps(res)

    def failed(self, res):
        return [f"{t['object']} seed {t['seed']}" for t in res["trials"] if t.get("error")]

    def interrupted(self, res):
        return bool(res.get("interrupted"))

    def error_message(self, error, args):
        return (f"--priors: {error}" if args.priors and str(args.priors) in str(error)
                else str(error))


def main(argv=None) -> int:
    return experiment.main(OperateTrials(), argv)


if __name__ == "__main__":
    sys.exit(main())
