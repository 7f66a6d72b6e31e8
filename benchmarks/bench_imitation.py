"""Speed and alignment benchmark of the imitation-learning model layer (thesis ch. 8; prints
figures, never fails on time).

    python benchmarks/bench_imitation.py [--repeats 5] [--seed 0] [--u-seeds 3] [--quick]
        [--json [FILE]]

Measures (median wall-clock and process CPU time over repeats, single process, BLAS limited
to one thread):

- one incremental step (:func:`constraint_step`) with a 7-joint Jacobian, 5 Cartesian
  constraints + the joint constraint (6) and the gripper, with and without one obstacle;
  target < 5 ms;
- learning (alignment + Parzen Gaussians) from 4 demonstrations of ~20 s at 5 Hz with 5
  objects, joints and gripper; target < 1 s;
- global reproduction (:func:`plan_global`) of a 20 s task (101 slices) with a 7-joint
  spatial chain stand-in (numpy forward kinematics, geometric Jacobian) and a box obstacle;
  target < 10 s; per-configuration ``fk`` calls (as the Drake system layer will give), the
  batched ``fk_batch``, and per-configuration ``body_points`` (5 joint origins) checked too;
  with the median distance of the planned hand from the model's hand target per slice;
- a 3-D U-shaped obstacle with the 7-joint chain (``--u-seeds`` seeds): where the incremental
  reproduction ends, and plan_global's end error, dense clearance and CPU time;
- alignment quality: mean phase error of DTW with derivative / position / both features on
  8 minimum-jerk pick-and-place demonstrations (+-25 % segment timing, 5 cm placement
  variation, 5 mm marker noise).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import argparse
import time
import warnings

import numpy as np

from _common import add_output_arguments, emit_json

from mmlearn.models.imitation.dbn import align_demonstrations, constraint_step, learn_task
from mmlearn.models.imitation.global_plan import plan_global
from mmlearn.models.imitation.types import Demonstration, Obstacle

# --------------------------------------------------------------------------------------------
# a 7-joint spatial chain (z, y, z, y, z, y, z axes; link offsets along z), base at the origin
_AX = np.array([2, 1, 2, 1, 2, 1, 2])
_OFF = np.array([[0, 0, 0.30], [0, 0, 0.0], [0, 0, 0.35], [0, 0, 0.0], [0, 0, 0.30], [0, 0, 0.0],
                 [0, 0, 0.12]])
_TCP = np.array([0.0, 0.0, 0.10])


def _rot(axis, a):
    """(N, 3, 3) rotations about x/y/z by angles a (N,)."""
    c, s = np.cos(a), np.sin(a)
    R = np.zeros(a.shape + (3, 3))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    R[..., axis, axis] = 1.0
    R[..., i, i] = c
    R[..., j, j] = c
    R[..., i, j] = -s
    R[..., j, i] = s
    return R


def chain_frames(Q):
    """Joint origins (N, 7, 3), joint axes in world (N, 7, 3) and TCP (N, 3) for (N, 7) q."""
    Q = np.atleast_2d(Q)
    N = Q.shape[0]
    R = np.tile(np.eye(3), (N, 1, 1))
    p = np.zeros((N, 3))
    origins, axes = np.zeros((N, 7, 3)), np.zeros((N, 7, 3))
    for j in range(7):
        p = p + np.einsum("nij,j->ni", R, _OFF[j])
        origins[:, j] = p
        axes[:, j] = R[:, :, _AX[j]]
        R = R @ _rot(_AX[j], Q[:, j])
    tcp = p + np.einsum("nij,j->ni", R, _TCP)
    return origins, axes, tcp


def fk7(q):
    return chain_frames(q)[2][0]


def fk7_batch(Q):
    return chain_frames(Q)[2]


def jac7(q):
    o, a, tcp = chain_frames(q)
    return np.cross(a[0], tcp[0] - o[0]).T          # (3, 7)


# --------------------------------------------------------------------------------------------
def _mj(s):
    s = np.clip(s, 0.0, 1.0)
    return 10 * s ** 3 - 15 * s ** 4 + 6 * s ** 5


def pick_place_demo(rng, *, n_extra_objects=2, joints=True):
    """A ~20 s pick-and-place demonstration at 5 Hz: hand, cup, two tables (+ extra objects),
    gripper, 7 'joint angles' (a smooth stand-in), true phase (segment index + fraction)."""
    start = np.array([0.3, 0.0, 0.5])
    cup = np.array([0.5, 0.3, 0.1]) + rng.normal(0, 0.05, 3) * [1, 1, 0]
    place = np.array([0.5, -0.3, 0.1]) + rng.normal(0, 0.05, 3) * [1, 1, 0]
    vias = [start, cup + [0, 0, 0.1], cup, cup, cup + [0, 0, 0.15], place + [0, 0, 0.15], place, place,
            place + [0, 0, 0.1], start]
    durs = np.array([3, 2, 1, 1, 3, 3, 1, 1, 3, 2])[:9] * rng.uniform(0.8, 1.25, 9) * 20 / 18
    edges = np.concatenate([[0], np.cumsum(durs)])
    t = np.arange(0, edges[-1], 0.2)
    seg = np.minimum(np.searchsorted(edges, t, side="right") - 1, 8)
    f = (t - edges[seg]) / durs[seg]
    V = np.array(vias)
    hand = V[seg] + (V[seg + 1] - V[seg]) * _mj(f)[:, None]
    phase = seg + f
    grip = np.where((phase >= 3) & (phase < 7), 0.0, 1.0)
    carried = (phase >= 3) & (phase < 7)
    cup_track = np.where(carried[:, None], hand, np.where((phase >= 7)[:, None], place, cup))
    objs = {"cup": cup_track, "table_a": np.tile(cup - [0, 0, 0.1], (len(t), 1)),
            "table_b": np.tile(place - [0, 0, 0.1], (len(t), 1))}
    for i in range(n_extra_objects):
        objs[f"board_c{i}"] = np.tile(rng.uniform(-0.5, 0.5, 3), (len(t), 1))
    noise = lambda a: a + rng.normal(0, 0.005, a.shape)
    q = np.stack([np.sin(phase / 9 * np.pi * (j + 1) / 3) for j in range(7)], axis=1) if joints else None
    return Demonstration(t=t, hand=noise(hand), objects={k: noise(v) for k, v in objs.items()},
                         gripper=grip, joints=q), phase


def u_obstacle_trial(seed):
    """A 4-demonstration reach (straight minimum jerk, 4 s + 1.5 s hold) of the 7-joint chain
    towards a target behind a U-shaped obstacle (back wall across the path at 65 %, two side
    walls, open towards the start; 0.3 m high). Incremental reproduction (5 steps of at most
    0.02 rad per 0.2 s slice, 2 s extra) against plan_global with 5 body points checked."""
    rng = np.random.default_rng(seed)
    q0 = np.array([0.6, 0.5, 0.0, 1.0, 0.0, 0.6, 0.0])
    p0 = fk7(q0)
    tgt = np.array([0.45, -0.35, 0.35]) + rng.normal(0, 0.03, 3)
    demos = []
    for _ in range(4):
        T = 4 * rng.uniform(0.9, 1.1)
        t = np.arange(0, T + 1.5, 0.2)
        hand = p0 + np.outer(_mj(t / T), tgt - p0) + rng.normal(0, 0.005, (len(t), 3))
        demos.append(Demonstration(t=t, hand=hand, objects={"target": np.tile(tgt, (len(t), 1))}))
    m = learn_task(demos)
    d = tgt - p0
    d = np.array([d[0], d[1], 0.0]) / np.hypot(d[0], d[1])
    side = np.cross(d, [0, 0, 1])
    R = np.stack([d, side, [0, 0, 1]], 1)
    c = p0 + (tgt - p0) * 0.65
    U = [Obstacle(c, [0.025, 0.15, 0.15], R), Obstacle(c - d * 0.1 + side * 0.125, [0.1, 0.025, 0.15], R),
         Obstacle(c - d * 0.1 - side * 0.125, [0.1, 0.025, 0.15], R)]
    body = lambda q: chain_frames(q)[0][0, 2:]
    q = q0.copy()
    for k in range(m.S + 10):
        for _ in range(5):
            r = constraint_step(m, min(k, m.S - 1), hand=fk7(q), objects={"target": tgt}, J=jac7(q),
                                use_joints=False, obstacles=U, max_step=0.02)
            q = q + r.dq
    inc_err = float(np.linalg.norm(fk7(q) - tgt))
    c0 = time.process_time()
    path = plan_global(m, q0=q0, objects={"target": tgt}, fk=fk7, jacobian=jac7, obstacles=U,
                       use_joints=False, seed=seed, body_points=body)
    cpu = time.process_time() - c0
    Qd = np.concatenate([np.linspace(a, b, 10) for a, b in zip(path[:-1], path[1:])])
    pts = np.concatenate([fk7_batch(Qd)[:, None, :], chain_frames(Qd)[0][:, 2:]], axis=1)
    clear = min(float(o.signed_distance(pts).min()) for o in U)
    return {"seed": seed, "incremental_end_error_m": inc_err,
            "global_end_error_m": float(np.linalg.norm(fk7(path[-1]) - tgt)),
            "global_min_clearance_m": clear, "global_cpu_s": cpu}


def _timeit(fn, repeats):
    wall, cpu = [], []
    out = None
    for _ in range(repeats):
        w0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        wall.append(time.perf_counter() - w0)
        cpu.append(time.process_time() - c0)
    return float(np.median(wall)), float(np.median(cpu)), out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--seed", type=int, default=0)
    add_output_arguments(ap, quick="one repeat; no body-point plan, no U-obstacle trial "
                                   "(a few seconds)")
    ap.add_argument("--u-seeds", type=int, default=3, help="seeds of the 3-D U-obstacle trial")
    args = ap.parse_args(argv)
    if args.quick:
        args.repeats, args.u_seeds = 1, 0
    rng = np.random.default_rng(args.seed)
    res = {}

    demos, phases = zip(*[pick_place_demo(rng) for _ in range(4)])
    dur = float(np.mean([d.duration for d in demos]))
    # ---- learning
    w, c, model = _timeit(lambda: learn_task(list(demos)), args.repeats)
    res["learn"] = {"demos": 4, "mean_duration_s": dur, "slices": model.S,
                    "constraints": model.constraints, "wall_s": w, "cpu_s": c}
    # ---- incremental step
    q = np.array([0.1, 0.6, 0.0, 0.9, 0.0, 0.5, 0.0])
    hand, J = fk7(q), jac7(q)
    objects = {k: v[0] for k, v in demos[0].objects.items()}
    k = model.S // 2
    n = 2000
    for obst, key in (((), "step"), ((Obstacle([0.5, 0.0, 0.3], [0.05, 0.1, 0.2]),), "step_obstacle")):
        def run():
            for _ in range(n):
                constraint_step(model, k, hand=hand, objects=objects, J=J, q=q, obstacles=obst)
        w, c, _ = _timeit(run, args.repeats)
        r = constraint_step(model, k, hand=hand, objects=objects, J=J, q=q, obstacles=obst)
        res[key] = {"n_joints": 7, "constraints": len(model.objects) + 1, "obstacles": len(obst),
                    "ms_per_step_wall": 1e3 * w / n, "ms_per_step_cpu": 1e3 * c / n,
                    "dq_finite": bool(np.all(np.isfinite(r.dq)))}
    # ---- global planning with the 7-joint chain
    q0 = np.array([0.0, 0.5, 0.0, 1.0, 0.0, 0.6, 0.0])
    box = Obstacle([0.45, 0.0, 0.25], [0.05, 0.12, 0.15])
    objs0 = {k: v[0] for k, v in demos[0].objects.items()}
    # the hand targets of the learned model (precision-weighted x_i - mu_i, carried objects skipped)
    carried = (model.mean["gripper"][:, 0] < 0.5) & (np.linalg.norm(model.mean["obj:cup"], axis=1) < 0.05)
    targets = np.array([constraint_step(model, k, hand=fk7(q0), objects=objs0, J=jac7(q0), use_joints=False,
                                        carried=("cup",) if carried[k] else ()).target_hand
                        for k in range(model.S)])
    for key, kw in (("plan_global", {}), ("plan_global_fk_batch", {"fk_batch": fk7_batch}),
                    ("plan_global_body_points", {"body_points": lambda q: chain_frames(q)[0][0, 2:]}))[
                        :2 if args.quick else 3]:
        def plan():
            return plan_global(model, q0=q0, objects=objs0, fk=fk7, jacobian=jac7, obstacles=[box],
                               use_joints=False, seed=args.seed, return_info=True, **kw)
        w, c, (path, info) = _timeit(plan, max(1, args.repeats // 2))
        hands = fk7_batch(path)
        dev = np.linalg.norm(hands - targets, axis=1)
        clear = box.signed_distance(hands).min()
        if "body_points" in kw:
            clear = min(clear, box.signed_distance(chain_frames(path)[0][:, 2:]).min())
        res[key] = {
            "slices": model.S, "task_s": float(model.t[-1]), "roadmap_nodes": info["roadmap_nodes"],
            "graph_edges": info["graph_edges"], "edge_check_points": info["edge_check_points"],
            "wall_s": w, "cpu_s": c, "cost": info["cost"],
            "median_target_deviation_m": float(np.median(dev[1:])),
            "min_clearance_m": float(clear)}
    # ---- 3-D U-shaped obstacle with the 7-joint chain: incremental stuck, global through?
    res["u_obstacle_3d"] = [u_obstacle_trial(seed) for seed in range(args.seed, args.seed + args.u_seeds)]
    # ---- alignment quality
    rng2 = np.random.default_rng(args.seed + 1)
    dp = [pick_place_demo(rng2, n_extra_objects=0, joints=False) for _ in range(8)]
    ref_phase = dp[0][1]
    for feat in ("derivative", "position", "both"):
        errs = []
        for d, ph in dp[1:]:
            # carry the true phase through the alignment as an extra "object" column
            dd = Demonstration(t=d.t, hand=d.hand, objects={"phase": np.repeat(ph[:, None], 3, 1)},
                               gripper=d.gripper)
            rr = Demonstration(t=dp[0][0].t, hand=dp[0][0].hand,
                               objects={"phase": np.repeat(ref_phase[:, None], 3, 1)}, gripper=dp[0][0].gripper)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                al = align_demonstrations([rr, dd], reference=0, features=feat)
            n_ = min(al[1].T, len(ref_phase))
            errs.append(np.abs(al[1].objects["phase"][:n_, 0] - ref_phase[:n_]).mean())
        res[f"align_{feat}"] = {"mean_phase_error_segments": float(np.mean(errs)),
                                "max_phase_error_segments": float(np.max(errs))}

    res["figures"] = {"learn_cpu_s": res["learn"]["cpu_s"],
                      "step_cpu_ms": res["step"]["ms_per_step_cpu"],
                      "step_obstacle_cpu_ms": res["step_obstacle"]["ms_per_step_cpu"],
                      "plan_global_cpu_s": res["plan_global"]["cpu_s"],
                      "plan_global_fk_batch_cpu_s": res["plan_global_fk_batch"]["cpu_s"]}
    if emit_json(args.json, res):
        return 0
    L = res["learn"]
    print(f"learn_task: 4 demos x {L['mean_duration_s']:.1f} s at 5 Hz, {len(L['constraints'])} constraints, "
          f"{L['slices']} slices: {L['wall_s'] * 1e3:.1f} ms wall, {L['cpu_s'] * 1e3:.1f} ms CPU (target < 1 s)")
    for key in ("step", "step_obstacle"):
        s = res[key]
        print(f"constraint_step ({s['n_joints']} joints, {s['constraints']} constraints + gripper, "
              f"{s['obstacles']} obstacle): {s['ms_per_step_wall']:.3f} ms wall, {s['ms_per_step_cpu']:.3f} ms CPU "
              f"per step (target < 5 ms)")
    for key in ("plan_global", "plan_global_fk_batch", "plan_global_body_points"):
        if key not in res:
            continue
        p = res[key]
        print(f"{key}: {p['task_s']:.1f} s task, {p['slices']} slices, {p['roadmap_nodes']} roadmap nodes, "
              f"{p['graph_edges']} time-expanded edges, {p['edge_check_points']} edge check points: "
              f"{p['wall_s']:.2f} s wall, {p['cpu_s']:.2f} s CPU (target < 10 s); median hand-target "
              f"deviation {p['median_target_deviation_m'] * 1e3:.1f} mm, min clearance "
              f"{p['min_clearance_m'] * 1e3:.0f} mm")
    for u in res["u_obstacle_3d"]:
        print(f"3-D U obstacle, seed {u['seed']}: incremental ends {u['incremental_end_error_m'] * 1e3:.0f} mm "
              f"from the target; global {u['global_end_error_m'] * 1e3:.1f} mm, min clearance (hand + "
              f"5 body points, dense) {u['global_min_clearance_m'] * 1e3:.0f} mm, {u['global_cpu_s']:.2f} s CPU")
    for feat in ("derivative", "position", "both"):
        a = res[f"align_{feat}"]
        print(f"alignment ({feat:10s}): mean phase error {a['mean_phase_error_segments']:.3f} segments "
              f"(worst demo {a['max_phase_error_segments']:.3f})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
