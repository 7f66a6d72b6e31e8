"""What each of the front detector's departures from the thesis buys: the detector on rendered
frames of the Drake kitchen with its default configuration and with one departure switched off
at a time (a configuration field set back), side by side on the same frames.

    python benchmarks/bench_detector_ablations.py [--frames 15] [--distances 1.5,2.2,2.8]
                                                 [--seed 1] [--variants a,b,...]
                                                 [--frames-dir DIR] [--json [FILE]]

The frames are rendered first by ``python -m mmlearn.apps.render_fronts`` (a door and a drawer
opening, camera straight in front at each distance, ``--frames`` frames each, evenly over the
opening, the first closed; a temporary folder), unless ``--frames-dir`` names a folder of
such frames (``*.json`` with ``*_depth.npy``, or ``*.npz`` holding ``depth_q`` as in
``tests/data/front_frames``).

Per variant and frame the detector runs once with the same seed; a frame's front counts as found
as in ``bench_front_detector.py`` (the nearest rectangle's centre within 0.1 m of the true one,
its normal within 20 deg, width and height within 0.1 m). Reported per variant: frames found
(all, closed fronts, per front and distance), the mean position, orientation, width and height
errors of the found fronts (and the largest width error), the median CPU time per frame, on how
many frames it found the same rectangles on vertical planes (normals within 20 deg of
horizontal: the fronts reported by default) as the default configuration, and the frames whose front the default
configuration found and the variant did not (``lost``), or the other way round (``gained``).
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import dataclasses
import glob
import json
import subprocess
import sys
import tempfile
import time

import cv2
import numpy as np

from _common import add_output_arguments, emit_json

from mmlearn.models.common.camera import PinholeIntrinsics
from mmlearn.models.perception.detection import FrontDetectorConfig, detect_fronts

cv2.setNumThreads(1)

#: variant -> (configuration fields set, what is switched off)
VARIANTS = {
    "default": ({}, "the detector as configured by default"),
    "thesis_costs": ({"cost_occluded": 0.2, "cost_unknown": 0.2},
                     "occluded and unknown pixels cost 0.2 instead of 20/255"),
    "no_crossings": ({"crossing_angle_deg": 90.0},
                     "no crossings: a pixel within L of two crossing planes is in-plane for both"),
    "no_own_pixel_refit": ({"own_pixel_refit_deg": 0.0}, "no own-pixel refit"),
    "no_reveals": ({"gap_min_length": 100.0},
                   "no reveals (and with them no region starts)"),
    "no_long_pass": ({"gap_long_window_px": 0}, "no long reveal pass"),
    "no_region_starts": ({"component_starts": 0}, "no region starts"),
    "no_layers": ({"layer_planes": 0}, "no offset layers"),
    "coarse_rotation": ({"rotation_step_factors": [8, 4]},
                        "rotation polish in 2 and 4 deg steps instead of 0.5 and 1 deg"),
    "all_planes_searched": ({"front_max_tilt_deg": 90.0},
                            "every plane searched, not only the vertical ones"),
    "cell_planes": ({"plane_method": "cells"},
                    "planes from the cell grid of the organised image instead of RANSAC"),
}


def render(out_dir, frames, distances, seed):
    """Render the frames with the render_fronts app into ``out_dir``."""
    cmd = [sys.executable, "-m", "mmlearn.apps.render_fronts", "--out-dir", out_dir,
           "--front", "door,drawer", "--distance", ",".join(f"{d:g}" for d in distances),
           "--frames", str(frames), "--seed", str(seed), "--json"]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"bench_detector_ablations: rendering failed: "
                 f"{(r.stderr.strip().splitlines() or ['?'])[-1]}")


def load_frames(directory):
    """The frames of ``directory``: dicts with name, depth, K, X_WC, X_WR, size, joint_value."""
    out = []
    for f in sorted(glob.glob(os.path.join(directory, "*.json"))):
        base = f[:-5]
        if os.path.exists(base + "_depth.npy"):
            depth = np.load(base + "_depth.npy")
        elif os.path.exists(base + ".npz"):
            q = np.load(base + ".npz")["depth_q"]
            depth = np.where(q > 0, q / 4000.0, np.nan).astype(np.float32)
        else:
            continue
        m = json.load(open(f))
        out.append(dict(name=os.path.basename(base), depth=depth,
                        K=PinholeIntrinsics(**m["intrinsics"]), X_WC=np.array(m["X_WC"]),
                        X_WR=np.array(m["X_WR"]), size=(m["width"], m["height"]),
                        joint_value=float(m.get("joint_value", 0.0)),
                        front=os.path.basename(base).split("_")[0],
                        distance=float(os.path.basename(base).split("_d")[1].split("_")[0])))
    return out


def _errors(rect, X):
    """Position (m), orientation (deg, up to the turn about the normal) and normal (deg)
    errors of ``rect`` against the true pose ``X``."""
    perr = float(np.linalg.norm(rect.center - X[:3, 3]))
    best = 180.0
    for flip in (np.eye(3), np.diag([-1.0, -1.0, 1.0])):
        R = X[:3, :3].T @ rect.X_WR[:3, :3] @ flip
        best = min(best, float(np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1)))))
    nerr = float(np.degrees(np.arccos(min(1.0, abs(float(rect.normal @ X[:3, 2]))))))
    return perr, best, nerr


def score(rects, fr):
    """The frame's front as found (dict of errors) or None."""
    best = None
    for r in rects:
        e = _errors(r, fr["X_WR"])
        if best is None or e[0] < best[0]:
            best = e + (r,)
    if best is None:
        return None
    perr, oerr, nerr, r = best
    w, h = fr["size"]
    if perr < 0.1 and nerr < 20.0 and abs(r.width - w) < 0.1 and abs(r.height - h) < 0.1:
        return dict(pos_err_m=perr, orient_err_deg=oerr, width_err_m=r.width - w,
                    height_err_m=r.height - h)
    return None


def _vertical(rects, max_tilt_deg=20.0):
    """The rectangles whose normal is within ``max_tilt_deg`` of horizontal (world z up): the
    fronts the default configuration reports."""
    s = np.sin(np.radians(max_tilt_deg))
    return [r for r in rects if abs(float(r.normal[2])) < s]


def _same(a, b, tol=1e-6):
    """Whether the rectangles on vertical planes are the same (poses and sizes within tol)."""
    a, b = _vertical(a), _vertical(b)
    return len(a) == len(b) and all(
        np.allclose(r.X_WR, q.X_WR, atol=tol) and abs(r.width - q.width) < tol
        and abs(r.height - q.height) < tol for r, q in zip(a, b))


def run(frames, names, seed):
    """Per variant: its summary over the frames (the variants alternate frame by frame)."""
    cfgs = {n: dataclasses.replace(FrontDetectorConfig(), **VARIANTS[n][0]).validate()
            for n in names}
    base_cfg = FrontDetectorConfig()
    if frames:  # untimed: the first call of a process loads the compiled kernels
        detect_fronts(frames[0]["depth"], frames[0]["K"], frames[0]["X_WC"], base_cfg, rng=seed)
    per = {n: [] for n in names}
    for fr in frames:
        base = detect_fronts(fr["depth"], fr["K"], fr["X_WC"], base_cfg, rng=seed)[0]
        for n in names:
            c0 = time.process_time()
            rects, _ = detect_fronts(fr["depth"], fr["K"], fr["X_WC"], cfgs[n], rng=seed)
            cpu = time.process_time() - c0
            per[n].append(dict(name=fr["name"], front=fr["front"], distance=fr["distance"],
                               closed=fr["joint_value"] == 0.0, cpu_s=cpu,
                               same_as_default=_same(rects, base), found=score(rects, fr)))
    out = {n: summary(rows, n) for n, rows in per.items()}
    if "default" in per:
        base = {r["name"]: bool(r["found"]) for r in per["default"]}
        for n, rows in per.items():
            out[n]["lost"] = [r["name"] for r in rows if base[r["name"]] and not r["found"]]
            out[n]["gained"] = [r["name"] for r in rows if r["found"] and not base[r["name"]]]
    return out


def summary(rows, name):
    found = [r for r in rows if r["found"]]
    closed = [r for r in rows if r["closed"]]

    def mean(key, subset=None, how=np.mean):
        xs = [abs(r["found"][key]) for r in found if subset is None or r["front"] == subset]
        return float(how(xs)) if xs else None

    by = {}
    for r in rows:
        k = f"{r['front']} {r['distance']:g} m"
        n, f = by.get(k, (0, 0))
        by[k] = (n + 1, f + bool(r["found"]))
    return dict(
        fields=VARIANTS[name][0], what=VARIANTS[name][1], frames=len(rows), found=len(found),
        closed_frames=len(closed), closed_found=sum(bool(r["found"]) for r in closed),
        found_by=by, same_as_default=sum(r["same_as_default"] for r in rows),
        pos_err_mm=None if mean("pos_err_m") is None else 1e3 * mean("pos_err_m"),
        orient_err_deg=mean("orient_err_deg"),
        **{f"{what}_err_mm_{front}": None if mean(f"{what}_err_m", front) is None
           else 1e3 * mean(f"{what}_err_m", front)
           for what in ("width", "height") for front in ("door", "drawer")},
        **{f"width_err_mm_{front}_max": None if mean("width_err_m", front) is None
           else 1e3 * mean("width_err_m", front, np.max) for front in ("door", "drawer")},
        cpu_ms_median=1e3 * float(np.median([r["cpu_s"] for r in rows])) if rows else None)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--frames", type=int, default=15, help="frames per front and distance")
    ap.add_argument("--distances", default="1.5,2.2,2.8", help="camera distances, m")
    ap.add_argument("--seed", type=int, default=1, help="noise and detector seed")
    ap.add_argument("--variants", default=",".join(VARIANTS),
                    help=f"comma-separated, from {', '.join(VARIANTS)}")
    ap.add_argument("--frames-dir", default=None,
                    help="use these frames instead of rendering them")
    add_output_arguments(ap)
    args = ap.parse_args(argv)
    names = [v.strip() for v in args.variants.split(",") if v.strip()]
    bad = [n for n in names if n not in VARIANTS]
    if bad or not names:
        ap.error(f"--variants: unknown {', '.join(bad) or '(none given)'}; choose from "
                 f"{', '.join(VARIANTS)}")
    try:
        distances = [float(d) for d in args.distances.split(",")]
    except ValueError:
        ap.error(f"--distances: not a list of numbers: {args.distances!r}")
    with tempfile.TemporaryDirectory() as tmp:
        directory = args.frames_dir
        if directory is None:
            directory = tmp
            render(tmp, args.frames, distances, args.seed)
        frames = load_frames(directory)
        if not frames:
            sys.exit(f"bench_detector_ablations: no frames in {directory}")
        variants = run(frames, names, args.seed)
    settings = dict(frames_per_front_and_distance=args.frames, distances=distances,
                    seed=args.seed, frames_dir=args.frames_dir)
    if emit_json(args.json, dict(settings=settings, variants=variants)):
        return
    for n, v in variants.items():
        print(f"{n:20s} found {v['found']:3d}/{v['frames']:3d} (closed {v['closed_found']}/"
              f"{v['closed_frames']})  same as default {v['same_as_default']:3d}  "
              f"pos {v['pos_err_mm'] or float('nan'):5.1f} mm  width door "
              f"{v['width_err_mm_door'] or float('nan'):5.1f} drawer "
              f"{v['width_err_mm_drawer'] or float('nan'):5.1f} mm  "
              f"CPU {v['cpu_ms_median']:5.1f} ms")


if __name__ == "__main__":
    main()
