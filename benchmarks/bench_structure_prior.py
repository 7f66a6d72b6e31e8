"""Benchmark: the furniture prior of the structure search on three cases, the BIC alone
against BIC + prior, over several seeds (prints a table; never fails).

    python benchmarks/bench_structure_prior.py [--seeds 1-10] [--json [FILE]]

Cases: ``together``, the two-drawer cabinet with both drawers only ever pulled together
(:func:`mmlearn.diagrams.common.object_tracks.cabinet_together_scenario`; right: both drawers
on the cabinet); ``independent``, the same cabinet with the drawers moved independently
(:func:`~mmlearn.diagrams.common.object_tracks.cabinet_scenario`; right: both on the cabinet);
``lid``, a lid hinged on a drawer (:func:`mmlearn.models.articulation.sim.drawer_with_lid_tracks`;
right: carcass - drawer prismatic, drawer - lid revolute).
"""

from __future__ import annotations

import argparse

import numpy as np

from _common import add_output_arguments, emit_json

RIGHT = {"together": ((0, 1), (0, 2)), "independent": ((0, 1), (0, 2)),
         "lid": ((0, 1), (1, 2))}


def _seeds(text: str) -> list[int]:
    a, _, b = text.partition("-")
    return list(range(int(a), int(b) + 1)) if b else [int(x) for x in text.split(",")]


def _case(name, seed):
    from mmlearn.diagrams.common.object_tracks import cabinet_scenario, cabinet_together_scenario
    from mmlearn.models.articulation.link import ObservationModel
    from mmlearn.models.articulation.sim import drawer_with_lid_tracks

    if name == "lid":
        return (drawer_with_lid_tracks(seed), ["carcass", "drawer", "lid"],
                ObservationModel(sigma_pos=0.005, sigma_orient=0.02))
    tr = (cabinet_together_scenario if name == "together" else cabinet_scenario)(rng=seed)
    return tr.poses, tr.parts, ObservationModel(sigma_pos=0.01, sigma_orient=np.deg2rad(5))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="1-10", help="seeds, e.g. 1-10 or 3,5,8")
    add_output_arguments(ap)
    a = ap.parse_args(argv)
    from mmlearn.models.articulation.graph import fit_structure
    from mmlearn.models.articulation.structure_prior import StructurePrior

    seeds = _seeds(a.seeds)
    rows = []
    for name in RIGHT:
        right = {"bic": 0, "prior": 0}
        for seed in seeds:
            Y, names, obs = _case(name, seed)
            r0 = fit_structure(Y, part_names=names, obs=obs, rng=seed)
            r1 = fit_structure(Y, part_names=names, obs=obs, rng=seed, prior=StructurePrior(),
                               pair_models=r0.pair_models)
            right["bic"] += r0.best.edges == RIGHT[name]
            right["prior"] += r1.best.edges == RIGHT[name]
        rows.append({"case": name, "seeds": len(seeds), "right_bic_alone": right["bic"],
                     "right_with_prior": right["prior"]})
    if a.json != "-":
        print(f"{'case':12s} {'BIC alone':>10s} {'BIC + prior':>12s}   (right structure, of "
              f"{len(seeds)} seeds)")
        for r in rows:
            print(f"{r['case']:12s} {r['right_bic_alone']:>10d} {r['right_with_prior']:>12d}")
    emit_json(a.json, {"benchmark": "structure_prior", "seeds": seeds, "rows": rows})


if __name__ == "__main__":
    main()
