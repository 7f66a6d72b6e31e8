"""Benchmark: what two demonstrations teach about where to put the cup (pick-and-place with
swapped tables), with and without the learner's isotropic prior (prints a table; never fails).

    python benchmarks/bench_teaching_prior.py [--seeds 200-209] [--priors 0,1,2,4] [--json [FILE]]

Per seed, two pairs of demonstrations: *interactive*, the teacher's usual first one and one
in the swapped situation of interactive teaching's first round
(:func:`mmlearn.diagrams.imitation.teaching.teach_interactively`); *batch*, the teacher's
spread pair (:func:`mmlearn.diagrams.imitation.trials.record_demos`). For each prior weight
(``isotropic_prior`` of :func:`mmlearn.models.imitation.dbn.learn_task`) the model is learned
and the hand target of the place slice (the first slice at which the learned gripper opens
again; the cup is carried, so only the tables steer) is fused in the next test situation
(interactive round 2's) and compared with the spot the demonstrations show there (table B
plus their mean hand-minus-table-B offset at the release): ``place_target_error_mm``, and
the standard deviation of table A's relation along x at that slice,
``table_a_x_sd_mm``. No simulation of the robot: only the learned model.
"""

from __future__ import annotations

import argparse
import warnings

import numpy as np

from _common import add_output_arguments, emit_json


def _seeds(text: str) -> list[int]:
    a, _, b = text.partition("-")
    return list(range(int(a), int(b) + 1)) if b else [int(x) for x in text.split(",")]


def _release(gripper) -> int:
    """Index of the first sample at which a closed gripper opens again."""
    g = np.asarray(gripper, float).ravel()
    return int(np.nonzero(g < 0.5)[0][-1]) + 1


def _measure(demos, objs, prior) -> tuple[float, float]:
    from mmlearn.models.imitation.dbn import constraint_step, learn_task

    m = learn_task(demos, use_joints=False, h=0.2, isotropic_prior=prior)
    k = _release(m.mean["gripper"][:, 0])
    r = constraint_step(m, k, hand=np.zeros(3), objects=objs, J=np.eye(3), use_joints=False,
                        carried=["cup"])
    off = np.mean([d.hand[_release(d.gripper)] - d.objects["table_b"][_release(d.gripper)]
                   for d in demos], axis=0)
    err = float(np.linalg.norm((r.target_hand - objs["table_b"] - off)[:2]))
    return 1000 * err, 1000 * float(np.sqrt(m.covariance("obj:table_a", k)[0, 0]))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="200-209", help="seeds, e.g. 200-209 or 3,5,8")
    ap.add_argument("--priors", default="0,1,2,4", help="prior weights, demonstrations")
    add_output_arguments(ap)
    a = ap.parse_args(argv)
    from mmlearn.diagrams.imitation.diagram import ImitationConfig
    from mmlearn.diagrams.imitation.teaching import _demo_in_situation, _first_demo
    from mmlearn.diagrams.imitation.trials import PLACEMENT, record_demos

    seeds, priors = _seeds(a.seeds), [float(p) for p in a.priors.split(",")]
    rows = []
    for seed in seeds:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            pairs = {"interactive": [_first_demo("pick_place", seed, PLACEMENT, 1.0),
                                     _demo_in_situation("pick_place", seed, 1, seed * 100 + 1,
                                                        True, 1.0)],
                     "batch": record_demos("pick_place", 2, seed=seed)}
            spec = ImitationConfig(task="pick_place", seed=seed * 100 + 2,
                                   swap_tables=True).scene_spec().resolved()
            objs = {"table_a": spec.table_marker("a"), "table_b": spec.table_marker("b")}
            for pair, demos in pairs.items():
                for p in priors:
                    e, sd = _measure(demos, objs, p)
                    rows.append({"seed": seed, "pair": pair, "prior": p,
                                 "place_target_error_mm": e, "table_a_x_sd_mm": sd})
    if a.json != "-":
        print(f"{'pair':12s} {'prior':>5s} {'place target error, mm':>24s} "
              f"{'table A x sd, mm':>18s}   (range over {len(seeds)} seeds)")
        for pair in ("interactive", "batch"):
            for p in priors:
                sel = [r for r in rows if r["pair"] == pair and r["prior"] == p]
                e = [r["place_target_error_mm"] for r in sel]
                sd = [r["table_a_x_sd_mm"] for r in sel]
                print(f"{pair:12s} {p:5g} {min(e):10.1f} - {max(e):6.1f} (>15: {sum(x > 15 for x in e)})"
                      f" {min(sd):8.0f} - {max(sd):5.0f}")
    emit_json(a.json, {"benchmark": "teaching_prior", "seeds": seeds, "priors": priors,
                       "rows": rows})


if __name__ == "__main__":
    main()
