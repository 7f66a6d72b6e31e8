"""Link-model selection with the link models' rotation conversions in numpy (used) against
scipy's ``Rotation`` (``models/common/se3``), side by side in one process (prints figures;
never fails on time).

    python benchmarks/bench_selection_rotations.py [--repeats 9] [--quick] [--json [FILE]]

Selection of all four candidates (rigid, prismatic, revolute, gp) on the speed benchmark's
tracks (simulated microwave door and drawer, n = 30 and 200, sigma 2 mm / 2 deg; see
``bench_articulation.py``), the two variants alternating within each repeat (process CPU
time, median); then every real track of ``tests/data/articulation_logs`` at sigma_pos 5, 20
and 50 mm with both variants: the selected model and its BIC must agree (reported).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import time
from pathlib import Path

import numpy as np

import mmlearn.models.articulation.geom as geom
import mmlearn.models.articulation.gp_link as gp_link
import mmlearn.models.articulation.link as link
import mmlearn.models.articulation.links as links
import mmlearn.models.articulation.refine as refine
from mmlearn.models.articulation.link import ObservationModel
from mmlearn.models.articulation.sim import simulate_link
from mmlearn.models.articulation.structure import select_link_model
from mmlearn.models.common import se3

from _common import add_output_arguments, emit_json

VARIANTS = {"numpy": (geom._rv2m, geom._m2rv),
            "scipy": (se3.rotvec_to_matrix, se3.matrix_to_rotvec)}
OBS = ObservationModel(sigma_pos=0.002, sigma_orient=np.deg2rad(2.0))
TRACKS = Path(__file__).resolve().parent.parent / "tests" / "data" / "articulation_logs"


def use(variant: str) -> None:
    """Make the link models use the rotation conversions of ``variant``."""
    rv2m, m2rv = VARIANTS[variant]
    for mod in (geom, links, gp_link, refine, link):
        if hasattr(mod, "_rv2m"):
            mod._rv2m = rv2m
        if hasattr(mod, "_m2rv"):
            mod._m2rv = m2rv


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=9)
    add_output_arguments(ap, quick="3 repeats, n = 30 only")
    a = ap.parse_args(argv)
    repeats = 3 if a.quick else a.repeats
    rows = []
    for n in (30,) if a.quick else (30, 200):
        for kind in ("microwave", "drawer"):
            tr = simulate_link(kind, n, rng=0)
            cpu = {v: [] for v in VARIANTS}
            sel = {}
            for r in range(repeats):
                for v in (list(VARIANTS) if r % 2 == 0 else list(VARIANTS)[::-1]):
                    use(v)
                    c0 = time.process_time()
                    s = select_link_model(tr.Z, obs=OBS, rng=0)
                    cpu[v].append(time.process_time() - c0)
                    sel[v] = s.selected
            rows.append({"track": f"{kind}_n{n}", "numpy_cpu_ms": 1e3 * np.median(cpu["numpy"]),
                         "scipy_cpu_ms": 1e3 * np.median(cpu["scipy"]),
                         "selected": sel["numpy"], "same_selection": sel["numpy"] == sel["scipy"]})
    checked = differ = 0
    for f in sorted(TRACKS.glob("*.log")):
        from mmlearn.models.common.track_io import read_track

        t = read_track(f)
        for sp in (0.005, 0.02, 0.05):
            out = {}
            for v in VARIANTS:
                use(v)
                s = select_link_model(t.poses, obs=ObservationModel(sp, np.deg2rad(5)), rng=0)
                out[v] = (s.selected, s.bic[s.selected])
            checked += 1
            (nm, bn), (ns, bs) = out["numpy"], out["scipy"]
            differ += int(nm != ns or abs(bn - bs) > 1e-6 * max(1.0, abs(bs)))
    use("numpy")
    figures = {f"select_{r['track']}_{v}_cpu_ms": r[f"{v}_cpu_ms"] for r in rows
               for v in VARIANTS}
    if not emit_json(a.json, {"rows": rows, "real_tracks_checked": checked,
                              "real_tracks_differing": differ, "figures": figures}):
        print("select 4 candidates (CPU ms)   numpy   scipy   numpy/scipy  selected")
        for r in rows:
            print(f"{r['track']:28s} {r['numpy_cpu_ms']:6.1f}  {r['scipy_cpu_ms']:6.1f}  "
                  f"{r['numpy_cpu_ms'] / r['scipy_cpu_ms']:11.2f}  {r['selected']}"
                  + ("" if r["same_selection"] else "  (scipy: different)"))
        print(f"real tracks: {checked} selections, {differ} with a different model or BIC")


if __name__ == "__main__":
    main()
