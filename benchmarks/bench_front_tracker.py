"""Speed benchmark of the front tracker (prints figures; never fails on time).

    python benchmarks/bench_front_tracker.py [--repeats 5] [--quick] [--json [FILE]]
    python benchmarks/bench_front_tracker.py --pipeline door:1.5:1 drawer:1.8:0 ...

Measures (median process CPU time over repeats, single process, one BLAS thread):

- the association of one frame (:func:`mmlearn.models.perception.tracking.track_frame`) with
  k rectangles against T tracks of m stored observations each (every rectangle is compared
  with every stored observation in all 8 parameterisations);
- one link-model selection (rigid, prismatic, revolute, gp) of a front track of n
  observations (what the FrontTracker does every ``refit_every`` observations per track);
- a whole FrontTracker run under a Simulator: 3 fronts (drawer, door, wall) over 60 frames.

``--pipeline FRONT:DISTANCE:SEED ...`` instead runs the kitchen scene end to end
(diagrams/perception/diagram.py: rendered noisy depth -> FrontDetector -> FrontTracker at 5 Hz over
the stepped opening) and prints, per run, the wall time per frame and every track with a
moving model: its selection, axis error against the true joint, radius / travel and the
hinge line's distance.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import time

import numpy as np

from _common import add_output_arguments, emit_json

from mmlearn.models.perception.tracking import (TrackingState, fit_track_model,
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


def pipeline(front: str, distance: float, seed: int) -> dict:
    """One end-to-end run (see the module docstring); returns a JSON-able record."""
    from pydrake.systems.analysis import Simulator

    from mmlearn.diagrams.perception.diagram import (AddFrontDetectorAndTracker, FrontPerceptionConfig,
                                                     MakeFrontPerceptionDiagram)
    from mmlearn.systems import FrontTrackerConfig

    parts = {}

    def add(builder, p):
        _, parts["tracker"] = AddFrontDetectorAndTracker(
            builder, p, seed=seed, tracker_config=FrontTrackerConfig(period_s=0.2))

    cfg = FrontPerceptionConfig(front=front, point_cloud=False)
    cfg.camera.distance = float(distance)
    cfg.noise.seed = int(seed)
    d = MakeFrontPerceptionDiagram(cfg, add_systems=add)
    sim = Simulator(d.diagram)
    t0 = time.perf_counter()
    sim.AdvanceTo(d.duration)
    wall = time.perf_counter() - t0
    trk = parts["tracker"]
    ctx = trk.GetMyContextFromRoot(sim.get_context())
    st = trk.state(ctx)
    models = trk.get_models_output_port().Eval(ctx)
    kin = d.kinematics
    nf = st.tracking.num_frames
    rec = {"front": front, "distance_m": distance, "seed": seed,
           "frames": nf, "ms_per_frame": 1e3 * wall / max(1, nf),
           "tracks": len(st.tracking.tracks), "selected": {}, "moving": []}
    for k, tm in sorted(models.items()):
        rec["selected"][tm.selected] = rec["selected"].get(tm.selected, 0) + 1
        if tm.selected not in ("revolute", "prismatic"):
            continue
        m, t = tm.model, st.tracking.track(k)
        r = {"track": k, "selected": tm.selected, "n": tm.n,
             "size_m": np.round(t.sizes.mean(axis=0), 3).tolist(),
             "axis_error_deg": float(np.degrees(np.arccos(min(1.0, abs(float(
                 np.dot(m.axis, kin.axis_W)))))))}
        if tm.selected == "revolute":
            v = np.asarray(kin.point_W) - np.asarray(m.center)
            r.update(radius_m=float(m.radius), true_radius_m=0.5 * kin.width,
                     hinge_line_m=float(np.linalg.norm(v - np.dot(v, m.axis) * m.axis)))
        else:
            r["travel_m"] = float(m.q_max[0] - m.q_min[0])
        rec["moving"].append(r)
    return rec


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    add_output_arguments(ap, quick="one repeat (a few seconds)")
    ap.add_argument("--pipeline", nargs="+", metavar="FRONT:DISTANCE:SEED", default=None)
    args = ap.parse_args(argv)
    if args.quick:
        args.repeats = 1
    if args.pipeline:
        recs = []
        for spec in args.pipeline:
            front, dist, seed = spec.split(":")
            recs.append(pipeline(front, float(dist), int(seed)))
            r = recs[-1]
            if args.json != "-":
                print(f"{front} at {float(dist):.1f} m, seed {seed}: {r['frames']} frames, "
                      f"{r['ms_per_frame']:.0f} ms per frame (wall, detector + tracker), "
                      f"{r['tracks']} tracks, fitted: {r['selected']}")
                for m in r["moving"]:
                    print("   ", {k: (round(v, 3) if isinstance(v, float) else v)
                                  for k, v in m.items()})
        emit_json(args.json, recs)
        return 0
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

    from mmlearn.systems.perception.front_tracker import FrontTracker, FrontTrackerConfig

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
    out["figures"] = {
        **{f"association_{r['tracks']}x{r['stored']}_cpu_ms": r["cpu_ms"]
           for r in out["association_ms"]},
        **{f"fit_{r['kind']}_n{r['n']}_cpu_ms": r["cpu_ms"] for r in out["fit_ms"]
           if r["n"] == 100},
        "simulation_cpu_ms_per_frame": out["simulation"]["cpu_ms_per_frame"]}
    if emit_json(args.json, out):
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
