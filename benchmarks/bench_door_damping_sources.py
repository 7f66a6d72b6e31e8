"""Diagnostic: what limits a door's learned damping, step by step, over many door trials
(prints a table, never fails on a figure).

    python benchmarks/bench_door_damping_sources.py [--seed 600] [--doors 20]
        [--damping 0.5,0.5,1,2,3,5] [--jobs 1] [--monitor NAME=VALUE,...] [--keep DIR]
        [--recordings DIR] [--json [FILE]]

Door ``i`` is seed ``--seed`` + i with the ``i``-th value of ``--damping`` (cycled), each an
``open_cabinet`` door trial with the dynamics monitor. Every 5 ms the simulator's door angle
and rate, the contact torque on the door's joint and where the hook touches the door are
recorded; at every wrist-sensor sample (10 ms) the sensor's reading, its
noise-free force and the hook position the monitor is given. The damping is then fitted with
the monitor's regression (:func:`~mmlearn.models.articulation.dynamics.fit_dynamics`, the
samples of the pull the monitor kept) from sources that go one step at a time from the
simulator's truth to what the robot has:

1. ``contact``: the simulator's own generalised contact torque on the door's joint (every
   contact on the door, at its own point), against the door's true angle, rate and
   acceleration: the regression on the simulated physics alone;
2. ``contact_point``: the noise-free wrist force at the point where the hook touches the
   handle (the simulator's contact point; what a wrist torque sensor would add) about the
   true axis, against the door's true motion;
3. ``ideal``: the noise-free wrist force times the true lever arm at the handle bar's
   centre, against the door's true angle, rate and acceleration;
4. ``sensor``: the sensor's reading instead (its noise, and its sample lag: a reading
   describes the force of up to one sample period before);
5. ``sensor_aligned``: each reading paired with the door's state at the previous sensor
   sample, the lag taken out;
6. ``learned_tangent``: as 5, the torque from the learned model's tangent instead of the true
   lever arm (the learned radius, and the force across the door leaking in through the
   tangent's direction error);
7. ``learned_tangent_leak``: as 6 with the leak as a nuisance term of the regression (the
   force across the door times the learned radius, of unknown size);
8. ``learned_kinematics``: as 7, with the opening, rate and acceleration from the hook's
   track along the learned model (local quadratic fits over +-0.2 s) instead of the door's;
9. ``contact_point_track``: the reading at the hook's contact point about the learned axis
   (what a wrist torque sensor would add), with the force's two components across the axis
   as nuisance terms (they take out an offset of the learned axis), and the opening, rate
   and acceleration from the hook's track as in 8;
10. ``robot``: the robot's own estimate (the monitor's regression samples: its 25 ms
    samples, or its own readings with ``DynamicsMonitorConfig.regression_period``; as the
    trial reports it);
11. ``robot_lag``: the monitor's samples, each force paired with the door's opening, rate
    and acceleration (from the hook's track) at the sensor's sample before
    (``DynamicsMonitorConfig.force_lag_period`` 0.01 s);
12. ``robot_lag_across``: as 11 with the force across the door as a nuisance term
    (``across_term``).

``--keep DIR`` keeps each trial's recording (``door_SEED.pkl``); ``--recordings DIR`` fits
the kept recordings again instead of simulating (seconds instead of minutes): ``--monitor``
may then change only the regression's fields (:data:`REFIT_FIELDS`), as the pull itself is
the recorded one. With ``regression_period`` on a recording made without it, the robot's
rows use the recorded readings of every sensor sample (those the monitor reads itself).

It also reports how fast the learned opening grows against the door's angle
(``opening_scale``) and the learned radius over the true one. The summary gives, per source,
the doors within 25 %, the mean signed error and the mean absolute error, for the doors at
the smallest damping and for the rest.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from _common import add_output_arguments, emit_json

#: the monitor's fields that change only the regression, not the pull (``--recordings``)
REFIT_FIELDS = ("force_lag_period", "across_term", "rate_window", "regression_period",
                "friction_velocity")

SOURCES = ("contact", "contact_point", "ideal", "sensor", "sensor_aligned", "learned_tangent",
           "learned_tangent_leak", "learned_kinematics", "contact_point_track", "robot",
           "robot_lag", "robot_lag_across")


def record(seed: int, damping: float, monitor: dict | None = None) -> dict:
    """Simulate one door trial with the dynamics monitor (see the module docstring);
    ``monitor``: fields of its ``DynamicsMonitorConfig`` other than the defaults."""
    from pydrake.systems.analysis import Simulator

    from mmlearn.diagrams.articulation.operate import MakeOperateDiagram, OperateConfig
    from mmlearn.systems.articulation.epc_controller import DONE
    from mmlearn.systems.articulation.jam_monitor import DynamicsMonitorConfig

    op = MakeOperateDiagram(OperateConfig(kind="left_door", seed=seed,
                                          mechanism_options={"damping": damping},
                                          monitor=DynamicsMonitorConfig(**(monitor or {}))))
    sim = Simulator(op.diagram)
    ctx = sim.get_mutable_context()
    op.scene.set_joint_positions(ctx, op.start_command)
    sim.Initialize()
    plant, mech = op.scene.plant, op.scene.mechanism
    pctx = plant.GetMyContextFromRoot(ctx)
    mon = op.monitor
    mctx = mon.GetMyContextFromRoot(ctx)
    sctx = op.force_sensor.GetMyContextFromRoot(ctx)
    phase = op.diagram.GetOutputPort("phase")
    contact_torque = plant.get_generalized_contact_forces_output_port(mech)
    contacts = plant.get_contact_results_output_port()
    door_bodies = set(plant.GetBodyIndices(mech))
    door, sensor = [], []
    k = 0
    while ctx.get_time() < 60.0:
        k += 1
        sim.AdvanceTo(0.005 * k)
        door.append((ctx.get_time(), plant.GetPositions(pctx, mech)[0],
                     plant.GetVelocities(pctx, mech)[0], contact_torque.Eval(pctx)[0],
                     *_contact_point(contacts.Eval(pctx), door_bodies)))
        if k % 2 == 0:
            sensor.append((ctx.get_time(), *mon.get_hook_position_input_port().Eval(mctx),
                           *mon.get_force_input_port().Eval(mctx),
                           *op.force_sensor.true_force(sctx)))
        if int(phase.Eval(ctx)[0]) == DONE:
            break
    s = mon.state(mctx)
    regression = mon.regression_input(mctx)
    est = op.estimator.GetMyContextFromRoot(ctx).get_abstract_state(0).get_value()
    link = est.model.edges[0].model if est.model is not None and est.model.edges else None
    spec = op.mechanism
    axis, p_axis = spec.axis_world()
    return {"seed": seed, "damping": damping, "door": np.array(door),
            "sensor": np.array(sensor), "monitor": s, "regression": regression,
            "link": link, "handle_offset": spec.handle_world(0.0)[0] - p_axis,
            "axis": axis, "p_axis": p_axis,
            "friction_velocity": mon.config.friction_velocity, "config": mon.config}


def _contact_point(results, bodies) -> np.ndarray:
    """The point where the door is touched: the mean of its point contacts' points weighted
    by their force magnitudes (NaN without a point contact)."""
    total, weight = np.zeros(3), 0.0
    for i in range(results.num_point_pair_contacts()):
        info = results.point_pair_contact_info(i)
        if info.bodyA_index() in bodies or info.bodyB_index() in bodies:
            w = float(np.linalg.norm(info.contact_force()))
            total += w * np.asarray(info.contact_point())
            weight += w
    return total / weight if weight > 0 else np.full(3, np.nan)


def contact_spread(c, q, rec) -> list[float]:
    """How far the hook's contact point moves on the door while pulling: the 5-95 % range
    (mm) of its position in the door's frame along the handle's path (the tangent of the
    handle's circle: the pull's direction) and towards the axis (radially), from contact
    points ``c`` (k, 3) at door angles ``q``."""
    from scipy.spatial.transform import Rotation

    axis = np.asarray(rec["axis"], float)
    local = Rotation.from_rotvec(-np.outer(q, axis)).apply(c - rec["p_axis"])
    h0 = np.asarray(rec["handle_offset"], float)
    radial = h0 - (h0 @ axis) * axis
    radial /= np.linalg.norm(radial)
    tangent = np.cross(axis, radial)
    return [float(np.ptp(np.percentile(local @ e, [5, 95])) * 1e3) for e in (tangent, radial)]


def radial_leak(link, G, F) -> np.ndarray:
    """The force across the door times the learned radius (N m): minus the wrist force along
    the learned model's outward radius at each hook position, times that radius. A tangent
    turned by a small angle e from the true one adds e times this to the torque."""
    q = np.asarray(link.inverse(G), float)[:, :1]
    h = 1e-3
    radial = -(np.asarray(link.jacobian(q + h), float)[:, :3, 0]
               - np.asarray(link.jacobian(q - h), float)[:, :3, 0]) / (2 * h)
    r = np.linalg.norm(radial, axis=1)
    return -np.sum(F * radial / r[:, None], axis=1) * r


def analyse(rec: dict) -> dict:
    """The damping from each source (see the module docstring), relative errors."""
    from mmlearn.models.articulation.dynamics import (fit_dynamics, generalized_samples,
                                                      local_derivatives)

    b_true, s, link = rec["damping"], rec["monitor"], rec["link"]
    out = {"seed": rec["seed"], "true_damping": b_true, "learned": {}}
    if link is None or link.name != "revolute":
        out["model"] = None if link is None else link.name
        return out
    fv = rec["friction_velocity"]
    door, sen = rec["door"], rec["sensor"]
    t_end = s.t_halt - 0.1 if math.isfinite(s.t_halt) else s.t[-1]
    # the sensor samples of the pull: those within one monitor period of a kept sample
    ts = sen[:, 0]
    near = np.zeros(ts.size, bool)
    idx = np.searchsorted(s.t, ts)
    for j in (idx - 1, idx):
        jj = np.clip(j, 0, s.t.size - 1)
        near |= np.abs(s.t[jj] - ts) < 0.026
    pick = np.flatnonzero(near & (ts >= s.t[0] - 1e-9) & (ts <= t_end + 1e-9)
                          & np.all(np.isfinite(sen[:, 1:]), axis=1))
    prev = np.maximum(pick - 1, 0)   # the previous sensor sample
    G, F, F0 = sen[pick, 1:4], sen[pick, 4:7], sen[pick, 7:10]
    acc = np.gradient(door[:, 2], door[:, 0])

    def truth(at):
        return (np.interp(at, door[:, 0], door[:, 1]), np.interp(at, door[:, 0], door[:, 2]),
                np.interp(at, door[:, 0], acc))

    def contact_at(at):  # the point where the door was touched (recorded every 5 ms)
        return np.column_stack([np.interp(at, door[:, 0], door[:, j]) for j in (4, 5, 6)])

    def lever(q):
        from scipy.spatial.transform import Rotation

        h0 = rec["handle_offset"]
        rot = Rotation.from_rotvec(np.outer(q, rec["axis"]))
        return np.cross(rec["axis"], rot.apply(h0))

    def fit(q, qd, tau, qdd, nuisance=None):
        d = fit_dynamics(q - q[0], qd, tau, qdd, joint="revolute", friction_velocity=fv,
                         nuisance=nuisance)
        return None if d is None else float(d.damping)

    q, v, a = truth(ts[pick])
    qp, vp, ap = truth(ts[prev])
    if door.shape[1] >= 7:  # (recordings made before the contacts were recorded: without)
        out["learned"]["contact"] = fit(q, v, np.interp(ts[pick], door[:, 0], door[:, 3]), a)
        c = contact_at(ts[pick])
        ok = np.all(np.isfinite(c), axis=1)
        tau_c = np.cross(c - rec["p_axis"], -F0) @ rec["axis"]
        out["learned"]["contact_point"] = fit(q[ok], v[ok], tau_c[ok], a[ok])
        out["contact_spread_mm"] = contact_spread(c[ok], q[ok], rec)
    out["learned"]["ideal"] = fit(q, v, -np.sum(F0 * lever(q), axis=1), a)
    out["learned"]["sensor"] = fit(q, v, -np.sum(F * lever(q), axis=1), a)
    # the reading at sample k describes the force at sample k - 1
    keep = (pick > 0) & np.all(np.isfinite(sen[prev, 1:]), axis=1)
    out["learned"]["sensor_aligned"] = fit(qp[keep], vp[keep],
                                           -np.sum(F[keep] * lever(qp[keep]), axis=1), ap[keep])
    Gp = sen[prev, 1:4]
    g = generalized_samples(link, ts[prev][keep], Gp[keep], F[keep])
    leak = radial_leak(link, Gp[keep], F[keep]) if g is not None else None
    if g is not None:
        out["learned"]["learned_tangent"] = fit(qp[keep], vp[keep], g["tau"], ap[keep])
        out["learned"]["learned_tangent_leak"] = fit(qp[keep], vp[keep], g["tau"], ap[keep],
                                                     leak[:, None])
        qd, qdd = local_derivatives(g["t"], g["q"])
        out["learned"]["learned_kinematics"] = fit(g["q"], qd, g["tau"], qdd, leak[:, None])
        if door.shape[1] >= 7 and g["t"].size == int(keep.sum()):
            # the reading at the contact point (what a wrist torque sensor adds) about the
            # learned axis, with the hook's track; the force's two components across the
            # axis as nuisance terms take out any offset of the learned axis exactly
            tk = ts[prev][keep]
            ck = contact_at(tk)
            axis_l = g["q_sign"] * np.asarray(link.axis, float)
            Fk = F[keep]
            tau_w = np.cross(ck - np.asarray(link.center, float), -Fk) @ axis_l
            u1 = np.cross(axis_l, [1.0, 0.0, 0.0] if abs(axis_l[0]) < 0.9 else [0.0, 1.0, 0.0])
            u1 /= np.linalg.norm(u1)
            u2 = np.cross(axis_l, u1)
            fin = np.all(np.isfinite(ck), axis=1)
            across = np.column_stack([Fk @ u1, Fk @ u2])
            out["learned"]["contact_point_track"] = fit(g["q"][fin], qd[fin], tau_w[fin],
                                                        qdd[fin], across[fin])
        out["opening_scale"] = float(np.polyfit(qp[keep] - qp[keep][0], g["q"], 1)[0])
        r_true = float(np.linalg.norm(lever(np.zeros(1))[0]))
        out["radius_ratio"] = g["radius"] / r_true
    cfg = rec["config"]
    gm = cfg.regression_samples(link, *rec.get("regression", (s.t, s.G, s.F_mean)))
    if gm is not None:
        k = gm["t"] < t_end + 1e-9
        d = cfg.fit({key: (v[k] if isinstance(v, np.ndarray) else v) for key, v in gm.items()})
        out["learned"]["robot"] = None if d is None else float(d.damping)
    # the monitor's own samples with each correction, whatever the trial's configuration
    from dataclasses import replace

    for name, lag, across in (("robot_lag", 0.01, False), ("robot_lag_across", 0.01, True)):
        c = replace(cfg, force_lag_period=lag, across_term=across)
        gc = c.regression_samples(link, s.t, s.G, s.F_mean)
        if gc is None:
            continue
        k = gc["t"] < t_end + 1e-9
        d = c.fit({key: (v[k] if isinstance(v, np.ndarray) else v) for key, v in gc.items()})
        out["learned"][name] = None if d is None else float(d.damping)
    out["error"] = {k: (None if b is None else b / b_true - 1) for k, b in out["learned"].items()}
    return out


def load_recording(path, monitor: dict | None = None) -> dict:
    """A recording kept by ``--keep``, with the monitor's regression fields in ``monitor``
    (:data:`REFIT_FIELDS`) changed. With ``regression_period`` on a recording whose
    monitor had none, its regression readings are the recorded sensor readings of the pull
    (hook on the handle, from the monitor's first sample on)."""
    import pickle
    from dataclasses import replace

    with open(path, "rb") as fh:
        rec = pickle.load(fh)
    if "handle_offset" not in rec:
        raise ValueError(f"{path}: not a recording of this benchmark")
    cfg = replace(rec["config"], **(monitor or {}))
    if cfg.own_regression_samples() and not rec["config"].own_regression_samples():
        sen, s = rec["sensor"], rec["monitor"]
        ok = np.all(np.isfinite(sen[:, 1:7]), axis=1) & (sen[:, 0] >= s.t[0] - cfg.period)
        rec["regression"] = (sen[ok, 0], sen[ok, 1:4], sen[ok, 4:7])
    elif not cfg.own_regression_samples():
        s = rec["monitor"]
        rec["regression"] = (s.t, s.G, s.F_mean)
    rec["config"] = cfg
    return rec


def run_door(job: tuple) -> dict:
    seed, damping, monitor, keep = job
    t0 = time.perf_counter()
    if isinstance(seed, str):       # a kept recording
        r = analyse(load_recording(seed, monitor))
        r["wall_s"] = round(time.perf_counter() - t0, 1)
        return r
    rec = record(seed, damping, monitor)
    if keep:
        import pickle
        from pathlib import Path

        Path(keep).mkdir(parents=True, exist_ok=True)
        with open(Path(keep) / f"door_{seed}.pkl", "wb") as fh:
            pickle.dump(rec, fh)
    r = analyse(rec)
    r["wall_s"] = round(time.perf_counter() - t0, 1)
    return r


def summary(results: list[dict]) -> dict:
    """Per source: doors within 25 %, mean signed and mean absolute error, for the doors at
    the smallest damping (``light``) and the rest (``heavier``)."""
    small = min(r["true_damping"] for r in results)
    out = {}
    for src in SOURCES:
        for group, pick in (("light", lambda r: r["true_damping"] == small),
                            ("heavier", lambda r: r["true_damping"] != small)):
            e = [r["error"][src] for r in results
                 if pick(r) and r.get("error", {}).get(src) is not None]
            out[f"{src}_{group}"] = {
                "doors": len(e), "within_25pct": int(sum(abs(x) <= 0.25 for x in e)),
                "mean_error": float(np.mean(e)) if e else None,
                "mean_abs_error": float(np.mean(np.abs(e))) if e else None}
    scales = [r["opening_scale"] for r in results if "opening_scale" in r]
    radii = [r["radius_ratio"] for r in results if "radius_ratio" in r]
    spread = [r["contact_spread_mm"] for r in results if "contact_spread_mm" in r]
    out["contact_spread_mm"] = ([float(max(x[0] for x in spread)),
                                 float(max(x[1] for x in spread))] if spread else None)
    out["light_damping"] = small
    out["opening_scale"] = [float(min(scales)), float(max(scales))] if scales else None
    out["radius_ratio"] = [float(min(radii)), float(max(radii))] if radii else None
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=600, help="seed of the first door")
    ap.add_argument("--doors", type=int, default=20, help="door trials")
    ap.add_argument("--damping", default="0.5,0.5,1,2,3,5",
                    help="true dampings (N m s/rad), comma-separated, cycled over the doors")
    ap.add_argument("--jobs", type=int, default=1, help="trials run at once")
    ap.add_argument("--monitor", default="",
                    help="the dynamics monitor's fields other than the defaults, as "
                         "name=value pairs separated by commas (e.g. excitation_ramp=0.5)")
    ap.add_argument("--keep", default="",
                    help="a folder to keep each trial's recording in (door_SEED.pkl)")
    ap.add_argument("--recordings", default="",
                    help="fit the recordings kept in this folder again instead of simulating "
                         "(--monitor: only " + ", ".join(REFIT_FIELDS) + ")")
    add_output_arguments(ap)
    a = ap.parse_args(argv)
    monitor = {}
    for item in filter(None, (x.strip() for x in a.monitor.split(","))):
        name, _, value = item.partition("=")
        try:
            v = value.strip().lower()
            monitor[name.strip()] = v == "true" if v in ("true", "false") else float(v)
        except ValueError:
            ap.error(f"--monitor: expected name=number, got {item!r}")
    try:
        from mmlearn.systems.articulation.jam_monitor import DynamicsMonitorConfig

        DynamicsMonitorConfig(**monitor)
    except (TypeError, ValueError) as e:
        ap.error(f"--monitor: {e}")
    try:
        values = [float(x) for x in a.damping.split(",") if x.strip()]
    except ValueError:
        ap.error(f"--damping: expected numbers separated by commas, got {a.damping!r}")
    if not values or not all(math.isfinite(v) and v > 0 for v in values):
        ap.error("--damping must name values > 0")
    if a.doors < 1 or a.jobs < 1:
        ap.error("--doors and --jobs must be >= 1")
    if a.recordings:
        from pathlib import Path

        paths = sorted(Path(a.recordings).glob("door_*.pkl"),
                       key=lambda f: int(f.stem.split("_")[-1]))
        if not paths:
            ap.error(f"--recordings: no door_SEED.pkl in {a.recordings}")
        other = sorted(set(monitor) - set(REFIT_FIELDS))
        if other:
            ap.error(f"--recordings: the pull is the recorded one; --monitor may set only "
                     f"{', '.join(REFIT_FIELDS)}, not {', '.join(other)}")
        jobs = [(str(f), None, monitor, "") for f in paths]
    else:
        jobs = [(a.seed + i, values[i % len(values)], monitor, a.keep)
                for i in range(a.doors)]
    table = a.json != "-"
    if a.jobs > 1:
        from concurrent.futures import ProcessPoolExecutor

        with ProcessPoolExecutor(min(a.jobs, len(jobs))) as pool:
            results = list(pool.map(run_door, jobs))
    else:
        results = [run_door(j) for j in jobs]
    if table:
        for r in results:
            errs = " ".join(f"{k} {'-' if e is None else f'{e:+.2f}'}"
                            for k, e in r.get("error", {}).items())
            print(f"seed {r['seed']} damping {r['true_damping']:g}: {errs}", flush=True)
    s = summary(results)
    if table:
        for src in SOURCES:
            for group in ("light", "heavier"):
                x = s[f"{src}_{group}"]
                if x["doors"]:
                    print(f"{src:22s} {group:8s} {x['within_25pct']}/{x['doors']} within 25 %, "
                          f"mean error {x['mean_error']:+.3f}, mean |error| "
                          f"{x['mean_abs_error']:.3f}")
    emit_json(a.json, {"seed": a.seed, "doors": a.doors, "damping": values, "monitor": monitor,
                       "summary": s,
                       "results": results})


if __name__ == "__main__":
    main()
