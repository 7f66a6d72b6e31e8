"""Decompose the pick_place place error of the imitation reproduction (issue 15).

    OPENBLAS_NUM_THREADS=1 python benchmarks/diag_place_error.py --seeds 1,2,3 [--swap-tables]

Per seed, in the table-B horizontal plane (m):
  (a) fused hand target at the release step minus the hand spot the demonstrated cup spot
      implies (spot + the learned cup-minus-hand offset at the release slice),
  (b) measured hand minus commanded hand at release,
  (c) cup marker minus (hand + learned cup-minus-hand offset) at release (held cup offset),
  (d) cup motion from release to the end,
  (e) final cup marker minus the demonstrated spot (= place_error_m).
"""
from __future__ import annotations

import argparse

import numpy as np


def diag(seed: int, swap: bool, demos: int, rcfg: dict | None = None):
    from dataclasses import replace

    from pydrake.systems.analysis import Simulator

    from mmlearn.apps.imitate import MAX_TIME_FACTOR, RELEASE_S, _final, record_demos
    from mmlearn.diagrams.imitation.diagram import ImitationConfig, MakeImitationDiagram, object_positions
    from mmlearn.models.imitation.dbn import learn_task

    demo_list = record_demos("pick_place", demos, seed=seed)
    model = learn_task(demo_list, use_joints=False)
    cfg = replace(ImitationConfig(), task="pick_place", seed=seed, swap_tables=swap)
    cfg = replace(cfg, reproducer=replace(cfg.reproducer, **(rcfg or {})))
    im = MakeImitationDiagram(cfg, model=model)
    d = im.diagram
    ctx = d.CreateDefaultContext()
    im.set_start(ctx)
    sim = Simulator(d, ctx)
    sim.Initialize()
    rep = im.reproducer
    ports = {n: d.GetOutputPort(n) for n in ("hand", "target_hand", "status", "attached", "command")}
    rows = []
    t, t_end = 0.0, None
    max_time = MAX_TIME_FACTOR * rep.duration + RELEASE_S
    dt = 0.01
    while t < (t_end if t_end is not None else max_time) - 1e-9:
        t = min(t + dt, max_time)
        sim.AdvanceTo(t)
        objs = object_positions(im.plant, ctx, ["cup", "table_b"])
        cmd = np.asarray(ports["command"].Eval(ctx), float)
        rows.append(dict(t=t, hand=np.array(ports["hand"].Eval(ctx)),
                         target=np.array(ports["target_hand"].Eval(ctx)),
                         cmd_hand=rep.forward_kinematics(cmd[:-1]), grip=cmd[-1],
                         att=float(ports["attached"].Eval(ctx)[0]),
                         k=int(ports["status"].Eval(ctx)[0]), cup=objs["cup"], tb=objs["table_b"]))
        if t_end is None and ports["status"].Eval(ctx)[5] > 0:
            t_end = min(t + RELEASE_S, max_time)
    offs = [_final(dm.objects["cup"]) - _final(dm.objects["table_b"]) for dm in demo_list]
    spot = rows[-1]["tb"] + np.mean(offs, axis=0)
    att = np.array([r["att"] for r in rows])
    i_rel = int(np.flatnonzero(att > 0.5)[-1]) if (att > 0.5).any() else len(rows) - 1
    # learned cup-minus-hand at the release slice: the last slice with gripper closed
    g = np.asarray(model.mean["gripper"]).ravel()
    closed = np.flatnonzero(g < 0.5)
    ks = int(closed[-1]) if closed.size else model.mean["gripper"].shape[0] - 1
    mu_cup = np.asarray(model.mean["obj:cup"])[ks]      # cup - hand
    mu_tb = np.asarray(model.mean["obj:table_b"])[ks]   # table_b - hand
    r = rows[i_rel]
    hand_spot_from_tb = r["tb"] - mu_tb                 # where the table constraint puts the hand
    hand_spot_from_spot = spot - mu_cup                 # hand that puts the cup on the spot
    h = lambda v: float(np.linalg.norm(np.asarray(v)[:2]))
    out = dict(
        seed=seed, release_t=r["t"], slice=ks,
        a_target_vs_spot=h(r["target"] - hand_spot_from_spot),
        a2_tableconstraint_vs_spot=h(hand_spot_from_tb - hand_spot_from_spot),
        b_meas_vs_cmd=h(r["hand"] - r["cmd_hand"]), b_cmd_vs_target=h(r["cmd_hand"] - r["target"]),
        c_cup_offset=h(r["cup"] - (r["hand"] + mu_cup)),
        d_cup_motion_after=h(rows[-1]["cup"] - r["cup"]),
        e_place_error=h(rows[-1]["cup"] - spot),
        cup_at_release_vs_spot=h(r["cup"] - spot),
        vec_cup_rel=(r["cup"] - spot)[:2].round(4).tolist(),
        vec_final=(rows[-1]["cup"] - spot)[:2].round(4).tolist(),
        vec_target=(r["target"] - hand_spot_from_spot)[:2].round(4).tolist(),
        vec_meas_cmd=(r["hand"] - r["cmd_hand"]).round(4).tolist(),
        vec_cup_off=(r["cup"] - (r["hand"] + mu_cup)).round(4).tolist(),
        cup_z_rel=float(r["cup"][2] - r["tb"][2]),
    )
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--demos", type=int, default=4)
    ap.add_argument("--swap-tables", action="store_true")
    ap.add_argument("--no-correction", action="store_true",
                    help="held_offset_correction off (the reproduction before issue 15's fix)")
    ap.add_argument("--filter", type=float, default=None, help="held_offset_filter")
    a = ap.parse_args()
    for s in [int(x) for x in a.seeds.split(",")]:
        rcfg = {"held_offset_correction": not a.no_correction}
        if a.filter is not None:
            rcfg["held_offset_filter"] = a.filter
        o = diag(s, a.swap_tables, a.demos, rcfg)
        print(" ".join(f"{k}={v:.4f}" if isinstance(v, float) else f"{k}={v}" for k, v in o.items()), flush=True)


if __name__ == "__main__":
    main()
