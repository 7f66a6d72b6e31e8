"""Structure experiments of thesis 4.4.1 / 4.4.3 on the simulated objects (sdf/objects.py).

Usage::

    python -m mmlearn.apps.structure_experiments [--only fig48,fig49,fig411,garage,fig416,fig417,fig418]
        [--quick] [--seeds N] [--n N] [--seed S] [--sensor ideal|camera] [--json] [--out-dir DIR]
        [--results FILE] [--executor local|ray] [--ray-address ADDR] [--jobs N]
    python -m mmlearn.apps.structure_experiments --report-only RESULTS.jsonl [--out-dir DIR]

- fig48: two-drawer cabinet, structure while the lower drawer alone moves, then both.
- fig49: table pushed on the floor: selected link model (rigid, prismatic, gp, gp2) as the
  motion grows.
- fig411: car door and window on a curved guide (r = 1.9 m): structure and window radius.
- garage: roll-up garage door (neither revolute nor prismatic): selected model.
- fig416: yardstick, open chain (3 hinges) and closed loop (4 links): structure and DOFs for
  several seeds (right DOF = 3 open, 1 closed).
- fig417: DOFs while the data arrive (open chain opened segment by segment; closed loop).
- fig418: closed yardstick: BIC of the spanning tree, local search and exhaustive search and
  their run times as n grows.

``--sensor``: ``ideal`` (default) observes the objects' markers with the scenarios' Gaussian
noise (``mmlearn.diagrams.common.object_tracks``); ``camera`` renders the same motion with
ArUco-textured marker squares on the parts and reads them with the
:class:`~mmlearn.systems.common.camera_marker_sensor.CameraMarkerSensor` (one 1920 x 1440 camera
placed by ``auto_cameras``; markers it does not detect are missing samples), and every
experiment adds a line with what the camera saw (share of frames per part, median position
error, share of orientations off by > 20 deg). Slow: ~0.3-1 s per sample.

Tables go to stdout, ``--json`` prints all results, ``--out-dir DIR`` writes the plots (PNG).
``--quick`` runs a small setting (for the test suite).

The trials (each experiment; fig416: each yardstick run; fig417: each yardstick; fig418:
each n) run through the sweep runner (``mmlearn.apps.common.sweep``): in parallel processes
(``--jobs``, default all cores) or as Ray tasks (``--executor ray``), streamed to
``--results`` (default ``structure_experiments_results.jsonl`` in ``--out-dir`` or the
current folder); re-running the same command resumes, ``--report-only FILE`` redraws the
tables and plots from a results file. Run times are those of each trial's process (with
several jobs on few cores they include the others' load).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

from mmlearn.apps.common import experiment
from mmlearn.apps.common.cli import (UsageError, check_out_dir, pos_int, progress_bar, save_figure)
from mmlearn.apps.common.experiment import Experiment
from mmlearn.models.articulation.link import ObservationModel
from mmlearn.models.articulation.graph import (KinematicGraphEvaluator, fit_pair_models,
                                               fit_structure, search_structure,
                                               spanning_tree_edges)
from mmlearn.models.articulation.incremental import incremental_structure
from mmlearn.models.articulation.structure import select_link_model
from mmlearn.models.common.se3 import relative_poses
from mmlearn.models.common.trials import register_trial

__all__ = ["run", "main", "EXPERIMENTS"]

EXPERIMENTS = ("fig48", "fig49", "fig411", "garage", "fig416", "fig417", "fig418")
PARAMETRIC = ("rigid", "prismatic", "revolute")
SENSORS = ("ideal", "camera")


def observe(track, sensor: str = "ideal", camera=None):
    """The scenario's track as ``sensor`` reports it: "ideal" = as generated (Gaussian
    noise), "camera" = rendered and read by the camera marker sensor
    (:func:`mmlearn.diagrams.common.object_tracks.camera_track`, ``camera`` its
    CameraMarkerSensorConfig, None = one automatic 1920 x 1440 camera; NaN rows where a
    marker was not detected)."""
    if sensor == "ideal":
        return track
    if sensor != "camera":
        raise ValueError(f"sensor must be one of {', '.join(SENSORS)}, got {sensor!r}")
    from mmlearn.diagrams.common.object_tracks import camera_track

    return camera_track(track, camera)


def sensor_stats(track) -> dict:
    """What the sensor saw of a track: per part the share of samples with a pose, the
    median position error (m) and the share of orientations off by > 20 deg, against the
    true marker poses."""
    from scipy.spatial.transform import Rotation

    out = {}
    for k, part in enumerate(track.parts):
        P, Pt = track.poses[k], track.poses_true[k]
        ok = np.isfinite(P).all(axis=1)
        rec = {"seen": float(ok.mean()), "pos_median_m": None, "flipped": None}
        if ok.any():
            rec["pos_median_m"] = float(np.median(np.linalg.norm(P[ok, :3] - Pt[ok, :3],
                                                                 axis=1)))
            ang = (Rotation.from_quat(Pt[ok, 3:]).inv() * Rotation.from_quat(P[ok, 3:])
                   ).magnitude()
            rec["flipped"] = float(np.mean(ang > np.radians(20)))
        out[part] = rec
    return out


def _sensor_line(name, stats) -> str:
    return f"camera ({name}): " + "; ".join(
        f"{p} seen {r['seen']:.2f}" + ("" if r["pos_median_m"] is None else
                                        f", {1000 * r['pos_median_m']:.1f} mm, "
                                        f"{100 * r['flipped']:.0f} % > 20 deg")
        for p, r in stats.items())


def _with_sensor(res, lines, track, sensor):
    if sensor != "ideal":
        res["sensor_stats"] = sensor_stats(track)
        lines.append(_sensor_line(track.name, res["sensor_stats"]))
    return res, lines


def _relative(track, i=0, j=1) -> np.ndarray:
    """(T, 7) relative poses of part j in part i, NaN rows where either is missing."""
    a, b = track.poses[i], track.poses[j]
    ok = np.isfinite(a).all(axis=1) & np.isfinite(b).all(axis=1)
    Z = np.full((a.shape[0], 7), np.nan)
    if ok.any():
        Z[ok] = relative_poses(a[ok], b[ok]).as_array()
    return Z


def exp_cabinet(*, quick, seed, progress, sensor="ideal"):
    from mmlearn.diagrams.common.object_tracks import cabinet_scenario

    tr = observe(cabinet_scenario(20, 20 if quick else 40, rng=seed), sensor)
    obs = ObservationModel(sigma_pos=0.01, sigma_orient=np.deg2rad(2))
    hist = incremental_structure(tr.poses, tr.parts, refit_every=5, obs=obs, rng=seed,
                                 models=PARAMETRIC if quick else ("rigid", "prismatic",
                                                                  "revolute", "gp"))
    rows = [{"n": s.n, "edges": [list(e) for e in s.edges], "dof": s.dof} for s in hist]
    lines = ["Fig. 4.8  two-drawer cabinet (lower drawer alone for 20 samples, then both)",
             "   n  dof  structure"]
    for r in rows:
        lines.append(f"{r['n']:4d}  {r['dof']:3d}  " + ", ".join(
            f"{m}({a},{b})" for a, b, m in r["edges"]))
    return _with_sensor({"rows": rows}, lines, tr, sensor)


def exp_table(*, quick, seed, progress, sensor="ideal"):
    from mmlearn.diagrams.common.object_tracks import table_phases, table_scenario

    m = 12 if quick else 20
    tr = observe(table_scenario(m, rng=seed), sensor)
    names = ["still", "line", "curve", "free"]
    ends = np.cumsum([table_phases(m)[k] for k in names])
    obs = ObservationModel(sigma_pos=0.01, sigma_orient=np.deg2rad(2))
    models = ("rigid", "prismatic", "revolute", "gp", "gp2")
    Z = _relative(tr)
    rows = []
    # every 5 samples and at the end of each phase
    steps = sorted(set(range(5, Z.shape[0] + 1, 5)) | {int(e) for e in ends})
    bar = progress_bar(len(steps), "table", enabled=progress)
    rng = np.random.default_rng(seed)
    for n in steps:
        phase = names[int(np.searchsorted(ends, n))]
        Zn = Z[:n][np.isfinite(Z[:n]).all(axis=1)]  # the samples the sensor saw
        if len(Zn) < 5:
            rows.append({"n": n, "phase": phase, "selected": None, "bic": {}, "seen": len(Zn)})
            bar.update(1)
            continue
        s = select_link_model(Zn, models=models, obs=obs, rng=rng, n_hypotheses=60)
        rows.append({"n": n, "phase": phase, "selected": s.selected,
                     "bic": {k: (v if math.isfinite(v) else None) for k, v in s.bic.items()},
                     "seen": len(Zn)})
        bar.update(1)
    bar.close()
    lines = ["Fig. 4.9  table pushed on the floor (phases end at n = %s)" % ", ".join(
        str(int(e)) for e in ends),
             "   n  phase  selected  " + "  ".join(f"{k:>8s}" for k in models)]
    for r in rows:
        lines.append(f"{r['n']:4d}  {r['phase']:5s}  {r['selected'] or '-':8s}  " + "  ".join(
            f"{r['bic'][k]:8.0f}" if r["bic"].get(k) is not None else "       -"
            for k in models))
    return _with_sensor({"rows": rows, "sequence": _sequence(
        [r["selected"] for r in rows if r["selected"] is not None])}, lines, tr, sensor)


def _sequence(names):
    out = []
    for n in names:
        if not out or out[-1] != n:
            out.append(n)
    return out


def exp_car(*, quick, seed, progress, sensor="ideal"):
    from mmlearn.diagrams.common.object_tracks import car_door_scenario

    tr = observe(car_door_scenario(30 if quick else 40, 30 if quick else 40, rng=seed), sensor)
    obs = ObservationModel(sigma_pos=0.005, sigma_orient=np.deg2rad(1))
    hist = incremental_structure(tr.poses, tr.parts, refit_every=10, obs=obs, rng=seed,
                                 models=PARAMETRIC, search="local")
    rows = []
    for s in hist:
        r = s.result
        radius = None
        for (i, j) in r.best.edges:
            if "window" in (tr.parts[i], tr.parts[j]) and r.best.models[(i, j)] == "revolute":
                radius = float(r.pair_models[(i, j)].best.radius)
        rows.append({"n": s.n, "edges": [list(e) for e in s.edges], "dof": s.dof,
                     "window_radius_m": radius})
    lines = ["Fig. 4.11  car door + window on a curved guide (true r = 1.9 m)",
             "   n  dof  window r [m]  structure"]
    for r in rows:
        rr = f"{r['window_radius_m']:.2f}" if r["window_radius_m"] is not None else "-"
        lines.append(f"{r['n']:4d}  {r['dof']:3d}  {rr:>12s}  " + ", ".join(
            f"{m}({a},{b})" for a, b, m in r["edges"]))
    return _with_sensor({"rows": rows}, lines, tr, sensor)


def exp_garage(*, quick, seed, progress, sensor="ideal"):
    from mmlearn.diagrams.common.object_tracks import garage_door_scenario

    tr = observe(garage_door_scenario(40 if quick else 60, rng=seed), sensor)
    obs = ObservationModel(sigma_pos=0.01, sigma_orient=np.deg2rad(2))
    Z = _relative(tr)
    Z = Z[np.isfinite(Z).all(axis=1)]
    if len(Z) < 5:
        return _with_sensor({"selected": None, "bic": {}, "avg_pos_error_m": None,
                             "seen": len(Z)},
                            [f"Roll-up garage door: {len(Z)} samples seen, nothing selected"],
                            tr, sensor)
    s = select_link_model(Z, obs=obs, rng=seed)
    res = {"selected": s.selected,
           "bic": {k: (v if math.isfinite(v) else None) for k, v in s.bic.items()},
           "avg_pos_error_m": float(s.best.avg_pos_error_), "seen": len(Z)}
    lines = ["Roll-up garage door: selected " + s.selected + "  (BIC " + ", ".join(
        f"{k} {v:.0f}" for k, v in s.bic.items() if math.isfinite(v)) + ")"]
    return _with_sensor(res, lines, tr, sensor)


def _yardstick_obs():
    return ObservationModel(sigma_pos=0.005, sigma_orient=np.deg2rad(3))


def yardstick_row(*, closed: bool, seed: int, n: int, sensor: str = "ideal") -> dict:
    """One yardstick run of Fig. 4.16 (a trial): the open chain (3 hinges) or the closed
    loop (4 links) with ``n`` samples, fitted with the spanning tree, the local and the
    exhaustive search (DOF reduction on); BICs, DOFs, run times [s] and graphs visited."""
    from mmlearn.diagrams.common.object_tracks import yardstick_scenario

    obs = _yardstick_obs()
    tr = observe(yardstick_scenario(closed, n, rng=seed), sensor)
    t0, c0 = time.perf_counter(), time.process_time()
    pm = fit_pair_models(tr.poses, obs=obs, rng=seed)
    t_pairs, c_pairs = time.perf_counter() - t0, time.process_time() - c0
    res = {}
    for search in ("tree", "local", "exhaustive"):
        res[search] = fit_structure(tr.poses, part_names=tr.parts, search=search,
                                    reduce_dofs=True, obs=obs, pair_models=pm)
    rl, rx = res["local"], res["exhaustive"]
    chain = [(0, 1), (1, 2), (2, 3)] + ([(0, 3)] if closed else [])
    true_graph = KinematicGraphEvaluator(tr.poses, pm, obs=obs).evaluate(
        chain, reduce_dofs=True)
    row = {
        "closed": closed, "seed": seed, "n": n,
        "dof_local": rl.best.dof, "dof_exhaustive": rx.best.dof,
        "dof_tree": res["tree"].best.dof,
        "edges_local": [[tr.parts[i], tr.parts[j], rl.best.models[(i, j)]]
                        for i, j in rl.best.edges],
        "has_loop": rl.best.has_loop,
        "bic_tree": res["tree"].best.bic, "bic_local": rl.best.bic,
        "bic_exhaustive": rx.best.bic,
        "gap_local_pct": 100 * (rl.best.bic - rx.best.bic) / abs(rx.best.bic),
        "gap_tree_pct": 100 * (res["tree"].best.bic - rx.best.bic) / abs(rx.best.bic),
        "local_optimal": bool(abs(rl.best.bic - rx.best.bic) < 1e-6),
        "bic_true_graph": true_graph.bic, "dof_true_graph": true_graph.dof,
        "fit_seconds": t_pairs,
        "search_seconds_local": rl.search_seconds,
        "search_seconds_exhaustive": rx.search_seconds,
        "fit_cpu_seconds": c_pairs,
        "search_cpu_seconds_local": rl.search_cpu_seconds,
        "search_cpu_seconds_exhaustive": rx.search_cpu_seconds,
        "graphs_local": len(rl.evaluated), "graphs_exhaustive": len(rx.evaluated),
    }
    if sensor != "ideal":
        row["sensor_stats"] = sensor_stats(tr)
    return row


def yardstick_summary(rows):
    """Fig. 4.16's summary and table lines from the runs of :func:`yardstick_row`."""
    rows = sorted(rows, key=lambda r: (r["closed"], r["seed"]))
    seeds = len({r["seed"] for r in rows})
    n = rows[0]["n"] if rows else 0
    summ = {}
    for closed, want in ((False, 3), (True, 1)):
        rr = [r for r in rows if r["closed"] == closed]
        if not rr:
            continue
        t_l = np.mean([r["search_seconds_local"] for r in rr])
        t_x = np.mean([r["search_seconds_exhaustive"] for r in rr])
        t_f = np.mean([r["fit_seconds"] for r in rr])
        c_l = np.mean([r["search_cpu_seconds_local"] for r in rr])
        c_x = np.mean([r["search_cpu_seconds_exhaustive"] for r in rr])
        c_f = np.mean([r["fit_cpu_seconds"] for r in rr])
        summ["closed" if closed else "open"] = {
            "right_dof": int(sum(r["dof_local"] == want for r in rr)), "runs": len(rr),
            "expected_dof": want,
            "mean_gap_local_pct": float(np.mean([r["gap_local_pct"] for r in rr])),
            "max_gap_local_pct": float(np.max([r["gap_local_pct"] for r in rr])),
            "mean_gap_tree_pct": float(np.mean([r["gap_tree_pct"] for r in rr])),
            "local_optimal_pct": 100.0 * float(np.mean([r["local_optimal"] for r in rr])),
            "search_seconds_local": float(t_l), "search_seconds_exhaustive": float(t_x),
            "pair_fit_seconds": float(t_f),
            "speedup_search": float(t_x / t_l), "speedup_total": float((t_x + t_f) / (t_l + t_f)),
            # CPU time of the trial's process (wall time counts other processes' load on a
            # shared machine); the thesis' "82.6% less time" (Fig. 4.18) compares the graph
            # search alone: both searches need every pair's link model (the spanning tree
            # of Eq. 4.40 starts from all of them)
            "search_cpu_seconds_local": float(c_l), "search_cpu_seconds_exhaustive": float(c_x),
            "pair_fit_cpu_seconds": float(c_f),
            "speedup_search_cpu": float(c_x / c_l),
            "speedup_total_cpu": float((c_x + c_f) / (c_l + c_f)),
            "graphs_local_mean": float(np.mean([r["graphs_local"] for r in rr])),
            "graphs_exhaustive_mean": float(np.mean([r["graphs_exhaustive"] for r in rr])),
            "loops_selected": int(sum(r["has_loop"] for r in rr)),
            "mean_gap_true_graph_pct": float(np.mean(
                [100 * (r["bic_true_graph"] - r["bic_exhaustive"]) / abs(r["bic_exhaustive"])
                 for r in rr])),
            "true_graph_right_dof": int(sum(r["dof_true_graph"] == want for r in rr)),
        }
    lines = [f"Fig. 4.16  yardstick, n = {n}, {seeds} seeds, local search with DOF reduction",
             "object  right DOF  loop sel.  gap local/exh. (mean/max %)  gap tree %  "
             "local optimal %  search s local/exh.  speed-up search/total"]
    for key, s in summ.items():
        lines.append(f"{key:6s}  {s['right_dof']:4d}/{s['runs']:<4d}  {s['loops_selected']:9d}  "
                     f"{s['mean_gap_local_pct']:12.2f} / {s['max_gap_local_pct']:6.2f}  "
                     f"{s['mean_gap_tree_pct']:10.2f}  {s['local_optimal_pct']:15.0f}  "
                     f"{s['search_seconds_local']:8.2f} / {s['search_seconds_exhaustive']:6.2f}  "
                     f"{s['speedup_search']:8.1f} / {s['speedup_total']:4.1f}")
    lines.append("CPU time (the trial's process): search local / exhaustive s, pair fits s, "
                 "speed-up search / total, graphs evaluated local / exhaustive")
    for key, s in summ.items():
        lines.append(f"{key:6s}  {s['search_cpu_seconds_local']:6.2f} / "
                     f"{s['search_cpu_seconds_exhaustive']:6.2f}  {s['pair_fit_cpu_seconds']:6.2f}"
                     f"  {s['speedup_search_cpu']:5.1f} / {s['speedup_total_cpu']:4.1f}  "
                     f"{s['graphs_local_mean']:5.1f} / {s['graphs_exhaustive_mean']:4.1f}")
    for key, s in summ.items():
        lines.append(f"{key}: true graph (chain{' + loop' if key == 'closed' else ''}) with "
                     f"PCA DOFs: right DOF {s['true_graph_right_dof']}/{s['runs']}, BIC "
                     f"{s['mean_gap_true_graph_pct']:.2f} % above the exhaustive optimum")
    for r in rows:
        if r.get("sensor_stats"):
            lines.append(_sensor_line(f"{'closed' if r['closed'] else 'open'} seed "
                                      f"{r['seed']}", r["sensor_stats"]))
    ex = [r for r in rows if r["closed"]]
    if ex:
        lines.append("closed, seed %d: %s" % (ex[0]["seed"], ", ".join(
            f"{m}({a},{b})" for a, b, m in ex[0]["edges_local"])))
    return {"runs": rows, "summary": summ}, lines


def dof_progress(*, closed: bool, seed: int, quick: bool, sensor: str = "ideal") -> list:
    """Fig. 4.17 for one yardstick (a trial): the open chain opened segment by segment or the
    closed loop; [n, estimated DOFs] every 20 samples."""
    from mmlearn.diagrams.common.object_tracks import yardstick_scenario

    n, step = (80, 20) if quick else (200, 20)
    obs = _yardstick_obs()
    tr = observe(yardstick_scenario(closed, n, staged=not closed, rng=seed), sensor)
    dofs = []
    for m in range(step, n + 1, step):
        r = fit_structure(tr.poses[:, :m], search="local", reduce_dofs=True, obs=obs,
                          rng=seed, models=PARAMETRIC if quick else
                          ("rigid", "prismatic", "revolute", "gp"))
        dofs.append([m, r.best.dof])
    return dofs


def dof_progress_summary(by_key: dict):
    """Fig. 4.17's result and table lines from {"open_staged" / "closed": dofs}."""
    step = 20
    out = {k: by_key[k] for k in ("open_staged", "closed") if k in by_key}
    lines = [f"Fig. 4.17  estimated DOFs while the data arrive (every {step} samples)"]
    for key, dofs in out.items():
        lines.append(f"{key:12s} " + "  ".join(f"n={m}:{d}" for m, d in dofs))
    return out, lines


def search_vs_n_row(*, n: int, seed: int, sensor: str = "ideal") -> dict:
    """Fig. 4.18 at one n (a trial): closed yardstick, BIC, DOFs, graphs visited and run
    time [s] of the spanning tree, the local and the exhaustive search."""
    from mmlearn.diagrams.common.object_tracks import yardstick_scenario

    obs = _yardstick_obs()
    tr = observe(yardstick_scenario(True, n, rng=seed), sensor)
    t0 = time.perf_counter()
    pm = fit_pair_models(tr.poses, obs=obs, rng=seed)
    t_fit = time.perf_counter() - t0
    tree_edges = spanning_tree_edges(pm, 4)
    row = {"n": n, "fit_seconds": t_fit}
    for search in ("tree", "local", "exhaustive"):
        ev = KinematicGraphEvaluator(tr.poses, pm, obs=obs)
        t0 = time.perf_counter()
        best, tree, order = search_structure(ev, tree_edges, search=search, reduce_dofs=True)
        row[search] = {"bic": best.bic, "seconds": time.perf_counter() - t0,
                       "graphs": len(order), "dof": best.dof}
        if search == "exhaustive":
            row["all_bics"] = sorted(e.bic for e in order)
    return row


def search_vs_n_summary(rows):
    """Fig. 4.18's result and table lines from the rows of :func:`search_vs_n_row`."""
    rows = sorted(rows, key=lambda r: r["n"])
    lines = ["Fig. 4.18  closed yardstick: BIC and search time vs n",
             "   n   BIC tree    BIC local   BIC exh.   t tree  t local  t exh. [s]  t pairs"]
    for r in rows:
        lines.append(f"{r['n']:4d}  {r['tree']['bic']:9.0f}  {r['local']['bic']:9.0f}  "
                     f"{r['exhaustive']['bic']:9.0f}  {r['tree']['seconds']:6.2f}  "
                     f"{r['local']['seconds']:6.2f}  {r['exhaustive']['seconds']:6.2f}  "
                     f"{r['fit_seconds']:8.2f}")
    return {"rows": rows}, lines


def _plots(results, out):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    if "fig418" in results:
        rows = results["fig418"]["rows"]
        fig, (a1, a2) = plt.subplots(2, 1, figsize=(6, 6), sharex=True)
        ns = [r["n"] for r in rows]
        for r in rows:
            a1.plot([r["n"]] * len(r["all_bics"]), r["all_bics"], ".", color="0.7")
        for key, st in (("tree", "r-"), ("local", "b--"), ("exhaustive", "g:")):
            a1.plot(ns, [r[key]["bic"] for r in rows], st, label=key)
            a2.plot(ns, [r[key]["seconds"] for r in rows], st, label=key)
        a1.set_ylabel("BIC")
        a1.legend()
        a2.set_ylabel("search time [s]")
        a2.set_xlabel("training samples n")
        save_figure(fig, out / "fig418_search.png", dpi=100)
        plt.close(fig)
        written.append(str(out / "fig418_search.png"))
    if "fig417" in results:
        fig, ax = plt.subplots(figsize=(6, 3))
        for key, d in results["fig417"].items():
            if key == "seconds":
                continue
            d = np.asarray(d)
            ax.step(d[:, 0], d[:, 1], where="post", label=key)
        ax.set_xlabel("training samples n")
        ax.set_ylabel("estimated DOFs")
        ax.legend()
        save_figure(fig, out / "fig417_dofs.png", dpi=100)
        plt.close(fig)
        written.append(str(out / "fig417_dofs.png"))
    if "fig49" in results:
        rows = results["fig49"]["rows"]
        fig, ax = plt.subplots(figsize=(6, 3))
        keys = [k for k in rows[-1]["bic"]]
        for k in keys:
            ax.plot([r["n"] for r in rows], [r["bic"].get(k) if r["bic"].get(k) is not None
                                             else np.nan for r in rows], label=k)
        ax.set_xlabel("samples n")
        ax.set_ylabel("BIC")
        ax.legend()
        save_figure(fig, out / "fig49_table.png", dpi=100)
        plt.close(fig)
        written.append(str(out / "fig49_table.png"))
    return written


RUNNERS = {"fig48": exp_cabinet, "fig49": exp_table, "fig411": exp_car, "garage": exp_garage}
"""The experiments that are one trial each (their table is the trial's record)."""


@register_trial("articulation.structure")
def trial(*, seed: int, experiment: str, quick: bool = False, closed: bool | None = None,
          n: int | None = None, sensor: str = "ideal", shared=None) -> dict:
    """One trial of the sweep (``mmlearn.apps.common.sweep``): a whole experiment of
    :data:`RUNNERS` (fig48, fig49, fig411, garage: its result and table lines), one yardstick
    run of fig416 (``closed``, ``n`` samples), one yardstick of fig417 (``closed``) or one
    ``n`` of fig418. ``sensor``: see :func:`observe`."""
    if experiment in RUNNERS:
        res, lines = RUNNERS[experiment](quick=quick, seed=seed, progress=False,
                                         sensor=sensor)
        return {"experiment": experiment, "result": res, "lines": lines}
    if experiment == "fig416":
        return {"experiment": experiment, "row": yardstick_row(closed=closed, seed=seed, n=n,
                                                               sensor=sensor)}
    if experiment == "fig417":
        return {"experiment": experiment, "closed": closed,
                "dofs": dof_progress(closed=closed, seed=seed, quick=quick, sensor=sensor)}
    if experiment == "fig418":
        return {"experiment": experiment, "row": search_vs_n_row(n=n, seed=seed, sensor=sensor)}
    raise ValueError(f"unknown experiment {experiment!r}; choose from {', '.join(EXPERIMENTS)}")


def trial_specs(*, only=EXPERIMENTS, quick: bool = False, seed: int = 0, seeds: int = 10,
                n: int = 200, sensor: str = "ideal") -> list:
    """The sweep's trials: one per experiment of :data:`RUNNERS`, one per yardstick run of
    fig416 (2 x ``seeds``), one per yardstick of fig417 (2), one per n of fig418. A
    ``sensor`` other than "ideal" is one more parameter of every trial (so the ideal
    trials' keys, and results files, stay as they were)."""
    from mmlearn.apps.common.sweep import TrialSpec

    fn = trial
    specs = []
    for k in only:
        if k in RUNNERS:
            specs.append(TrialSpec(fn=fn, seed=seed, label=k,
                                   params={"experiment": k, "quick": quick}))
        elif k == "fig416":
            ns, nn = (min(seeds, 2), 60) if quick else (seeds, n)
            specs += [TrialSpec(fn=fn, seed=seed + j, label=f"fig416 "
                                f"{'closed' if closed else 'open'} seed {seed + j}",
                                params={"experiment": k, "closed": closed, "n": nn,
                                        "quick": quick})
                      for closed in (False, True) for j in range(ns)]
        elif k == "fig417":
            specs += [TrialSpec(fn=fn, seed=seed, label=f"fig417 "
                                f"{'closed' if closed else 'open_staged'}",
                                params={"experiment": k, "closed": closed, "quick": quick})
                      for closed in (False, True)]
        elif k == "fig418":
            specs += [TrialSpec(fn=fn, seed=seed, label=f"fig418 n {m}",
                                params={"experiment": k, "n": m, "quick": quick})
                      for m in ([40, 80] if quick else [25, 50, 100, 150, 200])]
    if sensor != "ideal":
        specs = [TrialSpec(fn=sp.fn, seed=sp.seed, label=f"{sp.label} ({sensor})",
                           params={**sp.params, "sensor": sensor}) for sp in specs]
    return specs


def report(lines: list[dict], *, only=None) -> tuple[dict, list[str]]:
    """Every experiment's result and table lines from results-file lines (a run or
    ``--report-only``), in the order of ``only`` (default: :data:`EXPERIMENTS`). Trials that
    raised are listed in ``results["errors"]`` and left out of their experiment."""
    settings = {(bool(ln["spec"]["params"].get("quick")),
                 ln["spec"]["params"].get("n") if ln["spec"]["params"]["experiment"] == "fig416"
                 else None, ln["spec"]["params"].get("sensor", "ideal")) for ln in lines}
    if (len({q for q, _, _ in settings}) > 1 or len({n for _, n, _ in settings} - {None}) > 1
            or len({s for _, _, s in settings}) > 1):
        raise ValueError("the results file mixes settings (--quick or not, fig416 with "
                         "different --n, --sensor); use one results file per setting")
    ok = [ln for ln in lines if ln.get("error") is None]
    by = {}
    for ln in ok:
        by.setdefault(ln["record"]["experiment"], []).append(ln)
    results, text = {}, []
    for k in (only or EXPERIMENTS):
        mine = by.get(k)
        if not mine:
            continue
        recs = [ln["record"] for ln in mine]
        if k in RUNNERS:
            res, tab = dict(recs[0]["result"]), recs[0]["lines"]
        elif k == "fig416":
            res, tab = yardstick_summary([r["row"] for r in recs])
        elif k == "fig417":
            res, tab = dof_progress_summary({("closed" if r["closed"] else "open_staged"):
                                             r["dofs"] for r in recs})
        else:
            res, tab = search_vs_n_summary([r["row"] for r in recs])
        res["seconds"] = float(sum(ln.get("wall_s") or 0.0 for ln in mine))
        results[k] = res
        text.append("\n".join(tab) + "\n")
    results["errors"] = [{"trial": ln["spec"].get("label") or ln["key"], "error": ln["error"]}
                         for ln in lines if ln.get("error") is not None]
    for e in results["errors"]:
        text.append(f"error: trial {e['trial']} raised {e['error']} (left out above)")
    return results, text


def _only(only) -> list:
    if isinstance(only, str):
        only = [x.strip() for x in only.split(",") if x.strip()]
    return list(only)


class StructureExperiments(Experiment):
    name = "structure_experiments"
    description = (__doc__.split("\n\n")[0] + " Exit status: 0 every trial ran, 1 a trial "
                   "raised an error, 2 bad input.")
    seed_help = "random seed"
    json_help = "print JSON instead of tables"
    desc = "structure trials"

    def __init__(self):
        self.text: list[str] = []

    def add_arguments(self, ap):
        ap.add_argument("--only", default=",".join(EXPERIMENTS),
                        help="comma-separated experiments (default: all)")
        ap.add_argument("--quick", action="store_true", help="small, fast setting")
        ap.add_argument("--seeds", type=pos_int, default=10, help="yardstick seeds (fig416)")
        ap.add_argument("--n", type=pos_int, default=200, help="yardstick samples (fig416)")
        ap.add_argument("--sensor", choices=list(SENSORS), default="ideal",
                        help="ideal: the scenarios' Gaussian marker noise (default); camera: "
                             "ArUco markers on the parts read from rendered images (slow)")
        ap.add_argument("--out-dir", default=None,
                        help="folder for the plots (PNG) and the default results file")
        ap.add_argument("--out", dest="out_dir", help=argparse.SUPPRESS)  # old spelling
        ap.add_argument("--no-progress", action="store_true", help="no progress bars")

    def check(self, args):
        check_out_dir("--out-dir", args.out_dir)
        if args.report_only:
            bad = [x for x in _only(args.only) if x not in EXPERIMENTS]
            if bad:
                raise UsageError(f"--only: unknown experiment {bad[0]!r}; choose from "
                                 + ", ".join(EXPERIMENTS))

    def show_progress(self, args):
        return not args.no_progress

    def specs(self, args):
        only = _only(args.only)
        for k in only:
            if k not in EXPERIMENTS:
                raise ValueError(f"unknown experiment {k!r}; choose from "
                                 f"{', '.join(EXPERIMENTS)}")
        if args.seeds < 1 or args.n < 20:
            raise ValueError("--seeds must be >= 1 and --n >= 20")
        if args.sensor not in SENSORS:
            raise ValueError(f"sensor must be one of {', '.join(SENSORS)}, got {args.sensor!r}")
        return trial_specs(only=only, quick=args.quick, seed=args.seed, seeds=args.seeds,
                           n=args.n, sensor=args.sensor)

    def report(self, lines, args):
        res, self.text = report(lines, only=_only(args.only))
        return res

    def finish(self, res, args):
        if args.out_dir:
            res["plots"] = _plots(res, args.out_dir)
        return res

    def print_table(self, res, args):
        print("\n".join(self.text) + "\n", flush=True)
        if res.get("plots"):
            print("plots: " + ", ".join(res["plots"]))


def run(*, only=EXPERIMENTS, quick: bool = False, seed: int = 0, seeds: int = 10, n: int = 200,
        out: str | None = None, progress: bool = True, echo=None, results: str | None = None,
        executor: str = "local", jobs: int | None = None,
        ray_address: str | None = None, sensor: str = "ideal") -> dict:
    """Run the selected experiments; returns {experiment: result} (plus "errors": trials
    that raised, "plots": files written to ``out``). ``echo``: callable taking the table
    lines of every experiment at the end.

    The trials (see :func:`trial_specs`) run through the sweep runner
    (``mmlearn.apps.common.sweep``): streamed to ``results`` (a JSON Lines file; None: a temporary
    one; trials already in it are not run again), ``executor`` "local" (``jobs`` processes,
    default all cores) or "ray" (``ray_address``: a cluster, None: a local Ray instance).
    ``sensor``: "ideal" or "camera" (see :func:`observe`)."""
    exp = StructureExperiments()
    args = argparse.Namespace(only=only, quick=quick, seed=seed, seeds=seeds, n=n,
                              out_dir=out, no_progress=not progress, sensor=sensor)
    res = experiment.run_experiment(exp, args, results=results, executor=executor, jobs=jobs,
                                    ray_address=ray_address)
    if echo is not None:
        echo(exp.text)
    return res


def main(argv=None) -> int:
    return experiment.main(StructureExperiments(), argv)


if __name__ == "__main__":
    sys.exit(main())
