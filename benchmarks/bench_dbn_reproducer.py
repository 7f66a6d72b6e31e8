"""Timing of the DbnReproducer (targets: incremental step < 5 ms, learning from 4
demonstrations < 1 s, global reproduction of a 20 s task < 10 s).

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_dbn_reproducer.py [--seed 1] [--repeats 200]
        [--quick] [--json [FILE]]

Prints, for the pick_place task learned from 4 recorded demonstrations:

* the learning time (``learn_task``);
* the wall and the CPU (``time.thread_time``, load-independent) time of one incremental
  reproduction step inside the system (the discrete update:
  kinematics from a scratch plant context, the held-object bookkeeping, one or two
  ``constraint_step`` calls), over ``--repeats`` updates at the slices of the task;
* the time of the global plan (``plan_global``) of the u_obstacle reach, and of a
  pick_place task (about 10 s long) planned globally.
"""

import argparse
import time

import numpy as np

from _common import add_output_arguments, emit_json

def _update_times(im, ctx, repeats):
    """Wall time of the reproducer's discrete update at successive states."""
    from pydrake.systems.analysis import Simulator

    rep = im.reproducer
    sim = Simulator(im.diagram, ctx)
    sim.AdvanceTo(0.5)  # objects seen, first steps taken
    rc = rep.GetMyContextFromRoot(ctx)
    state = rc.get_discrete_state().Clone()
    out, cpu = [], []
    t = 0.5
    for _ in range(repeats):
        c0 = time.thread_time()
        t0 = time.perf_counter()
        rep._update(rc, state)  # the periodic event's callback
        out.append(time.perf_counter() - t0)
        cpu.append(time.thread_time() - c0)
        t += rep.period
        sim.AdvanceTo(t)
        if rep.get_status_output_port().Eval(rc)[5] > 0:
            break
    return np.array(out), np.array(cpu)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--repeats", type=int, default=200)
    add_output_arguments(ap, quick="2 demonstrations, 20 steps, the u_obstacle plan only "
                                   "(a few seconds)")
    args = ap.parse_args(argv)
    n_demos = 2 if args.quick else 4
    if args.quick:
        args.repeats = 20
    table = args.json != "-"
    res = {}

    from mmlearn.diagrams.imitation.trials import record_demos
    from mmlearn.diagrams.imitation.diagram import ImitationConfig, MakeImitationDiagram, \
        object_positions
    from mmlearn.models.imitation.dbn import learn_task
    from mmlearn.models.imitation.global_plan import plan_global
    from mmlearn.systems.imitation.dbn_reproducer import DbnReproducerConfig

    demos = record_demos("pick_place", n_demos, seed=args.seed)
    ts = []
    for _ in range(1 if args.quick else 5):
        t0 = time.perf_counter()
        model = learn_task(demos, use_joints=False)
        ts.append(time.perf_counter() - t0)
    res["learn"] = dict(demos=n_demos, slices=model.S, median_ms=1e3 * np.median(ts),
                        max_ms=1e3 * np.max(ts))
    if table:
        print(f"learn_task, {n_demos} pick_place demonstrations ({model.S} slices): "
              f"median {1e3 * np.median(ts):.1f} ms, max {1e3 * np.max(ts):.1f} ms")

    im = MakeImitationDiagram(ImitationConfig(task="pick_place", seed=args.seed), model=model)
    ctx = im.diagram.CreateDefaultContext()
    im.set_start(ctx)
    dt, cpu = _update_times(im, ctx, args.repeats)
    for label, x in (("wall", dt), ("CPU", cpu)):
        res[f"step_{label.lower()}"] = dict(steps=x.size, median_ms=1e3 * np.median(x),
                                            p95_ms=1e3 * np.percentile(x, 95),
                                            max_ms=1e3 * np.max(x))
        if not table:
            continue
        print(f"incremental step (DbnReproducer update), pick_place, {x.size} steps, {label} time: "
              f"median {1e3 * np.median(x):.2f} ms, p95 {1e3 * np.percentile(x, 95):.2f} ms, "
              f"max {1e3 * np.max(x):.2f} ms")

    for task in ("u_obstacle",) if args.quick else ("u_obstacle", "pick_place"):
        d = record_demos(task, n_demos, seed=args.seed)
        m = learn_task(d, use_joints=False)
        im = MakeImitationDiagram(ImitationConfig(
            task=task, seed=args.seed, reproducer=DbnReproducerConfig(mode="global")), model=m)
        ctx = im.diagram.CreateDefaultContext()
        objs = object_positions(im.plant, ctx, im.scene.bodies)
        rep = im.reproducer
        tracked = np.array([np.r_[objs[n], 1.0] for n in rep._tracked])
        kin = rep.kinematics()
        t0 = time.perf_counter()
        plan = plan_global(m, q0=im.start_command[:6],
                           objects={o: objs[o] for o in m.objects}, fk=kin.hand,
                           jacobian=kin.jacobian, body_points=kin.body_points,
                           obstacles=rep._obstacle_boxes(tracked), use_joints=False,
                           q_lower=rep._lo, q_upper=rep._hi, carry_radius=0.1,
                           clearance=rep._cfg.plan_clearance, seed=0)
        el = time.perf_counter() - t0
        res[f"plan_{task}"] = dict(task_s=float(m.t[-1]), slices=m.S, wall_s=el)
        if table:
            print(f"global plan, {task} ({m.t[-1]:.1f} s task, {m.S} slices, plan "
                  f"{plan.shape}): {el:.2f} s")
    res["figures"] = {"learn_ms": res["learn"]["median_ms"],
                      "step_cpu_ms": res["step_cpu"]["median_ms"],
                      "step_cpu_p95_ms": res["step_cpu"]["p95_ms"],
                      "plan_u_obstacle_wall_s": res["plan_u_obstacle"]["wall_s"]}
    emit_json(args.json, res)


if __name__ == "__main__":
    main()
