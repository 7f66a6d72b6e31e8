"""The README's demo as a speed benchmark: ``open_cabinet --object left_door --seed 1`` (the
robot drives to the door, hooks its handle and opens it while learning its model), timed by
its own record: the simulation's CPU seconds (``Simulator.AdvanceTo`` only, not the trial's
build) and its real-time factor on the CPU clock (simulated seconds / CPU seconds). One
whole trial runs untimed first, so loading the compiled kernels and the modules the trial
imports is not counted. Prints figures; never fails on time.

``--baseline-python PY``: the same trials side by side with another checkout's code, run by
that checkout's interpreter (e.g. the ``.venv/bin/python`` of a second checkout of the
revision to compare with): two worker processes, one per interpreter, each warmed up by an
untimed trial, run one timed trial in turn, ``--runs`` each; the table gives both sides and
the ratio of their CPU times per simulated second, run by run (on a shared machine the
ratio of trials run one after the other holds better than either side's figure).

``--plant-only``: what the plant alone costs in the trial: one trial runs with the plant's
command recorded after every simulator step, then the scene alone (the plant, SceneGraph,
the gravity compensation and the command's mapping to the PD targets, no Python system)
is driven through the recorded commands (linear between the steps) and timed, ``--runs``
times; the table gives its CPU seconds and real-time factor beside the trial's, and how far
the replay's final opening is from the trial's (it follows the trial closely, not to the
last bit: the command is recorded at the end of each step).

    python benchmarks/bench_demo.py [--runs N] [--quick] [--max-time S] [--json [FILE]]
    python benchmarks/bench_demo.py --baseline-python OTHER/.venv/bin/python [--runs N]
    python benchmarks/bench_demo.py --plant-only [--runs N]
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys

from _common import add_output_arguments, emit_json

#: a worker: one untimed trial, then one timed trial per line read, its figures as a JSON line
_WORKER = """
import json, sys
from mmlearn.diagrams.articulation.trials import open_mechanism
kind, seed, max_time = sys.argv[1], int(sys.argv[2]), float(sys.argv[3])
open_mechanism(kind=kind, seed=seed, max_time=max_time, show_progress=False)
print("ready", flush=True)
for _ in sys.stdin:
    r = open_mechanism(kind=kind, seed=seed, max_time=max_time, show_progress=False)
    print(json.dumps({"cpu_seconds": r["cpu_seconds"], "sim_seconds": r["sim_seconds"],
                      "success": bool(r["success"])}), flush=True)
"""


class _Worker:
    """A process of ``python`` running :data:`_WORKER` (its own checkout's code)."""

    def __init__(self, python: str, kind: str, seed: int, max_time: float):
        self.python = python
        try:
            # -I: the worker imports its own checkout's package, whatever the directory
            self._p = subprocess.Popen([python, "-I", "-c", _WORKER, kind, str(seed),
                                        str(max_time)],
                                       stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                       text=True)
        except OSError as e:
            raise SystemExit(f"--baseline-python: cannot run {python!r} ({e})") from None
        if self._p.stdout.readline().strip() != "ready":
            self._p.kill()
            raise SystemExit(f"--baseline-python: {python} could not run the demo (see its "
                             f"error above)")

    def run(self) -> dict:
        self._p.stdin.write("run\n")
        self._p.stdin.flush()
        line = self._p.stdout.readline()
        if not line:
            raise SystemExit(f"the worker of {self.python} stopped (see its error above)")
        return json.loads(line)

    def close(self):
        self._p.stdin.close()
        self._p.wait()


def _side_by_side(args) -> None:
    """``--runs`` trials of this checkout and of ``--baseline-python``'s, in turn."""
    ours, theirs = (_Worker(sys.executable, args.object, args.seed, args.max_time),
                    _Worker(args.baseline_python, args.object, args.seed, args.max_time))
    a, b = [], []
    try:
        for i in range(args.runs):
            # alternate which side goes first, so neither always runs after the other
            order = ((ours, a), (theirs, b)) if i % 2 == 0 else ((theirs, b), (ours, a))
            for worker, out in order:
                out.append(worker.run())
    finally:
        ours.close()
        theirs.close()
    per_s = [[r["cpu_seconds"] / r["sim_seconds"] for r in side] for side in (a, b)]
    ratios = [y / x for x, y in zip(*per_s)]
    figures = {"realtime_factor_cpu": 1.0 / statistics.median(per_s[0]),
               "baseline_realtime_factor_cpu": 1.0 / statistics.median(per_s[1]),
               "speedup_vs_baseline": statistics.median(ratios),
               "success": float(all(r["success"] for r in a))}
    if emit_json(args.json, {"object": args.object, "seed": args.seed, "runs": args.runs,
                             "baseline_python": args.baseline_python, "figures": figures,
                             "runs_this": a, "runs_baseline": b}):
        return
    print(f"{args.object} seed {args.seed}, {args.runs} trials each, in turn:")
    for name, side, ps in (("this checkout", a, per_s[0]), ("baseline", b, per_s[1])):
        print(f"  {name:13s}: {side[0]['sim_seconds']:.2f} s simulated; simulation CPU "
              + ", ".join(f"{r['cpu_seconds']:.2f}" for r in side)
              + f" s; real-time factor (CPU) {1.0 / statistics.median(ps):.2f}; opened "
              f"{sum(r['success'] for r in side)}/{len(side)}")
    print(f"  baseline / this checkout, CPU per simulated second, trial by trial: "
          f"median {figures['speedup_vs_baseline']:.3f} (range {min(ratios):.3f}-"
          f"{max(ratios):.3f}); baseline: {args.baseline_python}")


def _plant_only(args) -> None:
    """``--plant-only``: the trial's plant driven by its recorded commands (see the module
    docstring), against the trial itself."""
    import time

    import numpy as np
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder, EventStatus
    from pydrake.systems.primitives import TrajectorySource
    from pydrake.trajectories import PiecewisePolynomial

    from mmlearn.diagrams.articulation.operate import MakeOperateDiagram, OperateConfig
    from mmlearn.diagrams.articulation.trials import open_mechanism
    from mmlearn.diagrams.common.scene import MakeSceneDiagram
    from mmlearn.systems.articulation.epc_controller import DONE

    trials = [open_mechanism(kind=args.object, seed=args.seed, max_time=args.max_time,
                             show_progress=False) for _ in range(args.runs + 1)][1:]
    cfg = OperateConfig(kind=args.object, seed=args.seed)
    op = MakeOperateDiagram(cfg)
    d, sd = op.diagram, op.scene.diagram
    sim = Simulator(d)
    ctx = sim.get_mutable_context()
    op.scene.set_joint_positions(ctx, op.start_command)
    sim.Initialize()
    times, commands = [], []

    def record(root):
        times.append(root.get_time())
        commands.append(sd.GetInputPort("command").Eval(sd.GetMyContextFromRoot(root)).copy())
        return EventStatus.Succeeded()

    sim.set_monitor(record)
    while ctx.get_time() < args.max_time - 1e-9:
        sim.AdvanceTo(min(args.max_time, ctx.get_time() + 0.25))
        if int(d.GetOutputPort("phase").Eval(ctx)[0]) == DONE:
            break
    opening = float(d.GetOutputPort("mechanism_state").Eval(ctx)[0])
    t = np.round(np.array(times), 9)
    keep = np.r_[t[1:] != t[:-1], True]  # the last command of each instant
    commands = PiecewisePolynomial.FirstOrderHold(t[keep], np.array(commands)[keep].T)
    cpu, replayed = [], None
    for _ in range(args.runs):
        scene = MakeSceneDiagram(cfg.scene_config(op.mechanism))
        b = DiagramBuilder()
        s = b.AddSystem(scene.diagram)
        src = b.AddSystem(TrajectorySource(commands))
        b.Connect(src.get_output_port(), s.GetInputPort("command"))
        replay = b.Build()
        rsim = Simulator(replay)
        rctx = rsim.get_mutable_context()
        scene.set_joint_positions(rctx, op.start_command)
        rsim.Initialize()
        c0 = time.process_time()
        rsim.AdvanceTo(float(t[-1]))
        cpu.append(time.process_time() - c0)
        replayed = float(scene.diagram.GetOutputPort("mechanism_state").Eval(
            scene.diagram.GetMyContextFromRoot(rctx))[0])
    sim_s = float(t[-1])
    trial_cpu = statistics.median(r["cpu_seconds"] for r in trials)
    figures = {"plant_only_cpu_s": statistics.median(cpu),
               "plant_only_realtime_factor_cpu": sim_s / statistics.median(cpu),
               "trial_cpu_s": trial_cpu, "realtime_factor_cpu": sim_s / trial_cpu,
               "replay_opening_difference": abs(replayed - opening)}
    if emit_json(args.json, {"object": args.object, "seed": args.seed, "runs": args.runs,
                             "figures": figures}):
        return
    print(f"{args.object} seed {args.seed}, {sim_s:.2f} s simulated, {args.runs} runs each:")
    print(f"  the trial       : simulation CPU "
          + ", ".join(f"{r['cpu_seconds']:.2f}" for r in trials)
          + f" s; real-time factor (CPU) {figures['realtime_factor_cpu']:.2f}")
    print(f"  the plant alone : simulation CPU " + ", ".join(f"{c:.2f}" for c in cpu)
          + f" s; real-time factor (CPU) {figures['plant_only_realtime_factor_cpu']:.2f} "
          f"(final opening {abs(replayed - opening):.1e} from the trial's)")
    print(f"  not the plant   : {trial_cpu - figures['plant_only_cpu_s']:.2f} s of CPU "
          f"(medians), {1 - figures['plant_only_cpu_s'] / trial_cpu:.0%} of the trial's")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--object", default="left_door", help="the mechanism (default left_door)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--runs", type=int, default=3, help="timed trials (default 3)")
    ap.add_argument("--max-time", type=float, default=60.0,
                    help="simulated seconds at most (default 60: the whole demo)")
    ap.add_argument("--baseline-python", default=None, metavar="PYTHON",
                    help="the interpreter of another checkout: its trials side by side "
                         "with this checkout's (--runs each, in turn)")
    ap.add_argument("--plant-only", action="store_true",
                    help="time the scene alone driven by the trial's recorded commands, "
                         "beside the trial (--runs each)")
    add_output_arguments(ap, quick="one timed trial")
    args = ap.parse_args()
    if args.runs < 1:
        ap.error(f"--runs must be >= 1, got {args.runs}")
    if not 0 < args.max_time < float("inf"):
        ap.error(f"--max-time must be a number of seconds > 0, got {args.max_time}")
    if args.plant_only:
        if args.quick or args.baseline_python is not None:
            ap.error("--plant-only runs on its own (not with --quick or --baseline-python)")
        _plant_only(args)
        return
    if args.baseline_python is not None:
        import os
        import shutil

        found = shutil.which(args.baseline_python)
        if found is None or not os.access(found, os.X_OK):
            ap.error(f"--baseline-python: no interpreter at {args.baseline_python!r}")
        if args.quick:
            ap.error("--quick times one trial: a side-by-side run needs --runs")
        _side_by_side(args)
        return
    from mmlearn.diagrams.articulation.trials import open_mechanism

    runs = 1 if args.quick else args.runs
    open_mechanism(kind=args.object, seed=args.seed, max_time=args.max_time,
                   show_progress=False)
    records = [open_mechanism(kind=args.object, seed=args.seed, max_time=args.max_time,
                              show_progress=False) for _ in range(runs)]
    cpu = statistics.median(r["cpu_seconds"] for r in records)
    sim = records[0]["sim_seconds"]
    figures = {"simulation_cpu_s": cpu, "simulated_s": sim,
               "realtime_factor_cpu": sim / cpu if cpu > 0 else None,
               "success": float(all(r["success"] for r in records))}
    if emit_json(args.json, {"object": args.object, "seed": args.seed, "runs": runs,
                             "figures": figures,
                             "cpu_seconds": [r["cpu_seconds"] for r in records]}):
        return
    each = ", ".join(f"{r['cpu_seconds']:.2f}" for r in records)
    print(f"{args.object} seed {args.seed}: {sim:.2f} s simulated; simulation CPU "
          f"{each} s (median {cpu:.2f}); "
          f"real-time factor (CPU) {figures['realtime_factor_cpu']:.2f}; "
          f"opened {sum(r['success'] for r in records)}/{runs}")


if __name__ == "__main__":
    main()
