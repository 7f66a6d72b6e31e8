"""Benchmark and thesis experiments for body-schema learning (ch. 3).

Prints numbers; never fails on time. Wall-clock times depend on the load of the (shared)
machine; the CPU times of this single-threaded process are the load-independent figure.

    python benchmarks/bench_body_schema.py            # everything except Table 3.2
    python benchmarks/bench_body_schema.py --quick    # timings only
    python benchmarks/bench_body_schema.py --runs 20 --control   # full Table 3.1 + 3.2
    ... [--json FILE]                                            # the figures as JSON
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from _common import add_output_arguments, emit_json

from mmlearn.models.body_schema.schema import BodySchema, SearchConfig
from mmlearn.models.body_schema.evaluation import (
                                                   accuracy_curve,
                                                   control_experiment,
                                                   recovery_experiment,
                                                   structure_correct,
                                                   )
from mmlearn.models.body_schema.search import learn_structure
from mmlearn.models.body_schema.kinematic_sim import make_arm_2dof, make_arm_4dof, make_arm_7dof

CFG7 = SearchConfig(sigma_pos=0.02, sigma_orient=np.deg2rad(3.0))


def bench_search_7dof(seed: int, repeats: int = 3, n: int = 100, occluded=()):
    arm = make_arm_7dof()
    rng = np.random.default_rng(seed)
    A = arm.sample_actions(n, rng)
    Y, _ = arm.observe(A, rng, sigma_pos=0.01, sigma_orient=np.deg2rad(1.0),
                       occluded=occluded)
    times, cpu = [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        res = learn_structure(A, Y, config=CFG7)
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return dict(n=n, seconds_median=float(np.median(times)), seconds_all=times,
                cpu_seconds_median=float(np.median(cpu)),
                n_screened=res.n_screened, n_trained=res.n_trained, layers=res.layers,
                correct=bool(res.complete and structure_correct(arm, res.tree, res.nodes)))


def bench_update(seed: int, n_fit: int = 100, n_steps: int = 200):
    arm = make_arm_7dof()
    rng = np.random.default_rng(seed)
    A = arm.sample_actions(n_fit + n_steps, rng)
    Y, _ = arm.observe(A, rng, sigma_pos=0.01, sigma_orient=np.deg2rad(1.0), visibility=0.9)
    s = BodySchema(arm.n_parts, arm.n_actions, search=CFG7)
    s.fit(A[:n_fit], Y[:n_fit])
    half = n_fit + n_steps // 2
    arm.block_joint(3, 0.5)
    Y2, _ = arm.observe(A[half:], rng, sigma_pos=0.01, sigma_orient=np.deg2rad(1.0),
                        visibility=0.9)
    Y[half:] = Y2
    ts, cs = [], []
    for t in range(n_fit, n_fit + n_steps):
        t0, c0 = time.perf_counter(), time.process_time()
        s.update(A[t], Y[t])
        ts.append(time.perf_counter() - t0)
        cs.append(time.process_time() - c0)
    ts = np.array(ts) * 1e3
    cs = np.array(cs) * 1e3
    return dict(ms_median=float(np.median(ts)), ms_p95=float(np.percentile(ts, 95)),
                cpu_ms_median=float(np.median(cs)), cpu_ms_max=float(cs.max()),
                ms_max=float(ts.max()), valid_at_end=s.valid,
                events=[e for _, e in s.events])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--runs", type=int, default=5, help="runs per experiment (thesis: 20)")
    ap.add_argument("--control", action="store_true", help="also Table 3.2 (slow)")
    add_output_arguments(ap, quick="timings only")
    args = ap.parse_args(argv)
    out = {}

    r = bench_search_7dof(args.seed)
    out["search_7dof_100"] = r
    print(f"[speed] 7-DOF structure search, 100 samples: {r['seconds_median']:.3f} s wall, "
          f"{r['cpu_seconds_median']:.3f} s CPU (median of 3; screened {r['n_screened']}, trained {r['n_trained']}, "
          f"layers {r['layers']}, correct={r['correct']})")
    r = bench_update(args.seed)
    out["update_7dof"] = r
    print(f"[speed] per-observation update (7-DOF, 200 steps incl. a blocked joint): "
          f"median {r['ms_median']:.2f} ms, p95 {r['ms_p95']:.2f} ms, max {r['ms_max']:.1f} ms "
          f"wall; CPU median {r['cpu_ms_median']:.2f} ms, max {r['cpu_ms_max']:.1f} ms "
          f"(10 Hz budget 100 ms); events: {r['events']}")
    out["figures"] = {"search_7dof_100_cpu_s": out["search_7dof_100"]["cpu_seconds_median"],
                      "update_7dof_cpu_ms": out["update_7dof"]["cpu_ms_median"],
                      "update_7dof_cpu_max_ms": out["update_7dof"]["cpu_ms_max"]}
    if args.quick:
        emit_json(args.json, out)
        return out

    # Fig. 3.10: 2-DOF, sigma 0.044 m
    sizes = [5, 8, 10, 15, 20, 30, 50]
    cfg = SearchConfig(sigma_pos=0.044, sigma_orient=np.deg2rad(5.0))
    rows = {n: [] for n in sizes}
    for run in range(args.runs):
        for rr in accuracy_curve(make_arm_2dof(), sizes, seed=args.seed + run, sigma_pos=0.044,
                                 sigma_orient=np.deg2rad(3.0), search=cfg, n_control=10):
            rows[rr["n"]].append(rr)
    print(f"[2-DOF, sigma_markers 0.044 m RMS, {args.runs} runs] n: structure correct, "
          f"mean position error of prediction vs of observation, positioning error by DLS "
          f"on the learned model (true distance of x5 to the target)")
    out["2dof_noisy"] = {}
    for n in sizes:
        ok = sum(r["correct"] for r in rows[n])
        pe = np.nanmean([r.get("pos_err", np.nan) for r in rows[n]]) if ok else np.nan
        oe = np.mean([r.get("obs_pos_err", np.nan) for r in rows[n]])
        ce = np.nanmean([r.get("control_err", np.nan) for r in rows[n]]) if ok else np.nan
        out["2dof_noisy"][n] = dict(correct=ok, pos_err=pe, obs_err=oe, control_err=ce)
        print(f"  n={n:3d}: correct {ok}/{len(rows[n])}, prediction {pe:.4f} m, "
              f"observation {oe:.4f} m, positioning {ce:.4f} m")

    # noise-free 2-DOF
    cfg0 = SearchConfig(sigma_pos=0.01, sigma_orient=np.deg2rad(3.0))
    res = [accuracy_curve(make_arm_2dof(), [20, 100], seed=args.seed + run, search=cfg0)
           for run in range(args.runs)]
    out["2dof_noise_free"] = {}
    for k, n in enumerate([20, 100]):
        pe = np.mean([r[k]["pos_err"] for r in res])
        re = np.rad2deg(np.mean([r[k]["rot_err"] for r in res]))
        out["2dof_noise_free"][n] = dict(pos_err=pe, rot_err_deg=re)
        print(f"[2-DOF noise-free] n={n}: {pe * 1000:.4f} mm, {re:.4f} deg "
              f"(thesis: <2 mm/1 deg at 20, <1 mm/0.2 deg at 100)")

    # 7-DOF (Fig. 3.11), all parts seen and x4 occluded
    out["7dof"] = {}
    for occluded in ((), (3,)):
        for noise in (0.0, 0.01):
            sizes7 = [10, 15, 20, 30, 100]
            rows7 = {n: [] for n in sizes7}
            for run in range(args.runs):
                for rr in accuracy_curve(make_arm_7dof(), sizes7, seed=args.seed + run,
                                         sigma_pos=noise, sigma_orient=np.deg2rad(noise * 100),
                                         search=CFG7, occluded=occluded):
                    rows7[rr["n"]].append(rr)
            for n in sizes7:
                ok = sum(r["correct"] for r in rows7[n])
                pe = np.nanmean([r.get("pos_err", np.nan) for r in rows7[n]]) if ok else np.nan
                k2 = sum((2, 4, (1, 2)) in r.get("edges", []) for r in rows7[n])
                out["7dof"][str((occluded, noise, n))] = dict(correct=ok, pos_err=pe,
                                                              bridged=k2)
                extra = f", x3-x5|(q2,q3) bridge {k2}/{args.runs}" if occluded else ""
                print(f"[7-DOF, occluded {list(occluded)}, sigma {noise} m] n={n:3d}: correct "
                      f"{ok}/{args.runs}{extra}, mean position error {pe:.5f} m")

    # Table 3.1
    out["table_3_1"] = {}
    for failure, vis in (("joint", 0.919), ("tool", 0.790)):
        rs = [recovery_experiment(make_arm_7dof, failure, seed=args.seed + run, visibility=vis)
              for run in range(args.runs)]
        f = np.array([[r["first"], r["restore"], r["second"]] for r in rs], float)
        st = np.array([r["steps_stale"][1:] for r in rs], float)
        out["table_3_1"][failure] = dict(mean=f.mean(0).tolist(), std=f.std(0).tolist(),
                                         stale_mean=st.mean(0).tolist())
        print(f"[Table 3.1, {failure}, visibility {vis}] steps without a valid tree: "
              f"first {f[:, 0].mean():.2f} +- {f[:, 0].std():.2f}, restore "
              f"{f[:, 1].mean():.2f} +- {f[:, 1].std():.2f}, second {f[:, 2].mean():.2f} +- "
              f"{f[:, 2].std():.2f}; steps until the end-effector prediction is right again: "
              f"{st.mean(0).round(2).tolist()}")

    if args.control:
        rs = [control_experiment(make_arm_4dof, seed=args.seed + run) for run in range(args.runs)]
        out["table_3_2"] = {}
        for key in ("intact_static", "bent_static", "bent_adaptive"):
            m = np.mean([r[key][0] for r in rs])
            sd = np.mean([r[key][1] for r in rs])
            out["table_3_2"][key] = (m, sd)
            print(f"[Table 3.2] {key}: control error {m:.3f} +- {sd:.3f} m")
    emit_json(args.json, out)
    return out


if __name__ == "__main__":
    main()
