"""Regenerate the example CSV of ``fit_structure`` with mmlearn's own simulator.

    python -m mmlearn.apps.examples.make_examples

``two_drawer_cabinet.csv``: the two-drawer cabinet of thesis Fig. 4.8 (``sdf/objects.py``,
posed in a Drake MultibodyPlant by :func:`mmlearn.diagrams.common.object_tracks.cabinet_scenario`):
the lower drawer opens and closes alone for 20 time steps, then both drawers move
independently for 40; marker noise 3 mm / 1 deg (cabinet marker 0.6 mm / 0.2 deg), seed 0,
one row per part per time step, t = 0.1 s apart.

``two_drawers_pulled_together.csv``: the same cabinet with both drawers only ever pulled
together (:func:`mmlearn.diagrams.common.object_tracks.cabinet_together_scenario`, 40 time
steps, seed 0): the case the furniture prior decides (``fit_structure --furniture-prior``).
"""

from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent


def main() -> None:
    from mmlearn.diagrams.common.object_tracks import cabinet_scenario
    from mmlearn.models.articulation.graph import write_parts_csv

    tr = cabinet_scenario(20, 40, rng=0)
    Y = np.round(tr.poses, 5)
    write_parts_csv(HERE / "two_drawer_cabinet.csv", tr.parts, np.arange(Y.shape[1]) * 0.1, Y)
    print(f"wrote {HERE / 'two_drawer_cabinet.csv'}: parts {tr.parts}, {Y.shape[1]} time steps")
    from mmlearn.diagrams.common.object_tracks import cabinet_together_scenario

    tr = cabinet_together_scenario(40, rng=0)
    Y = np.round(tr.poses, 5)
    out = HERE / "two_drawers_pulled_together.csv"
    write_parts_csv(out, tr.parts, np.arange(Y.shape[1]) * 0.1, Y)
    print(f"wrote {out}: parts {tr.parts}, {Y.shape[1]} time steps")


if __name__ == "__main__":
    main()
