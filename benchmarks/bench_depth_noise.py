"""Speed benchmark of the depth camera: VTK render and DepthNoise per 640 x 480 frame
(prints figures; never fails on time).

    python benchmarks/bench_depth_noise.py [--repeats 20] [--quick] [--json [FILE]]

Renders the kitchen scene (drawer and door, 1.0 / 1.8 / 2.5 m, a few joint values) with the
perception diagram, then times on those clean renders:

- ``apply_depth_noise`` as a whole (wall-clock and process CPU time) and per stage
  (disparity, shadow, edges, grazing, dropout, noise, compose: CPU time of the thread),
  median over frames x repeats
  (on a shared machine the CPU time is the figure to compare: wall-clock also counts the time
  other processes hold the cores);
- the clean VTK depth render (``RgbdSensor`` output, cache invalidated by a new time);
- the share of missing pixels the noise leaves per distance.

Single thread (BLAS and OpenCV limited to one before numpy / cv2 are imported).
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from _common import add_output_arguments, emit_json  # noqa: E402


def _frames(quick=False):
    from mmlearn.diagrams.perception.diagram import FrontPerceptionConfig, MakeFrontPerceptionDiagram

    frames, render = [], []
    for front in ("door",) if quick else ("drawer", "door"):
        for dist in (1.8,) if quick else (1.0, 1.8, 2.5):
            cfg = FrontPerceptionConfig(front=front)
            cfg.camera.distance = dist
            P = MakeFrontPerceptionDiagram(cfg)
            ctx = P.diagram.CreateDefaultContext()
            port = P.diagram.GetOutputPort("clean_depth")
            for t in np.linspace(0.0, P.duration, 4):
                ctx.SetTime(float(t))
                t0 = time.perf_counter()
                img = port.Eval(ctx)
                render.append(time.perf_counter() - t0)
                frames.append((front, dist, np.array(img.data)[..., 0].copy(), P.intrinsics))
    return frames, render


def main(argv=None) -> int:
    import cv2

    cv2.setNumThreads(1)
    from mmlearn.models.common.depth_noise import DepthNoiseConfig, apply_depth_noise

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=20, help="noise draws per frame")
    add_output_arguments(ap, quick="the door at 1.8 m only, 2 noise draws (a few seconds)")
    args = ap.parse_args(argv)
    if args.quick:
        args.repeats = 2

    frames, render = _frames(args.quick)
    cfg = DepthNoiseConfig()
    apply_depth_noise(frames[0][2], frames[0][3], cfg)  # warm-up (imports)
    wall, cpu, stages, missing = [], [], {}, {}
    for k in range(args.repeats):
        for i, (front, dist, depth, K) in enumerate(frames):
            t = {}
            w0, c0 = time.perf_counter(), time.process_time()
            out = apply_depth_noise(depth, K, cfg, frame=k * 100 + i, timings=t)
            wall.append(time.perf_counter() - w0)
            cpu.append(time.process_time() - c0)
            for s, v in t.items():
                stages.setdefault(s, []).append(v)
            if k == 0:
                missing.setdefault(dist, []).append(float(np.isnan(out).mean()))
    res = {
        "frames": len(frames), "repeats": args.repeats,
        "noise_ms_wall_median": 1e3 * float(np.median(wall)),
        "noise_ms_wall_min": 1e3 * float(np.min(wall)),
        "noise_ms_cpu_median": 1e3 * float(np.median(cpu)),
        "stage_ms_cpu_median": {s: round(1e3 * float(np.median(v)), 3) for s, v in stages.items()},
        "render_ms_wall_median": 1e3 * float(np.median(render)),
        "render_ms_wall_min": 1e3 * float(np.min(render)),
        "missing_share_by_distance": {str(d): round(float(np.mean(v)), 4)
                                      for d, v in sorted(missing.items())},
        "load_average": os.getloadavg()[0],
    }
    res["figures"] = {"noise_cpu_ms": res["noise_ms_cpu_median"],
                      "noise_wall_ms": res["noise_ms_wall_median"],
                      "render_wall_ms": res["render_ms_wall_median"]}
    if emit_json(args.json, res):
        return 0
    print(f"{res['frames']} rendered 640x480 frames x {args.repeats} noise draws "
          f"(load average {res['load_average']:.1f})")
    print(f"DepthNoise (apply_depth_noise): median {res['noise_ms_wall_median']:.1f} ms wall, "
          f"min {res['noise_ms_wall_min']:.1f} ms, median {res['noise_ms_cpu_median']:.1f} ms CPU")
    print("  per stage (CPU time of the thread, median):")
    for s, v in res["stage_ms_cpu_median"].items():
        print(f"  {s:10s} {v:6.2f} ms")
    print(f"VTK depth render: median {res['render_ms_wall_median']:.1f} ms, "
          f"min {res['render_ms_wall_min']:.1f} ms (first render of a diagram included)")
    print("missing pixels after the noise, by distance: " + ", ".join(
        f"{d} m: {100 * v:.1f}%" for d, v in res["missing_share_by_distance"].items()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
