"""Fit articulation models (rigid, prismatic, revolute, gp) to recorded tracks and select by BIC.

Usage::

    python -m mmlearn.apps.fit_articulation PATH [PATH ...] [--sigma-pos M]
        [--sigma-orient RAD] [--models rigid,prismatic,revolute,gp] [--seed N]
        [--rectangles corner|centre] [--expect MODEL [--subsample N] [--repeats R]]
        [--plot OUT.png] [--json]

PATH is a track file (3, 7 or 9 whitespace columns, ``#`` comments; see
models/common/track_io.py) or a folder (searched recursively for *.log, *.txt, *.dat, *.track).
The track is the pose of the moving part in a fixed frame (the robot's or the camera's).

``--json`` prints one object::

    {"tracks": [{"path", "n", "selected", "bic": {model: value}, "gamma",
                 "avg_pos_error_m", "avg_orient_error_rad" (null for position-only),
                 "params": {...}, "fit_seconds", "not_selectable" (optional: candidates
                 that cannot be told from a simpler model, with the reason)}],
     "errors": [{"path", "error"}]}

``--rectangles ORIGIN`` reads 9-column files as tracks of cabinet-front rectangles (thesis ch. 5)
whose pose sits at ORIGIN of the rectangle: ``corner`` (the original detector's convention,
the rectangle spanning [0, w] x [0, h]; the files in shared/data/articulation_logs/
rectangle_tracks) or ``centre``. The track is converted to centre poses and its
observations are brought into one of the 8 parameterisations of a rectangle
(models/perception/tracking.py: align_track); each track's JSON gains ``"rectangle"``:
{"pose_origin_in_file", "axis_error_deg" (revolute: hinge axis against the nearer edge
direction; prismatic: axis against the front's normal), "hinge_edge", "half_size_m",
"radius_m", "cv_pos_error_m", "cv_orient_error_rad" (5-fold cross-validated prediction
errors of the selected model class)}. Reproduces the real-track results of
models/perception/tracking.py, e.g.::

    python -m mmlearn.apps.fit_articulation tests/data/articulation_logs/rectangle_door.txt \
        --rectangles corner --sigma-pos 0.02 --sigma-orient 0.0524 --expect revolute

``--expect MODEL`` adds ``"selection_vs_n"`` (the protocol of thesis Sec. 5.2.2, see
models/front_tracking.subsampled_selection: ``--subsample`` observations drawn in temporal
order, a model selected on the first n = 5, 10, ... of them, ``--repeats`` draws) with
``right_fraction`` per n, ``model_right_from`` per draw, and ``right_in_all_from`` (first n
from which every draw selects MODEL at every later n; null if none).

Revolute params: radius_m, axis (unit 3-vector), center (m), q range (rad); prismatic: axis,
origin_m, q range (m). Errors are averages over the observations the selected model classifies
as inliers. Bad files are reported on stderr (file:line: reason) and skipped; the exit code is
1 if any file failed, else 0.
"""

from __future__ import annotations

import json
import math
import os
import sys
import time

import numpy as np

from mmlearn.apps.common.cli import (ArgumentParser, UsageError, check_out_file, fail,
                                     json_clean, nonneg_int, pos_float, pos_int)
from mmlearn.apps.common.cli import save_figure
from mmlearn.models.articulation.link import ObservationModel, make_model
from mmlearn.models.articulation.structure import (DEFAULT_CANDIDATES, select_link_model,
                                                  track_scale_problem)
from mmlearn.models.common.progress import progress as progress_iter
from mmlearn.models.perception.tracking import (align_track, axis_errors, cross_validated_errors,
                                                rectangles_from_poses, subsampled_selection)
from mmlearn.models.common.track_io import (TRACK_SUFFIXES, TrackFileError, find_track_files,
                                            read_track)

__all__ = ["run", "main", "fit_track"]


def fit_track(poses, *, obs: ObservationModel, models=DEFAULT_CANDIDATES, rng=None):
    """Select a link model for one track; returns (result dict, LinkSelection)."""
    problem = track_scale_problem(poses, obs.sigma_pos)
    if problem:
        raise ValueError(problem)
    t0 = time.perf_counter()
    sel = select_link_model(poses, models=models, obs=obs, rng=rng)
    dt = time.perf_counter() - t0
    best = sel.best
    res = {
        "n": int(len(poses)),
        "selected": best.name,
        "bic": {k: float(v) for k, v in sel.bic.items()},
        "gamma": float(best.gamma),
        "avg_pos_error_m": float(best.avg_pos_error_),
        "avg_orient_error_rad": (None if best.avg_orient_error_ is None
                                 else float(best.avg_orient_error_)),
        "params": best.params(),
        "fit_seconds": dt,
    }
    if sel.errors:
        res["candidate_errors"] = dict(sel.errors)
    if sel.demoted:
        res["not_selectable"] = dict(sel.demoted)
    return res, sel


def _right_in_all_from(sel: dict):
    ns, frac = sel["n"], sel["right_fraction"]
    out = None
    for i in range(len(ns) - 1, -1, -1):
        if frac[i] < 1.0:
            break
        out = ns[i]
    return out


def _log(log, line: str) -> None:
    if log is not None:
        print(line, file=log)


def run(paths, *, sigma_pos: float = 0.01, sigma_orient: float = float(np.deg2rad(5.0)),
        models=DEFAULT_CANDIDATES, seed: int = 0, plot: str | None = None,
        progress: bool = True, log=sys.stderr, rectangles: str | None = None,
        expect: str | None = None, subsample: int = 60, repeats: int = 50) -> dict:
    """Fit every track in ``paths`` (files or folders). Returns
    {"tracks": [...], "errors": [...]} (see module docstring). ``rectangles``: None or the
    pose origin of 9-column rectangle files ("corner" / "centre"); ``expect``: a model name
    for the selection-vs-n protocol (``subsample`` observations, ``repeats`` draws)."""
    obs = ObservationModel(sigma_pos=sigma_pos, sigma_orient=sigma_orient)
    if isinstance(models, str):
        models = [m.strip() for m in models.split(",") if m.strip()]
    files = find_track_files(paths)
    rng = np.random.default_rng(seed)
    out = {"tracks": [], "errors": []}
    selections = []
    it = files
    if progress and len(files) > 1:
        it = progress_iter(files, desc="fitting tracks", unit="track")
    for f in it:
        try:
            tr = read_track(f)
        except TrackFileError as e:
            _log(log, f"error: {e}")
            out["errors"].append({"path": f, "error": str(e)})
            continue
        rects = None
        if rectangles is not None:
            if tr.extra is None:
                msg = (f"{f}: --rectangles needs 9 columns (x y z qx qy qz qw width height), "
                       f"the file has {tr.poses.shape[1]}")
                _log(log, f"error: {msg}")
                out["errors"].append({"path": f, "error": msg})
                continue
            rects = align_track(rectangles_from_poses(tr.poses, tr.extra, origin=rectangles))
            tr.poses = np.array([r.pose7() for r in rects])
        try:
            res, sel = fit_track(tr.poses, obs=obs, models=models, rng=rng)
        except ValueError as e:
            msg = f"{f}: {e}"
            _log(log, f"error: {msg}")
            out["errors"].append({"path": f, "error": msg})
            continue
        if rects is not None:
            cv = cross_validated_errors(tr.poses, sel.best.name, obs=obs, seed=seed)
            res["rectangle"] = {"pose_origin_in_file": rectangles,
                                **axis_errors(sel.best, rects),
                                "cv_pos_error_m": cv[0], "cv_orient_error_rad": cv[1]}
        if expect is not None:
            vs = subsampled_selection(tr.poses, expected=expect, n_sample=subsample,
                                      repeats=repeats, obs=obs, seed=seed)
            vs["right_in_all_from"] = _right_in_all_from(vs)
            res["selection_vs_n"] = vs
        res = {"path": f, **res}
        out["tracks"].append(json_clean(res))
        selections.append((f, tr, sel))
    if plot and selections:
        plot_tracks(selections, plot)
    return out


def plot_tracks(selections, path: str) -> None:
    """Observations (dots) and the selected model over its configuration range (line), one
    3-D panel per track (at most 16)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    selections = selections[:16]
    k = len(selections)
    cols = min(4, k)
    rows = int(math.ceil(k / cols))
    fig = plt.figure(figsize=(4 * cols, 3.6 * rows))
    for i, (f, tr, sel) in enumerate(selections):
        ax = fig.add_subplot(rows, cols, i + 1, projection="3d")
        P = tr.poses[:, :3]
        ax.scatter(P[:, 0], P[:, 1], P[:, 2], s=2, c="tab:blue", alpha=0.3,
                   label="observations")
        m = sel.best
        if m.dof == 0:
            Q = m.forward(None)[:, :3]
        elif m.dof == 1:
            qs = np.linspace(m.q_min[0], m.q_max[0], 100)
            Q = m.forward(qs[:, None])[:, :3]
        else:
            Q = m.project(tr.poses)[:, :3]
        ax.plot(Q[:, 0], Q[:, 1], Q[:, 2], "r-" if m.dof == 1 else "r.", lw=2,
                label=f"{m.name}")
        # equal scaling on all axes (a cube around the data), so arcs look like arcs
        allp = np.vstack([P, Q])
        ctr = 0.5 * (allp.min(axis=0) + allp.max(axis=0))
        half = 0.5 * max(float(np.max(np.ptp(allp, axis=0))), 1e-3)
        ax.set_xlim(ctr[0] - half, ctr[0] + half)
        ax.set_ylim(ctr[1] - half, ctr[1] + half)
        ax.set_zlim(ctr[2] - half, ctr[2] + half)
        name = "/".join(str(f).replace("\\", "/").split("/")[-2:])
        extra = f" r={m.radius:.2f} m" if m.name == "revolute" else ""
        ax.set_title(f"{name}: {m.name}{extra}", fontsize=8)
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.set_zlabel("z [m]")
        ax.legend(fontsize=6)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)


def _print_table(out, file=sys.stdout):
    print(f"{'track':50s} {'n':>5s} {'selected':>10s} {'gamma':>6s} {'pos_err':>8s} "
          f"{'ori_err':>8s} {'detail':s}", file=file)
    for t in out["tracks"]:
        p = t["params"]
        detail = ""
        if t["selected"] == "revolute":
            detail = f"r={p['radius_m']:.3f} m axis={np.round(p['axis'], 3).tolist()}"
        elif t["selected"] == "prismatic":
            detail = f"axis={np.round(p['axis'], 3).tolist()}"
        oe = t["avg_orient_error_rad"]
        print(f"{t['path'][-50:]:50s} {t['n']:5d} {t['selected']:>10s} {t['gamma']:6.3f} "
              f"{t['avg_pos_error_m']:8.4f} {'-' if oe is None else f'{oe:8.4f}':>8s} {detail}",
              file=file)
        rc = t.get("rectangle")
        if rc:
            ae = rc.get("axis_error_deg")
            print(f"    rectangle (pose at the {rc['pose_origin_in_file']} in the file, fitted at "
                  f"the centre): axis error {'-' if ae is None else f'{ae:.2f}'} deg, "
                  f"cross-validated error {rc['cv_pos_error_m']:.4f} m / "
                  f"{np.degrees(rc['cv_orient_error_rad']):.2f} deg"
                  + (f", half size across the hinge {rc['half_size_m']:.3f} m"
                     if "half_size_m" in rc else ""), file=file)
        vs = t.get("selection_vs_n")
        if vs:
            print("    n:          " + " ".join(f"{n:5d}" for n in vs["n"]), file=file)
            print("    right share:" + " ".join(f"{x:5.2f}" for x in vs["right_fraction"]),
                  file=file)
            print(f"    right in all draws from n = {vs['right_in_all_from']}", file=file)


def main(argv=None) -> int:
    ap = ArgumentParser(
        prog="python -m mmlearn.apps.fit_articulation",
        description="Fit rigid / prismatic / revolute / GP link models to articulation "
                    "tracks and select the best by BIC (thesis Sec. 4.1). Exit status: 0 all "
                    "tracks fitted, 1 some track could not be read or fitted, 2 bad input "
                    "(a missing path, no track files at all, or no track that could be "
                    "read and fitted).")
    ap.add_argument("paths", nargs="+", metavar="PATH", help="track file(s) or folder(s)")
    ap.add_argument("--sigma-pos", type=pos_float, default=0.01, metavar="M",
                    help="position noise std, metres (default 0.01)")
    ap.add_argument("--sigma-orient", type=pos_float, default=float(np.deg2rad(5.0)),
                    metavar="RAD", help="orientation noise std, radians (default 0.087)")
    ap.add_argument("--models", default=",".join(DEFAULT_CANDIDATES),
                    help="comma-separated candidates (rigid,prismatic,revolute,gp,gp2..gp5,"
                         "gp-lle)")
    ap.add_argument("--seed", type=nonneg_int, default=0, help="random seed (MLESAC sampling)")
    ap.add_argument("--rectangles", choices=("corner", "centre"), default=None,
                    help="9-column files are rectangle tracks with the pose at this point of "
                         "the rectangle: fit the centre pose in one consistent "
                         "parameterisation (the original detector's files: corner)")
    ap.add_argument("--expect", metavar="MODEL", default=None,
                    help="report model selection against the number of observations "
                         "(thesis Sec. 5.2.2 protocol) and from which n MODEL is selected")
    ap.add_argument("--subsample", type=pos_int, default=60, metavar="N",
                    help="--expect: observations drawn per repeat (default 60)")
    ap.add_argument("--repeats", type=pos_int, default=50, metavar="R",
                    help="--expect: number of draws (default 50)")
    ap.add_argument("--plot", metavar="OUT.png", default=None,
                    help="write a figure of the observations and fitted models")
    ap.add_argument("--json", action="store_true", help="print results as one JSON object")
    ap.add_argument("--no-progress", action="store_true", help="no progress bar")
    args = ap.parse_args(argv)
    try:
        names = [m.strip() for m in args.models.split(",") if m.strip()]
        if not names:
            raise UsageError(f"--models: expected a comma-separated list, got {args.models!r}")
        for name in names:
            try:
                make_model(name)
            except ValueError as e:
                raise UsageError(f"--models: {e}") from None
        if args.expect is not None:
            try:
                args.expect = make_model(args.expect).name
            except ValueError as e:
                raise UsageError(f"--expect: {e}") from None
        check_out_file("--plot", args.plot)
        for path in args.paths:
            if not os.path.exists(path):
                raise UsageError(f"{path}: file or folder not found")
        files = find_track_files(args.paths)
        if not files:
            raise UsageError(f"no track files (*{', *'.join(TRACK_SUFFIXES)}) in "
                             f"{', '.join(args.paths)}")
    except UsageError as e:
        return fail(ap.prog, str(e))
    try:
        out = run(args.paths, sigma_pos=args.sigma_pos, sigma_orient=args.sigma_orient,
                  models=args.models, seed=args.seed, plot=args.plot, log=None,
                  progress=not args.no_progress and not args.json,
                  rectangles=args.rectangles, expect=args.expect, subsample=args.subsample,
                  repeats=args.repeats)
    except ValueError as e:
        return fail(ap.prog, str(e))
    if out["errors"] and not out["tracks"]:
        first = out["errors"][0]["error"]
        more = len(out["errors"]) - 1
        return fail(ap.prog, first + (f" (and {more} more file(s) that could not be fitted)"
                                      if more else ""))
    for e in out["errors"]:  # some tracks fitted: name the others, exit status 1
        print(f"error: {e['error']}", file=sys.stderr)
    if args.json:
        print(json.dumps(out, indent=1))
    else:
        _print_table(out)
        if args.plot:
            print(f"plot written to {args.plot}")
    return 1 if out["errors"] else 0


if __name__ == "__main__":
    sys.exit(main())
