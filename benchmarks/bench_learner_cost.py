"""What the SchemaLearner costs inside the Drake simulation of
``python -m mmlearn.apps.learn_body_schema``.

Times, in CPU seconds of this single-threaded process (load-independent on the shared
machine; wall seconds are printed too): all ``Simulator.AdvanceTo`` calls, the learner's
update events, the structure re-searches inside them (the learning itself) and Drake's
copies of the learner's state. Prints figures; never fails on time.

    python benchmarks/bench_learner_cost.py --arm 7dof [--quick] [--json [FILE]]
"""

from __future__ import annotations

import argparse
import copy
import time

import pydrake.systems.analysis as analysis

from _common import add_output_arguments, emit_json

from mmlearn.diagrams.body_schema.trials import LearnBodySchemaConfig, learn_body_schema
from mmlearn.models.body_schema import schema as body_schema_module
from mmlearn.systems.body_schema import learner as sl

cpu = time.process_time
T = dict(advance=0.0, advance_cpu=0.0, update_cpu=0.0, relearn_cpu=0.0, copy_cpu=0.0,
         copies=0)


def _timed(fn, key):
    def wrapper(*args, **kwargs):
        c0 = cpu()
        try:
            return fn(*args, **kwargs)
        finally:
            T[key] += cpu() - c0
    return wrapper


def _instrument():
    state_cls = sl.SchemaLearnerState
    own = state_cls.__dict__.get("__deepcopy__")

    def deepcopy(self, memo):
        c0 = cpu()
        if own is not None:
            new = own(self, memo)
        else:
            new = state_cls.__new__(state_cls)
            new.__dict__.update(copy.deepcopy(self.__dict__, memo))
        T["copy_cpu"] += cpu() - c0
        T["copies"] += 1
        return new

    state_cls.__deepcopy__ = deepcopy
    sl.SchemaLearner._update = _timed(sl.SchemaLearner._update, "update_cpu")
    body_schema_module.BodySchema.relearn = _timed(body_schema_module.BodySchema.relearn,
                                                   "relearn_cpu")

    class Simulator(analysis.Simulator):
        def AdvanceTo(self, t):
            t0, c0 = time.perf_counter(), cpu()
            try:
                return super().AdvanceTo(t)
            finally:
                T["advance"] += time.perf_counter() - t0
                T["advance_cpu"] += cpu() - c0

    analysis.Simulator = Simulator


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--arm", default="7dof", choices=["2dof", "4dof", "7dof"])
    ap.add_argument("--samples", type=int, default=50)
    add_output_arguments(ap, quick="the 2-DOF arm, 5 samples (a few seconds)")
    args = ap.parse_args()
    if args.quick:
        args.arm, args.samples = "2dof", 5
    _instrument()
    r = learn_body_schema(config=LearnBodySchemaConfig(arm=args.arm, samples=args.samples),
                          show_progress=False)
    sim = r["sim_seconds"]
    learner = T["update_cpu"] + T["copy_cpu"]
    res = dict(
        arm=args.arm, samples=r["samples"], sim_seconds=sim,
        realtime_factor_wall=round(sim / T["advance"], 2),
        realtime_factor_cpu=round(sim / T["advance_cpu"], 2),
        simulation_cpu_s=round(T["advance_cpu"], 3),
        learner_updates_cpu_s=round(T["update_cpu"], 3),
        structure_researches_cpu_s=round(T["relearn_cpu"], 3),
        state_copies_cpu_s=round(T["copy_cpu"], 3), state_copies=T["copies"],
        learner_share=round(learner / T["advance_cpu"], 3),
        learner_share_without_researches=round(
            (learner - T["relearn_cpu"]) / T["advance_cpu"], 3),
        structure_correct=r["structure_correct"], pred_error_m=r["pred_error_m"])
    res["figures"] = {k: res[k] for k in ("realtime_factor_cpu", "simulation_cpu_s",
                                          "learner_updates_cpu_s", "learner_share")}
    if emit_json(args.json, res):
        return
    for k, v in res.items():
        if k != "figures":
            print(f"{k:34s} {v}")


if __name__ == "__main__":
    main()
