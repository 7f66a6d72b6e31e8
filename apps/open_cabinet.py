"""Open a door or drawer with the learned model: the main demo (thesis 4.3, 4.4.2).

The robot starts about 1 m away with a noisy handle location, drives to a stance, hooks
the handle and opens the mechanism by equilibrium-point control while it learns the
mechanism's kinematic model online from its hook's trajectory.

What the robot knows: its arm's joint angles and forward kinematics exactly (the hook
position relative to its base has no error), the front's normal and the bar's direction,
and the handle only as a click within 2 cm. Its base pose it knows only through a
drifting localisation and odometry (``--base-noise``, see
``mmlearn.systems.articulation.base_localization``): the hook trajectory the estimator learns from is in
that believed world frame, so it carries the drift; the estimator assumes sigma_pos =
0.05 m (the thesis' value) and has the GP candidate. ``--base-noise 0`` gives the robot its
exact base pose.

Success is the thesis' criterion on the largest opening reached: more than 60 deg or
0.3 m (``final_opening`` is the opening after the hook let go; a dishwasher's
counterbalance spring closes it again). ``right_kind`` says whether the model at the end
was the right kind (revolute for doors, prismatic for drawers and sliding doors) and
``right_model_at`` the opening from which it held.

    python -m mmlearn.apps.open_cabinet --object left_door --seed 3 --json
"""

import json
import math
import sys
import time

import numpy as np

from mmlearn.apps.common.cli import (ArgumentParser, UsageError, check_in_file, check_out_file,
                                     fail, finish_viewing, frame_camera, make_meshcat,
                                     nonneg_float, nonneg_int, pos_float, progress_bar, save_html)
from mmlearn.sdf.mechanisms import KINDS, REVOLUTE

SUCCESS_ANGLE = math.radians(60)  # thesis: opened > 60 deg (revolute) ...
SUCCESS_DISTANCE = 0.3            # ... or > 0.3 m (prismatic)


def _angle_between(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    c = abs(float(np.dot(a, b) / (np.linalg.norm(a) * np.linalg.norm(b))))
    return math.degrees(math.acos(min(1.0, c)))


def evaluate_model(link, spec) -> dict:
    """Compare the learned link model with the mechanism's true joint: axis direction and,
    for a revolute joint, the radius of the handle bar's circle (the hook's seat, which the
    estimator tracks, holds the bar's centre)."""
    axis_true, point = spec.axis_world()
    out = {"learned_model": None if link is None else link.name, "radius_m": None,
           "true_radius_m": None, "radius_error_m": None, "axis_error_deg": None}
    if link is None:
        return out
    if link.name in ("revolute", "prismatic"):
        out["axis_error_deg"] = _angle_between(link.axis, axis_true)
    if link.name == "revolute" and spec.is_revolute:
        d = spec.handle_world(0.0)[0] - point
        r_true = float(np.linalg.norm(d - np.dot(d, axis_true) * axis_true))
        out.update(radius_m=float(link.radius), true_radius_m=r_true,
                   radius_error_m=abs(float(link.radius) - r_true))
    return out


def scene_points(op) -> np.ndarray:
    """Points (world, m) that the camera must see: the cabinet's corners, the handle over
    the front's whole travel, the robot at its start (its base, the arm up to 1.3 m) and
    its base where it will stand to open the mechanism."""
    spec = op.mechanism
    T = spec.X_WF()
    half = spec.width / 2 + 0.06 if spec.kind != "sliding_door" else spec.width + 0.06
    top = spec.bottom + spec.height + 0.03
    corners_F = np.array([[x, y, z] for x in (-spec.depth, 0.0) for y in (-half, half)
                          for z in (0.0, top)])
    pts = [corners_F @ T[:3, :3].T + T[:3, 3]]
    pts.append([spec.handle_world(q)[0] for q in np.linspace(0.0, spec.limit, 5)])
    # the mobile base (0.55 m x 0.45 m, 0.3 m high, sdf/builders.py) at its start pose and
    # the arm above it
    x, y, yaw = op.start_command[:3]
    c, s = math.cos(yaw), math.sin(yaw)
    pts.append([[x + c * dx - s * dy, y + s * dx + c * dy, z] for dx in (-0.28, 0.28)
                for dy in (-0.23, 0.23) for z in (0.0, 0.3)])
    pts.append([[x, y, 1.3]])
    # ... and where it will stand, about 0.8 m in front of the handle and up to 0.3 m to
    # its side (EpcConfig.stance_distance, stance_side), at any yaw (half-diagonal 0.36 m)
    h, n = op.true_task.handle, op.true_task.normal
    n = np.array([n[0], n[1], 0.0]) / max(np.hypot(n[0], n[1]), 1e-9)
    side = np.array([-n[1], n[0], 0.0])
    for off in (-0.3, 0.3):
        c = np.array([h[0], h[1], 0.0]) + 0.8 * n + off * side
        pts.append([c + [dx, dy, z] for dx in (-0.36, 0.36) for dy in (-0.36, 0.36)
                    for z in (0.0, 0.3)])
    return np.concatenate([np.asarray(p, float) for p in pts])


def _draw_look(meshcat, look) -> None:
    """The front the robot chose (its outline), the handle it derived (a sphere) and the
    head camera's position, in the true world frame."""
    from pydrake.geometry import Rgba, Sphere
    from pydrake.math import RigidTransform

    c = look.estimate.front.corners()
    meshcat.SetLineSegments("perception/front", c.T, np.roll(c, -1, axis=0).T, 3.0,
                            Rgba(0.1, 0.8, 0.1, 1))
    meshcat.SetObject("perception/handle", Sphere(0.015), Rgba(0.9, 0.1, 0.1, 1))
    meshcat.SetTransform("perception/handle", RigidTransform(look.estimate.handle))
    meshcat.SetObject("perception/camera", Sphere(0.03), Rgba(0.1, 0.1, 0.1, 1))
    meshcat.SetTransform("perception/camera", RigidTransform(look.X_WC[:3, 3]))


def right_kind(model_log, right: str) -> tuple[bool, float | None]:
    """Whether the model at the end of a trial was the right kind, and from which opening on.

    ``model_log``: the trial's records ``(time s, true opening, model kind or None)`` in time
    order; ``right``: the true kind ("revolute" or "prismatic"). Returns ``(ok, opening)``:
    ``ok`` is True when the last record has the right kind, ``opening`` the true opening at
    the first record of the final unbroken run of right-kind records (None when not ok)."""
    if not model_log or model_log[-1][2] != right:
        return False, None
    k = len(model_log) - 1
    while k > 0 and model_log[k - 1][2] == right:
        k -= 1
    return True, float(model_log[k][1])


def run(*, kind: str = "left_door", seed: int = 0, meshcat=None, html_out: str = "",
        max_time: float = 60.0, sigma_pos: float | None = None, show_progress: bool = True,
        realtime: bool = False, priors: str = "", mechanism_seed: int | None = None,
        save_track: str = "", base_noise: float | None = None,
        perception: str = "click") -> dict:
    """Run one trial and return its results (see the module docstring).

    ``sigma_pos``: position noise the estimator assumes, m (None = OperateConfig's 0.05);
    ``base_noise``: scale of the base-localisation and odometry error (None = 1, the
    defaults of ``BaseLocalizationConfig``; 0 = the base pose is known exactly);
    ``priors``: prior database to use (see ``learn_priors``); ``mechanism_seed``: fix the
    mechanism's geometry while ``seed`` varies the click and the start; ``save_track``:
    write the hook trajectory the model was learned from (x y z per line, in the robot's
    believed world frame); ``perception``: "click" (the robot is told the handle within
    2 cm) or "depth" (it looks with its head depth camera first and derives the handle from
    the detected front; a trial without a front is a failed trial, outcome "no front
    detected").

    The result holds ``perception``, ``front_found`` (always True for a click),
    ``handle_error_m`` (distance of the handle position the robot used from the true one,
    m, before its localisation error) and, for "depth", ``handle_source`` ("bar": from the
    bar's points, "rectangle": by the kind's convention), ``frames_found`` and
    ``look_frames``."""
    from pydrake.systems.analysis import Simulator

    from mmlearn.diagrams.articulation.operate import PERCEPTIONS, MakeOperateDiagram, OperateConfig
    from mmlearn.diagrams.articulation.operate_perception import NoFrontDetected
    from mmlearn.models.common.fileio import atomic_write_text
    from mmlearn.systems.articulation.epc_controller import DONE, PHASE_NAMES, PULL

    if kind not in KINDS:
        raise ValueError(f"object must be one of {', '.join(KINDS)}; got {kind!r}")
    if not (max_time > 0 and math.isfinite(max_time)):
        raise ValueError(f"max_time must be a finite number of seconds > 0, got {max_time}")
    if perception not in PERCEPTIONS:
        raise ValueError(f"perception must be one of {', '.join(PERCEPTIONS)}; got "
                         f"{perception!r}")
    cfg = OperateConfig(kind=kind, seed=seed, priors=priors, mechanism_seed=mechanism_seed,
                        perception=perception)
    if sigma_pos is not None:
        cfg.sigma_pos = sigma_pos
    if base_noise is not None:
        cfg.base_noise = base_noise
    if meshcat is None and html_out:
        meshcat = make_meshcat(announce=False)
    t_build = time.perf_counter()
    try:
        op = MakeOperateDiagram(cfg, meshcat=meshcat)
    except NoFrontDetected as e:
        # the robot saw no front it could open: a failed trial, nothing simulated
        return {"object": kind, "seed": seed, "success": False, "opened": 0.0,
                "final_opening": 0.0, "unit": "deg" if kind in REVOLUTE else "m",
                "outcome": "no front detected",
                "perception": perception, "front_found": False, "handle_error_m": None,
                "handle_source": None, "frames_found": e.look.frames_found,
                "look_frames": e.look.frames, "learned_model": None, "right_kind": False,
                "base_noise": cfg.base_noise, "sigma_pos": cfg.sigma_pos,
                "track_saved": None, "sim_seconds": 0.0, "wall_seconds": 0.0,
                "true_kind": "revolute" if kind in REVOLUTE else "prismatic",
                "html_out": None}
    build_seconds = time.perf_counter() - t_build
    d = op.diagram
    if meshcat is not None and op.look is not None:
        _draw_look(meshcat, op.look)
    if meshcat is not None:
        # look at the mechanism from in front and to the side, so that the robot (which
        # starts in front of it) does not hide the front; frame the robot at its start and
        # the cabinet with the front's whole swing
        n = op.true_task.normal
        side = np.cross([0, 0, 1.0], n)
        frame_camera(meshcat, scene_points(op), view_from=1.0 * n + 1.6 * side + [0, 0, 1.0])
    simulator = Simulator(d)
    ctx = simulator.get_mutable_context()
    op.scene.set_joint_positions(ctx, op.start_command)
    if realtime:
        simulator.set_target_realtime_rate(1.0)
    vis = op.scene.visualizer
    if vis is not None:
        vis.StartRecording(False)
    simulator.Initialize()
    t0 = time.perf_counter()
    bar = progress_bar(int(max_time), f"{kind} seed {seed}", unit="sim s",
                       enabled=show_progress)
    phase = 0
    right = "revolute" if op.mechanism.is_revolute else "prismatic"
    to_unit = math.degrees if op.mechanism.is_revolute else float
    model_port = d.GetOutputPort("object_model")
    # (time, true opening, kind of the model the controller is given), every 0.25 s from
    # the start of the pull
    model_log = []
    base_err = []  # |believed - true| base position, m
    q_max = 0.0  # largest opening reached (the thesis: "opened it through ...")
    while ctx.get_time() < max_time - 1e-9:
        simulator.AdvanceTo(min(max_time, ctx.get_time() + 0.25))
        bar.update(0.25)
        bar.set_postfix_str(PHASE_NAMES[phase])
        phase = int(d.GetOutputPort("phase").Eval(ctx)[0])
        q_max = max(q_max, float(d.GetOutputPort("mechanism_state").Eval(ctx)[0]))
        base_err.append(float(np.hypot(*d.GetOutputPort("base_error").Eval(ctx)[:2])))
        if phase >= PULL:
            m = model_port.Eval(ctx)
            model_log.append((round(float(ctx.get_time()), 3),
                              to_unit(float(d.GetOutputPort("mechanism_state").Eval(ctx)[0])),
                              m.edges[0].model.name if m is not None and m.edges else None))
        if phase == DONE:
            break
    bar.close()
    wall = time.perf_counter() - t0
    q = float(d.GetOutputPort("mechanism_state").Eval(ctx)[0])
    spec = op.mechanism
    est_ctx = op.estimator.GetMyContextFromRoot(ctx)
    est_state = est_ctx.get_abstract_state(0).get_value()
    obj = est_state.model
    link = obj.edges[0].model if obj is not None else None
    track = est_state.poses[:, 1, :3] if est_state.poses.shape[0] else np.zeros((0, 3))
    ctrl = op.controller.state(op.controller.GetMyContextFromRoot(ctx))
    q_max = max(q_max, q)
    if spec.is_revolute:
        opened, unit, success = math.degrees(q_max), "deg", q_max > SUCCESS_ANGLE
    else:
        opened, unit, success = q_max, "m", q_max > SUCCESS_DISTANCE
    result = {"object": kind, "seed": seed, "success": bool(success), "opened": opened,
              "final_opening": to_unit(q),
              "unit": unit, "outcome": ctrl.outcome or PHASE_NAMES[phase]}
    result.update(evaluate_model(link, spec))
    used = (op.look.estimate.handle if op.look is not None else op.true_task.handle)
    result.update({"perception": perception, "front_found": True,
                   "handle_error_m": float(np.linalg.norm(used - spec.handle_world(0.0)[0])),
                   "handle_source": None if op.look is None else op.look.estimate.source,
                   "frames_found": None if op.look is None else op.look.frames_found,
                   "look_frames": None if op.look is None else op.look.frames,
                   "build_seconds": round(build_seconds, 3)})
    # the model's kind over the trial, and the opening from which the final right kind held
    ok, right_at = right_kind(model_log, right)
    result.update({"right_kind": ok, "right_model_at": right_at, "true_kind": right,
                   "model_log": model_log,
                   "base_noise": cfg.base_noise, "sigma_pos": cfg.sigma_pos,
                   "base_error_max_m": max(base_err) if base_err else 0.0})
    if priors:
        result["priors"] = priors
    result["track_saved"] = None
    if save_track and track.shape[0]:
        result["track_saved"] = save_track
        atomic_write_text(save_track, f"# hook trajectory, {kind}, seed {seed} (x y z, m)\n"
                          + "\n".join(" ".join(f"{v:.6f}" for v in row) for row in track)
                          + "\n")
    result.update({"estimated_opening": ctrl.opening, "track_length": int(track.shape[0]),
                   "sim_seconds": float(ctx.get_time()), "wall_seconds": round(wall, 3),
                   "realtime_factor": round(float(ctx.get_time() / wall), 2),
                   "html_out": None})
    if vis is not None:
        vis.StopRecording()
        vis.PublishRecording()
        if html_out:
            result["html_out"] = str(save_html(meshcat, html_out))
    return result


def add_trial_args(ap) -> None:
    """The flags of one opening trial that open_cabinet and operate_trials share."""
    ap.add_argument("--max-time", type=pos_float, default=60.0,
                    help="simulated seconds at most")
    ap.add_argument("--sigma-pos", type=pos_float, default=None,
                    help="position noise the estimator assumes, m (default 0.05, the "
                         "thesis' value)")
    ap.add_argument("--base-noise", type=nonneg_float, default=None,
                    help="scale of the robot's base-localisation and odometry error (default "
                         "1: 0.05 m RMS, 1.1 deg, drifting; 0: base pose known exactly)")
    ap.add_argument("--perception", default="click", choices=["click", "depth"],
                    help="where the handle comes from: click = told within 2 cm; depth = "
                         "the robot looks with its head depth camera, detects the front and "
                         "derives the handle")


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
    args = ap.parse_args(argv)
    try:
        check_out_file("--html-out", args.html_out)
        check_out_file("--save-track", args.save_track)
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
                base_noise=args.base_noise, perception=args.perception)
    except ValueError as e:
        return fail(ap.prog, str(e))
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
        if r["perception"] == "depth":
            print(f"handle from the depth camera ({r['handle_source']}, front in "
                  f"{r['frames_found']} of {r['look_frames']} frames): error "
                  f"{r['handle_error_m']:.3f} m")
        print(f"{verdict}: {r['object']} opened {r['opened']:.2f} {r['unit']} "
              f"({r['outcome']}); learned model: {r['learned_model']}")
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
        print(f"{r['sim_seconds']:.1f} s simulated in {r['wall_seconds']:.1f} s "
              f"(real-time factor {r['realtime_factor']})")
    finish_viewing(html_out=None if args.json else r["html_out"], live=args.meshcat)
    return 0 if r["success"] else 1


if __name__ == "__main__":
    sys.exit(main())
