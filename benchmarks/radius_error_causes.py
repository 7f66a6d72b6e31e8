"""Where the learned door radius' error comes from (an accuracy study of opening trials;
prints a table, never fails on figures).

    python benchmarks/radius_error_causes.py [--objects left_door,right_door,dishwasher]
        [--seeds 200,201,202] [--base-noise 1] [--frame odometry|map] [--json [FILE]]
    python benchmarks/radius_error_causes.py --model FILE --joint NAME [--seeds ...]

Runs opening trials (``open_mechanism``'s diagram, the same seeds and defaults as
``operate_trials``) and samples, every 0.1 s of the pull, the handle bar's true centre (from
the mechanism's geometry at its true opening), the hook's grip point in the true world frame
(the plant's hook pose and the controller's grip point: its seat ``P_HOOK_GRIP``, or its
finger's tip when it holds a knob there) and the grip point as the robot believes it (the
estimator's input, through the base localisation). Each position set gets a geometric circle
fit about the true hinge direction (centre and radius free), and the learned model is
compared:

- ``metric``: circle fit of the true bar centres minus the true radius (zero when "true
  radius" measures what the bar travels on);
- ``contact``: circle fit of the true grip point positions minus that of the bar centres
  (the bar does not stay where the grip point assumes it: the hook's offset from the bar);
- ``drift``: circle fit of the estimator's own track (the robot's believed frame: its
  odometry, or with ``--frame map`` its localisation) minus that of the true seat positions
  (the belief's drift while pulling: with the default odometry frame the odometry's error
  over the pull, with ``--frame map`` also the localisation's drift);
- ``fit``: the learned revolute model's radius minus the circle fit of the same track (the
  estimator's model selection and fit at its sigma_pos).

The four add up to the learned radius minus the true radius. Takes about 10-20 s of CPU per
trial.
"""

from __future__ import annotations

import argparse
import math
import statistics

import numpy as np
from scipy.optimize import least_squares

from _common import add_output_arguments, emit_json


def circle_radius(P: np.ndarray, axis: np.ndarray) -> float:
    """Radius of the geometric least-squares circle of points P (n, 3) projected on the
    plane normal to ``axis`` (centre and radius free)."""
    a = axis / np.linalg.norm(axis)
    u = np.cross(a, [1.0, 0, 0])
    if np.linalg.norm(u) < 0.1:
        u = np.cross(a, [0, 1.0, 0])
    u /= np.linalg.norm(u)
    v = np.cross(a, u)
    x, y = P @ u, P @ v
    A = np.column_stack([2 * x, 2 * y, np.ones_like(x)])
    cx, cy, c = np.linalg.lstsq(A, x * x + y * y, rcond=None)[0]
    r0 = math.sqrt(max(c + cx * cx + cy * cy, 1e-12))
    sol = least_squares(lambda p: np.hypot(x - p[0], y - p[1]) - p[2], [cx, cy, r0]).x
    return float(abs(sol[2]))


def trial(kind: str, seed: int, base_noise: float, frame: str = "odometry",
          model: str = "", joint: str = "") -> dict:
    """One opening trial with the positions of the bar, the seat and the believed seat
    (``model``, ``joint``: a user's model file and joint instead of ``kind``)."""
    from pydrake.systems.analysis import Simulator

    from mmlearn.diagrams.articulation import trials as T
    from mmlearn.diagrams.articulation.operate import MakeOperateDiagram
    from mmlearn.systems.articulation.epc_controller import DONE, PULL

    cfg = T._operate_config(kind=kind if not model else "left_door", seed=seed,
                            max_time=60.0, sigma_pos=None, priors="", mechanism_seed=None,
                            base_noise=base_noise, perception="click")
    cfg.frame = frame
    if model:
        from mmlearn.sdf.user_model import load_user_mechanism

        cfg.mechanism = load_user_mechanism(model, joint)
        cfg.kind = cfg.mechanism.kind
        kind = cfg.mechanism.name
    op = MakeOperateDiagram(cfg)
    d = op.diagram
    sim = Simulator(d)
    ctx = sim.get_mutable_context()
    op.scene.set_joint_positions(ctx, op.start_command)
    sim.Initialize()
    plant = op.scene.plant
    pctx = plant.GetMyContextFromRoot(ctx)
    hook = plant.GetBodyByName("hook", op.scene.robot)
    spec = op.mechanism
    bar, seat, phase, q_max = [], [], 0, 0.0
    while ctx.get_time() < 60.0:
        sim.AdvanceTo(ctx.get_time() + 0.1)
        phase = int(d.GetOutputPort("phase").Eval(ctx)[0])
        q = float(d.GetOutputPort("mechanism_state").Eval(ctx)[0])
        q_max = max(q_max, q)
        if phase == PULL and np.all(np.isfinite(d.GetOutputPort("hook_position").Eval(ctx))):
            ctrl = op.controller
            grip = ctrl._grip(ctrl.state(ctrl.GetMyContextFromRoot(ctx)))
            seat.append(plant.EvalBodyPoseInWorld(pctx, hook).multiply(grip))
            bar.append(spec.handle_world(q)[0])
        if phase == DONE:
            break
    run = T._Run(ctx=ctx, phase=phase, q_max=q_max, model_log=[], base_err=[], wall=1.0)
    rec = T._trial_record(op, cfg, run, build_seconds=0.0, save_track="")
    est = op.estimator.GetMyContextFromRoot(ctx).get_abstract_state(0).get_value()
    axis, _ = spec.axis_world()
    out = {"object": kind, "seed": seed, "base_noise": base_noise, "frame": frame,
           "success": rec["success"],
           "opened_deg": rec["opened"], "learned_model": rec["learned_model"],
           "true_radius_m": rec["true_radius_m"], "radius_m": rec["radius_m"],
           "axis_error_deg": rec["axis_error_deg"]}
    if rec["radius_m"] is None or len(seat) < 5:
        return out
    r_bar = circle_radius(np.array(bar), axis)
    r_seat = circle_radius(np.array(seat), axis)
    r_track = circle_radius(est.poses[:, 1, :3], axis)
    out.update(error_m=rec["radius_m"] - rec["true_radius_m"],
               metric_m=r_bar - rec["true_radius_m"], contact_m=r_seat - r_bar,
               drift_m=r_track - r_seat, fit_m=rec["radius_m"] - r_track)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--objects", default="left_door,right_door,dishwasher")
    ap.add_argument("--seeds", default="200,201,202")
    ap.add_argument("--base-noise", type=float, default=1.0)
    ap.add_argument("--model", default="", help="a user's model file (instead of --objects)")
    ap.add_argument("--joint", default="", help="the joint of --model to open")
    ap.add_argument("--frame", choices=("odometry", "map"), default="odometry",
                    help="the frame the robot works in (default: odometry)")
    add_output_arguments(ap)
    a = ap.parse_args(argv)
    objects = ["model"] if a.model else a.objects.split(",")
    rows = [trial(k, int(s), a.base_noise, a.frame, a.model, a.joint) for k in objects
            for s in a.seeds.split(",")]
    done = [r for r in rows if "error_m" in r]
    parts = ("error_m", "metric_m", "contact_m", "drift_m", "fit_m")
    summary = {p: statistics.fmean(r[p] for r in done) for p in parts} if done else {}
    if done:
        summary["mean_abs_error_m"] = statistics.fmean(abs(r["error_m"]) for r in done)
    if not emit_json(a.json, {"rows": rows, "summary": summary}):
        print(f"{'object':11s} seed  opened  true r  learned   error  metric  contact   drift"
              "     fit")
        for r in rows:
            if "error_m" not in r:
                print(f"{r['object']:11s} {r['seed']:4d}  {r['opened_deg']:5.0f}  no revolute "
                      f"model ({r['learned_model']})")
                continue
            print(f"{r['object']:11s} {r['seed']:4d}  {r['opened_deg']:5.0f}  "
                  f"{r['true_radius_m']:.3f}   {r['radius_m']:.3f}  " + "  ".join(
                      f"{r[p]:+.3f}" for p in parts) + f"  axis {r['axis_error_deg']:.1f} deg")
        if done:
            print(f"mean ({len(done)} trials)                    " + "  ".join(
                f"{summary[p]:+.3f}" for p in parts)
                  + f"   mean |error| {summary['mean_abs_error_m']:.3f}")


if __name__ == "__main__":
    main()
