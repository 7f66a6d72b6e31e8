"""Body-schema experiments of thesis Sec. 3.4: Fig. 3.10, the noise-free accuracy, the 7-DOF
arm with an occluded part, Table 3.1 (recovery after failures) and Table 3.2 (control with a
bent link).

Where each runs:

* **Drake simulation** (the arm in a MultibodyPlant with implicit PD control, observed by
  the MarkerSensor; data gathered by motor babbling with the SchemaLearner in the loop;
  failures in the plant: JointBlocker / hidden locked joints):
  Fig. 3.10 (2-DOF, sigma 0.044 m; the schema is re-fitted on the first n Drake samples for
  each n; mean of ``--fig310-runs`` runs), the noise-free accuracy (2-DOF, 20 and 100
  samples), the 7-DOF 10-part arm with x4 occluded (noise-free accuracy, and the structure
  convergence with the sensor noise of Fig. 3.10 over ``--structure-runs`` runs),
  ``--drake-runs`` runs of Table 3.1 per failure (2-DOF arm: joint q2 blocked, tool changed;
  the schema is learned from scratch in block 1) and ``--drake-runs`` / 2 runs of Table 3.2
  (4-DOF arm, link x3 bent by 45 deg in the plant; the goal commands are solved on the
  learned model by the SchemaController's solver and the error is measured on the plant's
  kinematics at those commands).
* **numpy simulation** (:mod:`mmlearn.models.kinematic_sim`) for the many-run statistics:
  Table 3.1 (7-DOF, ``--runs`` runs of 4 x 100 samples, engineered seed model) and
  Table 3.2 (4-DOF, 30 way points).

Prediction errors are measured on independent test configurations against the true
(noise-free) part poses, relative to the root part.

    python -m mmlearn.apps.body_schema_experiments --out-dir results/   # ~15-20 min
    python -m mmlearn.apps.body_schema_experiments --quick --json        # ~1 min CPU
"""

from __future__ import annotations

import copy
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

from mmlearn.apps._common import (ArgumentParser, UsageError, atomic_write_text, check_out_dir,
                                  fail, nonneg_int, pos_int, progress)
from mmlearn.apps._common import save_figure
from mmlearn.apps.learn_body_schema import (
    babble,
    converged_at,
    is_correct,
    observation_noise,
    prediction_error,
    sample_test_commands,
)


def _diagram(arm, noise, seed, **kw):
    from pydrake.systems.analysis import Simulator

    from mmlearn.diagrams.body_schema import BodySchemaDiagramConfig, MakeBodySchemaDiagram

    # noise-free runs need a floor on the learner's noise level for the 3-sigma validity
    # test: 1 cm
    kw.setdefault("search_min_pos", 0.01)
    bs = MakeBodySchemaDiagram(BodySchemaDiagramConfig(
        arm=arm, noise_pos=noise, noise_orient=0.0, seed=seed, babble_fraction=0.6, **kw))
    sim = Simulator(bs.diagram)
    root = sim.get_mutable_context()
    bs.prepare(root)
    sim.Initialize()
    return bs, sim, root


def _positioning_error(bs, root, schema, Q):
    """Mean true distance of the end effector (relative to the root part) to targets, at
    the commands the SchemaController's solver finds on ``schema``."""
    ee, r = bs.learner.end_effector, schema.root
    start = 0.5 * (bs.controller._lo + bs.controller._hi)
    errs = []
    for q in Q:
        X = bs.true_poses(root, q)
        tgt = (np.linalg.inv(X[r]) @ X[ee])[:3, 3]
        qs = bs.controller._solve(schema, start, tgt)
        Xs = bs.true_poses(root, qs)
        errs.append(np.linalg.norm((np.linalg.inv(Xs[r]) @ Xs[ee])[:3, 3] - tgt))
    return float(np.mean(errs))


def drake_accuracy(arm, noise, sizes, *, seed, n_test, n_control, occlude=(), show=True):
    """Gather max(sizes) samples in Drake, then fit the schema on the first n of them."""
    from mmlearn.models.body_schema import BodySchema

    bs, sim, root = _diagram(arm, noise, seed, occlude=list(occlude))
    t0 = time.perf_counter()
    babble(bs, sim, max(sizes), show_progress=show, desc=f"{arm} babbling")
    st = bs.learner.state(root)
    A, P = st.schema.buffer()
    rng = np.random.default_rng([seed, 99])
    Q = sample_test_commands(bs, n_test, rng)
    obs = observation_noise(bs, root, Q[:30], seed)
    rows = []
    for n in sizes:
        sch = BodySchema(len(bs.parts), A.shape[1], search=bs.learner._cfg.search)
        row = dict(n=int(n))
        try:
            res = sch.fit(A[:n], P[:n])
        except ValueError as e:
            rows.append({**row, "correct": False, "error": str(e)})
            continue
        keys = [(m.i, m.j, m.Q) for m in res.tree]
        row["correct"] = bool(res.complete and is_correct(keys, bs.truth, len(res.nodes)))
        if res.complete:
            row["pred_error_m"], row["pred_error_deg"] = prediction_error(bs, root, sch, Q)
            if n_control:
                row["positioning_error_m"] = _positioning_error(bs, root, sch,
                                                                Q[:n_control])
        rows.append(row)
    n_nodes = len(st.schema.nodes) or len(bs.parts)
    return dict(arm=arm, noise=noise, occluded=list(occlude), parts=bs.parts,
                obs_noise_m=obs, rows=rows,
                online_converged_at=converged_at(st.history, bs.truth, n_nodes),
                update_ms_median=float(1000 * np.median(st.update_seconds)),
                sim_seconds=float(root.get_time()), seconds=time.perf_counter() - t0)


def drake_recovery(failure, *, n_block, seed, arm="2dof", n_first=30, show=True):
    """Table 3.1 protocol in Drake: block 1 learns from scratch (intact; at least
    ``n_first`` samples), blocks 2 and 4
    with the failure (joint q2 stuck at 0.5 rad / a tool 0.10 m longer and tilted by
    30 deg), block 3 restored; samples without a valid spanning tree per block."""
    bs, sim, root = _diagram(arm, 0.01, seed)
    invalid = []
    for b in range(4):
        broken = b % 2 == 1
        if failure == "joint":
            if broken:
                bs.blocker.block(root, 1, value=0.5)  # q2 stuck at 0.5 rad, both times
            else:
                bs.blocker.unblock(root)
        else:
            if broken:
                bs.failures.change_tool(root, 0.10, math.radians(30))
            else:
                bs.failures.reset_tool(root)
        n_inv = 0
        n = max(n_block, n_first) if b == 0 else n_block  # block 1 also learns the schema
        for _ in progress(range(n), desc=f"{failure} block {b + 1}", unit="sample",
                          enabled=show):
            babble(bs, sim, 1, show_progress=False)
            n_inv += not bs.learner.state(root).schema.valid
        invalid.append(n_inv)
    return dict(steps_invalid=invalid, first=invalid[1], restore=invalid[2],
                second=invalid[3], events=[e for _, e in bs.learner.state(root).schema.events])


def _call(job):
    fn, kwargs = job
    return _guarded(fn, kwargs, show=False)


def _guarded(fn, kwargs, *, show):
    """fn(**kwargs); a run that raises becomes ``{"failed": reason}`` (counted in the
    tables, never silently dropped)."""
    try:
        return fn(**kwargs, show=show)
    except (ValueError, RuntimeError, np.linalg.LinAlgError) as e:
        return {"failed": f"{type(e).__name__}: {e}"}


def _ok(rs):
    """(runs that finished, their number failed, reasons)."""
    ok = [r for r in rs if "failed" not in r]
    return ok, len(rs) - len(ok), [r["failed"] for r in rs if "failed" in r]


def _parallel(fn, kwargs_list, *, workers=2, desc="", show=True):
    """fn(**kwargs) for every kwargs in ``workers`` processes (in order)."""
    if workers > 1 and len(kwargs_list) > 1:
        import multiprocessing as mp
        from concurrent.futures import ProcessPoolExecutor

        with ProcessPoolExecutor(workers, mp_context=mp.get_context("spawn")) as ex:
            return list(progress(ex.map(_call, [(fn, k) for k in kwargs_list]),
                                 total=len(kwargs_list), desc=desc, unit="run", enabled=show))
    return [_guarded(fn, k, show=show) for k in kwargs_list]


def drake_recovery_runs(failure, *, runs, n_block, seed, n_first=30, workers=2, show=True):
    """``runs`` independent Drake runs of :func:`drake_recovery` (seeds seed..seed+runs-1)
    in ``workers`` processes; mean and std of first / restore / second."""
    rs = _parallel(drake_recovery, [dict(failure=failure, n_block=n_block, seed=seed + r,
                                         n_first=n_first) for r in range(runs)],
                   workers=workers, desc=f"Drake Table 3.1 {failure}", show=show)
    ok, failed, why = _ok(rs)
    f = np.array([[r["first"], r["restore"], r["second"]] for r in ok], float).reshape(-1, 3)
    nan3 = [float("nan")] * 3
    return dict(mean=f.mean(0).tolist() if ok else nan3, std=f.std(0).tolist() if ok else nan3,
                runs=runs, failed_runs=failed, failures=why,
                per_run=f.astype(int).tolist(), first=ok[0]["first"] if ok else None,
                restore=ok[0]["restore"] if ok else None,
                second=ok[0]["second"] if ok else None)


def drake_control_runs(*, runs, seed, workers=2, show=True, **kw):
    """``runs`` independent Drake runs of :func:`drake_control`; means and per-run values."""
    rs = _parallel(drake_control, [dict(seed=seed + r, **kw) for r in range(runs)],
                   workers=workers, desc="Drake Table 3.2", show=show)
    keys = ("intact_static", "bent_static", "bent_adaptive")
    ok, failed, why = _ok(rs)
    out = {k: float(np.mean([r[k] for r in ok])) if ok else float("nan") for k in keys}
    out.update(runs=runs, failed_runs=failed, failures=why,
               per_run=[[r[k] for k in keys] for r in ok],
               valid_after=bool(ok) and all(r["valid_after"] for r in ok))
    return out


def drake_control(*, n_learn, n_adapt, n_waypoints, seed, show=True):
    """Table 3.2 in Drake: 4-DOF arm, x3 bent by 45 deg in the plant."""
    bs, sim, root = _diagram("4dof", 0.005, seed)
    babble(bs, sim, n_learn, show_progress=show, desc="4dof learning")
    static = copy.deepcopy(bs.learner.state(root).schema)
    rng = np.random.default_rng([seed, 5])
    # a smooth trajectory of way points inside the babbling range
    lo, hi = bs.babbling._lo, bs.babbling._hi
    s_ = np.linspace(0, 1, n_waypoints)[:, None]
    Qw = 0.5 * (lo + hi) + 0.35 * (hi - lo) * np.sin(2 * np.pi * s_ +
                                                     rng.uniform(0, 2 * np.pi, lo.size))
    out = dict(intact_static=_positioning_error(bs, root, static, Qw))
    bs.failures.bend_link(root, math.pi / 4)
    out["bent_static"] = _positioning_error(bs, root, static, Qw)
    babble(bs, sim, n_adapt, show_progress=show, desc="4dof adapting")
    sch = bs.learner.state(root).schema
    out["bent_adaptive"] = _positioning_error(bs, root, sch, Qw)
    out["valid_after"] = bool(sch.valid)
    return out


def numpy_tables(*, runs, quick, seed, show=True):
    from mmlearn.models.body_schema_experiments import control_experiment, recovery_experiment
    from mmlearn.models.kinematic_sim import make_arm_4dof, make_arm_7dof

    def guarded(fn, *a, **k):
        try:
            return fn(*a, **k)
        except (ValueError, RuntimeError, np.linalg.LinAlgError) as e:
            return {"failed": f"{type(e).__name__}: {e}"}

    kw = dict(n_block=20) if quick else {}
    t31 = {}
    for failure, vis in (("joint", 0.919), ("tool", 0.790)):
        rs = [guarded(recovery_experiment, make_arm_7dof, failure, seed=seed + r,
                      visibility=vis, **kw)
              for r in progress(range(runs), desc=f"Table 3.1 {failure}", unit="run",
                                enabled=show)]
        ok, failed, why = _ok(rs)
        f = np.array([[r["first"], r["restore"], r["second"]] for r in ok], float).reshape(-1, 3)
        nan3 = [float("nan")] * 3
        t31[failure] = dict(mean=f.mean(0).tolist() if ok else nan3,
                            std=f.std(0).tolist() if ok else nan3, runs=runs,
                            failed_runs=failed, failures=why)
    ckw = dict(n_learn=30, n_waypoints=6, n_adapt=40) if quick else {}
    rs = [guarded(control_experiment, make_arm_4dof, seed=seed + r, **ckw)
          for r in progress(range(max(1, runs // 4)), desc="Table 3.2", unit="run",
                            enabled=show)]
    ok, failed, why = _ok(rs)
    t32 = {k: float(np.mean([r[k][0] for r in ok])) if ok else float("nan") for k in
           ("intact_static", "bent_static", "bent_adaptive")}
    t32.update(runs=len(rs), failed_runs=failed, failures=why)
    return t31, t32


def _drake_tables(*, quick, drake_runs, seed, show):
    """Tables 3.1 and 3.2 in Drake (``--drake-runs`` runs per failure, half as many of
    Table 3.2; one run each with ``quick``)."""
    n_block = 10 if quick else 100
    out = {"table_3_1_drake": {f: drake_recovery_runs(f, runs=1 if quick else drake_runs,
                                                      n_block=n_block, seed=seed, show=show)
                               for f in ("joint", "tool")}}
    out["table_3_2_drake"] = drake_control_runs(runs=1 if quick else max(1, drake_runs // 2),
                                                n_learn=30 if quick else 100,
                                                n_adapt=30 if quick else 150,
                                                n_waypoints=4 if quick else 30, seed=seed,
                                                show=show)
    return out


def _plot(fig310, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = [r for r in fig310["rows"] if "pred_error_m" in r]
    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    n = [r["n"] for r in rows]
    ax[0].plot(n, [r["pred_error_m"] for r in rows], "o-", label="prediction (learned model)")
    ax[0].axhline(fig310["obs_noise_m"], color="r", ls="--", label="observation noise")
    ax[0].set_xlabel("samples")
    ax[0].set_ylabel("mean position error [m]")
    ax[0].set_title("Fig. 3.10: 2-DOF, sigma 0.044 m (Drake)")
    ax[0].legend()
    if any("positioning_error_m" in r for r in rows):
        ax[1].plot(n, [r.get("positioning_error_m", np.nan) for r in rows], "s-")
    ax[1].set_xlabel("samples")
    ax[1].set_ylabel("positioning error [m]")
    ax[1].set_title("positioning by the learned model")
    for a in ax:
        a.set_xscale("log")
        a.grid(True, alpha=0.3)
    fig.tight_layout()
    save_figure(fig, path, dpi=100)
    plt.close(fig)


def _average_runs(results):
    """Fig. 3.10 over several Drake runs: per n the share of runs with the correct structure
    and the mean errors over the runs with a complete schema."""
    rows = []
    for i, r0 in enumerate(results[0]["rows"]):
        rs = [d["rows"][i] for d in results]
        row = dict(n=r0["n"], correct=all(r["correct"] for r in rs),
                   correct_share=float(np.mean([r["correct"] for r in rs])))
        for k in ("pred_error_m", "pred_error_deg", "positioning_error_m"):
            v = [r[k] for r in rs if k in r]
            if v:
                row[k] = float(np.mean(v))
                row[k + "_runs"] = v
        # runs whose schema was incomplete or whose fit failed have no errors: say how many
        row["runs_in_mean"] = sum("pred_error_m" in r for r in rs)
        row["runs_left_out"] = len(rs) - row["runs_in_mean"]
        rows.append(row)
    conv = [d["online_converged_at"] for d in results]
    return dict(results[0], rows=rows, runs=len(results),
                obs_noise_m=float(np.mean([d["obs_noise_m"] for d in results])),
                online_converged_at=(None if None in conv else max(conv)),
                online_converged_at_runs=conv,
                update_ms_median=float(np.median([d["update_ms_median"] for d in results])),
                seconds=float(sum(d["seconds"] for d in results)))


def _correct_from(rows):
    """Smallest n from which the fitted structure is correct for every larger n (None)."""
    n = None
    for r in reversed(rows):
        if not r["correct"]:
            break
        n = r["n"]
    return n


def run(*, quick: bool = False, runs: int = 20, seed: int = 0, out_dir: str | Path = ".",
        show_progress: bool = True, structure_runs: int = 5, drake_runs: int = 6,
        fig310_runs: int = 3) -> dict:
    """Run every experiment; write ``fig_3_10.png`` and ``body_schema_experiments.json`` to
    ``out_dir``; return the results. ``structure_runs``: Drake runs of the 7-DOF structure
    convergence (sensor noise 0.044 m); ``drake_runs``: Drake runs of Table 3.1 per failure
    and drake_runs // 2 of Table 3.2 (two at a time); ``fig310_runs``: Drake runs averaged
    in Fig. 3.10."""
    if min(runs, structure_runs, drake_runs, fig310_runs) < 1:
        raise ValueError(f"runs, structure_runs, drake_runs and fig310_runs must be >= 1, "
                         f"got {runs}, {structure_runs}, {drake_runs}, {fig310_runs}")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    show = show_progress
    sizes = [5, 10, 15, 20] if quick else [5, 10, 15, 20, 30, 50, 100]
    tables = pool = None
    if quick:
        # one run of each Drake table in a second process while this one runs the accuracy
        # experiments (the full setting parallelises the tables' runs instead)
        import multiprocessing as mp
        from concurrent.futures import ProcessPoolExecutor

        pool = ProcessPoolExecutor(1, mp_context=mp.get_context("spawn"))
        tables = pool.submit(_drake_tables, quick=True, drake_runs=1, seed=seed, show=False)
    try:
        return _run_rest(tables, quick=quick, runs=runs, seed=seed, out=out, t0=t0,
                         show=show, sizes=sizes, structure_runs=structure_runs,
                         drake_runs=drake_runs, fig310_runs=fig310_runs)
    finally:
        if pool is not None:
            pool.shutdown(cancel_futures=True)


def _run_rest(tables, *, quick, runs, seed, out, t0, show, sizes, structure_runs,
              drake_runs, fig310_runs):
    res = {"quick": quick, "where": {
        "fig_3_10": "drake", "noise_free": "drake", "7dof_occluded": "drake",
        "7dof_structure": "drake",
        "table_3_1": "numpy (statistics) + drake (--drake-runs runs per failure, 2-DOF)",
        "table_3_2": "numpy (statistics) + drake (--drake-runs // 2 runs, 4-DOF)"}}
    res["fig_3_10"] = _average_runs([
        drake_accuracy("2dof", 0.044, sizes, seed=seed + 100 * r, n_test=30 if quick else 200,
                       n_control=1 if quick else 20, show=show)
        for r in range(1 if quick else fig310_runs)])
    res["noise_free"] = drake_accuracy("2dof", 0.0, [20] if quick else [20, 100],
                                       seed=seed + 1, n_test=30 if quick else 60, n_control=0,
                                       show=show)
    res["7dof_occluded"] = drake_accuracy("7dof", 0.0, [15] if quick else [10, 15, 20, 50, 100],
                                          seed=seed + 2, n_test=20 if quick else 100,
                                          n_control=0, occlude=["x4"], show=show)
    # structure convergence of the 7-DOF arm with the sensor noise of Fig. 3.10
    n_struct = [8, 10, 12, 15, 20, 30]
    res["7dof_structure"] = []
    for r in range(1 if quick else structure_runs):
        d = drake_accuracy("7dof", 0.044, [8, 10, 12] if quick else n_struct,
                           seed=seed + 10 + r, n_test=10 if quick else 60, n_control=0,
                           occlude=["x4"], show=show)
        d["correct_from"] = _correct_from(d["rows"])
        res["7dof_structure"].append(d)
    t31, t32 = numpy_tables(runs=1 if quick else runs, quick=quick, seed=seed, show=show)
    res.update(tables.result() if tables is not None else
               _drake_tables(quick=quick, drake_runs=drake_runs, seed=seed, show=show))
    res["table_3_1_numpy"], res["table_3_2_numpy"] = t31, t32
    res["seconds"] = time.perf_counter() - t0
    _plot(res["fig_3_10"], out / "fig_3_10.png")
    res["plots"] = [str(out / "fig_3_10.png")]
    atomic_write_text(out / "body_schema_experiments.json", json.dumps(res, indent=1))
    return res


def _runs(d) -> str:
    """"k runs" or "k runs, f failed" (failed runs are left out of the means)."""
    f = d.get("failed_runs", 0)
    return f"{d['runs']} runs" + (f", {f} failed: left out of the mean" if f else ", 0 failed")


def report(res) -> str:
    nan = float("nan")
    L = []
    f = res["fig_3_10"]
    L.append(f"Fig. 3.10 [Drake, mean of {f['runs']} runs] 2-DOF, sigma 0.044 m; "
             f"observation noise (mean position "
             f"error of a marker) {f['obs_noise_m']:.4f} m; online structure correct from "
             f"sample {f['online_converged_at_runs']}; "
             f"schema update median "
             f"{f['update_ms_median']:.2f} ms")
    L.append("   n  structure  prediction [m]  [deg]  positioning [m]  runs in mean (left out: "
             "no complete schema / fit failed)")
    for r in f["rows"]:
        L.append(f"{r['n']:4d}  {'correct' if r['correct'] else 'wrong  '}    "
                 f"{r.get('pred_error_m', nan):.4f}        "
                 f"{r.get('pred_error_deg', nan):.2f}   "
                 f"{r.get('positioning_error_m', nan):.4f}           "
                 f"{r.get('runs_in_mean', f['runs'])}/{f['runs']}")
    for key, title in (("noise_free", "noise-free 2-DOF"),
                       ("7dof_occluded", "7-DOF, 10 parts, x4 occluded, noise-free")):
        d = res[key]
        L.append(f"{title} [Drake]:")
        for r in d["rows"]:
            if "error" in r:
                L.append(f"  n={r['n']:3d}: fit failed ({r['error']})")
            elif "pred_error_m" not in r:
                L.append(f"  n={r['n']:3d}: structure {'correct' if r['correct'] else 'WRONG'},"
                         f" schema incomplete: no prediction error")
            else:
                L.append(f"  n={r['n']:3d}: structure "
                         f"{'correct' if r['correct'] else 'WRONG'}, error "
                         f"{1000 * r['pred_error_m']:.2f} mm / {r['pred_error_deg']:.3f} deg")
    st = res["7dof_structure"]
    cf = [d["correct_from"] for d in st]
    ok = [c for c in cf if c is not None]
    L.append(f"7-DOF, 10 parts, x4 occluded, sigma 0.044 m [Drake, {len(st)} runs]: structure "
             f"correct from n = {cf} (median "
             f"{'n/a' if not ok else f'{float(np.median(ok)):g}'} over {len(ok)} runs; "
             f"{len(cf) - len(ok)} never correct up to the largest n, left out; tested n = "
             f"{[r['n'] for r in st[0]['rows']]})")
    L.append("Table 3.1: samples until a valid model again (first / restore / second)")
    for fl, name in (("joint", "joint stuck"), ("tool", "tool exchange")):
        nm = res["table_3_1_numpy"][fl]
        m = nm["mean"]
        d = res["table_3_1_drake"][fl]
        dm = d["mean"]
        L.append(f"  {name:14s} numpy 7-DOF ({_runs(nm)}): "
                 f"{m[0]:.2f} / {m[1]:.2f} / {m[2]:.2f};  Drake 2-DOF ({_runs(d)}): "
                 f"{dm[0]:.2f} / {dm[1]:.2f} / {dm[2]:.2f}  (per run {d['per_run']})")
    L.append("Table 3.2: control error [m] (intact static / bent static / bent adaptive)")
    n = res["table_3_2_numpy"]
    d = res["table_3_2_drake"]
    L.append(f"  numpy 4-DOF ({_runs(n)}): {n['intact_static']:.3f} / "
             f"{n['bent_static']:.3f} / {n['bent_adaptive']:.3f}")
    L.append(f"  Drake 4-DOF ({_runs(d)}): {d['intact_static']:.3f} / "
             f"{d['bent_static']:.3f} / "
             f"{d['bent_adaptive']:.3f}")
    for t in (res["table_3_1_numpy"], res["table_3_1_drake"]):
        for fl in ("joint", "tool"):
            for why in t[fl].get("failures", []):
                L.append(f"  failed run (Table 3.1 {fl}): {why}")
    for t in (n, d):
        for why in t.get("failures", []):
            L.append(f"  failed run (Table 3.2): {why}")
    L.append(f"plots: {', '.join(res['plots'])}; {res['seconds']:.0f} s")
    return "\n".join(L)


def main(argv=None) -> int:
    ap = ArgumentParser(
        prog="python -m mmlearn.apps.body_schema_experiments",
        description="Reproduce the body-schema experiments of thesis Sec. 3.4 (Fig. 3.10, "
                    "noise-free accuracy, 7-DOF with an occluded part, Tables 3.1 and 3.2). "
                    "Learning runs in the Drake simulation; the many-run statistics of the "
                    "tables use the numpy simulation. Every mean says how many runs failed "
                    "and were left out.")
    ap.add_argument("--quick", action="store_true", help="one run of each, fewer samples (about a minute of CPU time, in "
                         "two processes)")
    ap.add_argument("--runs", type=pos_int, default=20, help="numpy runs of Table 3.1 (20)")
    ap.add_argument("--seed", type=nonneg_int, default=0)
    ap.add_argument("--structure-runs", type=pos_int, default=5,
                    help="Drake runs of the 7-DOF structure convergence (5)")
    ap.add_argument("--drake-runs", type=pos_int, default=6,
                    help="Drake runs of Table 3.1 per failure, half as many of Table 3.2; "
                         "two processes (6)")
    ap.add_argument("--fig310-runs", type=pos_int, default=3,
                    help="Drake runs averaged in Fig. 3.10 (3)")
    ap.add_argument("--out-dir", type=Path, default=Path("."),
                    help="where plots and the JSON go (default: current directory)")
    ap.add_argument("--json", action="store_true", help="print the results as JSON")
    args = ap.parse_args(argv)
    try:
        check_out_dir("--out-dir", args.out_dir)
    except UsageError as e:
        return fail(ap.prog, str(e))
    try:
        res = run(quick=args.quick, runs=args.runs, seed=args.seed, out_dir=args.out_dir,
                  show_progress=not args.json, structure_runs=args.structure_runs,
                  drake_runs=args.drake_runs, fig310_runs=args.fig310_runs)
    except ValueError as e:
        return fail(ap.prog, str(e))
    print(json.dumps(res) if args.json else report(res))
    return 0


if __name__ == "__main__":
    sys.exit(main())
