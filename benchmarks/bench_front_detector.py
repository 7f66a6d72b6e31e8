"""Speed and accuracy of the front detector (thesis 5.1.1-5.1.2), side by side with Open3D's
RANSAC plane segmentation (prints figures; never fails on time).

    python benchmarks/bench_front_detector.py [--frames-dir DIR] [--synthetic 12] [--repeats 3]
                                              [--seed 0] [--no-open3d] [--quick]
                                              [--json [FILE]] [--baseline REV]
    python benchmarks/bench_front_detector.py --sweep [--seeds 3]

``--sweep`` instead measures accuracy only on synthetic frames: door and drawer, camera
1.0 / 1.5 / 2.0 / 2.3 / 2.5 m away and 0 / 15 / 30 / 45 deg off the front's normal (alternating
sides), 0.5 m above the front, ``--seeds`` frames each (random pull-out and lateral offset);
detection rate and position / orientation errors per distance and per angle.

Frames (640 x 480):

- ``--synthetic N`` frames rendered in numpy (models/perception/synth.py: wall, floor, cabinet, one
  door or drawer front pulled out 0.1-0.3 m, camera 1.0-2.5 m away and up to 30 deg off the
  front's normal, noise 0.0015 z^2 m, 1 % drop-outs);
- every ``*.json`` + ``*_depth.npy`` pair in ``--frames-dir`` (default /work/shared-frames when it
  exists: frames of the Drake kitchen scene with the DepthNoise model, see its README.txt).

Per frame the detector runs ``--repeats`` times (seed fixed); the figures are the median over
frames of the per-frame median: the CPU time per stage (the detector's timings with
``clock=time.thread_time``) and the process CPU time of the whole call. Compare the CPU time
with the targets (whole detector < 100 ms, planes < 30 ms per frame on one core; thesis
anchors 0.845 / 0.008 / 0.010 / 0.313 s for planes / mask / sampling / optimisation on a
2 GHz core).

Accuracy per frame with ground truth: the detected rectangle nearest to the true front counts
as found when its centre is within 0.1 m, its normal within 20 deg and its width and height
within 0.1 m of the true ones;
reported: detection rate, and mean / median / max position and orientation error of the found
ones (orientation: the rotation angle between the poses up to the 180 deg turn about the
normal).

``--baseline REV`` (a git revision of this repository, e.g. ``HEAD~3``) runs the detector of
that revision too, on the same frames in the same process, frame by frame alternating with the
current one, and prints both per stage side by side with their ratio, and whether the two
found the same rectangles (the revision's ``models/perception/detection`` is extracted into a
temporary directory as a package of its own; everything else is the current code).

Open3D (only here, not a project dependency; skipped with a message when it does not import):
``PointCloud.segment_plane(distance_threshold=0.02, ransac_n=3, num_iterations=200)`` on the
same frames' points, planes extracted one after another (inliers removed) up to the detector's
``max_planes``, on the full-resolution cloud and on the cloud subsampled like ours (every 8th
pixel). Open3D 0.20's wheel needs libusb-1.0.so.0; when the system lacks it, ``pip install
libusb-package`` provides it and this script preloads it.

Single-threaded: BLAS, OpenMP and OpenCV threads are limited to one (set before numpy is
imported).
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import argparse
import glob
import json
import math
import time

import cv2
import numpy as np

from _common import add_output_arguments, emit_json, import_revision

from mmlearn.models.perception.detection import STAGES, FrontDetectorConfig, detect_fronts
from mmlearn.models.perception.synth import (DOOR_SIZE, DRAWER_SIZE, add_depth_noise, front_pose,
                                             kitchen_scene, look_at, render_depth)
from mmlearn.models.common.camera import PinholeIntrinsics, depth_to_points

cv2.setNumThreads(1)

THESIS_S = {"planes": 0.845, "masks": 0.008, "sampling": 0.010, "optimisation": 0.313,
            "check": 0.0023}


def synthetic_frames(n, seed):
    rng = np.random.default_rng(seed)
    K = PinholeIntrinsics.from_fov(640, 480, 58.0)
    frames = []
    for i in range(n):
        size = DOOR_SIZE if i % 2 == 0 else DRAWER_SIZE
        dist = 1.0 + 1.5 * (i / max(1, n - 1))
        view = math.radians(rng.uniform(-30, 30))
        X = front_pose(0.62 + rng.uniform(0.1, 0.3), rng.uniform(-0.3, 0.3),
                       0.45 if size == DOOR_SIZE else 0.75)
        cam = X[:3, 3] + dist * np.array([math.cos(view), math.sin(view), 0.0])
        cam[2] = X[2, 3] + 0.6
        X_WC = look_at(cam, X[:3, 3])
        depth = add_depth_noise(render_depth(kitchen_scene([(size, X, 0.02)]), K, X_WC), rng)
        frames.append(dict(name=f"synthetic_{i:02d}_{'door' if size == DOOR_SIZE else 'drawer'}"
                           f"_d{dist:.1f}", depth=depth.astype(np.float32), K=K, X_WC=X_WC,
                           X_WR=X, size=size))
    return frames


def shared_frames(directory):
    frames = []
    for f in sorted(glob.glob(os.path.join(directory, "*.json"))):
        dpath = f[:-5] + "_depth.npy"
        if not os.path.exists(dpath):
            continue
        m = json.load(open(f))
        frames.append(dict(name=os.path.basename(f)[:-5], depth=np.load(dpath),
                           K=PinholeIntrinsics(**m["intrinsics"]), X_WC=np.array(m["X_WC"]),
                           X_WR=np.array(m["X_WR"]), size=(m["width"], m["height"]),
                           joint_value=m.get("joint_value")))
    return frames


def errors(rect, X):
    perr = float(np.linalg.norm(rect.center - X[:3, 3]))
    best = 180.0
    for flip in (np.eye(3), np.diag([-1.0, -1.0, 1.0])):
        R = X[:3, :3].T @ rect.X_WR[:3, :3] @ flip
        best = min(best, math.degrees(math.acos(np.clip((np.trace(R) - 1) / 2, -1, 1))))
    nerr = math.degrees(math.acos(min(1.0, abs(float(rect.normal @ X[:3, 2])))))
    return perr, best, nerr


PKG = "models/perception/detection"


def load_baseline(rev):
    """The detector package of git revision ``rev`` of this repository, imported as a package
    of its own (``_baseline_detection``, from a temporary directory): (detect_fronts,
    FrontDetectorConfig). Raises SystemExit with a one-line message when it cannot."""
    mod = import_revision(rev, [PKG], PKG, "_baseline_detection",
                          ("mmlearn.models.perception.detection", "_baseline_detection"))
    return mod.detect_fronts, mod.FrontDetectorConfig


def _time_one(detect, fr, cfg, seed):
    c0 = time.process_time()
    rects, tm = detect(fr["depth"], fr["K"], fr["X_WC"], cfg, rng=seed, clock=time.thread_time)
    return rects, tm, time.process_time() - c0


def _same_rects(a, b, tol=1e-6):
    """Whether two detections are the same rectangles (poses and sizes within ``tol``)."""
    return len(a) == len(b) and all(
        np.allclose(r.X_WR, q.X_WR, atol=tol) and abs(r.width - q.width) < tol
        and abs(r.height - q.height) < tol for r, q in zip(a, b))


def run_detector(frames, cfg, repeats, seed, baseline=None):
    """Per frame: the median CPU time per stage over ``repeats`` runs, the rectangles'
    accuracy; with ``baseline`` (detect_fronts, config) the baseline's times too (keys
    ``base_<stage>``, ``base_cpu``), its runs alternating with the current one's, and
    ``same``: whether both found the same rectangles."""
    rows = []
    if frames:  # untimed: the first call of a process loads the compiled kernels
        _time_one(detect_fronts, frames[0], cfg, seed)
        if baseline is not None:
            _time_one(baseline[0], frames[0], baseline[1](), seed)
    for fr in frames:
        stage = {k: [] for k in STAGES + ("total",)}
        bstage = {k: [] for k in STAGES + ("total",)}
        cpu, bcpu = [], []
        for _ in range(repeats):
            if baseline is not None:
                brects, btm, bc = _time_one(baseline[0], fr, baseline[1](), seed)
                bcpu.append(bc)
                for k in bstage:
                    bstage[k].append(btm[k])
            rects, tm, c = _time_one(detect_fronts, fr, cfg, seed)
            cpu.append(c)
            for k in stage:
                stage[k].append(tm[k])
        row = dict(name=fr["name"], n_rects=len(rects), cpu=float(np.median(cpu)),
                   **{k: float(np.median(v)) for k, v in stage.items()})
        if baseline is not None:
            row.update(base_cpu=float(np.median(bcpu)), same=_same_rects(rects, brects),
                       **{f"base_{k}": float(np.median(v)) for k, v in bstage.items()})
        best = None
        for r in rects:
            e = errors(r, fr["X_WR"])
            if best is None or e[0] < best[0]:
                best = e + (r,)
        found = (best is not None and best[0] < 0.1 and best[2] < 20.0
                 and abs(best[3].width - fr["size"][0]) < 0.1
                 and abs(best[3].height - fr["size"][1]) < 0.1)
        row.update(found=bool(found))
        if found:
            row.update(pos_err=best[0], orient_err=best[1], width=best[3].width,
                       height=best[3].height)
        rows.append(row)
    return rows


def load_open3d():
    try:
        import ctypes
        try:
            import libusb_package
            ctypes.CDLL(os.path.join(os.path.dirname(libusb_package.__file__), "libusb-1.0.so"),
                        mode=ctypes.RTLD_GLOBAL)
        except (ImportError, OSError):
            pass
        import open3d as o3d
        return o3d, None
    except Exception as e:  # noqa: BLE001 - any import failure means "skip"
        return None, f"{type(e).__name__}: {e}"


def run_open3d(o3d, frames, cfg, stride):
    out = []
    for fr in frames:
        P = depth_to_points(fr["depth"], fr["K"])
        if stride > 1:
            off = stride // 2
            P = P[off::stride, off::stride]
        P = P.reshape(-1, 3)
        P = P[np.isfinite(P[:, 2]) & (P[:, 2] <= cfg.max_depth)]
        pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(P))
        min_inl = max(3, cfg.min_plane_points * (1 if stride > 1 else cfg.ransac_stride_px ** 2))
        w0, c0 = time.perf_counter(), time.process_time()
        planes = 0
        for _ in range(int(cfg.max_planes)):
            if len(pc.points) < min_inl:
                break
            _, inl = pc.segment_plane(distance_threshold=cfg.inlier_distance, ransac_n=3,
                                      num_iterations=cfg.ransac_hypotheses)
            if len(inl) < min_inl:
                break
            planes += 1
            pc = pc.select_by_index(inl, invert=True)
        out.append(dict(wall=time.perf_counter() - w0, cpu=time.process_time() - c0,
                        planes=planes, points=len(P)))
    return out


def sweep(seeds):
    K = PinholeIntrinsics.from_fov(640, 480, 58.0)
    dists, angles = (1.0, 1.5, 2.0, 2.3, 2.5), (0, 15, 30, 45)
    rows = []
    for size, name in ((DOOR_SIZE, "door"), (DRAWER_SIZE, "drawer")):
        for dist in dists:
            for ang in angles:
                for seed in range(seeds):
                    rng = np.random.default_rng([seed, ang, int(100 * dist), len(name)])
                    X = front_pose(0.62 + rng.uniform(0.1, 0.3), rng.uniform(-0.3, 0.3),
                                   0.45 if name == "door" else 0.75)
                    a = math.radians(ang * (1 if seed % 2 else -1))
                    cam = X[:3, 3] + dist * np.array([math.cos(a), math.sin(a), 0.0])
                    cam[2] = X[2, 3] + 0.5
                    X_WC = look_at(cam, X[:3, 3])
                    depth = add_depth_noise(
                        render_depth(kitchen_scene([(size, X, 0.02)]), K, X_WC), rng)
                    rects, _ = detect_fronts(depth, K, X_WC, FrontDetectorConfig(), rng=seed)
                    best = None
                    for r in rects:
                        e = errors(r, X)
                        if (e[0] < 0.1 and e[2] < 20 and abs(r.width - size[0]) < 0.1
                                and abs(r.height - size[1]) < 0.1
                                and (best is None or e[0] < best[0])):
                            best = e
                    rows.append((name, dist, ang, best))
    out = []
    for name in ("door", "drawer"):
        for key, vals, col in (("distance_m", dists, 1), ("angle_deg", angles, 2)):
            for v in vals:
                sel = [r[3] for r in rows if r[0] == name and r[col] == v]
                found = [f for f in sel if f is not None]
                pe = np.array([f[0] for f in found]) if found else np.full(1, np.nan)
                oe = np.array([f[1] for f in found]) if found else np.full(1, np.nan)
                out.append(dict(front=name, **{key: v}, frames=len(sel), found=len(found),
                                pos_err_mean=float(pe.mean()), pos_err_max=float(pe.max()),
                                orient_err_mean=float(oe.mean()),
                                orient_err_max=float(oe.max())))
    return out


def _config(settings) -> FrontDetectorConfig:
    """The detector's configuration with the ``FIELD=VALUE`` overrides ``settings`` (VALUE
    parsed as YAML); raises ValueError naming a bad one."""
    import yaml
    kw = {}
    for text in settings:
        key, sep, value = text.partition("=")
        if not sep or key not in FrontDetectorConfig.__dataclass_fields__:
            raise ValueError(f"expected FIELD=VALUE with a FrontDetectorConfig field, got "
                             f"{text!r}")
        kw[key] = yaml.safe_load(value)
    return FrontDetectorConfig(**kw).validate()


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--frames-dir", default="/work/shared-frames",
                    help="directory of *.json + *_depth.npy frames (skipped when missing)")
    ap.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE",
                    help="a FrontDetectorConfig field of the timed detector (repeatable; the "
                         "--baseline revision keeps its defaults)")
    ap.add_argument("--synthetic", type=int, default=12, help="number of synthetic frames")
    ap.add_argument("--repeats", type=int, default=3, help="detector runs per frame")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--no-open3d", action="store_true", help="skip the Open3D comparison")
    add_output_arguments(ap, quick="12 synthetic frames, one run each, no shared frames, no "
                                   "Open3D (a few seconds)")
    ap.add_argument("--sweep", action="store_true",
                    help="accuracy sweep over distance and viewing angle (synthetic frames)")
    ap.add_argument("--seeds", type=int, default=3, help="frames per cell of the sweep")
    ap.add_argument("--baseline", default=None, metavar="REV",
                    help="also run the detector of this git revision, side by side")
    args = ap.parse_args(argv)
    if args.quick:
        args.synthetic, args.repeats, args.frames_dir, args.no_open3d = 12, 1, "", True
        args.seeds = 1
    if args.sweep:
        rows = sweep(args.seeds)
        if emit_json(args.json, dict(sweep=rows)):
            return
        for r in rows:
            cell = (f"d = {r['distance_m']:.1f} m" if "distance_m" in r
                    else f"angle = {r['angle_deg']:2d} deg")
            print(f"{r['front']:6s} {cell:15s} found {r['found']:2d}/{r['frames']:2d}  "
                  f"position mean {1e3 * r['pos_err_mean']:5.1f} max "
                  f"{1e3 * r['pos_err_max']:5.1f} mm  orientation mean "
                  f"{r['orient_err_mean']:.2f} max {r['orient_err_max']:.2f} deg")
        return
    try:
        cfg = _config(args.set)
    except ValueError as e:
        ap.error(f"--set: {e}")
    sets = {"synthetic": synthetic_frames(args.synthetic, args.seed)}
    if args.frames_dir and os.path.isdir(args.frames_dir):
        sets["shared"] = shared_frames(args.frames_dir)
    report = {}
    baseline = None if args.baseline is None else load_baseline(args.baseline)
    o3d, why = (None, "--no-open3d") if args.no_open3d else load_open3d()
    for name, frames in sets.items():
        if not frames:
            continue
        rows = run_detector(frames, cfg, args.repeats, args.seed, baseline)
        keys = STAGES + ("total", "cpu")
        med = {k: float(np.median([r[k] for r in rows])) for k in keys}
        found = [r for r in rows if r["found"]]
        acc = dict(frames=len(rows), found=len(found),
                   detection_rate=len(found) / len(rows))
        if found:
            pe = np.array([r["pos_err"] for r in found])
            oe = np.array([r["orient_err"] for r in found])
            acc.update(pos_err_mean=float(pe.mean()), pos_err_median=float(np.median(pe)),
                       pos_err_max=float(pe.max()), orient_err_mean=float(oe.mean()),
                       orient_err_median=float(np.median(oe)), orient_err_max=float(oe.max()))
        entry = dict(median_s=med, accuracy=acc, frames=rows)
        if baseline is not None:
            entry["baseline"] = dict(
                revision=args.baseline, same_rects=sum(r["same"] for r in rows),
                median_s={k: float(np.median([r[f"base_{k}"] for r in rows])) for k in keys})
        if o3d is not None:
            for stride, key in ((1, "open3d_full"), (cfg.ransac_stride_px, "open3d_subsampled")):
                res = run_open3d(o3d, frames, cfg, stride)
                entry[key] = dict(wall_s=float(np.median([r["wall"] for r in res])),
                                  cpu_s=float(np.median([r["cpu"] for r in res])),
                                  planes=float(np.median([r["planes"] for r in res])),
                                  points=float(np.median([r["points"] for r in res])))
        report[name] = entry
    syn = report.get("synthetic")
    figures = {} if syn is None else {
        **{f"{k}_cpu_ms": 1e3 * syn["median_s"][k] for k in STAGES + ("total",)},
        "process_cpu_ms": 1e3 * syn["median_s"]["cpu"],
        "detection_rate": syn["accuracy"]["detection_rate"]}
    if emit_json(args.json, dict(report=report, open3d=None if o3d is None else o3d.__version__,
                                 open3d_skipped=why, figures=figures)):
        return
    for name, e in report.items():
        n = e["accuracy"]["frames"]
        print(f"== {name} frames ({n}, 640x480, median over frames of the median of "
              f"{args.repeats} runs) ==")
        b = e.get("baseline")
        print(f"{'stage':14s} {'ours CPU ms':>13s} {'thesis ms':>10s}" + (
            "" if b is None else f" {b['revision'] + ' ms':>14s} {'ratio':>6s}"))
        th_all = dict(THESIS_S, cpu=sum(THESIS_S.values()))
        for k in STAGES + ("total", "cpu"):
            th = th_all.get(k)
            line = (f"{'process CPU' if k == 'cpu' else k:14s} {1e3 * e['median_s'][k]:13.1f} "
                    f"{'' if th is None else f'{1e3 * th:10.1f}':>10s}")
            if b is not None:
                ratio = b["median_s"][k] / max(e["median_s"][k], 1e-9)
                line += f" {1e3 * b['median_s'][k]:14.1f} {ratio:5.2f}x"
            print(line)
        if b is not None:
            print(f"same rectangles as {b['revision']}: {b['same_rects']}/{n} frames")
        for key in ("open3d_full", "open3d_subsampled"):
            if key in e:
                o = e[key]
                print(f"{key:18s}: planes stage {1e3 * o['wall_s']:.1f} ms wall, "
                      f"{1e3 * o['cpu_s']:.1f} ms CPU ({o['planes']:.0f} planes, "
                      f"{o['points']:.0f} points)")
        a = e["accuracy"]
        line = f"detection {a['found']}/{a['frames']} = {100 * a['detection_rate']:.0f} %"
        if a["found"]:
            line += (f"; position error mean {1e3 * a['pos_err_mean']:.1f} mm (median "
                     f"{1e3 * a['pos_err_median']:.1f}, max {1e3 * a['pos_err_max']:.1f}); "
                     f"orientation mean {a['orient_err_mean']:.2f} deg (median "
                     f"{a['orient_err_median']:.2f}, max {a['orient_err_max']:.2f})")
        print(line)
        for r in e["frames"]:
            err = (f"pos {1e3 * r['pos_err']:6.1f} mm  orient {r['orient_err']:5.2f} deg  "
                   f"w x h {r['width']:.3f} x {r['height']:.3f}") if r["found"] else "not found"
            print(f"   {r['name']:28s} {r['n_rects']:2d} rects  cpu {1e3 * r['cpu']:5.1f} ms  "
                  f"{err}")
    if o3d is None:
        print(f"Open3D comparison skipped ({why})")
    else:
        print(f"Open3D {o3d.__version__}")


if __name__ == "__main__":
    main()
