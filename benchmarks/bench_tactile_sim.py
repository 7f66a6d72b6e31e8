"""Speed of the simulated tactile sensing (thesis ch. 6-7; targets: a taxel frame
< 3 ms, one grasp simulated faster than real time).

Prints, for a steady grasp of a flat block (ch. 6 pad, 14 x 6) and of a container (PR2 pad,
5 x 3): the time of one taxel frame (contact surfaces -> cell pressures -> readings) and the
number of contact faces; then the wall time of whole grasps (switching controller) against
their simulated time.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_tactile_sim.py [--grasps N] [--quick] [--json [FILE]]
"""

import argparse
import os
import time

import numpy as np

from pydrake.systems.analysis import Simulator

from _common import add_output_arguments, emit_json

from mmlearn.diagrams.tactile.grasp import (MakeTactileGraspDiagram, TactileGraspConfig,
                                            simulate_grasp)
from mmlearn.models.tactile.containers import sample_container, states_of
from mmlearn.sdf.tactile import block_sdf


def frame_time(cfg, **kw):
    d, parts = MakeTactileGraspDiagram(cfg, **kw)
    sim = Simulator(d)
    sim.Initialize()
    sim.AdvanceTo(1.5)
    s = parts["sensor"]
    ctx = s.GetMyContextFromRoot(sim.get_context())
    plant = parts["plant"]
    cr = plant.get_contact_results_output_port().Eval(plant.GetMyContextFromRoot(sim.get_context()))
    faces = [cr.hydroelastic_contact_info(i).contact_surface().num_faces()
             for i in range(cr.num_hydroelastic_contacts())]
    reps = 200
    s.cell_pressures(ctx)
    t0, c0 = time.perf_counter(), time.process_time()
    for _ in range(reps):
        s.cell_pressures(ctx)
    wall = (time.perf_counter() - t0) / reps * 1e3
    return wall, (time.process_time() - c0) / reps * 1e3, faces


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grasps", type=int, default=4)
    add_output_arguments(ap, quick="one grasp (a few seconds)")
    a = ap.parse_args()
    if a.quick:
        a.grasps = 1
    res = {"load_average": os.getloadavg()[0], "grasps": []}
    say = print if a.json != "-" else (lambda *args, **kw: None)  # JSON instead of a table
    say(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    ms, cpu, faces = frame_time(TactileGraspConfig(pad="ch6", f_target=30.0, hold_time=5.0,
                                                   grasp_height=0.06),
                                object_sdf=block_sdf((0.07, 0.1, 0.12)))
    res["frame_block"] = dict(wall_ms=ms, cpu_ms=cpu, faces=faces)
    say(f"taxel frame, flat block on 14x6 pads: {ms:.2f} ms wall, {cpu:.2f} ms CPU "
          f"(contact faces {faces})")
    inst = sample_container("odwalla", "full_closed", np.random.default_rng(0))
    ms, cpu, faces = frame_time(TactileGraspConfig(pad="pr2", f_target=20.0, hold_time=5.0),
                                container=inst)
    res["frame_container"] = dict(wall_ms=ms, cpu_ms=cpu, faces=faces)
    say(f"taxel frame, odwalla on 5x3 pads:     {ms:.2f} ms wall, {cpu:.2f} ms CPU "
          f"(contact faces {faces})")
    rng = np.random.default_rng(1)
    cfg = TactileGraspConfig(f_target=20.0)
    for k in range(a.grasps):
        st = states_of("odwalla")[k % 4]
        inst = sample_container("odwalla", st, rng)
        t0 = time.perf_counter()
        g = simulate_grasp(cfg, container=inst)
        w = time.perf_counter() - t0
        res["grasps"].append(dict(state=st, sim_s=cfg.duration, wall_s=w,
                                  f_max_n=float(g.f.max())))
        say(f"grasp odwalla/{st:13s}: simulated {cfg.duration:.2f} s in {w:.2f} s wall "
              f"(real-time factor {cfg.duration / w:.2f}), f_max {g.f.max():.1f} N")
    res["figures"] = {"frame_block_cpu_ms": res["frame_block"]["cpu_ms"],
                      "frame_container_cpu_ms": res["frame_container"]["cpu_ms"],
                      "grasp_realtime_factor_wall": sum(g["sim_s"] for g in res["grasps"])
                      / sum(g["wall_s"] for g in res["grasps"])}
    emit_json(a.json, res)


if __name__ == "__main__":
    main()
