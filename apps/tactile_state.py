"""Object and internal-state recognition from grasp dynamics (thesis Sec. 7.1-7.2) on real data.

Usage::

    python -m mmlearn.apps.tactile_state --train DIR [--test DIR] [--classifier tree|forest|boost]
        [--include-full-coke] [--folds 10] [--steady-average] [--plot FILE] --seed S [--json]

``DIR`` holds iCub grasp dataset files ``<label>_<trial>.txt`` (format: README.txt of the data
set; reader: :mod:`mmlearn.models.tactile.icub_grasp`). Each grasp gives the six features of Table 7.1
(:mod:`mmlearn.models.tactile.state`): finger closure at first two-finger contact, at rest,
summed taxel pressure at rest, the time between them and the two average rates. A classifier
(``forest`` by default, see below) is trained on ``--train`` and scored on ``--test``; without
``--test``, stratified ``--folds``-fold cross-validation on ``--train``. ``full_coke`` is left
out unless ``--include-full-coke`` (the data set's author marks it unreliable).

Classifier choice: the thesis used a C4.5 decision tree (``--classifier tree``: scikit-learn's
entropy-criterion CART). On the shared iCub trials (10 classes x 10 trials) 10-fold CV gave
0.86-0.90 for the tree and 0.95-0.97 for a random forest of 300 such trees over seeds 0-4
(benchmarks/bench_tactile_state.py prints these figures): the six features are noisy single
readings and averaging many trees cancels much of that noise, so the forest is the default.
Gradient boosting (``--classifier boost``) is offered as a third. The run also reports the
other classifiers' rates (``compare``).

``--json`` prints one object (real-data mode)::

    {"mode": "real", "classifier", "evaluation": "test" | "<k>-fold CV", "rate",
     "per_class": {label: rate}, "labels", "confusion" (rows true, columns predicted),
     "n_train", "n_test", "compare": {classifier: rate}, "no_contact": {label: count},
     "features": [...], "settings": {...}}

**Simulation mode** (``--f-target N`` without ``--train``)::

    python -m mmlearn.apps.tactile_state --f-target 20 [--trials 16] [--f-sweep]
        [--sweep-trials 24] [--classifier tree|forest|boost] [--wall-model pressure|linear]
        [--grasp-variation wall|shell|none]
        [--results FILE] [--jobs J] [--executor local|ray] [--report-only FILE]
        [--plot FILE] [--meshcat] [--html-out FILE] --seed S [--json]

The Drake gripper (:mod:`mmlearn.diagrams.tactile.grasp`: PR2-like fingertip pads, the
switching controller of Eq. 7.8 probing with ``f_target`` N per finger) squeezes random
instances of the four container classes of Sec. 7.1.3 in each of their internal states
(:mod:`mmlearn.models.tactile.containers`; cans have no ``empty_closed``), ``--trials`` grasps per
(class, state). ``--wall-model``: the walls' squeeze-volume model (``pressure``, default: the
content's pressure grows with the squeeze) or constant linearised springs (``linear``, the
ablation of the pressure model).
``--grasp-variation``: ``wall`` (default) gives every grasp its own draw of the container's
wall response around the instance's (the grasp-to-grasp spread of the squeeze of the same
container measured on the real iCub grasps, :func:`mmlearn.models.tactile.containers.vary_grasp`);
``shell`` varies the shell stiffness alone; ``none`` meets every instance as drawn (the
ablation of the variation). The features come only from the simulated finger encoders and
taxel pads.
Reports (10-fold CV, ``--classifier``; the other classifiers in ``compare``):
``container_rate`` (class from all grasps), ``state_rate_by_container`` {class: rate of the
state given the class}, ``combined_rate`` (all class x state labels) and
``combined_rate_without_water`` (the thesis' 11-label experiment). ``--f-sweep`` adds Table
7.2: the state rate of the Odwalla bottle at 17 / 20 / 23 N (``--sweep-trials`` grasps per
state). Grasps run through the sweep runner (:mod:`mmlearn.apps.common.sweep`, the shared
front-end of :mod:`mmlearn.apps.common.experiment`): ``--results`` keeps them in a JSON Lines
file so a rerun resumes (without it they go to a temporary file), and ``--report-only FILE``
recomputes the report from such a file without simulating.
``--plot FILE`` draws the grasp profiles p / v / f of one grasp per state of the first
container class (Fig. 7.3), the force on a rigid block with the switching controller and
with pure force control (Fig. 7.5 vs 7.6) and the two taxel images of one more grasp at its
peak force; ``--meshcat`` shows that grasp live (scene and taxel pads coloured by pressure,
:class:`~mmlearn.systems.tactile.taxel_visualizer.TaxelPadVisualizer`) and ``--html-out FILE``
writes its recording as standalone HTML. The JSON then has ``demo_grasp``.

Exit status: 0 success, 2 bad input (unreadable or malformed files name the file and line,
unknown labels, missing folders, test classes absent from training).
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mmlearn.apps.common import experiment
from mmlearn.apps.common.cli import (UsageError, check_out_file, finish_viewing, json_clean,
                                     make_meshcat, name_list, pos_float, pos_int, save_figure,
                                     save_html)
from mmlearn.apps.common.experiment import Experiment
from mmlearn.apps.common.sweep import TrialSpec
from mmlearn.models.tactile.icub_grasp import CONTACT_LEVEL, REST_VELOCITY, load_icub_dir
from mmlearn.models.tactile.evaluation import (SIM_CONTACT_FORCE, SIM_REST_VELOCITY,
                                               container_grasp_features, cv_with_compare,
                                               icub_state_report, state_recognition_report)
from mmlearn.models.tactile.state import CLASSIFIERS, FEATURE_NAMES, extract_grasp_features
from mmlearn.diagrams.tactile.trials import (SWEEP_FORCES, container_grasp_plan,
                                             container_grasp_trial,
                                             odwalla_sweep_plan)

__all__ = ["run", "run_simulation", "simulation_specs", "simulation_report",
           "real_data_report", "main", "TactileStateConfig"]

#: the container classes of the simulation mode (Sec. 7.1.3)
CONTAINERS = ("odwalla", "naked", "can", "water")


@dataclass
class TactileStateConfig:
    """Settings of one run (real-data mode).

    Attributes:
        train: folder of iCub grasp files to train on.
        test: folder of files to score; None: ``folds``-fold cross-validation on ``train``.
        classifier: "forest", "tree" or "boost".
        include_full_coke: keep the full_coke trials.
        folds: cross-validation folds.
        seed: random seed (fold assignment, forest).
        contact_level: contact threshold F on a finger's highest taxel pressure, counts.
        rest_velocity: rest threshold V on the closure rate, rad per slice.
        steady_average: steady-phase means instead of single samples for p/f_steady.
        plot: image file for the confusion matrix and profiles (real data) or the grasp
            profiles, impact and tactile images (simulation), or None.
        f_target: simulation mode (with ``train`` empty): probing force per finger, N.
        trials: simulation: grasps per (container, state).
        f_sweep: simulation: add the Odwalla f_target sweep 17 / 20 / 23 N (Table 7.2).
        sweep_trials: simulation: grasps per Odwalla state and force in the sweep.
        results: simulation: JSON Lines file of the grasps (None: temporary).
        jobs: simulation: parallel grasps (None: all cores).
        executor, ray_address: simulation: the sweep runner's executor ("local" or "ray").
        progress: simulation: show a progress bar.
        containers: simulation: container classes to grasp (default: all four).
        wall_model: simulation: the containers' wall model, "pressure" (the squeeze-volume
            model, default) or "linear" (the linearised constant stiffness;
            :class:`~mmlearn.diagrams.tactile.grasp.TactileGraspConfig`).
        grasp_variation: simulation: "wall" (default): every grasp meets its container with
            its own draw of the wall's static response (the grasp-to-grasp spread of the
            squeeze measured on the iCub grasps, :func:`mmlearn.models.tactile.containers.vary_grasp`);
            "shell": of the shell stiffness alone; "none": every grasp meets the instance as
            drawn.
    """

    train: str = ""
    test: str | None = None
    classifier: str = "forest"
    include_full_coke: bool = False
    folds: int = 10
    seed: int = 0
    contact_level: float = CONTACT_LEVEL
    rest_velocity: float = REST_VELOCITY
    steady_average: bool = False
    plot: str | None = None
    f_target: float | None = None
    trials: int = 16
    f_sweep: bool = False
    sweep_trials: int = 24
    results: str | None = None
    jobs: int | None = None
    executor: str = "local"
    ray_address: str | None = None
    progress: bool = False
    containers: tuple = CONTAINERS
    wall_model: str = "pressure"
    grasp_variation: str = "wall"


def _specs(plan) -> list:
    return [TrialSpec(**d) for d in plan]


def _simulation(c: TactileStateConfig) -> bool:
    return not c.train and c.f_target is not None


def _check_simulation(c: TactileStateConfig) -> None:
    from mmlearn.models.tactile.containers import CONTAINER_CLASSES, GRASP_VARIATIONS

    if not (c.f_target is not None and np.isfinite(c.f_target) and c.f_target > 0):
        raise ValueError(f"f_target: expected a force > 0 N, got {c.f_target!r}")
    if c.trials < 2:
        raise ValueError(f"trials: expected at least 2 grasps per container and state, got {c.trials}")
    if c.classifier not in CLASSIFIERS:
        raise ValueError(f"classifier: unknown {c.classifier!r}; choose from {', '.join(CLASSIFIERS)}")
    if not c.containers:
        raise ValueError("containers: empty; choose from " + ", ".join(CONTAINER_CLASSES))
    if c.wall_model not in ("pressure", "linear"):
        raise ValueError(f"wall_model: expected 'pressure' or 'linear', got {c.wall_model!r}")
    if c.grasp_variation not in GRASP_VARIATIONS:
        raise ValueError(f"grasp_variation: expected one of {', '.join(GRASP_VARIATIONS)}, "
                         f"got {c.grasp_variation!r}")
    if c.f_sweep and c.sweep_trials < 2:
        raise ValueError(f"sweep_trials: expected at least 2, got {c.sweep_trials}")


def _grasps(c: TactileStateConfig):
    """The grasp specs: those of the main experiment and, with ``f_sweep``, those of the
    Odwalla sweep by force."""
    wm, gv = c.wall_model, c.grasp_variation
    grasps = _specs(container_grasp_plan(list(c.containers), c.f_target, c.trials, c.seed, wm,
                                         gv))
    sweep = {f: _specs(odwalla_sweep_plan(f, c.sweep_trials, c.seed, wm, gv))
             for f in SWEEP_FORCES} if c.f_sweep else {}
    return grasps, sweep


def simulation_specs(config: TactileStateConfig) -> list:
    """The grasps of the simulation mode (checks the settings: ``ValueError``)."""
    _check_simulation(config)
    grasps, sweep = _grasps(config)
    have = {s.key for s in grasps}
    for s in (s for ss in sweep.values() for s in ss):
        if s.key not in have:
            grasps.append(s)
            have.add(s.key)
    return grasps


def simulation_report(lines: list[dict], config: TactileStateConfig):
    """The simulation mode's result (see the module docstring) from results-file lines, and
    the records of the main experiment's grasps."""
    c = config
    grasps, sweep = _grasps(c)
    by_key = {ln["key"]: ln for ln in lines}
    keys = {s.key for s in grasps} | {s.key for ss in sweep.values() for s in ss}
    failed = [ln for ln in lines if ln.get("error") and ln["key"] in keys]

    def records(spec_list):
        return [by_key[s.key]["record"] for s in spec_list
                if s.key in by_key and by_key[s.key].get("record")]

    recs = records(grasps)
    if not recs:
        raise ValueError("no grasp finished")
    X, yc, ys, feats = container_grasp_features(recs, steady_average=c.steady_average)
    out = {"mode": "simulation", "classifier": c.classifier, "f_target": float(c.f_target),
           "features": list(FEATURE_NAMES), "n_grasps": len(recs),
           "failed_grasps": len(grasps) - len(recs),
           "errors": sorted({(ln.get("error") or "")[:200] for ln in failed}),
           "no_contact": int(sum(not f.contact for f in feats)),
           "not_steady": int(sum(not f.steady for f in feats))}
    out.update(state_recognition_report(X, yc, ys, classifier=c.classifier, folds=c.folds,
                                        seed=c.seed))
    if c.f_sweep:
        out["f_sweep_odwalla"] = {f"{f:g}": _sweep_rates(records(ss), c)
                                  for f, ss in sweep.items()}
    out["settings"] = {"trials": c.trials, "folds": c.folds, "seed": c.seed,
                       "contact_force_N": SIM_CONTACT_FORCE,
                       "rest_velocity_m_per_s": SIM_REST_VELOCITY,
                       "steady_average": c.steady_average, "wall_model": c.wall_model,
                       "grasp_variation": c.grasp_variation,
                       "sweep_trials": c.sweep_trials if c.f_sweep else None}
    return out, recs


def _sweep_rates(recs, c: TactileStateConfig) -> dict:
    """The Odwalla state rate at one force of the sweep (Table 7.2)."""
    X, _, ys, _ = container_grasp_features(recs, steady_average=c.steady_average)
    r, cm, _ = cv_with_compare(X, ys, classifier=c.classifier, folds=c.folds, seed=c.seed)
    return {"rate": r.rate, "compare": cm, "n": len(recs),
            "failed": c.sweep_trials * 4 - len(recs), "labels": r.labels,
            "confusion": r.confusion.astype(int).tolist()}


def _demo(c: TactileStateConfig, recs, meshcat) -> dict:
    """The demo grasp (shown in ``meshcat``) and, with ``plot``, the figure of the grasps."""
    demo = demo_grasps(c, meshcat=meshcat, impact=bool(c.plot))
    out = {"container": demo["grasp"].container, "state": demo["grasp"].state,
           "f_max_N": float(demo["grasp"].f.max())}
    if demo["impact"]:
        out["impact_peak_N"] = {m: float(tr["f"].max()) for m, tr in demo["impact"].items()}
    if c.plot:
        plot_simulation(recs, demo, c.plot, containers=list(c.containers),
                        title=f"simulation, f_target {c.f_target:g} N, seed {c.seed}")
    return out


def run_simulation(config: TactileStateConfig, *, meshcat=None) -> dict:
    """Simulation mode (see the module docstring for the result): the grasps through the
    sweep runner (``config.results``, ``jobs``, ``executor``, ``ray_address``). With
    ``meshcat`` (or ``config.plot``) one more grasp is simulated and shown:
    :func:`demo_grasps`."""
    c = config
    app = TactileState()
    app.meshcat = meshcat
    args = argparse.Namespace(config=c, report_only=None, meshcat=False, html_out=None)
    return experiment.run_experiment(app, args, results=c.results, executor=c.executor,
                                     jobs=c.jobs, ray_address=c.ray_address)


#: the probing force per finger of the rigid-block impact grasps of the plot (Fig. 7.5 vs
#: 7.6), N, whatever the containers' ``f_target``: the impact peaks stay comparable
IMPACT_F_TARGET = 10.0


def demo_grasps(config: TactileStateConfig, *, meshcat=None, impact: bool = True) -> dict:
    """The grasps the viewer and the plot show: one grasp of the first container class in
    its first state (a random instance from ``config.seed``; shown and recorded in
    ``meshcat`` if given, taxel pads coloured by pressure) and, with ``impact``, a rigid
    block grasped with the switching controller and with pure force control (Fig. 7.5 vs
    7.6, 10 N; the contact force every 2 ms, :func:`contact_force_trace`). Returns
    {"grasp": TactileGrasp, "impact": {mode: {"t", "f", "f_target"}}, "f_target": the
    containers' probing force}."""
    from mmlearn.diagrams.tactile.grasp import TactileGraspConfig, simulate_grasp
    from mmlearn.models.tactile.containers import sample_container, states_of
    from mmlearn.sdf.tactile import block_sdf

    c = config
    name = c.containers[0]
    state = states_of(name)[0]
    rng = np.random.default_rng([int(c.seed), 4242])
    inst = sample_container(name, state, rng)
    cfg = TactileGraspConfig(pad="pr2", f_target=float(c.f_target), seed=int(c.seed),
                             wall_model=c.wall_model)
    out = {"grasp": simulate_grasp(cfg, container=inst, meshcat=meshcat), "impact": {},
           "f_target": float(c.f_target)}
    if impact:
        block = block_sdf((0.07, 0.1, 0.12))
        for mode in ("switching", "force"):
            cfg = TactileGraspConfig(pad="pr2", f_target=IMPACT_F_TARGET, mode=mode,
                                     hold_time=1.0, duration=2.5, seed=int(c.seed))
            out["impact"][mode] = contact_force_trace(cfg, object_sdf=block)
    return out


def contact_force_trace(cfg, *, object_sdf: str, dt: float = 0.002) -> dict:
    """The normal contact force per finger (N) of one grasp every ``dt`` s, read from the
    plant's hydroelastic contact results (the impact lasts a few ms: the 25 Hz pad force
    would miss it). Returns {"t": (T,) s, "f": (T,) N}."""
    from mmlearn.diagrams.tactile.grasp import simulate_contact_force

    ts, f, _, _ = simulate_contact_force(cfg, object_sdf=object_sdf, dt=dt)
    return {"t": ts, "f": f, "f_target": float(cfg.f_target)}


def plot_simulation(records, demo, path, *, containers, title: str = "") -> None:
    """Grasp profiles and tactile images of the simulation mode, one figure:
    top, the finger distance p(t), its rate v(t) and the summed force f(t) of the first
    grasp of every state of the first container class (Fig. 7.3); bottom, f(t) of the rigid
    block under the switching controller and under pure force control (Fig. 7.5 vs 7.6) and
    the two taxel images of the demo grasp at its peak force."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from mmlearn.models.tactile.evaluation import grasp_from_record

    fig, ax = plt.subplots(2, 3, figsize=(16, 8.5))
    name = containers[0]
    seen = {}
    for r in records:
        if r["container"] == name:
            seen.setdefault(r["state"], r)
    cmap = plt.get_cmap("tab10")
    for k, (state, r) in enumerate(sorted(seen.items())):
        g = grasp_from_record(r)
        col = cmap(k % 10)
        ax[0, 0].plot(g.t, g.p * 1e3, color=col, label=state)
        ax[0, 1].plot(g.t, g.v * 1e3, color=col, label=state)
        ax[0, 2].plot(g.t, g.f, color=col, label=state)
    for a, lab in zip(ax[0], ("finger distance p(t) [mm]", "finger velocity v(t) [mm/s]",
                              "summed pad force f(t) [N]")):
        a.set_xlabel("time [s]")
        a.set_ylabel(lab)
        a.set_title(f"{name}: first grasp per state (Fig. 7.3)", fontsize=9)
    ax[0, 2].legend(fontsize=8)
    styles = {"switching": ("tab:blue", "switching controller, Eq. 7.8 (Fig. 7.6)"),
              "force": ("tab:red", "pure force control (Fig. 7.5)")}
    for mode, tr in demo.get("impact", {}).items():
        colr, lab = styles.get(mode, ("k", mode))
        ax[1, 0].plot(tr["t"], tr["f"], color=colr, lw=1.0,
                      label=f"{lab}, peak {tr['f'].max():.1f} N")
    if demo.get("impact"):
        block_f = next(iter(demo["impact"].values())).get("f_target", IMPACT_F_TARGET)
        others = ("" if demo.get("f_target") is None
                  else f"; the containers above: {demo['f_target']:g} N")
        ax[1, 0].axhline(block_f, color="k", ls="--", lw=0.8,
                         label=f"block's target force {block_f:g} N per finger{others}")
    ax[1, 0].set_xlabel("time [s]")
    ax[1, 0].set_ylabel("contact force per finger [N] (plant, every 2 ms)")
    ax[1, 0].set_title("rigid block: impact without / with the switching controller",
                       fontsize=9)
    ax[1, 0].legend(fontsize=8)
    g = demo["grasp"]
    k = int(np.argmax(g.f))
    for a, side in zip(ax[1, 1:], ("left", "right")):
        img = g.pads[side][k]
        im = a.imshow(img, vmin=0.0, vmax=1.0, cmap="jet")
        a.set_title(f"{g.container}/{g.state}: {side} pad at t = {g.t[k]:.2f} s "
                    f"(f = {g.f[k]:.1f} N)", fontsize=9)
        a.set_xlabel("column")
        a.set_ylabel("row (0 = fingertip)")
        fig.colorbar(im, ax=a, label="reading [0, 1]")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    save_figure(fig, path, dpi=100)
    plt.close(fig)


def run(*, config: TactileStateConfig, meshcat=None) -> dict:
    """Train and evaluate on iCub grasp files, or (``train`` empty, ``f_target`` set) run the
    simulation mode (see the module docstring for the result; ``meshcat``: simulation mode
    only, shows one more grasp with the taxel pads coloured by pressure)."""
    if _simulation(config):
        return run_simulation(config, meshcat=meshcat)
    if meshcat is not None:
        raise ValueError("meshcat: real-data mode has no 3-D scene to show")
    return real_data_report(config)


def real_data_report(config: TactileStateConfig) -> dict:
    """The real-data mode's result (see the module docstring;
    :func:`~mmlearn.models.tactile.evaluation.icub_state_report`) and, with ``plot``, its
    figure."""
    c = config
    if c.classifier not in CLASSIFIERS:
        raise ValueError(f"classifier: unknown {c.classifier!r}; choose from {', '.join(CLASSIFIERS)}")
    tr, _ = load_icub_dir(c.train, include_unreliable=c.include_full_coke)
    if not tr:
        raise ValueError(f"{c.train}: no usable trials")
    te = None
    if c.test is not None:
        te, _ = load_icub_dir(c.test, include_unreliable=c.include_full_coke)
        if not te:
            raise ValueError(f"{c.test}: no usable trials")
        unseen = sorted({t.label for t in te} - {t.label for t in tr})
        if unseen:
            raise ValueError(f"--test has classes that --train lacks: {', '.join(unseen)}")
    out = {"mode": "real", "classifier": c.classifier, "features": list(FEATURE_NAMES),
           "settings": {"contact_level_counts": c.contact_level,
                        "rest_velocity_rad_per_slice": c.rest_velocity,
                        "steady_average": c.steady_average, "seed": c.seed,
                        "include_full_coke": c.include_full_coke}}
    res, rep = icub_state_report(tr, te, classifier=c.classifier, folds=c.folds, seed=c.seed,
                                 contact_level=c.contact_level, rest_velocity=c.rest_velocity,
                                 steady_average=c.steady_average)
    out.update(res)
    if c.plot:
        plot_results(rep, tr, c.plot, title=f"{c.classifier}, {out['evaluation']}: "
                                            f"rate {rep.rate:.3f}",
                     feature_kw={"contact_force": c.contact_level,
                                 "rest_velocity": c.rest_velocity})
    return json_clean(out)


def plot_results(rep, trials, path, *, title: str = "", feature_kw=None) -> None:
    """Confusion matrix (left) and the closure p(t) and summed pressure f(t) of the first
    trial of every class (right), with t_first (circle) and t_steady (square) marked;
    ``feature_kw`` are the keyword arguments of ``extract_grasp_features``."""
    feature_kw = feature_kw or {"contact_force": CONTACT_LEVEL, "rest_velocity": REST_VELOCITY}
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(17, 5.5))
    ax = axes[0]
    C = rep.confusion
    ax.imshow(C, cmap="Blues")
    n = len(rep.labels)
    ax.set_xticks(range(n), rep.labels, rotation=60, ha="right", fontsize=7)
    ax.set_yticks(range(n), rep.labels, fontsize=7)
    for i in range(n):
        for j in range(n):
            if C[i, j]:
                ax.text(j, i, str(C[i, j]), ha="center", va="center", fontsize=7,
                        color="white" if C[i, j] > C.max() / 2 else "black")
    ax.set_xlabel("predicted")
    ax.set_ylabel("true")
    ax.set_title(title, fontsize=9)
    seen = {}
    for t in trials:
        seen.setdefault(t.label, t)
    cmap = plt.get_cmap("tab10")
    for k, (lab, t) in enumerate(sorted(seen.items())):
        g = t.to_grasp()
        col = cmap(k % 10)
        axes[1].plot(g.t, np.rad2deg(g.p), color=col, label=lab)
        axes[2].plot(g.t, g.f, color=col, label=lab)
        ft = extract_grasp_features(g, **feature_kw)
        for i, m in ((ft.i_first, "o"), (ft.i_steady, "s")):  # t_first (o), t_steady (s)
            if i is not None:
                axes[1].plot(g.t[i], np.rad2deg(g.p[i]), m, color=col, ms=6, mfc="none")
                axes[2].plot(g.t[i], g.f[i], m, color=col, ms=6, mfc="none")
    axes[1].set_xlabel("time [slices]")
    axes[1].set_ylabel("closure p(t) [deg, mean flexion]")
    axes[2].set_xlabel("time [slices]")
    axes[2].set_ylabel("summed pressure f(t) [counts]")
    axes[2].legend(fontsize=7)
    axes[1].set_title("finger closure (first trial per class; o t_first, [] t_steady)",
                      fontsize=9)
    axes[2].set_title("summed taxel pressure", fontsize=9)
    fig.tight_layout()
    save_figure(fig, path, dpi=100)
    plt.close(fig)


def _print_text(out, file=sys.stdout):
    print(f"{out['classifier']} on {out['n_train']} training grasps, {out['evaluation']}: "
          f"rate {out['rate']:.3f} ({', '.join(f'{k} {v:.3f}' for k, v in out['compare'].items())})",
          file=file)
    for lab, r in out["per_class"].items():
        print(f"  {lab:22s} {r:.3f}", file=file)
    labs = out["labels"]
    print("confusion (rows true, columns predicted):", file=file)
    for lab, row in zip(labs, out["confusion"]):
        print(f"  {lab[:20]:20s} " + " ".join(f"{v:3d}" for v in row), file=file)


def _print_sim(out, file=sys.stdout):
    print(f"simulation, f_target {out['f_target']:g} N, {out['n_grasps']} grasps, "
          f"{out['classifier']}:", file=file)
    print(f"  container_rate {out['container_rate']:.3f}", file=file)
    for k, v in out["state_rate_by_container"].items():
        print(f"  state | {k:10s} {v:.3f}", file=file)
    print(f"  combined_rate {out['combined_rate']:.3f}", file=file)
    for f, r in out.get("f_sweep_odwalla", {}).items():
        print(f"  odwalla state rate at {f} N: {r['rate']:.3f}", file=file)


class TactileState(Experiment):
    """The command line (:mod:`mmlearn.apps.common.experiment`): the simulation mode's grasps
    run through the sweep; the real-data mode runs no trial and is reported at once."""

    name = "tactile_state"
    trials = (container_grasp_trial,)
    description = ("Recognise objects and their internal state from the dynamics of a grasp "
                   "(thesis Sec. 7.1-7.2: six features of Table 7.1, decision tree / random "
                   "forest) on iCub grasp dataset files. Exit status: 0 success, 2 bad input.")
    seed_help = "random seed (fold assignment, forest)"
    json_help = "print results as one JSON object"
    desc = "grasps"
    keeps_results = False  # without --results the grasps go to a temporary file
    meshcat = None  # the Meshcat of --meshcat / --html-out (simulation mode)

    def add_arguments(self, ap):
        ap.add_argument("--train", metavar="DIR", default=None,
                        help="folder of iCub grasp files <label>_<trial>.txt to train on")
        ap.add_argument("--test", metavar="DIR", default=None,
                        help="folder of grasp files to score (default: cross-validation on "
                             "--train)")
        ap.add_argument("--classifier", choices=CLASSIFIERS, default="forest",
                        help="random forest (default), the thesis' decision tree or gradient "
                             "boosting; the others' rates are reported as compare")
        ap.add_argument("--include-full-coke", action="store_true",
                        help="keep the full_coke trials (marked unreliable by the data set's "
                             "author)")
        ap.add_argument("--folds", type=pos_int, default=10,
                        help="cross-validation folds without --test (default 10)")
        ap.add_argument("--contact-level", type=pos_float, default=None,
                        metavar="COUNTS",
                        help=f"contact threshold F on a finger's highest taxel pressure, sensor "
                             f"counts (default {CONTACT_LEVEL:g})")
        ap.add_argument("--rest-velocity", type=pos_float, default=None, metavar="RAD",
                        help=f"rest threshold V on the closure rate, rad per slice (default "
                             f"{REST_VELOCITY:.4f})")
        ap.add_argument("--steady-average", action="store_true",
                        help="p_steady and f_steady as means over the steady phase (default: "
                             "the single sample at t_steady, as the thesis)")
        ap.add_argument("--f-target", type=pos_float, default=None, metavar="N",
                        help="simulation mode: probing force of the simulated gripper per "
                             "finger, newtons (without --train)")
        ap.add_argument("--trials", type=pos_int, default=16,
                        help="simulation: grasps per container and state (default 16)")
        ap.add_argument("--f-sweep", action="store_true",
                        help="simulation: add the Odwalla f_target sweep 17 / 20 / 23 N (Table "
                             "7.2)")
        ap.add_argument("--sweep-trials", type=pos_int, default=24,
                        help="simulation: grasps per Odwalla state and force in --f-sweep "
                             "(default 24, as the thesis)")
        ap.add_argument("--progress", action="store_true", help="simulation: progress bar")
        ap.add_argument("--containers", type=name_list(list(CONTAINERS)),
                        default=list(CONTAINERS),
                        help="simulation: comma-separated container classes (default: all "
                             "four)")
        ap.add_argument("--wall-model", choices=("pressure", "linear"), default="pressure",
                        help="simulation: the containers' walls: 'pressure' (default: shell "
                             "spring plus the content's pressure through the squeezed volume) "
                             "or 'linear' (a constant linearised stiffness: the ablation of the "
                             "pressure model)")
        ap.add_argument("--grasp-variation", choices=("wall", "shell", "none"), default="wall",
                        help="simulation: 'wall' (default): each grasp meets its container "
                             "with its own draw of the wall's response (rotation, where the "
                             "pads land; the grasp-to-grasp spread of the squeeze measured on "
                             "the iCub grasps), 'shell' (the shell stiffness alone) or 'none' "
                             "(every grasp meets the instance as drawn: the ablation of the "
                             "variation)")
        ap.add_argument("--plot", metavar="FILE", default=None,
                        help="write an image: real data, the confusion matrix and example "
                             "grasp profiles; simulation, the grasp profiles p / v / f (Fig. "
                             "7.3), the impact with and without the switching controller (Fig. "
                             "7.5 / 7.6) and the tactile images of one grasp")
        ap.add_argument("--meshcat", action="store_true",
                        help="simulation: show one more grasp live in Meshcat, the taxel pads "
                             "coloured by pressure (real data has no scene)")
        ap.add_argument("--html-out", metavar="FILE", default=None,
                        help="simulation: write that grasp's Meshcat recording as standalone "
                             "HTML")

    def check(self, args):
        from mmlearn.apps.common.sweep import report_only_lines

        sim = args.train is None and args.f_target is not None
        for flag, val in (("--meshcat", args.meshcat), ("--html-out", args.html_out)):
            if val and not sim:
                raise UsageError(f"{flag}: real-data mode has no 3-D scene to show (use "
                                 f"--plot FILE; the simulation mode, --f-target N, has one)")
        if args.train is None and not sim:
            raise UsageError("--train DIR is required (or --f-target N for the simulation mode)")
        if args.train is not None and args.f_target is not None:
            raise UsageError("--f-target applies to simulation mode only (without --train); "
                             "the real data were recorded with the iCub's own controller")
        if sim and args.test is not None:
            raise UsageError("--test applies to real-data mode only")
        for flag, value in (("--contact-level", args.contact_level),
                            ("--rest-velocity", args.rest_velocity)):
            if sim and value is not None:
                raise UsageError(f"{flag} applies to real-data mode only (the simulation "
                                 f"uses {SIM_CONTACT_FORCE:g} N and {SIM_REST_VELOCITY:g} m/s)")
        if args.contact_level is None:
            args.contact_level = CONTACT_LEVEL
        if args.rest_velocity is None:
            args.rest_velocity = REST_VELOCITY
        if args.report_only and not sim:
            raise UsageError("--report-only applies to simulation mode only (the real-data "
                             "mode runs no trials)")
        if args.results:
            check_out_file("--results", args.results)
        check_out_file("--plot", args.plot)
        check_out_file("--html-out", args.html_out)
        for flag, d in (("--train", args.train), ("--test", args.test)):
            if d is not None and not Path(d).is_dir():
                raise UsageError(f"{flag}: {d}: " + ("not a folder" if Path(d).exists()
                                                     else "folder not found"))
        report_only_lines(args, simulates="a grasp", trials=self.trials)
        args.config = TactileStateConfig(
            train=args.train or "", test=args.test, classifier=args.classifier,
            include_full_coke=args.include_full_coke, folds=args.folds, seed=args.seed,
            contact_level=args.contact_level, rest_velocity=args.rest_velocity,
            steady_average=args.steady_average, plot=args.plot, f_target=args.f_target,
            trials=args.trials, f_sweep=args.f_sweep, sweep_trials=args.sweep_trials,
            progress=args.progress, containers=tuple(args.containers),
            wall_model=args.wall_model, grasp_variation=args.grasp_variation)

    def specs(self, args):
        if not _simulation(args.config):
            return []  # real data: no trial to run
        if args.meshcat or args.html_out:
            self.meshcat = make_meshcat(announce=args.meshcat)
            self.viewing = {"html_out": None if args.json else args.html_out,
                            "live": args.meshcat}
        return simulation_specs(args.config)

    def show_progress(self, args) -> bool:
        return args.config.progress

    def report(self, lines, args):
        if not _simulation(args.config):
            return real_data_report(args.config)
        res, args.records = simulation_report(lines, args.config)
        return res

    def attach_sweep(self, res, sweep, args):
        res["wall_seconds"] = round(sweep.wall_s, 1)
        res["resumed"] = sweep.resumed

    def finish(self, res, args):
        c = args.config
        if _simulation(c) and (self.meshcat is not None or c.plot):
            res["demo_grasp"] = _demo(c, args.records, self.meshcat)
        if args.html_out:
            save_html(self.meshcat, args.html_out)
        return json_clean(res)

    def failed(self, res):
        return []  # a grasp that raised is counted in the result, not in the exit status

    def print_table(self, res, args):
        (_print_sim if res["mode"] == "simulation" else _print_text)(res)
        if args.plot:
            print(f"plot written to {args.plot}")

    def to_json(self, res):
        return json.dumps(res, indent=1)


def main(argv=None) -> int:
    app = TactileState()
    rc = experiment.main(app, argv)
    if app.meshcat is not None and rc == 0:
        finish_viewing(**app.viewing)
    return rc


if __name__ == "__main__":
    sys.exit(main())
