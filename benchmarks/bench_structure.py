"""Benchmark: kinematic-graph evaluation and structure search on the closed yardstick, and
sequential clustering of trajectories (prints numbers; never fails on time).

    python benchmarks/bench_structure.py [--n 50,100,200] [--seed 0] [--quick] [--json [FILE]]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from _common import add_output_arguments, emit_json


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", default="50,100,200", help="sample counts")
    ap.add_argument("--seed", type=int, default=0)
    add_output_arguments(ap, quick="n = 50 only (a few seconds)")
    a = ap.parse_args(argv)
    table = a.json != "-"
    from mmlearn.diagrams.common.object_tracks import yardstick_scenario
    from mmlearn.models.articulation.link import ObservationModel
    from mmlearn.models.articulation.graph import (KinematicGraphEvaluator, fit_pair_models,
                                                   search_structure, spanning_tree_edges)

    obs = ObservationModel(sigma_pos=0.005, sigma_orient=np.deg2rad(3))
    rows = []
    if table:
        print("    n  pairs [s]  eval loop [ms]  eval loop+DOF [ms]  tree [s]  local [s]  "
              "exhaustive [s]  graphs local/exh.")
    for n in [50] if a.quick else [int(x) for x in a.n.split(",")]:
        tr = yardstick_scenario(True, n, rng=a.seed)
        t0 = time.perf_counter()
        pm = fit_pair_models(tr.poses, obs=obs, rng=a.seed)
        t_pairs = time.perf_counter() - t0
        loop = [(0, 1), (1, 2), (2, 3), (0, 3)]
        ev = KinematicGraphEvaluator(tr.poses, pm, obs=obs)
        ev.link_configurations((0, 1))
        t0 = time.perf_counter()
        ev.evaluate(loop)
        t_eval = time.perf_counter() - t0
        t0 = time.perf_counter()
        ev.evaluate(loop, reduce_dofs=True)
        t_eval_dof = time.perf_counter() - t0
        tree = spanning_tree_edges(pm, 4)
        res = {}
        for s in ("tree", "local", "exhaustive"):
            e = KinematicGraphEvaluator(tr.poses, pm, obs=obs)
            t0 = time.perf_counter()
            _, _, order = search_structure(e, tree, search=s, reduce_dofs=True)
            res[s] = (time.perf_counter() - t0, len(order))
        rows.append(dict(n=n, pairs_s=t_pairs, eval_loop_ms=1e3 * t_eval,
                         eval_loop_dof_ms=1e3 * t_eval_dof,
                         **{f"{k}_s": v[0] for k, v in res.items()},
                         **{f"{k}_graphs": v[1] for k, v in res.items()}))
        if table:
            print(f"{n:5d}  {t_pairs:9.2f}  {1e3 * t_eval:14.1f}  {1e3 * t_eval_dof:18.1f}  "
                  f"{res['tree'][0]:8.2f}  {res['local'][0]:9.2f}  "
                  f"{res['exhaustive'][0]:14.2f}  {res['local'][1]:>8d}/{res['exhaustive'][1]}")
    figures = {f"{k}_n{r['n']}": r[k] for r in rows
               for k in ("pairs_s", "eval_loop_ms", "local_s", "exhaustive_s")}
    emit_json(a.json, dict(rows=rows, figures=figures))


if __name__ == "__main__":
    main()
