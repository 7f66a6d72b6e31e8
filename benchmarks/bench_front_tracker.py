"""Speed benchmark of the front tracker (prints figures; never fails on time).

    python benchmarks/bench_front_tracker.py [--repeats 5] [--json]

Measures (median process CPU time over repeats, single process, one BLAS thread):

- the association of one frame (:func:`mmlearn.models.front_tracking.track_frame`) with
  k rectangles against T tracks of m stored observations each (every rectangle is compared
  with every stored observation in all 8 parameterisations);
- one link-model selection (rigid, prismatic, revolute, gp) of a front track of n
  observations (what the FrontTracker does every ``refit_every`` observations per track);
- a whole FrontTracker run under a Simulator: 3 fronts (drawer, door, wall) over 60 frames.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import json
import time

import numpy as np

from mmlearn.models.front_tracking import (TrackingState, fit_track_model,
                                           simulate_front_rectangles, track_frame,
                                           track_rectangles)


def _cpu(fn, repeats):
    ts = []
    for _ in range(repeats):
        t0 = time.process_time()
        fn()
        ts.append(time.process_time() - t0)
    return float(np.median(ts))


def _state(T, m, rng):
    frames = []
    fronts = []
    for t in range(T):
        X = np.eye(4)
        X[:3, 3] = [1.0 * t, 0.0, 0.0]
        fronts.append(simulate_front_rectangles("rigid", m, rng=rng, X_WO=X))
    for i in range(m):
        frames.append([f[i] for f in fronts])
    return track_rectangles(frames), [f[-1] for f in fronts]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    rng = np.random.default_rng(0)
    out = {"association_ms": [], "fit_ms": [], "simulation": {}}
    for T, m, k in [(3, 50, 3), (10, 50, 10), (10, 500, 10), (50, 100, 20)]:
        st, rects = _state(T, m, rng)
        frame = rects[:k] + simulate_front_rectangles("rigid", max(0, k - T), rng=rng)
        assert isinstance(st, TrackingState)
        ms = 1e3 * _cpu(lambda: track_frame(st, frame, 1e3), args.repeats)
        out["association_ms"].append({"tracks": T, "stored": m, "rectangles": len(frame),
                                      "cpu_ms": ms})
    for kind in ("drawer", "door"):
        for n in (30, 100, 400):
            st = track_rectangles([[r] for r in simulate_front_rectangles(kind, n, rng=rng)])
            P = st.tracks[0].poses
            ms = 1e3 * _cpu(lambda: fit_track_model(P, rng=0), args.repeats)
            out["fit_ms"].append({"kind": kind, "n": n, "cpu_ms": ms})
    # a FrontTracker under a Simulator
    from pydrake.common.value import AbstractValue
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder, LeafSystem

    from mmlearn.systems.front_tracker import FrontTracker, FrontTrackerConfig

    n = 60
    X = np.eye(4)
    X[:3, 3] = [1.0, 0.0, 0.4]
    door = simulate_front_rectangles("door", n, rng=1, X_WO=X)
    drawer = simulate_front_rectangles("drawer", n, rng=2)
    X[:3, 3] = [-0.8, 0.2, 0.0]
    wall = simulate_front_rectangles("rigid", n, rng=3, X_WO=X, width=0.6, height=0.9)
    frames = [[a, b, c] for a, b, c in zip(door, drawer, wall)]

    class Replay(LeafSystem):
        def __init__(self):
            super().__init__()
            self.DeclareAbstractOutputPort("rectangles", lambda: AbstractValue.Make(list()),
                                           self._calc, {self.time_ticket()})

        def _calc(self, context, o):
            k = int(context.get_time() / 0.1 + 1e-9)
            o.set_value(frames[k] if k < n else [])

    b = DiagramBuilder()
    src = b.AddSystem(Replay())
    trk = b.AddSystem(FrontTracker(config=FrontTrackerConfig(period_s=0.1)))
    b.Connect(src.get_output_port(), trk.get_rectangles_input_port())
    diagram = b.Build()
    sim = Simulator(diagram)
    t0, c0 = time.perf_counter(), time.process_time()
    sim.AdvanceTo(0.1 * (n - 0.5))
    wall_s, cpu_s = time.perf_counter() - t0, time.process_time() - c0
    models = trk.get_models_output_port().Eval(trk.GetMyContextFromRoot(sim.get_context()))
    out["simulation"] = {"frames": n, "fronts": 3, "cpu_s": cpu_s, "wall_s": wall_s,
                         "cpu_ms_per_frame": 1e3 * cpu_s / n,
                         "selected": sorted(m.selected for m in models.values())}
    if args.json:
        print(json.dumps(out, indent=1))
        return 0
    print("association of one frame (CPU ms, median of %d)" % args.repeats)
    for r in out["association_ms"]:
        print(f"  {r['tracks']:3d} tracks x {r['stored']:4d} stored obs, {r['rectangles']:3d} "
              f"rectangles: {r['cpu_ms']:8.2f} ms")
    print("link-model selection of one track (CPU ms)")
    for r in out["fit_ms"]:
        print(f"  {r['kind']:7s} n = {r['n']:4d}: {r['cpu_ms']:8.1f} ms")
    s = out["simulation"]
    print(f"FrontTracker under a Simulator: {s['frames']} frames x {s['fronts']} fronts, "
          f"{s['cpu_s']:.2f} s CPU ({s['cpu_ms_per_frame']:.1f} ms per frame, fits included), "
          f"{s['wall_s']:.2f} s wall; selected {s['selected']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
