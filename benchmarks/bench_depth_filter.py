"""CPU time of the temporal depth filter (models/perception/depth_filter.py) per 640x480 frame, and the
noise it leaves on a static scene (prints figures; never fails on time).

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_depth_filter.py [--frames 30] [--distance 2.2]
        [--quick] [--json [FILE]]
"""

import argparse
import time

import numpy as np

from _common import add_output_arguments, emit_json
from mmlearn.models.perception.depth_filter import DepthFilterConfig, filter_depth, new_filter_state
from mmlearn.models.common.depth_noise import DepthNoiseConfig, apply_depth_noise, predicted_depth_std
from mmlearn.models.common.camera import PinholeIntrinsics


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=30, help="frames of the static scene")
    ap.add_argument("--distance", type=float, default=2.2, help="plane distance, m")
    add_output_arguments(ap, quick="8 frames (a few seconds)")
    a = ap.parse_args(argv)
    if a.quick:
        a.frames = 8
    table = a.json != "-"
    if a.frames < 2 or not a.distance > 0.5:
        ap.error("need --frames >= 2 and --distance > 0.5 (m)")
    K = PinholeIntrinsics.from_fov(640, 480, 58.0)
    ncfg = DepthNoiseConfig(seed=0)
    cfg = DepthFilterConfig(depth_std_at_1m=float(predicted_depth_std(1.0, K, ncfg)))
    # a plane seen from above, like the kitchen's fronts (depth rising down the image)
    v = np.arange(K.height, dtype=np.float32)[:, None]
    clean = np.ascontiguousarray(np.broadcast_to(
        np.float32(a.distance) + np.float32(0.0009) * (v - np.float32(K.cy)),
        (K.height, K.width)))
    st = new_filter_state(K.height, K.width)
    times, rows = [], []
    sig = float(predicted_depth_std(a.distance, K, ncfg))
    for k in range(a.frames):
        d = apply_depth_noise(clean, K, ncfg, frame=k)
        t0 = time.thread_time()
        out, scale, st = filter_depth(d, st, cfg)
        times.append(time.thread_time() - t0)
        if k + 1 in (1, 2, 4, 8, 16, 30) or k + 1 == a.frames:
            ok = np.isfinite(out)
            rms = float(np.sqrt(np.mean((out[ok] - clean[ok]) ** 2)))
            rows.append(dict(frame=k + 1, rms_error_m=rms, one_frame_std_m=sig,
                             median_scale=float(np.median(scale[ok]))))
            if table:
                print(f"frame {k + 1:3d}: rms error {1000 * rms:.2f} mm (one frame "
                      f"{1000 * sig:.2f} mm, / sqrt(n) "
                      f"{1000 * sig / np.sqrt(min(k + 1, cfg.max_frames)):.2f} mm), "
                      f"median scale {np.median(scale[ok]):.3f}")
    t = 1000 * np.array(times[1:])
    figures = {"filter_cpu_ms": float(np.median(t)), "filter_cpu_max_ms": float(t.max()),
               "rms_error_last_frame_mm": 1000 * rows[-1]["rms_error_m"]}
    if emit_json(a.json, dict(frames=a.frames, distance_m=a.distance, rows=rows,
                              figures=figures)):
        return
    print(f"filter_depth CPU per 640x480 frame: median {np.median(t):.1f} ms, max {t.max():.1f} ms "
          f"({len(t)} frames)")


if __name__ == "__main__":
    main()
