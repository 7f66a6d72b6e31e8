"""Which detector finds more true fronts and fewer false ones? The front detector of a git
revision (``--ref``) against the working tree's on saved frames, scored against the truth
(prints figures; a development tool).

    python benchmarks/compare_front_truth.py --frames-dir DIR [--ref main] [--pattern GLOB]

Frames: ``*.json`` + ``*_depth.npy`` of ``python -m mmlearn.apps.render_fronts ... --out-dir
DIR`` (the moving front's pose, ``closed_fronts``' poses). Per frame and detector: whether the
moving front is found (``apps/track_fronts.match_front``: 5 cm, 10 deg, 0.1 m; the inner face
once the door turned past the camera's line of sight), its position error, and how many
rectangles match a true front (moving or closed) and how many match none ("other": the
table, walls, countertop, or a false rectangle), and how many of those lie on a front (a part
of a front, or fronts merged: false fronts). Seed ``[0, frame]``, default config.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import glob
import json
import sys

import numpy as np

import mmlearn.models.perception.detection as new
from mmlearn.apps.track_fronts import TrackFrontsConfig, front_visibility, match_front
from mmlearn.models.common.camera import PinholeIntrinsics

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from compare_front_detector import load_ref  # noqa: E402
from diagnose_front_misses import _truth  # noqa: E402


def score(rects, meta, X, tcfg):
    w, h = meta["width"], meta["height"]
    kw = dict(max_pos_m=tcfg.match_pos_m, max_angle_deg=tcfg.match_angle_deg,
              max_size_m=tcfg.match_size_m)
    m = match_front(rects, X, w, h, **kw)
    truths = [(X, w, h)] + [(np.asarray(c["X_WR"], float), c["width"], c["height"])
                            for c in meta.get("closed_fronts", {}).values()]
    matched = set()
    for Xt, wt, ht in truths:
        for i, r in enumerate(rects):
            if match_front([r], Xt, wt, ht, **kw) is not None:
                matched.add(i)
    # false fronts: a rectangle matching no front whose centre lies on a front (within 3 cm
    # of its plane, normals within 10 deg, inside its outline): a part of a front, or fronts
    # merged with each other or with what lies beside them
    false = 0
    for i, r in enumerate(rects):
        if i in matched:
            continue
        for Xt, wt, ht in truths:
            q = Xt[:3, :3].T @ (r.X_WR[:3, 3] - Xt[:3, 3])
            if (abs(q[2]) < 0.03 and abs(q[0]) <= wt / 2 and abs(q[1]) <= ht / 2
                    and abs(r.X_WR[:3, 2] @ Xt[:3, 2]) > np.cos(np.radians(10))):
                false += 1
                break
    return (m is not None, None if m is None else m["pos_error_m"], len(matched),
            len(rects) - len(matched), false)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames-dir", required=True)
    ap.add_argument("--ref", default="main")
    ap.add_argument("--pattern", default="*.json")
    a = ap.parse_args(argv)
    ref = load_ref(a.ref)
    tcfg = TrackFrontsConfig()
    tot = {"ref": np.zeros(5), "new": np.zeros(5)}
    n_el = 0
    for path in sorted(glob.glob(os.path.join(a.frames_dir, a.pattern))):
        meta = json.load(open(path))
        depth = np.load(path[:-5] + "_depth.npy")
        K = PinholeIntrinsics(**meta["intrinsics"])
        X, X_WC, _ = _truth(meta)
        vis = front_visibility(X, meta["width"], meta["height"], X_WC, K, X)
        el = vis["in_view"] and vis["incidence_deg"] < tcfg.max_incidence_deg
        n_el += el
        res = {}
        for nm, mod in (("ref", ref), ("new", new)):
            rects, _ = mod.detect_fronts(depth, K, X_WC, mod.FrontDetectorConfig(),
                                         np.random.default_rng([0, meta["frame"]]))
            res[nm] = score(rects, meta, X, tcfg)
            if el:
                tot[nm] += [res[nm][0], 0.0 if res[nm][1] is None else res[nm][1],
                            res[nm][2], res[nm][3], res[nm][4]]
            else:
                tot[nm] += [0, 0, res[nm][2], res[nm][3], res[nm][4]]
        if res["ref"] != res["new"]:
            f = lambda r: (f"found {int(r[0])} err {'-' if r[1] is None else f'{1000 * r[1]:.1f} mm'}"
                           f" fronts {r[2]} false {r[4]} other {r[3]}")
            print(f"{os.path.basename(path)[:-5]:28s} eligible {int(el)}  ref: {f(res['ref'])}"
                  f"  |  new: {f(res['new'])}", flush=True)
    for nm in ("ref", "new"):
        t = tot[nm]
        print(f"{nm}: moving front found in {int(t[0])} of {n_el} eligible frames, "
              f"mean position error {1000 * t[1] / max(t[0], 1):.1f} mm, rectangles matching a "
              f"true front {int(t[2])}, false fronts (on a front, matching none) {int(t[4])}, "
              f"other (matching none) {int(t[3])}")


if __name__ == "__main__":
    main()
