"""Learn prior models from experience: sequential clustering of trajectories (Algorithm 2).

Usage::

    python -m mmlearn.apps.learn_priors PATH [PATH ...] [--sigma-pos M] [--seed N] [--json]
        [--save DB.json] [--load DB.json] [--evaluate [--fractions 0.1,0.2,...]
        [--exact-loo] [--plot OUT.png]]

PATH is a track file (format of shared/data/articulation_logs: 3, 7 or 9 whitespace
columns, ``#`` comments) or a folder (its track files, sorted). Trajectories are clustered in
the given order; each is first translated to start at the origin (the robot recorded every
trial in its own base frame from a different stopping place).

``--json`` prints ``{"clusters": [[path, ...], ...], "models": [model name per cluster],
"tracks": number of tracks read}``
and, with ``--evaluate``, ``"evaluation": {"fractions": [...], "error_without_m": [...],
"error_with_m": [...], "ratio": [...], "merged_fraction": [...]}`` (mean over the
leave-one-out trajectories). ``--evaluate`` runs the leave-one-out experiment of Fig. 4.15:
each trajectory is held out, the priors are the other trajectories' clusters, and the first
10 %..100 % of it is observed; the prediction error of the model (learned from scratch, or
with priors) on the full trajectory is reported.

``--save`` writes the prior database (JSON, atomic); ``--load`` starts from a saved one.
Bad input prints the problem on stderr and exits with status 2.
"""

from __future__ import annotations

import json
import sys

import numpy as np

from mmlearn.apps.common.cli import (ArgumentParser, UsageError, check_in_file, check_out_file,
                                     fail, nonneg_float, nonneg_int, pos_float, progress_bar)
from mmlearn.apps.common.cli import save_figure
from mmlearn.models.articulation.link import DEFAULT_GAMMA_WEIGHT, ObservationModel, make_model
from mmlearn.models.articulation.priors import PriorDatabase, evaluate_priors
from mmlearn.models.articulation.structure import DEFAULT_CANDIDATES
from mmlearn.models.articulation.structure import track_scale_problem
from mmlearn.models.common.track_io import TrackFileError, find_track_files, read_track

__all__ = ["run", "main"]




def run(*, paths, sigma_pos: float = 0.05, sigma_orient: float = float(np.deg2rad(15.0)),
        gamma_weight: float = DEFAULT_GAMMA_WEIGHT, max_points: int | None = 50, models=DEFAULT_CANDIDATES,
        seed: int = 0, evaluate: bool = False, fractions=None, exact_loo: bool = False,
        save: str | None = None, load: str | None = None, plot: str | None = None,
        progress: bool = True) -> dict:
    """Cluster the tracks in ``paths`` (files or folders, in order); returns the --json
    dictionary (plus "evaluation" with ``evaluate``)."""
    if isinstance(models, str):
        models = [m.strip() for m in models.split(",") if m.strip()]
    for m in models:
        make_model(m)
    files = find_track_files(paths)
    if not files:
        raise ValueError(f"no track files (*.log, *.txt, *.dat, *.track) in "
                         f"{', '.join(map(str, paths))}")
    db = PriorDatabase.load(load) if load else None  # a bad database fails before any work
    tracks = [read_track(f).poses for f in files]
    for f, t in zip(files, tracks):
        problem = track_scale_problem(t, sigma_pos)
        if problem:
            raise ValueError(f"{f}: {problem}")
    ncol = {t.shape[1] for t in tracks}
    if len(ncol) > 1:
        raise ValueError("tracks mix position-only (3 columns) and full poses (7 columns)")
    if len(set(files)) != len(files):
        raise ValueError("the same track file is given twice")
    obs = ObservationModel(sigma_pos=sigma_pos, sigma_orient=sigma_orient,
                           gamma_weight=gamma_weight)
    kw = dict(obs=obs, models=models, max_points=max_points)
    rng = np.random.default_rng(seed)
    if db is None:
        db = PriorDatabase(**kw)
    bar = progress_bar(len(files), "clustering", enabled=progress)
    for f, t in zip(files, tracks):
        db.add(t, f, rng=rng)
        bar.update(1)
    bar.close()
    out = {"clusters": db.assignments(), "models": db.model_names(), "tracks": len(files)}
    if save:
        db.save(save)
    if evaluate:
        fr = (np.linspace(0.1, 1.0, 10) if fractions is None
              else np.asarray(fractions, float))
        bar = progress_bar(len(files), "leave-one-out", enabled=progress)
        ev = evaluate_priors(tracks, files, fractions=fr, rng=rng,
                             progress=lambda i: bar.update(1), exact_loo=exact_loo, **kw)
        bar.close()
        wo, w = ev["error_without"].mean(axis=0), ev["error_with"].mean(axis=0)
        out["evaluation"] = {
            "fractions": [float(x) for x in fr],
            "error_without_m": wo.tolist(), "error_with_m": w.tolist(),
            "std_without_m": ev["error_without"].std(axis=0).tolist(),
            "std_with_m": ev["error_with"].std(axis=0).tolist(),
            "ratio": (wo / np.maximum(w, 1e-12)).tolist(),
            "merged_fraction": ev["merged"].mean(axis=0).tolist(),
            "seconds": ev["seconds"],
        }
        if plot:
            _plot(ev, plot)
    return out


def _plot(ev, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    f = np.asarray(ev["fractions"]) * 100
    fig, ax = plt.subplots(figsize=(6, 4))
    for key, lab in (("error_without", "without prior"), ("error_with", "with prior")):
        m, s = ev[key].mean(axis=0), ev[key].std(axis=0)
        ax.plot(f, m, label=lab)
        ax.fill_between(f, np.maximum(m - s, 0), m + s, alpha=0.2)
    ax.set_xlabel("observed part of the trajectory [%]")
    ax.set_ylabel("prediction error on the full trajectory [m]")
    ax.legend()
    fig.tight_layout()
    save_figure(fig, path, dpi=100)
    plt.close(fig)


def main(argv=None) -> int:
    ap = ArgumentParser(prog="python -m mmlearn.apps.learn_priors",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("paths", nargs="+", help="track files or folders, in observation order")
    ap.add_argument("--sigma-pos", type=pos_float, default=0.05, help="position noise, m (0.05)")
    ap.add_argument("--sigma-orient", type=pos_float, default=float(np.deg2rad(15.0)),
                    help="orientation noise, rad (full-pose tracks only)")
    ap.add_argument("--gamma-weight", type=nonneg_float, default=DEFAULT_GAMMA_WEIGHT,
                    help="outlier prior weight w per observation (default ln(100)/0.05 ~ 92)")
    ap.add_argument("--max-points", type=nonneg_int, default=50,
                    help="thin each trajectory to at most this many observations (0 = all)")
    ap.add_argument("--models", default=",".join(DEFAULT_CANDIDATES),
                    help="candidate link models (comma separated)")
    ap.add_argument("--seed", type=nonneg_int, default=0, help="random seed")
    ap.add_argument("--json", action="store_true", help="print JSON")
    ap.add_argument("--save", default=None, help="write the prior database (JSON)")
    ap.add_argument("--load", default=None,
                    help="start from a saved prior database (its settings are kept)")
    ap.add_argument("--evaluate", action="store_true",
                    help="leave-one-out prediction experiment (Fig. 4.15)")
    ap.add_argument("--fractions", default=None,
                    help="observed fractions for --evaluate, e.g. 0.1,0.3,0.5 (default 0.1..1.0)")
    ap.add_argument("--exact-loo", action="store_true",
                    help="re-cluster without each held-out trajectory (slower)")
    ap.add_argument("--plot", default=None, help="PNG of the --evaluate errors")
    ap.add_argument("--no-progress", action="store_true", help="no progress bars")
    a = ap.parse_args(argv)
    try:
        check_out_file("--save", a.save)
        check_out_file("--plot", a.plot)
        check_in_file("--load", a.load)
        if a.plot and not a.evaluate:
            raise UsageError("--plot: needs --evaluate (it plots the leave-one-out errors)")
        if a.load:
            try:
                PriorDatabase.load(a.load)
            except ValueError as e:
                raise UsageError(f"--load: {e}") from None
    except UsageError as e:
        return fail(ap.prog, str(e))
    try:
        fr = None
        if a.fractions:
            try:
                fr = [float(x) for x in a.fractions.split(",") if x.strip()]
            except ValueError:
                raise ValueError(f"--fractions: not a list of numbers: {a.fractions!r}") from None
            if not fr or not all(0.0 < x <= 1.0 for x in fr):
                raise ValueError(f"--fractions: expected numbers in (0, 1], got {a.fractions!r}")
        out = run(paths=a.paths, sigma_pos=a.sigma_pos, sigma_orient=a.sigma_orient,
                  gamma_weight=a.gamma_weight,
                  max_points=None if a.max_points == 0 else a.max_points, models=a.models,
                  seed=a.seed, evaluate=a.evaluate, fractions=fr, exact_loo=a.exact_loo,
                  save=a.save, load=a.load, plot=a.plot, progress=not a.no_progress)
    except (ValueError, FileNotFoundError, OSError, TrackFileError) as e:
        return fail(ap.prog, str(e))
    if a.json:
        print(json.dumps(out))
    else:
        n_all = sum(len(c) for c in out["clusters"])
        loaded = f" (+{n_all - out['tracks']} from --load)" if n_all > out["tracks"] else ""
        print(f"{out['tracks']} tracks{loaded} -> {len(out['clusters'])} clusters"
              + (f" (saved to {a.save})" if a.save else ""))
        for k, (c, m) in enumerate(zip(out["clusters"], out["models"])):
            print(f"cluster {k} ({m}, {len(c)} trajectories): {', '.join(c)}")
        ev = out.get("evaluation")
        if ev:
            print("observed  error without prior [m]  error with prior [m]  ratio")
            for f, a_, b_, r in zip(ev["fractions"], ev["error_without_m"], ev["error_with_m"],
                                    ev["ratio"]):
                print(f"{100 * f:7.0f}%  {a_:24.4f}  {b_:19.4f}  {r:5.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
