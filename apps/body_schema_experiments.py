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
* **numpy simulation** (:mod:`mmlearn.models.body_schema.kinematic_sim`) for the many-run statistics:
  Table 3.1 (7-DOF, ``--runs`` runs of 4 x 100 samples, engineered seed model) and
  Table 3.2 (4-DOF, 30 way points).

Prediction errors are measured on independent test configurations against the true
(noise-free) part poses, relative to the root part.

    python -m mmlearn.apps.body_schema_experiments --out-dir results/   # ~15-20 min
    python -m mmlearn.apps.body_schema_experiments --quick --json        # ~1 min CPU
        [--results FILE] [--executor local|ray] [--ray-address ADDR] [--jobs N]
    python -m mmlearn.apps.body_schema_experiments --report-only RESULTS.jsonl [--out-dir DIR]

Every run (of Fig. 3.10, the 7-DOF structure convergence, each table) is a trial of the
sweep runner (``mmlearn.apps.common.sweep``): run in parallel processes (``--jobs``, default all
cores) or as Ray tasks (``--executor ray``), streamed to ``--results`` (default
``body_schema_experiments_results.jsonl`` in ``--out-dir``); re-running the same command
resumes, ``--report-only FILE`` redraws the tables, the plot and the JSON from a results
file without running anything.
"""

from __future__ import annotations

import argparse
import copy
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

from mmlearn.apps.common import experiment
from mmlearn.apps.common.cli import (atomic_write_text, check_out_dir, pos_int, progress,
                                     save_figure)
from mmlearn.apps.common.experiment import Experiment
from mmlearn.apps.learn_body_schema import (
                                            babble,
                                            converged_at,
                                            is_correct,
                                            observation_noise,
                                            prediction_error,
                                            sample_test_commands,
                                            )
from mmlearn.models.common.trials import register_trial


def _diagram(arm, noise, seed, **kw):
    from pydrake.systems.analysis import Simulator

    from mmlearn.diagrams.body_schema.diagram import BodySchemaDiagramConfig, MakeBodySchemaDiagram

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
    from mmlearn.models.body_schema.schema import BodySchema

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


def _guarded(fn, kwargs):
    """fn(**kwargs, show=False); a run that raises ValueError, RuntimeError or LinAlgError
    becomes ``{"failed": reason}`` (a failed run of the robot / learner: counted in the
    tables, never silently dropped)."""
    try:
        return fn(**kwargs, show=False)
    except (ValueError, RuntimeError, np.linalg.LinAlgError) as e:
        return {"failed": f"{type(e).__name__}: {e}"}


def _ok(rs):
    """(runs that finished, their number failed, reasons)."""
    ok = [r for r in rs if "failed" not in r]
    return ok, len(rs) - len(ok), [r["failed"] for r in rs if "failed" in r]


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

def _numpy_recovery(*, failure, visibility, show=False, **kw):
    from mmlearn.models.body_schema.evaluation import recovery_experiment
    from mmlearn.models.body_schema.kinematic_sim import make_arm_7dof

    return recovery_experiment(make_arm_7dof, failure, visibility=visibility, **kw)


def _numpy_control(*, show=False, **kw):
    from mmlearn.models.body_schema.evaluation import control_experiment
    from mmlearn.models.body_schema.kinematic_sim import make_arm_4dof

    return control_experiment(make_arm_4dof, **kw)


#: the experiments' blocks: (trial function, its runs raising ValueError / RuntimeError /
#: LinAlgError are failed runs counted in the tables (True) or trial errors (False))
BLOCKS = {"fig_3_10": ("accuracy", False), "noise_free": ("accuracy", False),
          "7dof_occluded": ("accuracy", False), "7dof_structure": ("accuracy", False),
          "table_3_1_numpy": ("numpy_recovery", True), "table_3_2_numpy": ("numpy_control", True),
          "table_3_1_drake": ("recovery", True), "table_3_2_drake": ("control", True)}


@register_trial("body_schema.experiment")
def trial(*, seed: int, block: str, run: int = 0, kwargs: dict, quick: bool = False,
          shared=None) -> dict:
    """One run of one experiment (the sweep's trial function, ``mmlearn.apps.common.sweep``):
    ``block`` names the experiment (:data:`BLOCKS`), ``run`` the run's index in it,
    ``kwargs`` the keyword arguments of its function (:func:`drake_accuracy`,
    :func:`drake_recovery`, :func:`drake_control` or the numpy simulation's
    ``recovery_experiment`` / ``control_experiment``). A Table 3.1 / 3.2 run that raises
    returns ``{"failed": reason}`` (counted in the table); ``quick`` only names the setting."""
    if block not in BLOCKS:
        raise ValueError(f"unknown block {block!r}; choose from {', '.join(BLOCKS)}")
    fn = {"accuracy": drake_accuracy, "recovery": drake_recovery, "control": drake_control,
          "numpy_recovery": _numpy_recovery, "numpy_control": _numpy_control}[BLOCKS[block][0]]
    kw = dict(kwargs, seed=seed)
    if BLOCKS[block][1]:
        return _guarded(fn, kw)
    if fn is drake_accuracy:
        kw = dict(kw, sizes=list(kw["sizes"]))
        arm, noise, sizes = kw.pop("arm"), kw.pop("noise"), kw.pop("sizes")
        out = drake_accuracy(arm, noise, sizes, show=False, **kw)
        if block == "7dof_structure":
            out["correct_from"] = _correct_from(out["rows"])
        return out
    return fn(**kw, show=False)


def trial_specs(*, quick: bool = False, runs: int = 20, seed: int = 0, structure_runs: int = 5,
                drake_runs: int = 6, fig310_runs: int = 3) -> list:
    """The sweep's trials (one per run of every experiment), with the seeds of the
    experiments: Fig. 3.10 seed + 100 r, noise-free seed + 1, 7-DOF occluded seed + 2, 7-DOF
    structure seed + 10 + r, the tables seed + r."""
    from mmlearn.apps.common.sweep import TrialSpec

    fn = trial

    def spec(block, r, s, label, **kw):
        return TrialSpec(fn=fn, seed=s, label=f"{label} run {r} seed {s}",
                         params={"block": block, "run": r, "quick": quick, "kwargs": kw})

    sizes = [5, 10, 15, 20] if quick else [5, 10, 15, 20, 30, 50, 100]
    specs = [spec("fig_3_10", r, seed + 100 * r, "Fig. 3.10", arm="2dof", noise=0.044,
                  sizes=sizes, n_test=30 if quick else 200, n_control=1 if quick else 20)
             for r in range(1 if quick else fig310_runs)]
    specs.append(spec("noise_free", 0, seed + 1, "noise-free 2-DOF", arm="2dof", noise=0.0,
                      sizes=[20] if quick else [20, 100], n_test=30 if quick else 60,
                      n_control=0))
    specs.append(spec("7dof_occluded", 0, seed + 2, "7-DOF occluded", arm="7dof", noise=0.0,
                      sizes=[15] if quick else [10, 15, 20, 50, 100],
                      n_test=20 if quick else 100, n_control=0, occlude=["x4"]))
    specs += [spec("7dof_structure", r, seed + 10 + r, "7-DOF structure", arm="7dof",
                   noise=0.044, sizes=[8, 10, 12] if quick else [8, 10, 12, 15, 20, 30],
                   n_test=10 if quick else 60, n_control=0, occlude=["x4"])
              for r in range(1 if quick else structure_runs)]
    nkw = dict(n_block=20) if quick else {}
    for failure, vis in (("joint", 0.919), ("tool", 0.790)):
        specs += [spec("table_3_1_numpy", r, seed + r, f"Table 3.1 numpy {failure}",
                       failure=failure, visibility=vis, **nkw)
                  for r in range(1 if quick else runs)]
    ckw = dict(n_learn=30, n_waypoints=6, n_adapt=40) if quick else {}
    specs += [spec("table_3_2_numpy", r, seed + r, "Table 3.2 numpy", **ckw)
              for r in range(max(1, (1 if quick else runs) // 4))]
    for failure in ("joint", "tool"):
        specs += [spec("table_3_1_drake", r, seed + r, f"Table 3.1 Drake {failure}",
                       failure=failure, n_block=10 if quick else 100, n_first=30)
                  for r in range(1 if quick else drake_runs)]
    specs += [spec("table_3_2_drake", r, seed + r, "Table 3.2 Drake",
                   n_learn=30 if quick else 100, n_adapt=30 if quick else 150,
                   n_waypoints=4 if quick else 30)
              for r in range(1 if quick else max(1, drake_runs // 2))]
    return specs


def recovery_summary(rs, *, drake: bool) -> dict:
    """Table 3.1 over runs (records of :func:`drake_recovery` or the numpy
    ``recovery_experiment``, ``{"failed": reason}`` for a failed run): mean and std of
    first / restore / second over the runs that finished; the Drake rows also per run."""
    ok, failed, why = _ok(rs)
    f = np.array([[r["first"], r["restore"], r["second"]] for r in ok], float).reshape(-1, 3)
    nan3 = [float("nan")] * 3
    out = dict(mean=f.mean(0).tolist() if ok else nan3, std=f.std(0).tolist() if ok else nan3,
               runs=len(rs), failed_runs=failed, failures=why)
    if drake:
        out.update(per_run=f.astype(int).tolist(), first=ok[0]["first"] if ok else None,
                   restore=ok[0]["restore"] if ok else None,
                   second=ok[0]["second"] if ok else None)
    return out


def control_summary(rs, *, drake: bool) -> dict:
    """Table 3.2 over runs: mean control errors [m] over the runs that finished."""
    keys = ("intact_static", "bent_static", "bent_adaptive")
    ok, failed, why = _ok(rs)
    if drake:
        out = {k: float(np.mean([r[k] for r in ok])) if ok else float("nan") for k in keys}
        out.update(runs=len(rs), failed_runs=failed, failures=why,
                   per_run=[[r[k] for k in keys] for r in ok],
                   valid_after=bool(ok) and all(r["valid_after"] for r in ok))
    else:
        out = {k: float(np.mean([r[k][0] for r in ok])) if ok else float("nan") for k in keys}
        out.update(runs=len(rs), failed_runs=failed, failures=why)
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

WHERE = {"fig_3_10": "drake", "noise_free": "drake", "7dof_occluded": "drake",
         "7dof_structure": "drake",
         "table_3_1": "numpy (statistics) + drake (--drake-runs runs per failure, 2-DOF)",
         "table_3_2": "numpy (statistics) + drake (--drake-runs // 2 runs, 4-DOF)"}


def report(lines: list[dict]) -> dict:
    """The experiments' results from results-file lines (a run or ``--report-only``).
    A trial that raised is listed in ``errors``; in Tables 3.1 / 3.2 it also counts as a
    failed run, elsewhere it is left out (the averages say over how many runs)."""
    if len({bool(ln["spec"]["params"].get("quick")) for ln in lines}) > 1:
        raise ValueError("the results file holds runs of --quick and of the full setting; "
                         "use one results file per setting")
    by: dict[str, list] = {}
    for ln in lines:
        p = ln["spec"]["params"]
        by.setdefault(p["block"], []).append(ln)
    for v in by.values():
        v.sort(key=lambda ln: ln["spec"]["params"]["run"])

    def recs(block, *, failed_as_run):
        out = []
        for ln in by.get(block, []):
            if ln.get("error") is None:
                out.append(ln["record"])
            elif failed_as_run:
                out.append({"failed": f"trial error: {ln['error']}"})
        return out

    quick = any(ln["spec"]["params"].get("quick") for ln in lines)
    res = {"quick": quick, "where": dict(WHERE)}
    fig = recs("fig_3_10", failed_as_run=False)
    if fig:
        res["fig_3_10"] = _average_runs(fig)
    for block in ("noise_free", "7dof_occluded"):
        r = recs(block, failed_as_run=False)
        if r:
            res[block] = r[0]
    st = recs("7dof_structure", failed_as_run=False)
    if st:
        res["7dof_structure"] = st
    t31 = {f: [r for r, ln in zip(recs("table_3_1_drake", failed_as_run=True),
                                  by.get("table_3_1_drake", []))
               if ln["spec"]["params"]["kwargs"]["failure"] == f] for f in ("joint", "tool")}
    if any(t31.values()):
        res["table_3_1_drake"] = {f: recovery_summary(v, drake=True) for f, v in t31.items()}
    c = recs("table_3_2_drake", failed_as_run=True)
    if c:
        res["table_3_2_drake"] = control_summary(c, drake=True)
    t31 = {f: [r for r, ln in zip(recs("table_3_1_numpy", failed_as_run=True),
                                  by.get("table_3_1_numpy", []))
               if ln["spec"]["params"]["kwargs"]["failure"] == f] for f in ("joint", "tool")}
    if any(t31.values()):
        res["table_3_1_numpy"] = {f: recovery_summary(v, drake=False) for f, v in t31.items()}
    c = recs("table_3_2_numpy", failed_as_run=True)
    if c:
        res["table_3_2_numpy"] = control_summary(c, drake=False)
    res["seconds"] = float(sum(ln.get("wall_s") or 0.0 for ln in lines))
    res["errors"] = [{"trial": ln["spec"].get("label") or ln["key"], "error": ln["error"]}
                     for ln in lines if ln.get("error") is not None]
    return res


def write_outputs(res: dict, out_dir: str | Path) -> dict:
    """Fig. 3.10's plot and ``body_schema_experiments.json`` in ``out_dir``."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    res["plots"] = []
    if "fig_3_10" in res:
        _plot(res["fig_3_10"], out / "fig_3_10.png")
        res["plots"].append(str(out / "fig_3_10.png"))
    atomic_write_text(out / "body_schema_experiments.json", json.dumps(res, indent=1))
    return res


class BodySchemaExperiments(Experiment):
    name = "body_schema_experiments"
    description = ("Reproduce the body-schema experiments of thesis Sec. 3.4 (Fig. 3.10, "
                   "noise-free accuracy, 7-DOF with an occluded part, Tables 3.1 and 3.2). "
                   "Learning runs in the Drake simulation; the many-run statistics of the "
                   "tables use the numpy simulation. Every mean says how many runs failed "
                   "and were left out. Every run is a trial of the sweep runner (resumable, "
                   "local processes or Ray). Exit status: 0 every trial ran, 1 a trial "
                   "raised an error, 2 bad input.")
    json_help = "print the results as JSON"
    desc = "body-schema runs"

    def add_arguments(self, ap):
        ap.add_argument("--quick", action="store_true",
                        help="one run of each, fewer samples (about a minute of CPU time)")
        ap.add_argument("--runs", type=pos_int, default=20,
                        help="numpy runs of Table 3.1 per failure, a quarter as many of Table "
                             "3.2 (20)")
        ap.add_argument("--structure-runs", type=pos_int, default=5,
                        help="Drake runs of the 7-DOF structure convergence (5)")
        ap.add_argument("--drake-runs", type=pos_int, default=6,
                        help="Drake runs of Table 3.1 per failure, half as many of Table 3.2 "
                             "(6)")
        ap.add_argument("--fig310-runs", type=pos_int, default=3,
                        help="Drake runs averaged in Fig. 3.10 (3)")
        ap.add_argument("--out-dir", type=Path, default=Path("."),
                        help="where plots, the JSON and the default results file go (default: "
                             "current directory)")

    def check(self, args):
        check_out_dir("--out-dir", args.out_dir)

    def specs(self, args):
        counts = (args.runs, args.structure_runs, args.drake_runs, args.fig310_runs)
        if min(counts) < 1:
            raise ValueError("runs, structure_runs, drake_runs and fig310_runs must be >= 1, "
                             "got " + ", ".join(map(str, counts)))
        return trial_specs(quick=args.quick, runs=args.runs, seed=args.seed,
                           structure_runs=args.structure_runs, drake_runs=args.drake_runs,
                           fig310_runs=args.fig310_runs)

    def report(self, lines, args):
        return report(lines)

    def attach_sweep(self, res, sweep, args):
        res["seconds"] = sweep.wall_s
        res["sweep"] = sweep.summary()

    def finish(self, res, args):
        return write_outputs(res, args.out_dir)

    def print_table(self, res, args):
        print(format_report(res))

    def to_json(self, res):
        return json.dumps(res)


def run(*, quick: bool = False, runs: int = 20, seed: int = 0, out_dir: str | Path = ".",
        show_progress: bool = True, structure_runs: int = 5, drake_runs: int = 6,
        fig310_runs: int = 3, results: str | None = None, executor: str = "local",
        jobs: int | None = None, ray_address: str | None = None) -> dict:
    """Run every experiment; write ``fig_3_10.png`` and ``body_schema_experiments.json`` to
    ``out_dir``; return the results. ``runs``: numpy runs of Table 3.1 per failure (runs // 4
    of Table 3.2); ``structure_runs``: Drake runs of the 7-DOF structure convergence (sensor
    noise 0.044 m); ``drake_runs``: Drake runs of Table 3.1 per failure and drake_runs // 2
    of Table 3.2; ``fig310_runs``: Drake runs averaged in Fig. 3.10.

    Every run is a trial of the sweep runner (``mmlearn.apps.common.sweep``): streamed to
    ``results`` (a JSON Lines file; None: a temporary one; runs already in it are not run
    again), ``executor`` "local" (``jobs`` processes, default all cores) or "ray"
    (``ray_address``: a cluster, None: a local Ray instance of ``jobs`` CPUs)."""
    args = argparse.Namespace(quick=quick, runs=runs, seed=seed, out_dir=out_dir,
                              json=not show_progress, structure_runs=structure_runs,
                              drake_runs=drake_runs, fig310_runs=fig310_runs)
    return experiment.run_experiment(BodySchemaExperiments(), args, results=results,
                                     executor=executor, jobs=jobs, ray_address=ray_address)


def _runs(d) -> str:
    """"k runs" or "k runs, f failed" (failed runs are left out of the means)."""
    f = d.get("failed_runs", 0)
    return f"{d['runs']} runs" + (f", {f} failed: left out of the mean" if f else ", 0 failed")


def format_report(res) -> str:
    """The tables of :func:`report`'s result (sections without any run are left out)."""
    nan = float("nan")
    L = []
    if "fig_3_10" in res:
        f = res["fig_3_10"]
        L.append(f"Fig. 3.10 [Drake, mean of {f['runs']} runs] 2-DOF, sigma 0.044 m; "
                 f"observation noise (mean position "
                 f"error of a marker) {f['obs_noise_m']:.4f} m; online structure correct from "
                 f"sample {f['online_converged_at_runs']}; "
                 f"schema update median "
                 f"{f['update_ms_median']:.2f} ms")
        L.append("   n  structure  prediction [m]  [deg]  positioning [m]  runs in mean (left "
                 "out: no complete schema / fit failed)")
        for r in f["rows"]:
            L.append(f"{r['n']:4d}  {'correct' if r['correct'] else 'wrong  '}    "
                     f"{r.get('pred_error_m', nan):.4f}        "
                     f"{r.get('pred_error_deg', nan):.2f}   "
                     f"{r.get('positioning_error_m', nan):.4f}           "
                     f"{r.get('runs_in_mean', f['runs'])}/{f['runs']}")
    for key, title in (("noise_free", "noise-free 2-DOF"),
                       ("7dof_occluded", "7-DOF, 10 parts, x4 occluded, noise-free")):
        if key not in res:
            continue
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
    if "7dof_structure" in res:
        st = res["7dof_structure"]
        cf = [d["correct_from"] for d in st]
        ok = [c for c in cf if c is not None]
        L.append(f"7-DOF, 10 parts, x4 occluded, sigma 0.044 m [Drake, {len(st)} runs]: "
                 f"structure correct from n = {cf} (median "
                 f"{'n/a' if not ok else f'{float(np.median(ok)):g}'} over {len(ok)} runs; "
                 f"{len(cf) - len(ok)} never correct up to the largest n, left out; tested n = "
                 f"{[r['n'] for r in st[0]['rows']]})")
    nan3 = {"mean": [nan] * 3, "runs": 0, "per_run": []}
    t31n, t31d = res.get("table_3_1_numpy"), res.get("table_3_1_drake")
    if t31n or t31d:
        L.append("Table 3.1: samples until a valid model again (first / restore / second)")
        for fl, name in (("joint", "joint stuck"), ("tool", "tool exchange")):
            nm = (t31n or {}).get(fl, nan3)
            m = nm["mean"]
            d = (t31d or {}).get(fl, nan3)
            dm = d["mean"]
            L.append(f"  {name:14s} numpy 7-DOF ({_runs(nm)}): "
                     f"{m[0]:.2f} / {m[1]:.2f} / {m[2]:.2f};  Drake 2-DOF ({_runs(d)}): "
                     f"{dm[0]:.2f} / {dm[1]:.2f} / {dm[2]:.2f}  (per run {d['per_run']})")
    n, d = res.get("table_3_2_numpy"), res.get("table_3_2_drake")
    if n or d:
        L.append("Table 3.2: control error [m] (intact static / bent static / bent adaptive)")
    if n:
        L.append(f"  numpy 4-DOF ({_runs(n)}): {n['intact_static']:.3f} / "
                 f"{n['bent_static']:.3f} / {n['bent_adaptive']:.3f}")
    if d:
        L.append(f"  Drake 4-DOF ({_runs(d)}): {d['intact_static']:.3f} / "
                 f"{d['bent_static']:.3f} / "
                 f"{d['bent_adaptive']:.3f}")
    for t in (t31n, t31d):
        for fl in ("joint", "tool"):
            for why in (t or {}).get(fl, {}).get("failures", []):
                L.append(f"  failed run (Table 3.1 {fl}): {why}")
    for t in (n, d):
        for why in (t or {}).get("failures", []):
            L.append(f"  failed run (Table 3.2): {why}")
    for e in res.get("errors", []):
        L.append(f"  error: trial {e['trial']} raised {e['error']}")
    L.append(f"plots: {', '.join(res.get('plots', []))}; {res['seconds']:.0f} s")
    return "\n".join(L)


def main(argv=None) -> int:
    return experiment.main(BodySchemaExperiments(), argv)


if __name__ == "__main__":
    sys.exit(main())
