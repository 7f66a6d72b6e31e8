"""Grasp-to-grasp variation of a container's squeeze, measured on the real iCub grasps (prints
the figures behind ``ContainerClass.grasp_spread`` in models/tactile/containers.py).

    python benchmarks/bench_grasp_variation.py [--data DIR] [--json [FILE]]

DIR defaults to ``../shared/data/icub_grasp/train`` beside the repository (trials 1-10 of every
object; reader :mod:`mmlearn.models.tactile.icub_grasp`). The same hand grasped the same object in the
same state ten times; what changes from grasp to grasp is where and how the fingers land on it
(its rotation, the label, seams and ribs under the fingers, the shell's own response) and the
hand's own repeatability. For every object the script prints, over its ten grasps, the final
closure ``p_steady`` (mean, sd) and the squeeze ``p_steady - p_first`` (mean), both in degrees
of the mean finger flexion, with the features of Table 7.1 as the app computes them
(``CONTACT_LEVEL`` / ``REST_VELOCITY`` of models/tactile/icub_grasp.py, nothing chosen here).

The relative grasp-to-grasp spread of a container's squeeze is then

    ``sigma = sqrt(sd(p_steady)^2 - sd_ref^2) / mean(p_steady - p_first)``

with ``sd_ref`` the final-closure sd of the lotion bottle (a thick-walled bottle of a similar
size in a single state: the hand's and the placement's own repeatability, taken out in
quadrature), for the container states whose mean squeeze is at least two encoder steps (1 deg:
the empty plastic bottle's 0.7 deg squeeze is below that and its sd is mostly placement).
``sigma`` is the relative sd of the squeeze at the hand's force, i.e. of the container's
effective stiffness (x = F / k: sd(ln x) = sd(ln k)). Plastic bottle: the half-full and full
vitamin-water bottle pooled (root mean square); can: the empty and half-full coke can.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from _common import add_output_arguments, emit_json

from mmlearn.models.tactile.icub_grasp import CONTACT_LEVEL, REST_VELOCITY, load_icub_dir
from mmlearn.models.tactile.state import feature_matrix

DEFAULT = Path(__file__).resolve().parents[2] / "shared" / "data" / "icub_grasp" / "train"
REFERENCE = "lotion"
GROUPS = {"plastic_bottle": ("med_vitamin_water", "full_vitamin_water"),
          "can": ("empty_coke", "med_coke")}
MIN_SQUEEZE_DEG = 1.0  # two steps of the iCub encoders' 0.5 deg


def measure(data) -> dict:
    trials, _ = load_icub_dir(data)
    X, feats = feature_matrix([t.to_grasp() for t in trials], contact_force=CONTACT_LEVEL,
                              rest_velocity=REST_VELOCITY)
    y = np.array([t.label for t in trials])
    rows = {}
    for lab in sorted(set(y.tolist())):
        m = y == lab
        ps, pf = np.rad2deg(X[m, 1]), np.rad2deg(X[m, 0])
        rows[lab] = {"n": int(m.sum()), "p_steady_mean_deg": float(ps.mean()),
                     "p_steady_sd_deg": float(ps.std(ddof=1)),
                     "squeeze_mean_deg": float((ps - pf).mean())}
    sd_ref = rows[REFERENCE]["p_steady_sd_deg"]
    for r in rows.values():
        ex = np.sqrt(max(r["p_steady_sd_deg"] ** 2 - sd_ref ** 2, 0.0))
        r["sigma"] = (float(ex / r["squeeze_mean_deg"])
                      if r["squeeze_mean_deg"] >= MIN_SQUEEZE_DEG else None)
    groups = {}
    for g, labs in GROUPS.items():
        s = [rows[lab]["sigma"] for lab in labs if rows[lab]["sigma"] is not None]
        groups[g] = float(np.sqrt(np.mean(np.square(s)))) if s else None
    return {"reference": REFERENCE, "sd_ref_deg": sd_ref, "objects": rows, "sigma": groups}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", default=str(DEFAULT))
    add_output_arguments(ap)
    args = ap.parse_args(argv)
    out = measure(args.data)
    if emit_json(args.json, out):
        return 0
    print(f"{'object':22s} {'n':>3s} {'p_steady deg':>16s} {'squeeze deg':>12s} {'sigma':>6s}")
    for lab, r in out["objects"].items():
        sig = "-" if r["sigma"] is None else f"{r['sigma']:.3f}"
        print(f"{lab:22s} {r['n']:3d} {r['p_steady_mean_deg']:8.2f} +- {r['p_steady_sd_deg']:4.2f}"
              f" {r['squeeze_mean_deg']:12.2f} {sig:>6s}")
    print(f"reference {out['reference']}: sd {out['sd_ref_deg']:.2f} deg; relative grasp-to-grasp "
          f"spread of the squeeze: " + ", ".join(f"{g} {v:.3f}" for g, v in out["sigma"].items()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
