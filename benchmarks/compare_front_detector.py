"""Same rectangles, less time? The front detector of a git revision (``--ref``, default
``main``) against the working tree's, interleaved in one process on the same frames (prints
figures; never fails on time).

    python benchmarks/compare_front_detector.py --frames-dir DIR [--ref main] [--repeats 3]
                                                [--tol 1e-9]

Frames: every ``*.json`` + ``*_depth.npy`` pair in ``--frames-dir`` (as
``bench_front_detector.py``; e.g. frames 12 / 30 / 48 of ``python -m mmlearn.apps.render_fronts
--front door,drawer --distance 0.8,1.3,1.8,2.3 --frames 60 --seed 1 --out-dir ALL``). Per frame
both detectors run ``--repeats`` times, alternating which goes first (seed 0, default config);
reported per frame: the rectangle counts, the largest difference of the rectangles' poses,
sizes, precision and recall (identical when <= ``--tol``), the CPU times; then the median over
frames and the worst frame, per stage (the detector's own timings with
``clock=time.thread_time``). Single-threaded (BLAS and OpenCV threads limited to one). Exit
status 1 when a frame's rectangles differ.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import argparse
import importlib.util
import subprocess
import sys
import tempfile
import time

import cv2
import numpy as np

import mmlearn.models.perception.detection as new
from mmlearn.models.perception.detection import STAGES

cv2.setNumThreads(1)
HERE = os.path.dirname(os.path.abspath(__file__))


def load_ref(ref):
    """The module models/perception/detection.py of git revision ``ref``, imported from a copy."""
    try:
        src = subprocess.run(["git", "-C", HERE, "show", f"{ref}:models/perception/detection.py"],
                             check=True, capture_output=True, text=True).stdout
    except subprocess.CalledProcessError as e:
        raise SystemExit(f"compare_front_detector: cannot read models/perception/detection.py at "
                         f"{ref!r}: {e.stderr.strip()}")
    src = src.replace("from .fronts import", "from mmlearn.models.perception.fronts import")
    path = os.path.join(tempfile.mkdtemp(prefix="fd_ref_"), "front_detection_ref.py")
    with open(path, "w") as f:
        f.write(src)
    spec = importlib.util.spec_from_file_location("front_detection_ref", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def load_frames(directory):
    """(name, depth, intrinsics, X_WC) of every saved frame in ``directory`` (the frames of
    :func:`bench_front_detector.shared_frames`)."""
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    from bench_front_detector import shared_frames

    return [(f["name"], f["depth"], f["K"], f["X_WC"]) for f in shared_frames(directory)]


def flat(rects):
    """(n, 20): pose (16), width, height, precision, recall of each rectangle."""
    return np.array([np.concatenate([r.X_WR.ravel(), [r.width, r.height, r.precision,
                                                      r.recall]]) for r in rects]).reshape(-1, 20)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames-dir", required=True, help="directory of *.json + *_depth.npy frames")
    ap.add_argument("--ref", default="main", help="git revision of the detector compared with")
    ap.add_argument("--repeats", type=int, default=3, help="runs per frame and detector")
    ap.add_argument("--tol", type=float, default=1e-9,
                    help="largest difference that counts as identical (m, and unitless)")
    args = ap.parse_args(argv)
    if args.repeats < 1:
        raise SystemExit("compare_front_detector: --repeats must be >= 1")
    frames = load_frames(args.frames_dir)
    if not frames:
        raise SystemExit(f"compare_front_detector: no *.json + *_depth.npy frames in "
                         f"{args.frames_dir!r}")
    old = load_ref(args.ref)
    mods = {"ref": old, "new": new}
    res = {"ref": [], "new": []}
    same, worst_diff = True, 0.0
    for name, depth, K, X in frames:
        per = {"ref": [], "new": []}
        outs = {}
        for rep in range(args.repeats):
            order = ("ref", "new") if rep % 2 == 0 else ("new", "ref")
            for tag in order:
                mod = mods[tag]
                c0 = time.process_time()
                rects, tm = mod.detect_fronts(depth, K, X, mod.FrontDetectorConfig(), rng=0,
                                              clock=time.thread_time)
                per[tag].append([time.process_time() - c0] + [tm[s] for s in STAGES])
                outs[tag] = flat(rects)
        a, b = outs["ref"], outs["new"]
        if a.shape != b.shape:
            same = False
            diff = "DIFFERENT counts"
        else:
            dmax = float(np.abs(a - b).max()) if a.size else 0.0
            worst_diff = max(worst_diff, dmax)
            same &= dmax <= args.tol
            diff = f"max |diff| {dmax:.2g}" + ("" if dmax <= args.tol else " DIFFERENT")
        for tag in per:
            res[tag].append(np.median(np.array(per[tag]), axis=0))
        print(f"{name:28s} rects {a.shape[0]:2d} / {b.shape[0]:2d}  {diff:24s} CPU ms "
              f"{1e3 * res['ref'][-1][0]:6.1f} -> {1e3 * res['new'][-1][0]:6.1f}", flush=True)
    print(f"rectangles identical (<= {args.tol:g}) on all {len(frames)} frames: {same} "
          f"(largest difference {worst_diff:.2g})")
    for tag, label in (("ref", args.ref), ("new", "working tree")):
        r = 1e3 * np.array(res[tag])
        w = int(r[:, 0].argmax())
        print(f"{label}: process CPU median {np.median(r[:, 0]):.1f} ms, worst frame "
              f"{r[w, 0]:.1f} ms ({frames[w][0]}); stage medians "
              + ", ".join(f"{s} {np.median(r[:, i + 1]):.1f}" for i, s in enumerate(STAGES))
              + "; worst frame's " + ", ".join(f"{s} {r[w, i + 1]:.1f}"
                                               for i, s in enumerate(STAGES)))
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
