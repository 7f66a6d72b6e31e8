"""Fig. 7.5 vs 7.6: the impact force of the pure force controller against the switching
velocity-force controller of Eq. 7.8, grasping a rigid (wooden) block and a soft (rubber)
one. Prints the peak and final contact force per finger (from the plant's hydroelastic
contact results at 1 kHz); ``--plot FILE`` draws the force profiles.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_grasp_controller.py [--f-target 10] [--plot F]
        [--json [FILE]]
"""

import argparse

from _common import add_output_arguments, emit_json
from mmlearn.diagrams.tactile.grasp import TactileGraspConfig, simulate_contact_force
from mmlearn.sdf.tactile import block_sdf


def trace(cfg, sdf, t_end):
    t, F, _, _ = simulate_contact_force(cfg, object_sdf=sdf, t_end=t_end)
    return t, F


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--f-target", type=float, default=10.0)
    ap.add_argument("--plot", default=None)
    add_output_arguments(ap)
    a = ap.parse_args()
    say = print if a.json != "-" else (lambda *args, **kw: None)  # JSON instead of a table
    rows = []
    objects = {"wooden block": block_sdf((0.07, 0.1, 0.12)),
               "rubber block": block_sdf((0.07, 0.1, 0.12), modulus=2e5)}
    curves = {}
    for oname, sdf in objects.items():
        for mode in ("force", "switching"):
            cfg = TactileGraspConfig(f_target=a.f_target, mode=mode, hold_time=5.0)
            t, F = trace(cfg, sdf, 1.6)
            curves[(oname, mode)] = (t, F)
            rows.append(dict(object=oname, controller=mode, peak_n=float(F.max()),
                             final_n=float(F[-1])))
            say(f"{oname:13s} {mode:9s}: peak {F.max():6.2f} N "
                  f"({100 * (F.max() / a.f_target - 1):+5.1f} % of f_target), "
                  f"final {F[-1]:6.2f} N")
    emit_json(a.json, dict(f_target_n=a.f_target, rows=rows))
    if a.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, axes = plt.subplots(1, 2, figsize=(11, 4), sharey=True)
        for ax, mode in zip(axes, ("force", "switching")):
            for oname in objects:
                t, F = curves[(oname, mode)]
                ax.plot(t, F, label=oname)
            ax.axhline(a.f_target, color="k", ls=":", lw=0.8)
            ax.set_title(f"{mode} controller")
            ax.set_xlabel("time [s]")
        axes[0].set_ylabel("contact force per finger [N]")
        axes[0].legend()
        fig.tight_layout()
        fig.savefig(a.plot, dpi=100)
        print(f"plot written to {a.plot}")


if __name__ == "__main__":
    main()
