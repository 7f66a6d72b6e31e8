"""CPU time of the temporal depth filter per 640x480 frame (the model, models/perception/
depth_filter.py, and one periodic update of the DepthTemporalFilter system in a simulation,
which includes Drake's copies of its state) and the noise it leaves on a static scene (prints
figures; never fails on time).

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_depth_filter.py [--frames 30] [--distance 2.2]
        [--updates 60] [--quick] [--json [FILE]]
"""

import argparse
import time

import numpy as np
from _common import add_output_arguments, emit_json

from mmlearn.models.common.camera import PinholeIntrinsics
from mmlearn.models.common.depth_noise import DepthNoiseConfig, apply_depth_noise, predicted_depth_std
from mmlearn.models.perception.depth_filter import DepthFilterConfig, filter_depth, new_filter_state


def _plane(K, distance):
    """A plane seen from above, like the kitchen's fronts (depth rising down the image)."""
    v = np.arange(K.height, dtype=np.float32)[:, None]
    return np.ascontiguousarray(np.broadcast_to(
        np.float32(distance) + np.float32(0.0009) * (v - np.float32(K.cy)),
        (K.height, K.width)))


def model_cost(K, clean, cfg, ncfg, frames, distance, *, table=True):
    """filter_depth on ``frames`` noisy frames: the rms error after some of them (printed) and
    the CPU ms per frame (the first frame not counted)."""
    st = new_filter_state(K.height, K.width)
    times = []
    sig = float(predicted_depth_std(distance, K, ncfg))
    rms_at = {}
    for k in range(frames):
        d = apply_depth_noise(clean, K, ncfg, frame=k)
        t0 = time.thread_time()
        out, scale, st = filter_depth(d, st, cfg)
        times.append(time.thread_time() - t0)
        if k + 1 in (1, 2, 4, 8, 16, 30) or k + 1 == frames:
            ok = np.isfinite(out)
            rms = float(np.sqrt(np.mean((out[ok] - clean[ok]) ** 2)))
            rms_at[k + 1] = rms
            if table:
                print(f"frame {k + 1:3d}: rms error {1000 * rms:.2f} mm (one frame {1000 * sig:.2f} "
                      f"mm, / sqrt(n) {1000 * sig / np.sqrt(min(k + 1, cfg.max_frames)):.2f} "
                      f"mm), median scale {np.median(scale[ok]):.3f}")
    return 1000 * np.array(times[1:]), rms_at


def system_update_cost(K, depth, cfg, updates, rate_hz=30.0, repeats=3):
    """CPU ms per periodic update of a DepthTemporalFilter fed a constant frame in a
    simulation (``updates`` updates; the least of ``repeats`` runs)."""
    from pydrake.common.value import AbstractValue
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.primitives import ConstantValueSource
    from pydrake.systems.sensors import ImageDepth32F

    from mmlearn.systems import DepthTemporalFilter

    img = ImageDepth32F(K.width, K.height)
    img.mutable_data[:, :, 0] = depth
    best = None
    for _ in range(repeats):
        b = DiagramBuilder()
        src = b.AddSystem(ConstantValueSource(AbstractValue.Make(img)))
        filt = b.AddSystem(DepthTemporalFilter(intrinsics=K, config=cfg, rate_hz=rate_hz))
        b.Connect(src.get_output_port(0), filt.get_depth_image_input_port())
        sim = Simulator(b.Build())
        sim.Initialize()
        t0 = time.thread_time()
        sim.AdvanceTo(updates / rate_hz)
        dt = (time.thread_time() - t0) / updates
        best = dt if best is None else min(best, dt)
    return 1000 * best


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=30, help="frames of the static scene")
    ap.add_argument("--distance", type=float, default=2.2, help="plane distance, m")
    ap.add_argument("--updates", type=int, default=60,
                    help="periodic updates of the system timed (30 Hz); 0 = skip")
    add_output_arguments(ap, quick="8 frames and 10 updates (a few seconds)")
    a = ap.parse_args(argv)
    if a.quick:
        a.frames, a.updates = 8, min(a.updates, 10)
    table = a.json != "-"
    if a.frames < 2 or not a.distance > 0.5 or a.updates < 0:
        ap.error("need --frames >= 2, --distance > 0.5 (m) and --updates >= 0")
    K = PinholeIntrinsics.from_fov(640, 480, 58.0)
    ncfg = DepthNoiseConfig(seed=0)
    cfg = DepthFilterConfig(depth_std_at_1m=float(predicted_depth_std(1.0, K, ncfg)))
    clean = _plane(K, a.distance)
    t, rms_at = model_cost(K, clean, cfg, ncfg, a.frames, a.distance, table=table)
    if table:
            print(f"filter_depth CPU per 640x480 frame: median {np.median(t):.1f} ms, max "
              f"{t.max():.1f} ms ({len(t)} frames)")
    res = {"filter_depth_ms_median": float(np.median(t)), "filter_depth_ms_max": float(t.max()),
           "frames": len(t), "rms_error_m": {str(k): v for k, v in rms_at.items()}}
    if a.updates:
        ms = system_update_cost(K, apply_depth_noise(clean, K, ncfg, frame=0), cfg, a.updates)
        if table:
            print(f"DepthTemporalFilter CPU per periodic update (30 Hz, 640x480): {ms:.1f} ms "
                  f"(least of 3 runs of {a.updates} updates)")
        res["system_update_ms"] = ms
    figures = {"filter_cpu_ms": res["filter_depth_ms_median"],
               "filter_cpu_max_ms": res["filter_depth_ms_max"]}
    if "system_update_ms" in res:
        figures["system_update_cpu_ms"] = res["system_update_ms"]
    emit_json(a.json, dict(res, figures=figures))


if __name__ == "__main__":
    main()
