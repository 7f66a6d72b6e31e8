"""Open a door or drawer with the learned model: the main demo (thesis 4.3, 4.4.2).

The robot starts about 1 m away with a noisy handle location, drives to a stance, hooks
the handle and opens the mechanism by equilibrium-point control while it learns the
mechanism's kinematic model online from its hook's trajectory.

What the robot knows: its arm's joint angles and forward kinematics exactly (the hook
position relative to its base has no error), the front's normal and the bar's direction,
and the handle only as a click within 2 cm. Its base pose it knows only through a
drifting localisation and odometry (``--base-noise``, see
``mmlearn.systems.articulation.base_localization``). While it opens the mechanism it works
in its odometry frame (anchored at its localisation's belief at the start): the hook
trajectory the estimator learns from drifts only by the odometry's error over the pull
(a few percent of the base's motion), not by the localisation's drift; the estimator
assumes sigma_pos = 0.05 m (the thesis' value) and has the GP candidate. ``--base-noise 0``
gives the robot its exact base pose.

Success is the thesis' criterion on the largest opening reached: more than 60 deg or
0.3 m (``final_opening`` is the opening after the hook let go; a dishwasher's
counterbalance spring closes it again). ``right_kind`` says whether the model at the end
was the right kind (revolute for doors, prismatic for drawers and sliding doors) and
``right_model_at`` the opening from which it held.

While it pulls, the robot also learns the mechanism's damping, friction and closing spring
from its wrist force (JSON ``dynamics``; ``--damping``, ``--friction``, ``--spring`` set the
true values, ``--save-model`` writes the learned model with them, as SDFormat or the
project's model format), and stops pulling at a mechanism that no longer follows the model:
``--jam-at Q`` (a hard stop) gives outcome "jammed" with ``jammed_at``, ``--locked`` outcome
"locked" (exit status 1); see docs/mechanism_dynamics.md.

    python -m mmlearn.apps.open_cabinet --object left_door --seed 3 --json
    python -m mmlearn.apps.open_cabinet --object drawer --damping 20 --save-model d.sdf

``--model FILE --joint NAME`` opens a joint of your own SDFormat or URDF furniture instead
(placement, handle and pulling direction derived from the file, see docs/user_models.md);
the JSON then also holds ``true_joint``, the joint as the file gives it. The mechanism flags
(``--damping`` ... ``--locked``) apply to the project's objects; a user model brings its own.
"""

import json
import sys

import numpy as np

from mmlearn.apps.common.cli import (ArgumentParser, UsageError, check_in_file, check_out_file,
                                     fail, finish_viewing, frame_camera, make_meshcat,
                                     nonneg_int, save_html)
from mmlearn.apps.common.operate_args import (add_mechanism_args, add_model_args,
                                              add_trial_args, load_model_args,
                                              mechanism_options)
from mmlearn.sdf.mechanisms import KINDS, REVOLUTE


def run(*, kind: str = "left_door", seed: int = 0, meshcat=None, html_out: str = "",
        max_time: float = 60.0, sigma_pos: float | None = None, show_progress: bool = True,
        realtime: bool = False, priors: str = "", mechanism_seed: int | None = None,
        save_track: str = "", base_noise: float | None = None,
        perception: str = "click", model: str = "", joint: str = "", model_pose=None,
        handle=None, mechanism_options: dict | None = None, save_model: str = "",
        learn_dynamics: bool | None = None) -> dict:
    """Run one trial and return its results: :func:`mmlearn.diagrams.articulation.trials.
    open_mechanism`, viewed in ``meshcat`` (its camera framing the robot and the cabinet's
    whole swing) and, with ``html_out``, recorded there as standalone HTML."""
    from mmlearn.diagrams.articulation.trials import open_mechanism, scene_points

    if meshcat is None and html_out:
        meshcat = make_meshcat(announce=False)

    def frame(op):
        # look at the mechanism from in front and to the side, so that the robot (which
        # starts in front of it) does not hide the front; frame the robot at its start and
        # the cabinet with the front's whole swing
        n = op.true_task.normal
        side = np.cross([0, 0, 1.0], n)
        frame_camera(meshcat, scene_points(op), view_from=1.0 * n + 1.6 * side + [0, 0, 1.0])

    result = open_mechanism(kind=kind, seed=seed, meshcat=meshcat, max_time=max_time,
                            sigma_pos=sigma_pos, show_progress=show_progress,
                            realtime=realtime, priors=priors, mechanism_seed=mechanism_seed,
                            save_track=save_track, base_noise=base_noise,
                            perception=perception,
                            on_built=frame if meshcat is not None else None,
                            model=model, joint=joint, model_pose=model_pose, handle=handle,
                            mechanism_options=mechanism_options, save_model=save_model,
                            learn_dynamics=learn_dynamics)
    if meshcat is not None and html_out and result["front_found"]:
        result["html_out"] = str(save_html(meshcat, html_out))
    return result


def _model_line(mech) -> str:
    """What the robot derived from the user's model."""
    tj = mech.true_joint()
    where = {"geometry": f"from its geometry ({mech.handle_geometry})", "given": "given",
             "fallback": "NOT found on the geometry: put on the front's "
                         + ("edge away from the hinge" if mech.is_revolute else "top edge")}
    h = ", ".join(f"{v:.3f}" for v in tj["handle"])
    r = f", radius at the handle {tj['radius_m']:.3f} m" if mech.is_revolute else ""
    return (f"{mech.name}: {mech.joint_type} joint (like a {mech.kind}{r}); handle at ({h}) "
            f"m {where[mech.handle_source]}")


def _check_options(kind: str, seed: int, options: dict) -> None:
    """Bad mechanism options (a jam beyond the end stop, ...) as a UsageError."""
    if not options:
        return
    from mmlearn.diagrams.articulation.mechanism_dynamics import apply_mechanism_options
    from mmlearn.sdf.mechanisms import sample_mechanism

    import numpy as np

    spec = sample_mechanism(kind, np.random.default_rng([seed, KINDS.index(kind)]))
    try:
        apply_mechanism_options(spec, **options)
    except ValueError as e:
        flag = "--jam-at" if "jam_at" in str(e) else "--" + str(e).split()[0]
        raise UsageError(f"{flag}: {e}") from None


def _print_dynamics(r: dict) -> None:
    """The learned dynamics against the true ones, one line each."""
    d = r.get("dynamics") or {}
    learned, true, u = d, d.get("true", {}), d.get("units", {})
    if not d.get("learned"):
        print("dynamics: not learned (no revolute or prismatic model)")
        return
    for k in ("damping", "friction", "stiffness"):
        print(f"{k}: learned {learned[k]:.3g} +- {learned[k + '_std']:.2g} {u.get(k, '')}, "
              f"true {true.get(k, 0.0):.3g}")
    if r.get("model_saved"):
        print(f"learned model with its dynamics written to {r['model_saved']}")


def main(argv=None) -> int:
    ap = ArgumentParser(
        prog="python -m mmlearn.apps.open_cabinet",
        description="A mobile robot with a hook opens a door or drawer while learning its "
                    "kinematic model (equilibrium-point control along the learned model). "
                    "Exit status: 0 opened, 1 not opened, 2 bad input.")
    ap.add_argument("--object", default="left_door", choices=list(KINDS))
    ap.add_argument("--seed", type=nonneg_int, default=0)
    add_trial_args(ap)
    ap.add_argument("--priors", default="",
                    help="prior database (JSON from learn_priors / operate_trials "
                         "--save-tracks) to use while learning")
    ap.add_argument("--mechanism-seed", type=nonneg_int, default=None,
                    help="fix the mechanism's geometry (the seed then varies the handle "
                         "click and the robot's start)")
    ap.add_argument("--save-track", default="", help="write the hook trajectory to a file")
    ap.add_argument("--meshcat", action="store_true", help="show the trial live in Meshcat")
    ap.add_argument("--html-out", default="", help="save the Meshcat recording as HTML")
    ap.add_argument("--json", action="store_true", help="print the result as JSON")
    add_model_args(ap)
    add_mechanism_args(ap)
    args = ap.parse_args(argv)
    options = mechanism_options(args, revolute=args.object in REVOLUTE)
    try:
        mech = load_model_args(args)
        if mech is not None and (options or args.save_model):
            raise ValueError("--damping, --friction, --spring, --jam-at, --locked and "
                             "--save-model apply to the project's objects; your --model "
                             "brings its own mechanism")
    except ValueError as e:
        return fail(ap.prog, str(e))
    try:
        check_out_file("--html-out", args.html_out)
        check_out_file("--save-track", args.save_track)
        check_out_file("--save-model", args.save_model)
        if args.save_model and not args.save_model.lower().endswith(
                (".sdf", ".json", ".yaml", ".yml")):
            raise UsageError(f"--save-model: use a .sdf, .json, .yaml or .yml file, got "
                             f"{args.save_model}")
        if mech is None:
            _check_options(args.object, args.seed, options)
        if args.priors:
            from mmlearn.models.articulation.priors import PriorDatabase

            check_in_file("--priors", args.priors)
            PriorDatabase.load(args.priors)
    except (UsageError, ValueError, OSError) as e:
        msg = str(e)
        return fail(ap.prog, msg if msg.startswith("--") else f"--priors: {msg}")
    meshcat = make_meshcat() if args.meshcat else None
    try:
        r = run(kind=args.object, seed=args.seed, meshcat=meshcat, html_out=args.html_out,
                max_time=args.max_time, sigma_pos=args.sigma_pos,
                show_progress=not args.json, realtime=args.meshcat, priors=args.priors,
                mechanism_seed=args.mechanism_seed, save_track=args.save_track,
                base_noise=args.base_noise, perception=args.perception,
                model=args.model, joint=args.joint, model_pose=args.model_pose,
                handle=args.handle, mechanism_options=options, save_model=args.save_model,
                learn_dynamics=True if args.learn_dynamics else None)
    except ValueError as e:
        return fail(ap.prog, str(e))
    if r["outcome"] in ("jammed", "locked"):
        if args.json:
            print(json.dumps(r))
        where = (f" at {r['jammed_at']:.2f} {r['unit']}" if r.get("jammed_at") is not None
                 else "")
        force = r.get("block_force_N")
        force = r["peak_force_N"] if force is None else force
        print(f"{r['object']}: {r['outcome']}{where}; stopped pulling at a wrist force of "
              f"{force:.1f} N", file=sys.stderr)
        return 1
    if args.save_track and r["track_saved"] is None:
        print(f"--save-track: nothing written to {args.save_track}: the estimator received "
              f"no hook observations", file=sys.stderr)
    if args.json:
        print(json.dumps(r))
    else:
        verdict = "SUCCESS" if r["success"] else "FAILED"
        if not r["front_found"]:
            print(f"FAILED: {r['object']}: no front detected")
            return 1
        if mech is not None:
            print(_model_line(mech))
        if r["perception"] == "depth":
            print(f"handle from the depth camera ({r['handle_source']}, front in "
                  f"{r['frames_found']} of {r['look_frames']} frames): error "
                  f"{r['handle_error_m']:.3f} m")
        print(f"{verdict}: {r['object']} opened {r['opened']:.2f} {r['unit']} (the "
              f"mechanism's largest true opening; {r['outcome']})")
        span = r.get("model_span")
        print(f"learned model: {r['learned_model']}"
              + ("" if span is None else f", fitted to a hook track spanning {span:.2f} "
                 f"{r['unit']} (the range drawn in the recording)"))
        if r["radius_error_m"] is not None:
            print(f"learned radius {r['radius_m']:.3f} m, true {r['true_radius_m']:.3f} m "
                  f"(error {r['radius_error_m']:.3f} m), axis error "
                  f"{r['axis_error_deg']:.1f} deg")
        elif r["axis_error_deg"] is not None:
            print(f"learned axis error {r['axis_error_deg']:.1f} deg")
        if r["right_kind"]:
            print(f"the model was the right kind ({r['true_kind']}) from an opening of "
                  f"{r['right_model_at']:.2f} {r['unit']} on")
        else:
            print(f"the model was NOT the right kind ({r['true_kind']}) at the end")
        if options or args.save_model or args.learn_dynamics:
            _print_dynamics(r)
        print(f"{r['sim_seconds']:.1f} s simulated in {r['wall_seconds']:.1f} s "
              f"(real-time factor {r['realtime_factor']}; {r['cpu_seconds']:.1f} s CPU)")
    finish_viewing(html_out=None if args.json else r["html_out"], live=args.meshcat)
    return 0 if r["success"] else 1


if __name__ == "__main__":
    sys.exit(main())
