"""Object and internal-state recognition from grasp dynamics (thesis Sec. 7.1-7.2) on real data.

Usage::

    python -m mmlearn.apps.tactile_state --train DIR [--test DIR] [--classifier tree|forest]
        [--include-full-coke] [--folds 10] [--steady-average] [--plot FILE] --seed S [--json]

``DIR`` holds iCub grasp dataset files ``<label>_<trial>.txt`` (format: README.txt of the data
set; reader: :mod:`mmlearn.models.icub_grasp`). Each grasp gives the six features of Table 7.1
(:mod:`mmlearn.models.tactile_state`): finger closure at first two-finger contact, at rest,
summed taxel pressure at rest, the time between them and the two average rates. A classifier
(``forest`` by default, see below) is trained on ``--train`` and scored on ``--test``; without
``--test``, stratified ``--folds``-fold cross-validation on ``--train``. ``full_coke`` is left
out unless ``--include-full-coke`` (the data set's author marks it unreliable).

Classifier choice: the thesis used a C4.5 decision tree (``--classifier tree``: scikit-learn's
entropy-criterion CART). On the shared iCub trials (10 classes x 10 trials) 10-fold CV gave
0.86-0.90 for the tree and 0.95-0.97 for a random forest of 300 such trees over seeds 0-4
(benchmarks/bench_tactile_state.py prints these figures): the six features are noisy single
readings and averaging many trees cancels much of that noise, so the forest is the default.
The run also reports the other classifier's rate (``compare``).

``--json`` prints one object::

    {"mode": "real", "classifier", "evaluation": "test" | "<k>-fold CV", "rate",
     "per_class": {label: rate}, "labels", "confusion" (rows true, columns predicted),
     "n_train", "n_test", "compare": {classifier: rate}, "no_contact": {label: count},
     "features": [...], "settings": {...}}

The simulation mode (``--f-target N`` without ``--train``: the Drake gripper squeezing simulated
containers) is not built yet; asking for it exits with status 2 and says so.

Exit status: 0 success, 2 bad input (unreadable or malformed files name the file and line,
unknown labels, missing folders, test classes absent from training).
"""

from __future__ import annotations

import json
import sys
from collections import Counter
from dataclasses import dataclass

import numpy as np

from mmlearn.apps._common import (ArgumentParser, UsageError, check_out_file, fail,
                                  json_clean, nonneg_int, pos_float, pos_int, save_figure)
from mmlearn.models.icub_grasp import (CONTACT_LEVEL, REST_VELOCITY, ICubFileError,
                                       load_icub_dir)
from mmlearn.models.tactile_state import (CLASSIFIERS, FEATURE_NAMES, cross_validate,
                                          evaluate_split, extract_grasp_features,
                                          feature_matrix)

__all__ = ["run", "main", "TactileStateConfig"]


def _features(trials, *, contact_level, rest_velocity, steady_average):
    grasps = [t.to_grasp() for t in trials]
    X, feats = feature_matrix(grasps, contact_force=contact_level, rest_velocity=rest_velocity,
                              steady_average=steady_average)
    y = np.array([t.label for t in trials])
    return X, y, feats


@dataclass
class TactileStateConfig:
    """Settings of one run (real-data mode).

    Attributes:
        train: folder of iCub grasp files to train on.
        test: folder of files to score; None: ``folds``-fold cross-validation on ``train``.
        classifier: "forest" or "tree".
        include_full_coke: keep the full_coke trials.
        folds: cross-validation folds.
        seed: random seed (fold assignment, forest).
        contact_level: contact threshold F on a finger's highest taxel pressure, counts.
        rest_velocity: rest threshold V on the closure rate, rad per slice.
        steady_average: steady-phase means instead of single samples for p/f_steady.
        plot: image file for the confusion matrix and profiles, or None.
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


def run(*, config: TactileStateConfig) -> dict:
    """Train and evaluate on iCub grasp files (see the module docstring for the result)."""
    c = config
    train, test, classifier = c.train, c.test, c.classifier
    include_full_coke, folds, seed = c.include_full_coke, c.folds, c.seed
    contact_level, rest_velocity = c.contact_level, c.rest_velocity
    steady_average, plot = c.steady_average, c.plot
    if classifier not in CLASSIFIERS:
        raise ValueError(f"classifier: unknown {classifier!r}; choose from {', '.join(CLASSIFIERS)}")
    tr, _ = load_icub_dir(train, include_unreliable=include_full_coke)
    if not tr:
        raise ValueError(f"{train}: no usable trials")
    kw = dict(contact_level=contact_level, rest_velocity=rest_velocity,
              steady_average=steady_average)
    X, y, feats = _features(tr, **kw)
    out = {"mode": "real", "classifier": classifier, "features": list(FEATURE_NAMES),
           "settings": {"contact_level_counts": contact_level,
                        "rest_velocity_rad_per_slice": rest_velocity,
                        "steady_average": steady_average, "seed": seed,
                        "include_full_coke": include_full_coke}}
    other = [c for c in CLASSIFIERS if c != classifier]
    if test is None:
        rep = cross_validate(X, y, classifier=classifier, folds=folds, seed=seed)
        out["evaluation"] = f"{folds}-fold CV"
        out["n_train"], out["n_test"] = int(len(y)), int(len(y))
        out["compare"] = {c: cross_validate(X, y, classifier=c, folds=folds, seed=seed).rate
                          for c in other}
        eval_feats, eval_y = feats, y
    else:
        te, _ = load_icub_dir(test, include_unreliable=include_full_coke)
        if not te:
            raise ValueError(f"{test}: no usable trials")
        Xt, yt, feats_t = _features(te, **kw)
        unseen = sorted(set(yt.tolist()) - set(y.tolist()))
        if unseen:
            raise ValueError(f"--test has classes that --train lacks: {', '.join(unseen)}")
        rep, _ = evaluate_split(X, y, Xt, yt, classifier=classifier, seed=seed)
        out["evaluation"] = "test"
        out["n_train"], out["n_test"] = int(len(y)), int(len(yt))
        out["compare"] = {c: evaluate_split(X, y, Xt, yt, classifier=c, seed=seed)[0].rate
                          for c in other}
        eval_feats, eval_y = feats_t, yt
    out.update(rep.to_dict())
    out.pop("n", None)
    nc = Counter(lab for f, lab in zip(eval_feats, eval_y.tolist()) if not f.contact)
    out["no_contact"] = {lab: int(nc.get(lab, 0)) for lab in rep.labels}
    if plot:
        plot_results(rep, tr, plot, title=f"{classifier}, {out['evaluation']}: "
                                          f"rate {rep.rate:.3f}",
                     feature_kw={"contact_force": contact_level,
                                 "rest_velocity": rest_velocity})
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


def main(argv=None) -> int:
    ap = ArgumentParser(
        prog="python -m mmlearn.apps.tactile_state",
        description="Recognise objects and their internal state from the dynamics of a grasp "
                    "(thesis Sec. 7.1-7.2: six features of Table 7.1, decision tree / random "
                    "forest) on iCub grasp dataset files. Exit status: 0 success, 2 bad input.")
    ap.add_argument("--train", metavar="DIR", default=None,
                    help="folder of iCub grasp files <label>_<trial>.txt to train on")
    ap.add_argument("--test", metavar="DIR", default=None,
                    help="folder of grasp files to score (default: cross-validation on --train)")
    ap.add_argument("--classifier", choices=CLASSIFIERS, default="forest",
                    help="random forest (default) or the thesis' decision tree")
    ap.add_argument("--include-full-coke", action="store_true",
                    help="keep the full_coke trials (marked unreliable by the data set's author)")
    ap.add_argument("--folds", type=pos_int, default=10,
                    help="cross-validation folds without --test (default 10)")
    ap.add_argument("--contact-level", type=pos_float, default=CONTACT_LEVEL, metavar="COUNTS",
                    help=f"contact threshold F on a finger's highest taxel pressure, sensor "
                         f"counts (default {CONTACT_LEVEL:g})")
    ap.add_argument("--rest-velocity", type=pos_float, default=REST_VELOCITY, metavar="RAD",
                    help=f"rest threshold V on the closure rate, rad per slice (default "
                         f"{REST_VELOCITY:.4f})")
    ap.add_argument("--steady-average", action="store_true",
                    help="p_steady and f_steady as means over the steady phase (default: the "
                         "single sample at t_steady, as the thesis)")
    ap.add_argument("--f-target", type=pos_float, default=None, metavar="N",
                    help="probing force of the simulated gripper, newtons (simulation mode: "
                         "not built yet)")
    ap.add_argument("--seed", type=nonneg_int, default=0,
                    help="random seed (fold assignment, forest)")
    ap.add_argument("--plot", metavar="FILE", default=None,
                    help="write the confusion matrix and example grasp profiles as an image")
    ap.add_argument("--meshcat", action="store_true",
                    help="live 3-D view (simulation mode only: not built yet)")
    ap.add_argument("--html-out", metavar="FILE", default=None,
                    help="Meshcat recording (simulation mode only: not built yet)")
    ap.add_argument("--json", action="store_true", help="print results as one JSON object")
    args = ap.parse_args(argv)
    try:
        for flag, val in (("--meshcat", args.meshcat), ("--html-out", args.html_out)):
            if val:
                raise UsageError(f"{flag}: real-data mode has no 3-D scene to show, and the "
                                 f"simulation mode is not built yet (use --plot FILE)")
        if args.train is None:
            if args.f_target is not None:
                raise UsageError("simulation mode not built yet (--f-target needs the Drake "
                                 "gripper and containers); use --train DIR for real data")
            raise UsageError("--train DIR is required (simulation mode not built yet)")
        if args.f_target is not None:
            raise UsageError("--f-target applies to simulation mode only (not built yet); "
                             "the real data were recorded with the iCub's own controller")
        check_out_file("--plot", args.plot)
        from pathlib import Path

        for flag, d in (("--train", args.train), ("--test", args.test)):
            if d is not None and not Path(d).is_dir():
                raise UsageError(f"{flag}: {d}: " + ("not a folder" if Path(d).exists()
                                                     else "folder not found"))
    except UsageError as e:
        return fail(ap.prog, str(e))
    try:
        out = run(config=TactileStateConfig(
            train=args.train, test=args.test, classifier=args.classifier,
            include_full_coke=args.include_full_coke, folds=args.folds, seed=args.seed,
            contact_level=args.contact_level, rest_velocity=args.rest_velocity,
            steady_average=args.steady_average, plot=args.plot))
    except (ICubFileError, ValueError) as e:
        return fail(ap.prog, str(e))
    if args.json:
        print(json.dumps(out, indent=1))
    else:
        _print_text(out)
        if args.plot:
            print(f"plot written to {args.plot}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
