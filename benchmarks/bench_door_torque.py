"""Diagnostic: where the torque on a door goes while the robot opens it with the dynamics
monitor, and which step of the estimate loses the damping (prints a table, never fails).

    python benchmarks/bench_door_torque.py [--seeds 700,701] [--damping 3]
        [--base-noise S] [--json [FILE]]

Every 10 ms of one ``open_cabinet`` door trial it records the simulator's door angle and
rate, the generalised contact force on the door joint, the torque about the hinge of every
contact on the door by the body that touches it, and the wrist sensor's noise-free force;
it keeps the monitor's samples (hook positions in the robot's believed world frame, wrist
forces) and the learned model. It then fits the damping (the regression of
:func:`~mmlearn.models.articulation.dynamics.fit_dynamics`) from four sources, each step
closer to what the robot has:

1. ``contact``: the hook's contact torque on the door against the true rate: the
   simulator's own balance (should give the true damping);
2. ``wrist_true_geometry``: the wrist force times the true hinge lever arm at the true
   handle, against the true rate: does the sensor carry the whole torque?
3. ``wrist_true_q_local_rate``: as 2 at the monitor's samples, with the rate from the
   monitor's local quadratic fits of the true angle;
4. ``pipeline``: the monitor's estimate (opening, rate and lever arm from the learned
   model);

and reports the learned and true handle radius, the radius factor (r_learned / r_true)^2
by which a radius error scales a damping in N m s/rad, and the pipeline's damping divided
by it.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from _common import add_output_arguments, emit_json
from mmlearn.systems.articulation.base_localization import FRAMES


def record_trial(seed: int, damping: float, base_noise: float | None,
                 frame: str = "odometry") -> dict:
    """Simulate one door trial with the monitor, recording the torque balance."""
    from pydrake.systems.analysis import Simulator

    from mmlearn.diagrams.articulation.operate import MakeOperateDiagram, OperateConfig
    from mmlearn.systems.articulation.epc_controller import DONE
    from mmlearn.systems.articulation.jam_monitor import DynamicsMonitorConfig

    cfg = OperateConfig(kind="left_door", seed=seed, mechanism_options={"damping": damping},
                        monitor=DynamicsMonitorConfig(), frame=frame)
    if base_noise is not None:
        cfg.base_noise = base_noise
    op = MakeOperateDiagram(cfg)
    sim = Simulator(op.diagram)
    ctx = sim.get_mutable_context()
    op.scene.set_joint_positions(ctx, op.start_command)
    sim.Initialize()
    plant = op.scene.plant
    pctx = plant.GetMyContextFromRoot(ctx)
    mech = op.scene.mechanism
    inspector = op.scene.scene_graph.model_inspector()
    axis, p_axis = op.mechanism.axis_world()
    front = plant.GetBodyByName("front", mech).index()
    sensor_ctx = op.force_sensor.GetMyContextFromRoot(ctx)
    phase = op.diagram.GetOutputPort("phase")
    rows = []
    while ctx.get_time() < 60.0:
        sim.AdvanceTo(ctx.get_time() + 0.01)
        per = {}
        cr = plant.get_contact_results_output_port().Eval(pctx)
        pairs = []
        for i in range(cr.num_point_pair_contacts()):
            c = cr.point_pair_contact_info(i)
            pairs.append((c.bodyA_index(), c.bodyB_index(), -c.contact_force(),
                          np.zeros(3), c.contact_point()))
        for i in range(cr.num_hydroelastic_contacts()):
            c = cr.hydroelastic_contact_info(i)
            s = c.contact_surface()
            a = plant.GetBodyFromFrameId(inspector.GetFrameId(s.id_M())).index()
            b = plant.GetBodyFromFrameId(inspector.GetFrameId(s.id_N())).index()
            F = c.F_Ac_W()
            pairs.append((a, b, F.translational(), F.rotational(), s.centroid()))
        for a, b, f_on_a, m_on_a, p in pairs:   # force and moment on body A at p
            for body, other, sign in ((a, b, 1.0), (b, a, -1.0)):
                if body == front:
                    name = plant.get_body(other).name()
                    tq = float((np.cross(p - p_axis, sign * f_on_a) + sign * m_on_a) @ axis)
                    per[name] = per.get(name, 0.0) + tq
        rows.append((ctx.get_time(), plant.GetPositions(pctx, mech)[0],
                     plant.GetVelocities(pctx, mech)[0],
                     plant.get_generalized_contact_forces_output_port(mech).Eval(pctx)[0],
                     op.force_sensor.true_force(sensor_ctx), per))
        if int(phase.Eval(ctx)[0]) == DONE:
            break
    s = op.monitor.state(op.monitor.GetMyContextFromRoot(ctx))
    est = op.estimator.GetMyContextFromRoot(ctx).get_abstract_state(0).get_value()
    link = est.model.edges[0].model if est.model is not None and est.model.edges else None
    return {"rows": rows, "monitor": s, "link": link, "spec": op.mechanism}


def analyse(rec: dict, damping: float) -> dict:
    """The damping from each source (see the module docstring)."""
    from mmlearn.models.articulation.dynamics import (fit_dynamics, generalized_samples,
                                                      local_derivatives)

    spec, rows, s, link = rec["spec"], rec["rows"], rec["monitor"], rec["link"]
    axis, p_axis = spec.axis_world()
    t = np.array([r[0] for r in rows])
    q, v = np.array([r[1] for r in rows]), np.array([r[2] for r in rows])
    gcf = np.array([r[3] for r in rows])
    F = np.array([r[4] for r in rows])
    bodies = sorted({k for r in rows for k in r[5]})
    contact = {k: np.array([r[5].get(k, 0.0) for r in rows]) for k in bodies}
    vd = np.gradient(v, t)
    lever = np.array([np.cross(axis, spec.handle_world(x)[0] - p_axis) for x in q])
    wrist = -np.sum(F * lever, axis=1)

    def fit(q_, qd, tau, qdd):
        d = fit_dynamics(q_ - q_[0], qd, tau, qdd, joint="revolute")
        return None if d is None else float(d.damping)

    out = {"true_damping": damping, "bodies_touching_door": bodies,
           "contact": fit(q, v, sum(contact.values()) if bodies else gcf, vd),
           "generalized_contact_force": fit(q, v, gcf, vd),
           "wrist_true_geometry": fit(q, v, wrist, vd)}
    r_true = float(np.linalg.norm(np.cross(axis, spec.handle_world(0.0)[0] - p_axis)))
    out["true_radius_m"] = r_true
    g = generalized_samples(link, s.t, s.G, s.F)
    if g is None:
        return out
    ok = np.all(np.isfinite(s.G), axis=1) & np.all(np.isfinite(s.F), axis=1)
    qm = np.interp(g["t"], t, q)
    lev = np.array([np.cross(axis, spec.handle_world(x)[0] - p_axis) for x in qm])
    tau_true_lever = -np.sum(s.F[ok] * lev, axis=1)
    qd_l, qdd_l = local_derivatives(g["t"], qm)
    out["wrist_true_q_local_rate"] = fit(qm, qd_l, tau_true_lever, qdd_l)
    out["pipeline"] = fit(g["q"], g["qdot"], g["tau"], g["qddot"])
    out["learned_radius_m"] = g["radius"]
    out["radius_factor"] = (g["radius"] / r_true) ** 2
    out["pipeline_over_radius_factor"] = (None if out["pipeline"] is None
                                          else out["pipeline"] / out["radius_factor"])
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="700,701", help="door seeds, comma-separated")
    ap.add_argument("--damping", type=float, default=3.0, help="true damping, N m s/rad")
    ap.add_argument("--base-noise", type=float, default=None,
                    help="scale of the base-localisation error (0: exact base pose)")
    ap.add_argument("--frame", choices=FRAMES, default="odometry",
                    help="the frame the robot tracks its hook in while opening (default odometry)")
    add_output_arguments(ap)
    a = ap.parse_args(argv)
    try:
        seeds = [int(x) for x in a.seeds.split(",") if x.strip()]
    except ValueError:
        ap.error(f"--seeds: expected integers separated by commas, got {a.seeds!r}")
    if not seeds or not (math.isfinite(a.damping) and a.damping > 0):
        ap.error("--seeds must name a seed and --damping be > 0")
    table = a.json != "-"
    results = []
    for seed in seeds:
        t0 = time.perf_counter()
        r = {"seed": seed, **analyse(record_trial(seed, a.damping, a.base_noise, a.frame), a.damping),
             "wall_s": round(time.perf_counter() - t0, 1)}
        results.append(r)
        if table:
            print(f"seed {seed}: " + ", ".join(
                f"{k} {v:.3g}" if isinstance(v, float) else f"{k} {v}"
                for k, v in r.items() if k != "seed"), flush=True)
    emit_json(a.json, {"damping": a.damping, "base_noise": a.base_noise, "frame": a.frame,
                       "results": results})


if __name__ == "__main__":
    main()
