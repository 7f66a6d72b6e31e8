"""Experiments of thesis Sec. 3.4 on the simulated arms, and the metrics and report of the
body-schema experiments (their Drake runs: :mod:`mmlearn.diagrams.body_schema.trials`).

* :func:`accuracy_curve`: structure and prediction error vs number of samples (Fig. 3.10).
* :func:`recovery_experiment`: steps until a valid model again after a failure (Table 3.1).
* :func:`control_experiment`: control error of a static vs adaptive model on a bent arm
  (Table 3.2).
"""

from __future__ import annotations

import numpy as np

from mmlearn.models.body_schema.schema import AdaptationConfig, BodySchema
from mmlearn.models.body_schema.local import pose_errors, se3_inv
from mmlearn.models.body_schema.search import SearchConfig
from mmlearn.models.body_schema.kinematic_sim import SimArm

__all__ = ["structure_correct", "prediction_errors", "accuracy_curve",
           "recovery_experiment", "control_experiment", "is_correct", "converged_at",
           "recovery_summary", "control_summary", "average_runs", "correct_from", "BLOCK_WHERE",
           "body_schema_report"]


def structure_correct(arm: SimArm, tree, nodes) -> bool:
    """True when the tree spans ``nodes`` and every edge depends on exactly the joints on the
    true kinematic path between its two parts."""
    if len(tree) != len(nodes) - 1:
        return False
    return all(frozenset(m.Q) == arm.joints_between(m.i, m.j) for m in tree)


def prediction_errors(schema: BodySchema, arm: SimArm, actions, parts=None):
    """Mean translational (m) and rotational (rad) error of the learned FK (root frame)
    against the true poses, over ``actions`` and ``parts`` (default: all tree nodes but the
    root)."""
    X = arm.forward(actions)
    r = schema.root
    T_true = se3_inv(X[:, r:r + 1]) @ X
    T_pred = schema.forward_kinematics(actions)
    parts = [p for p in schema.nodes if p != r] if parts is None else list(parts)
    dp, dr = pose_errors(T_pred[:, parts], T_true[:, parts])
    return float(dp.mean()), float(dr.mean())


def accuracy_curve(arm: SimArm, sizes, *, seed, sigma_pos: float = 0.0,
                   sigma_orient: float = 0.0, search: SearchConfig | None = None,
                   occluded=(), visibility: float = 1.0, n_test: int = 200,
                   n_control: int = 0):
    """For each training-set size: structure correct?, prediction error, observation error
    and (``n_control`` > 0) the positioning error of the last part when DLS on the learned
    model drives it to ``n_control`` random reachable targets (true error, Fig. 3.10).

    Returns a list of dicts(n, complete, correct, pos_err, rot_err, obs_pos_err, seconds
    [, control_err])."""
    import time

    rng = np.random.default_rng(seed)
    n_max = max(sizes)
    A = arm.sample_actions(n_max, rng)
    Y, _ = arm.observe(A, rng, sigma_pos=sigma_pos, sigma_orient=sigma_orient,
                       visibility=visibility, occluded=occluded)
    At = arm.sample_actions(n_test, rng)
    Yt, Xt = arm.observe(At, rng, sigma_pos=sigma_pos, sigma_orient=sigma_orient)
    obs_err = float(pose_errors(Yt, Xt)[0].mean())
    search = search or SearchConfig()
    out = []
    for n in sizes:
        schema = BodySchema(arm.n_parts, arm.n_actions, search=search)
        t0 = time.perf_counter()
        try:
            res = schema.fit(A[:n], Y[:n])
        except ValueError as e:  # too few samples
            out.append(dict(n=n, complete=False, correct=False, error=str(e)))
            continue
        dt = time.perf_counter() - t0
        ok = structure_correct(arm, res.tree, res.nodes) and res.complete
        pe, re = prediction_errors(schema, arm, At) if res.complete else (np.nan, np.nan)
        row = dict(n=n, complete=res.complete, correct=ok, pos_err=pe, rot_err=re,
                   obs_pos_err=obs_err, seconds=dt, edges=sorted(res.edges()))
        if n_control and res.complete:
            row["control_err"] = _positioning_error(schema, arm, At[:n_control])
        out.append(row)
    return out


def _positioning_error(schema, arm, q_targets):
    """Mean true distance of the last part to targets reached by DLS on the learned model."""
    ee = arm.n_parts - 1
    r = schema.root
    X = arm.forward(q_targets)
    targets = (se3_inv(X[:, r]) @ X[:, ee])[:, :3, 3]
    mid = 0.5 * (arm.action_low + arm.action_high)
    err = []
    for tgt in targets:
        q, _ = schema.reach(mid, ee, tgt, max_iter=60, tol=1e-3, q_low=arm.action_low,
                            q_high=arm.action_high, centering=0.05)
        Xq = arm.forward(q)
        err.append(np.linalg.norm((se3_inv(Xq[r]) @ Xq[ee])[:3, 3] - tgt))
    return float(np.mean(err))


def recovery_experiment(make_arm, failure: str, *, seed, n_block: int = 100,
                        sigma_pos: float = 0.01, sigma_orient: float = np.deg2rad(2.0),
                        visibility: float = 0.9, search: SearchConfig | None = None,
                        adapt: AdaptationConfig | None = None, verbose: bool = False):
    """Table 3.1 protocol on one run: 4 blocks of ``n_block`` samples; blocks 2 and 4 with the
    failure ("joint" = q4 stuck at 0.5 rad, "tool" = different tool length/angle); the schema
    starts from the engineered (exact) model of the intact arm.

    Returns dict(steps_invalid=[per block: steps without a valid spanning tree], first,
    restore, second (those for blocks 2-4), steps_stale=[per block: steps until the
    end-effector prediction error stays below n_sigma*sigma_pos], events, pred_err=[per
    block mean end-effector position error of the current tree])."""
    rng = np.random.default_rng(seed)
    arm = make_arm()
    search = search or SearchConfig(sigma_pos=0.02, sigma_orient=np.deg2rad(5.0))
    schema = BodySchema.from_models(arm.engineered_models(), arm.n_parts, arm.n_actions,
                                    search=search, adapt=adapt)
    ee = arm.n_parts - 1
    invalid, errs, stale = [], [], []
    for b in range(4):
        broken = b % 2 == 1
        if failure == "joint":
            if broken:
                arm.block_joint(3, 0.5)
            else:
                arm.unblock_joint(3)
        elif failure == "tool":
            if broken:
                arm.change_tool(length=0.2, angle=np.deg2rad(30))
            else:
                arm.reset_tool()
        else:
            raise ValueError(f"failure must be 'joint' or 'tool', got {failure!r}")
        A = arm.sample_actions(n_block, rng)
        Y, X = arm.observe(A, rng, sigma_pos=sigma_pos, sigma_orient=sigma_orient,
                           visibility=visibility)
        n_inv, e = 0, []
        for t in range(n_block):
            st = schema.update(A[t], Y[t])
            n_inv += not st["valid"]
            if verbose and st["event"]:
                print(b, t, st["event"])
            T = schema.forward_kinematics(A[t])
            Tt = se3_inv(X[t, schema.root]) @ X[t, ee]
            e.append(np.linalg.norm(T[ee, :3, 3] - Tt[:3, 3]))
        invalid.append(n_inv)
        errs.append(float(np.mean(e)))
        bad = np.flatnonzero(np.array(e) > search.n_sigma * search.sigma_pos)
        stale.append(int(bad[-1]) + 1 if len(bad) and bad[-1] < n_block - 1 else len(bad))
    return dict(steps_invalid=invalid, first=invalid[1], restore=invalid[2],
                second=invalid[3], steps_stale=stale, events=list(schema.events),
                pred_err=errs)


def control_experiment(make_arm, *, seed, n_learn: int = 100, n_waypoints: int = 30,
                       n_adapt: int = 150, bend_part: int = 2, sigma_pos: float = 0.005,
                       sigma_orient: float = np.deg2rad(1.0), search: SearchConfig | None = None,
                       adapt: AdaptationConfig | None = None):
    """Table 3.2: learn the 4-DOF arm, bend the middle link by 45 deg, and compare the control
    error (true end-effector distance to targets reached by DLS on the model) of the intact
    arm (static model), the bent arm with the static model, and the bent arm after adaptation.
    """
    import copy

    rng = np.random.default_rng(seed)
    arm = make_arm()
    search = search or SearchConfig(sigma_pos=0.02, sigma_orient=np.deg2rad(5.0))
    A = arm.sample_actions(n_learn, rng)
    Y, _ = arm.observe(A, rng, sigma_pos=sigma_pos, sigma_orient=sigma_orient)
    schema = BodySchema(arm.n_parts, arm.n_actions, search=search, adapt=adapt)
    schema.fit(A, Y)
    static = copy.deepcopy(schema)
    ee = arm.n_parts - 1
    # a smooth trajectory of targets: reachable end-effector positions of the arm in use
    s_ = np.linspace(0.0, 1.0, n_waypoints)[:, None]
    phase = rng.uniform(0, 2 * np.pi, size=arm.n_actions)
    mid = 0.5 * (arm.action_low + arm.action_high)
    amp = 0.35 * (arm.action_high - arm.action_low)
    Qw = mid + amp * np.sin(2 * np.pi * s_ + phase)
    starts = arm.sample_actions(4, rng)

    def control_error(model, arm_now):
        """Follow the trajectory with DLS on ``model`` (joint limits, null-space centering,
        warm start from the previous solution; 4 restarts when the predicted error stays above 5 mm); error measured on
        the true arm."""
        X = arm_now.forward(Qw)
        targets = (se3_inv(X[:, 0]) @ X[:, ee])[:, :3, 3]
        err = []
        q = np.zeros(arm.n_actions)
        for tgt in targets:
            best = model.reach(q, ee, tgt, max_iter=60, tol=1e-3, q_low=arm.action_low,
                               q_high=arm.action_high, centering=0.1)
            if best[1]["error"] > 5e-3:
                for q0 in starts:
                    cand = model.reach(q0, ee, tgt, max_iter=60, tol=1e-3,
                                       q_low=arm.action_low, q_high=arm.action_high,
                                       centering=0.1)
                    if cand[1]["error"] < best[1]["error"]:
                        best = cand
            q = best[0]
            Xq = arm_now.forward(q)
            err.append(np.linalg.norm((se3_inv(Xq[0]) @ Xq[ee])[:3, 3] - tgt))
        return float(np.mean(err)), float(np.std(err))

    intact = control_error(static, arm)
    arm.bend_link(bend_part, np.pi / 4)
    bent_static = control_error(static, arm)
    A2 = arm.sample_actions(n_adapt, rng)
    Y2, _ = arm.observe(A2, rng, sigma_pos=sigma_pos, sigma_orient=sigma_orient)
    for t in range(n_adapt):
        schema.update(A2[t], Y2[t])
    bent_adaptive = control_error(schema, arm)
    return dict(intact_static=intact, bent_static=bent_static, bent_adaptive=bent_adaptive,
                valid=schema.valid, events=list(schema.events))


# ---------------------------------------------------------------------------- metrics, report

def is_correct(keys, truth, n_nodes) -> bool:
    """The tree (a, b, Q) keys span ``n_nodes`` parts with the true action sets."""
    return len(keys) == n_nodes - 1 and all(
        frozenset(Q) == truth[(min(a, b), max(a, b))] for a, b, Q in keys)


def converged_at(history, truth, n_nodes):
    """First sample count after which the structure stayed correct (None if never)."""
    at = None
    for n, _valid, keys in history:
        if is_correct(keys, truth, n_nodes):
            at = n if at is None else at
        else:
            at = None
    return at


def _ok(rs):
    """(runs that finished, their number failed, reasons)."""
    ok = [r for r in rs if "failed" not in r]
    return ok, len(rs) - len(ok), [r["failed"] for r in rs if "failed" in r]


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


def average_runs(results):
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


def correct_from(rows):
    """Smallest n from which the fitted structure is correct for every larger n (None)."""
    n = None
    for r in reversed(rows):
        if not r["correct"]:
            break
        n = r["n"]
    return n

#: where each experiment runs
BLOCK_WHERE = {"fig_3_10": "drake", "noise_free": "drake", "7dof_occluded": "drake",
         "7dof_structure": "drake",
         "table_3_1": "numpy (statistics) + drake (--drake-runs runs per failure, 2-DOF)",
         "table_3_2": "numpy (statistics) + drake (--drake-runs // 2 runs, 4-DOF)"}


def body_schema_report(lines: list[dict]) -> dict:
    """The results of the experiments of Sec. 3.4 from results-file lines of
    ``body_schema.experiment`` trials.
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
    res = {"quick": quick, "where": dict(BLOCK_WHERE)}
    fig = recs("fig_3_10", failed_as_run=False)
    if fig:
        res["fig_3_10"] = average_runs(fig)
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
