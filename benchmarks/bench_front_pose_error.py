"""Where the front detector's pose error comes from: per frame, the found rectangle's
centre error split into its components in the true front's frame (along the width, along
the height, along the normal) and the error of each side (hinge / free side, lower / upper
edge), on frames rendered by ``render_fronts`` (prints figures; never fails).

    python -m mmlearn.apps.render_fronts --front door --distance 1.3,2.3 --frames 60 \\
        --seed 2 --out-dir F
    python benchmarks/bench_front_pose_error.py F [F2 ...] --front door --distance 1.3,2.3 \\
        [--every 3] [--clean] [--verbose]

A frame's front is *found* by :func:`mmlearn.apps.track_fronts.match_front` (centre within
0.05 m, orientation within 10 deg, width and height within 0.1 m). Side errors are positive
when the detected side lies inside the true one. ``--clean`` runs on the noise-free renders
(``*_clean.npy``): what remains there is the detector's own bias, not the camera's noise.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import glob
import json
import math

import cv2
import numpy as np

from mmlearn.models.perception.evaluation import match_front
from mmlearn.models.perception.detection import FrontDetectorConfig, detect_fronts
from mmlearn.models.perception.tracking import align_rectangle, as_rectangle
from mmlearn.models.common.camera import PinholeIntrinsics

cv2.setNumThreads(1)


def frame_errors(path, clean, cfg):
    """(joint value, None or dict of the errors, m / deg) of one saved frame."""
    m = json.load(open(path))
    depth = np.load(path[:-5] + ("_clean.npy" if clean else "_depth.npy"))
    K = PinholeIntrinsics(**m["intrinsics"])
    X, W, H = np.array(m["X_WR"]), m["width"], m["height"]
    rects, _ = detect_fronts(depth, K, np.array(m["X_WC"]), cfg,
                             np.random.default_rng([m["seed"], m["frame"]]))
    hit = match_front(rects, X, W, H, max_size_m=0.1)
    if hit is None:
        return m["joint_value"], None
    r = as_rectangle(rects[hit["index"]])
    Xa, w, h, ang = align_rectangle(X, r.X_WR, r.width, r.height)
    dl = X[:3, :3].T @ (Xa[:3, 3] - X[:3, 3])
    return m["joint_value"], {
        "pos": float(np.linalg.norm(dl)), "along_width": dl[0], "along_height": dl[1],
        "along_normal": dl[2], "side_x-": (dl[0] - w / 2) + W / 2,
        "side_x+": W / 2 - (dl[0] + w / 2), "side_y-": (dl[1] - h / 2) + H / 2,
        "side_y+": H / 2 - (dl[1] + h / 2), "angle_deg": math.degrees(ang)}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("dirs", nargs="+", help="folders written by render_fronts --out-dir")
    ap.add_argument("--front", choices=("door", "drawer"), default="door")
    ap.add_argument("--distance", default="0.8,1.3,1.8,2.3", help="comma-separated, m")
    ap.add_argument("--angle", default="+0", help="as in the frame names, e.g. +0, +45")
    ap.add_argument("--every", type=int, default=1, help="use every n-th frame")
    ap.add_argument("--clean", action="store_true", help="noise-free renders")
    ap.add_argument("--verbose", action="store_true", help="one line per frame")
    a = ap.parse_args(argv)
    cfg = FrontDetectorConfig()
    keys = ("along_width", "along_height", "along_normal", "side_x-", "side_x+", "side_y-",
            "side_y+")
    print(f"{a.front}: x = along the width (door: x- is the hinge side), y = along the height "
          "(y- lower edge); side error > 0: inside the true side; mm (std)")
    for dist in a.distance.split(","):
        rows, n = [], 0
        for d in a.dirs:
            files = sorted(glob.glob(os.path.join(
                d, f"{a.front}_d{float(dist):.1f}_a{a.angle}_f*.json")))[::a.every]
            for f in files:
                n += 1
                q, e = frame_errors(f, a.clean, cfg)
                if e is None:
                    continue
                rows.append(e)
                if a.verbose:
                    print(f"  {os.path.basename(f)} q={q:.3f} |d|={1e3 * e['pos']:5.1f} "
                          + " ".join(f"{k}={1e3 * e[k]:+6.1f}" for k in keys))
        if not rows:
            print(f"{dist} m: found 0/{n}")
            continue
        E = {k: 1e3 * np.array([r[k] for r in rows]) for k in keys + ("pos",)}
        print(f"{dist} m: found {len(rows)}/{n}; position error {E['pos'].mean():.1f} mm; "
              + "; ".join(f"{k} {E[k].mean():+.1f} ({E[k].std():.1f})" for k in keys)
              + f"; orientation {np.mean([r['angle_deg'] for r in rows]):.2f} deg")


if __name__ == "__main__":
    main()
