"""Reproduce the thesis' synthetic articulation analysis (Sec. 4.4.4) and Table 4.2.

Usage::

    python -m mmlearn.apps.articulation_experiments [--runs 100] [--quick] [--seed 0]
        [--out-dir DIR] [--only noise,outliers,...] [--json]
        [--results FILE] [--executor local|ray] [--ray-address ADDR] [--jobs N]
    python -m mmlearn.apps.articulation_experiments --report-only RESULTS.jsonl [--out-dir DIR]

Experiments (ground truths: models/articulation/sim.py; rigid, prismatic and revolute
estimators on their own ground truth, the GP on the roll-up door, Fig. 4.19):

- ``noise``     (Fig. 4.20): sample error vs Gaussian noise sigma_pos, n = 100, gamma = 0.
- ``outliers``  (Fig. 4.21): sample error vs outlier ratio gamma, sigma = 0.01 m / 3 deg.
  By default each training sequence has exactly round(gamma n) outliers at random positions
  (the thesis generates "an observation sequence with outlier ratio gamma").
  ``--outliers bernoulli`` draws each observation as an outlier with probability gamma (the
  mixture of Eq. 4.13-4.15); then some runs have no more inliers than a minimal sample (1
  rigid, 2 prismatic, 3 revolute) and any minimal sample of outliers explains the data as
  well, so no estimator can find the model: at n = 100, gamma = 0.95 that is P(k <= 1) =
  3.7% of the rigid runs, each with an error of ~0.5 m (outliers fill a 1 m cube). The table
  therefore also gives the median, the mean over the identifiable runs and their share.
- ``gamma``     (Fig. 4.22): estimated vs true outlier ratio (same runs as ``outliers``).
- ``size``      (Fig. 4.23): sample error vs training size n, sigma = 0.05 m, gamma = 0.
- ``time``      (Fig. 4.24): fit time of each estimator vs n.
- ``bic_n``     (Fig. 4.25): BIC and selection vs n on the roll-up door, samples presented in
  the order of the configuration (vertical segment, quarter circle, horizontal segment).
- ``bic_noise`` (Fig. 4.26): BIC and selection vs the assumed noise, roll-up door, n = 50,
  true noise 0.002 m / 2 deg (assumed noise from the true level upwards).
- ``selection`` (issue 10): the observation-model variants of SELECTION_VARIANTS compared on
  real tracks (``--tracks``, default the copies in the repository's tests/data: Cody's
  drawers, doors and dishwasher, position-only, and the cosine-synth GP tracks; the expected
  joint is read from the file name) at assumed sigma_pos 0.005-0.1 m, on the simulated
  garage door of Table 4.2 (10 folds, n = 20) and on the outlier-ratio estimate of a
  revolute link with 30 % outliers (mean |estimated - true gamma|).
- ``table``     (Table 4.2): simulated microwave door and drawer (sigma 0.002 m / 2 deg) and
  garage door (0.05 m / 5 deg), 200 samples, 10 folds, n = 20 training samples per fold
  (microwave and drawer also with motion-capture-level true noise, 0.3 mm / 0.3 deg, under the
  same assumed 2 mm / 2 deg: the thesis' rows come from a motion capture studio, and its
  0.0003 m / 0.15 deg for the microwave is below what 20 samples with 2 mm / 2 deg noise allow);
  prediction errors of every candidate on the held-out samples (against the noisy
  observations, as on real data, and against the noise-free truth), gamma and the selection.
  The simulated garage door is the roll-up path scaled by 2.
  Measured (``--runs 10``; the observation model of models/articulation/link.py): garage door GP
  in 7/10 folds at seed 0 (8, 9, 9 at seeds 1-3; thesis: GP), microwave revolute and drawer
  prismatic in 10/10. Fig. 4.25: prismatic up to n = 20, revolute at 21-22, GP from 23
  (thesis: revolute 24-28, GP from 29).
  Fig. 4.26 deviates at high assumed noise: GP up to sigma 0.05, revolute 0.1-0.5, rigid at
  1.0 (thesis: GP up to 0.02, revolute to 0.2, rigid above): the configuration prior is the
  integral along the path, not n^-d, and charges less where the noise blurs the
  configurations (see models/articulation/link.py).

The *sample error* is the mean distance between noise-free test poses and their projection
f(f^-1(z)) onto the fitted model (thesis Sec. 4.4.4). Tables are printed; plots are written to
``--out-dir`` (PNG per experiment); ``--json`` prints all numbers as one JSON object.
``--quick`` uses 2 runs and small grids (seconds; used by the test suite).

The trials run through the sweep runner (``mmlearn.apps.common.sweep``; one trial: ``--runs``
fits of one model at one grid point, the fit times at one n, one run of Fig. 4.25 / 4.26,
one object of Table 4.2, one variant of ``selection``): in parallel processes (``--jobs``,
default all cores) or as Ray tasks (``--executor ray``), streamed to ``--results``
(default ``articulation_experiments_results.jsonl`` in ``--out-dir``); re-running the same
command resumes, ``--report-only FILE`` redraws the tables and plots from a results file.
Each trial has its own random stream (``_rng``: seed, experiment, model, grid point), so its
numbers do not depend on ``--jobs`` or on the other trials. Before the sweep runner one
stream ran through all experiments in turn: the numbers of a seed changed then, not the
conclusions (``--runs 10``, seed 0, old / new: the selections of Fig. 4.25 and 4.26, of
Table 4.2's microwave and drawer and on every real track identical; Table 4.2's garage door
GP in 9/10 / 7/10 folds; the sample errors within their run-to-run spread). Fit times
(Fig. 4.24) with several jobs on few cores include the other jobs' load.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from mmlearn.apps.common import experiment
from mmlearn.apps.common.cli import check_out_dir, name_list, pos_int, save_figure
from mmlearn.apps.common.experiment import Experiment
from mmlearn.models.articulation.link import ObservationModel, make_model
from mmlearn.models.articulation.sim import simulate_link
from mmlearn.models.articulation.structure import select_link_model
from mmlearn.models.common.trials import register_trial

__all__ = ["run", "main", "EXPERIMENTS"]

EXPERIMENTS = ("noise", "outliers", "gamma", "size", "time", "bic_n", "bic_noise", "table",
               "selection")
#: (label, ObservationModel keyword arguments, identifiability tests) compared by
#: ``--only selection``; the last one is the default of models/articulation/link.py
SELECTION_VARIANTS = [
    ("before 2026-11: p(gamma) once per track, w = 1, n^-d",
     dict(gamma_prior="track", gamma_weight=1.0, config_prior="n"), False),
    ("per observation, MAP gamma, w = 92, n^-d",
     dict(gamma_prior="observation", config_prior="n"), False),
    ("per observation, ML gamma, w = 10, n^-d",
     dict(gamma_prior="plugin", gamma_weight=10.0, config_prior="n"), False),
    ("per observation, ML gamma, w = 30, n^-d",
     dict(gamma_prior="plugin", gamma_weight=30.0, config_prior="n"), False),
    ("original code: per observation, ML gamma, w = 92, n^-d",
     dict(gamma_prior="plugin", config_prior="n"), False),
    ("per observation, ML gamma, w = 92, resolved p(q)",
     dict(gamma_prior="plugin", config_prior="resolved"), False),
    ("default: + identifiability (travel above noise, bow above sigma)",
     dict(gamma_prior="plugin", config_prior="resolved"), True),
]
SELECTION_SIGMAS = (0.005, 0.01, 0.02, 0.05, 0.1)
GROUND_TRUTH = {"rigid": "rigid", "prismatic": "prismatic", "revolute": "revolute",
                "gp": "rollup"}
MODELS = ("rigid", "prismatic", "revolute", "gp")




def _sample_error(model, kind, rng, n_test=100):
    test = simulate_link(kind, n_test, sigma_pos=0.0, sigma_orient=0.0, rng=rng)
    ep, eo = model.residuals(test.Z_true)
    return float(ep.mean()), (None if eo is None else float(eo.mean()))


def _fit_err(model_name, kind, n, sp, so, gamma, rng, exact_ratio=False):
    tr = simulate_link(kind, n, sigma_pos=sp, sigma_orient=so, gamma=gamma, rng=rng,
                       exact_ratio=exact_ratio)
    m = make_model(model_name, obs=ObservationModel(sp, so)).fit(tr.Z, rng=rng)
    ep, _ = _sample_error(m, kind, rng)
    return ep, m, tr


def _try_fit_err(*a, **k):
    """_fit_err, or None when the fit raises ValueError (a failed run: counted in the
    tables' "failed" rows, left out of the means)."""
    try:
        return _fit_err(*a, **k)
    except ValueError:
        return None


def _rng(seed: int, experiment: str, *index: int):
    """The random generator of one trial: its own stream for (seed, experiment, index...),
    so that a trial's numbers do not depend on which other trials ran, in which order or
    in which process."""
    return np.random.default_rng([int(seed), EXPERIMENTS.index(experiment), *map(int, index)])


def _grid(experiment: str, quick: bool) -> list:
    """The grid of one experiment: sigma_pos [m] (noise, bic_noise: assumed), outlier ratio
    (outliers), training size n (size, time, bic_n: prefix lengths)."""
    return {
        "noise": [0.01, 0.1, 1.0] if quick else [0.001, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0],
        "outliers": [0.0, 0.5, 0.8] if quick else [0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.65,
                                                    0.7, 0.8, 0.9, 0.95],
        "size": [3, 6, 10, 20] if quick else [3, 4, 5, 6, 8, 10, 15, 20, 30, 50, 100],
        "time": [10, 30, 100] if quick else [10, 20, 30, 40, 50, 100, 200],
        "bic_n": list(range(3, (30 if quick else 50) + 1, 3 if quick else 1)),
        "bic_noise": [0.002, 0.02, 0.2, 1.0] if quick else [0.002, 0.005, 0.01, 0.02, 0.05,
                                                             0.1, 0.2, 0.5, 1.0],
    }[experiment]


# (label, link type, assumed sigma_pos [m], sigma_orient [deg], true noise pos [m], orient
# [deg]) of Table 4.2: the thesis' microwave and drawer were motion-capture recordings, whose
# true noise is far below the assumed 2 mm / 2 deg; the "mocap" rows simulate that
# (0.3 mm / 0.3 deg).
TABLE_OBJECTS = [("microwave", "microwave", 0.002, 2.0, 0.002, 2.0),
                 ("drawer", "drawer", 0.002, 2.0, 0.002, 2.0),
                 ("microwave (mocap noise)", "microwave", 0.002, 2.0, 0.0003, 0.3),
                 ("drawer (mocap noise)", "drawer", 0.002, 2.0, 0.0003, 0.3),
                 ("garage door", "garage", 0.05, 5.0, 0.05, 5.0)]


def noise_point(model: str, sigma_pos: float, runs: int, rng) -> dict:
    """Fig. 4.20 at one noise level: ``runs`` fits of ``model`` on 100 samples of its ground
    truth (sigma_orient 5 deg, no outliers); sample errors [m] of the fits that worked."""
    e = []
    for _ in range(runs):
        r = _try_fit_err(model, GROUND_TRUTH[model], 100, sigma_pos, np.deg2rad(5.0), 0.0, rng)
        if r is not None:
            e.append(r[0])
    return {"errors": e, "failed": runs - len(e)}


def outliers_point(model: str, gamma: float, runs: int, rng, exact: bool = True) -> dict:
    """Fig. 4.21 / 4.22 at one outlier ratio (sigma 0.01 m / 3 deg, n = 100): per fit that
    worked its sample error [m], estimated and true outlier ratio, and whether it had at
    most a minimal sample of inliers (unidentifiable)."""
    sp, so = 0.01, np.deg2rad(3.0)
    e, ge, gt, few = [], [], [], []
    for _ in range(runs):
        r = _try_fit_err(model, GROUND_TRUTH[model], 100, sp, so, gamma, rng, exact_ratio=exact)
        if r is None:
            continue
        ep, m, tr = r
        e.append(ep)
        ge.append(float(m.gamma))
        gt.append(float(tr.outlier.mean()))
        # at most a minimal sample of inliers: any minimal sample of outliers is as
        # consistent as the inliers, no estimator can tell which is the model
        few.append(bool(int((~tr.outlier).sum()) <= m.min_samples))
    return {"errors": e, "gamma_est": ge, "gamma_true": gt, "few_inliers": few,
            "failed": runs - len(e)}


def size_point(model: str, n: int, runs: int, rng) -> dict:
    """Fig. 4.23 at one training size (sigma 0.05 m / 5 deg): sample errors [m] of the fits
    that worked (too few samples for the model: a failed run, counted)."""
    e = []
    for _ in range(runs):
        r = _try_fit_err(model, GROUND_TRUTH[model], n, 0.05, np.deg2rad(5.0), 0.0, rng)
        if r is not None:
            e.append(r[0])
    return {"errors": e, "failed": runs - len(e)}


def time_point(n: int, runs: int, rng) -> dict:
    """Fig. 4.24 at one n: fit time [s] of each estimator on ``runs`` revolute tracks."""
    obs = ObservationModel(0.002, np.deg2rad(2.0))
    per = {m: [] for m in MODELS}
    tot = []
    for _ in range(runs):
        tr = simulate_link("revolute", n, rng=rng)
        t_all = 0.0
        for m in MODELS:
            t0 = time.perf_counter()
            make_model(m, obs=obs).fit(tr.Z, rng=rng)
            dt = time.perf_counter() - t0
            per[m].append(dt)
            t_all += dt
        tot.append(t_all)
    return {"seconds": per, "all_four_seconds": tot}


def _rollup_sequence(n_total, sp, so, rng):
    from mmlearn.models.articulation.sim import _q_range

    lo, hi = _q_range("rollup")
    q = np.linspace(lo, hi, n_total)
    return simulate_link("rollup", n_total, sigma_pos=sp, sigma_orient=so, rng=rng, q=q)


def bic_run(experiment: str, quick: bool, rng) -> dict:
    """One run of Fig. 4.25 (``bic_n``: the first n samples of a roll-up door track, sigma
    0.01 m / 2 deg, presented in the order of the configuration) or Fig. 4.26
    (``bic_noise``: 50 samples, true noise 0.002 m / 2 deg, selection under each assumed
    sigma_pos): BIC of every candidate (None: its fit failed) and the selection per grid
    point."""
    grid = _grid(experiment, quick)
    so = np.deg2rad(2.0)
    bic = {m: [] for m in MODELS}
    sel = []
    if experiment == "bic_n":
        sp = 0.01
        tr = _rollup_sequence(30 if quick else 50, sp, so, rng)
        fits = [(tr.Z[:n], ObservationModel(sp, so)) for n in grid]
    else:
        tr = _rollup_sequence(50, 0.002, so, rng)
        fits = [(tr.Z, ObservationModel(s, max(so, s))) for s in grid]
    for Z, obs in fits:
        s = select_link_model(Z, obs=obs, rng=rng)
        for m in MODELS:
            v = s.bic.get(m, np.inf)
            bic[m].append(float(v) if np.isfinite(v) else None)
        sel.append(s.selected)
    return {"bic": bic, "selected": sel}


def table_object(index: int, folds: int, rng) -> dict:
    """Table 4.2 for object ``TABLE_OBJECTS[index]``: 200 simulated samples, ``folds`` folds
    of n = 20 training samples; held-out prediction errors of every candidate (against the
    noisy observations and against the truth), gamma and the selection."""
    label, kind, sp, so_deg, true_sp, true_so_deg = TABLE_OBJECTS[index]
    obs = ObservationModel(sp, np.deg2rad(so_deg))
    data = simulate_link(kind, 200, sigma_pos=true_sp, sigma_orient=np.deg2rad(true_so_deg),
                         rng=rng)
    acc = {m: {"pos": [], "ori": [], "pos_true": [], "ori_true": [], "gamma": []}
           for m in MODELS}
    selected = []
    for _ in range(folds):
        idx = rng.permutation(200)
        tr_i, te_i = idx[:20], idx[20:]
        s = select_link_model(data.Z[tr_i], obs=obs, rng=rng)
        selected.append(s.selected)
        for m in MODELS:
            if m not in s.candidates:
                continue
            mod = s.candidates[m]
            ep, eo = mod.residuals(data.Z[te_i])
            acc[m]["pos"].append(float(np.mean(ep)))
            acc[m]["ori"].append(float(np.degrees(np.mean(eo))))
            ept, eot = mod.residuals(data.Z_true[te_i])
            acc[m]["pos_true"].append(float(np.mean(ept)))
            acc[m]["ori_true"].append(float(np.degrees(np.mean(eot))))
            acc[m]["gamma"].append(float(mod.gamma))
    vals, cnt = np.unique(selected, return_counts=True)
    return {
        "sigma_pos": sp, "sigma_orient_deg": so_deg, "folds": folds,
        "true_sigma_pos": true_sp, "true_sigma_orient_deg": true_so_deg,
        "selected_counts": {str(v): int(c) for v, c in zip(vals, cnt)},
        "models": {m: {**{k: float(np.mean(v)) for k, v in a.items() if v},
                       "folds": len(a["pos"]), "skipped_folds": folds - len(a["pos"])}
                   for m, a in acc.items()},
    }


def _expected_kind(path: str):
    name = Path(path).name.lower() + " " + Path(path).parent.name.lower()
    for key, kind in (("drawer", "prismatic"), ("door", "revolute"), ("dishwasher", "revolute"),
                      ("cosine", "gp")):
        if key in name:
            return kind
    return None


def default_track_dir():
    """The repository's copies of the real tracks (tests/data), or None when not there."""
    root = Path(__file__).resolve().parents[1] / "tests" / "data"
    return str(root) if root.is_dir() else None


def selection_tracks(tracks=None) -> list:
    """The real tracks of ``--only selection``: [(file, expected joint, poses)], each track
    once (the test data hold some twice, in two folders)."""
    from mmlearn.models.common.track_io import find_track_files, read_track

    tracks = tracks or default_track_dir()
    if tracks is None:
        raise ValueError("--only selection needs --tracks DIR (real track files)")
    files = [f for f in find_track_files([tracks]) if _expected_kind(f)]
    seen, data = set(), []
    for f in files:
        t = read_track(f).poses
        key = (t.shape, float(np.round(t.sum(), 6)))
        if key not in seen:
            seen.add(key)
            data.append((f, _expected_kind(f), t))
    if not data:
        raise ValueError(f"no drawer / door / dishwasher / cosine track files in {tracks}")
    return data


def selection_variant(index: int, data: list, quick: bool, seed: int) -> dict:
    """One observation-model variant of ``SELECTION_VARIANTS`` on the real tracks ``data``
    (right joint per assumed sigma_pos), the simulated garage door of Table 4.2 (n = 20)
    and the outlier ratio of a revolute link with 30 % outliers. The garage-door data, its
    folds and the revolute links are the same for every variant."""
    label, kw, ident = SELECTION_VARIANTS[index]
    sigmas = (0.01, 0.05) if quick else SELECTION_SIGMAS
    folds = 2 if quick else 10
    gamma_runs = 2 if quick else 10
    rng = _rng(seed, "selection", 0)
    garage = simulate_link("garage", 200, sigma_pos=0.05, sigma_orient=np.deg2rad(5.0), rng=rng)
    arcs = [simulate_link("revolute", 100, sigma_pos=0.01, sigma_orient=np.deg2rad(3.0),
                          gamma=0.3, rng=rng, exact_ratio=True) for _ in range(gamma_runs)]
    rng = _rng(seed, "selection", 1)
    kinds = sorted({k for _, k, _ in data})
    row = {"label": label, "observation_model": kw, "identifiability": ident,
           "real": {}, "rigid_at": {}}
    for s in sigmas:
        right = {k: [0, 0] for k in kinds}
        rigid = failed = 0
        for i, (f, kind, t) in enumerate(data):
            try:
                sel = select_link_model(t, obs=ObservationModel(sigma_pos=s, **kw),
                                        rng=i, identifiability=ident)
            except ValueError:  # no candidate could be fitted: counted, not dropped
                failed += 1
                right[kind][1] += 1
                continue
            right[kind][0] += sel.selected == kind
            right[kind][1] += 1
            rigid += sel.selected == "rigid"
        row["real"][str(s)] = {k: f"{a}/{b}" for k, (a, b) in right.items()}
        row["rigid_at"][str(s)] = rigid
        row.setdefault("failed_at", {})[str(s)] = failed
    obs_g = ObservationModel(0.05, np.deg2rad(5.0), **kw)
    sel_g = []
    for _ in range(folds):
        idx = rng.permutation(200)[:20]
        sel_g.append(select_link_model(garage.Z[idx], obs=obs_g, rng=rng,
                                       identifiability=ident).selected)
    row["garage_n20"] = {m: sel_g.count(m) for m in sorted(set(sel_g))}
    dev = []
    for tr in arcs:
        m = make_model("revolute", obs=ObservationModel(0.01, np.deg2rad(3.0), **kw))
        dev.append(abs(m.fit(tr.Z, rng=rng).gamma - 0.3))
    row["gamma_abs_dev_at_0.3"] = float(np.mean(dev))
    return {"row": row, "tracks": [f for f, _, _ in data], "sigma_pos": list(sigmas),
            "n_tracks": {k: sum(1 for _, kk, _ in data if kk == k) for k in kinds}}


# ---------------------------------------------------------------------------- the sweep

@register_trial("articulation.experiment")
def trial(*, seed: int, experiment: str, quick: bool = False, runs: int = 2,
          model: str | None = None, i: int = 0, x=None, exact: bool = True,
          tracks_sha1: str = "", shared=None) -> dict:
    """One trial of the sweep (``mmlearn.apps.common.sweep``), with its own random stream
    (:func:`_rng`): ``runs`` fits of ``model`` at grid point ``i`` (value ``x``) of noise /
    outliers / size, the fit times at one n (time), one run of bic_n / bic_noise (run
    ``i``), one object of Table 4.2 (``i``) or one observation-model variant of selection
    (``i``; the real tracks in ``shared``, named by ``tracks_sha1``)."""
    rng = _rng(seed, experiment, MODELS.index(model) if model else 0, i)
    if experiment == "noise":
        return noise_point(model, x, runs, rng)
    if experiment == "outliers":
        return outliers_point(model, x, runs, rng, exact=exact)
    if experiment == "size":
        return size_point(model, x, runs, rng)
    if experiment == "time":
        return time_point(x, runs, rng)
    if experiment in ("bic_n", "bic_noise"):
        return bic_run(experiment, quick, rng)
    if experiment == "table":
        return table_object(i, 3 if quick else 10, rng)
    if experiment == "selection":
        if not shared or "selection" not in shared:
            raise ValueError("the selection trial needs the real tracks in shared['selection']")
        return selection_variant(i, shared["selection"], quick, seed)
    raise ValueError(f"unknown experiment {experiment!r}; choose from {EXPERIMENTS}")


def _tracks_sha1(data) -> str:
    import hashlib

    h = hashlib.sha1()
    for f, kind, t in data:
        h.update(f"{Path(f).name}:{kind}:".encode())
        h.update(np.ascontiguousarray(t, float).tobytes())
    return h.hexdigest()


def trial_specs(*, only, runs: int, seed: int, quick: bool, exact: bool = True,
                tracks_sha1: str = "") -> list:
    """The sweep's trials of the experiments in ``only``: one per (model, grid point) of
    noise / outliers / size (``runs`` fits each), one per n of time, one per run of bic_n /
    bic_noise, one per object of Table 4.2, one per variant of selection."""
    from mmlearn.apps.common.sweep import TrialSpec

    fn = trial
    base = {"quick": quick, "runs": runs}
    specs = []

    def add(experiment, label, **p):
        specs.append(TrialSpec(fn=fn, seed=seed, label=f"{experiment} {label}",
                               params={**base, "experiment": experiment, **p}))

    exps = [e for e in EXPERIMENTS if e in only or (e == "outliers" and "gamma" in only)]
    for e in exps:
        if e in ("noise", "outliers", "size"):
            for m in MODELS:
                for i, x in enumerate(_grid(e, quick)):
                    extra = {"exact": exact} if e == "outliers" else {}
                    add(e, f"{m} {x}", model=m, i=i, x=x, **extra)
        elif e == "time":
            for i, x in enumerate(_grid(e, quick)):
                add(e, f"n {x}", i=i, x=x)
        elif e in ("bic_n", "bic_noise"):
            for r in range(1 if quick else max(1, runs // 10)):
                add(e, f"run {r}", i=r)
        elif e == "table":
            for i, obj in enumerate(TABLE_OBJECTS):
                add(e, obj[0], i=i)
        elif e == "selection":
            for i, v in enumerate(SELECTION_VARIANTS):
                add(e, f"variant {i}", i=i, tracks_sha1=tracks_sha1)
    return specs


# ---------------------------------------------------------------------------- the tables

def _point_stats(experiment, recs, grid, runs, raised=frozenset()):
    """noise / outliers / size: per model the statistics of every grid point (a point
    whose trial raised, (model, index) in ``raised``, counts as ``runs`` failed runs; one
    not run, after an interruption, as none)."""
    res = {"error_mean": {}, "error_std": {}, "failed": {}}
    if experiment == "outliers":
        res.update({k: {} for k in ("gamma_est_mean", "gamma_true_mean", "gamma_abs_dev_mean",
                                    "below_noise_up_to", "error_median",
                                    "unidentifiable_runs_pct", "error_mean_identifiable")})
    for m in MODELS:
        cols = {k: [] for k in ("mu", "sd", "nf", "med", "unid", "mu_id", "gest", "gtrue",
                                "gdev")}
        for i in range(len(grid)):
            r = recs.get((m, i))
            e = r["errors"] if r else []
            cols["nf"].append(r["failed"] if r else runs if (m, i) in raised else 0)
            if experiment != "outliers":
                cols["mu"].append(float(np.mean(e)) if e else None)
                cols["sd"].append(float(np.std(e)) if e else None)
                continue
            if not e:
                for k in ("mu", "sd", "med", "unid", "mu_id", "gest", "gtrue", "gdev"):
                    cols[k].append(None)
                continue
            cols["mu"].append(float(np.mean(e)))
            cols["sd"].append(float(np.std(e)))
            cols["med"].append(float(np.median(e)))
            few = np.asarray(r["few_inliers"], bool)
            cols["unid"].append(100.0 * float(few.mean()))
            cols["mu_id"].append(float(np.mean(np.asarray(e)[~few])) if (~few).any() else None)
            cols["gest"].append(float(np.mean(r["gamma_est"])))
            cols["gtrue"].append(float(np.mean(r["gamma_true"])))
            cols["gdev"].append(float(np.mean(np.abs(np.subtract(r["gamma_est"],
                                                                 r["gamma_true"])))))
        res["error_mean"][m], res["error_std"][m] = cols["mu"], cols["sd"]
        res["failed"][m] = cols["nf"]
        if experiment == "outliers":
            res["gamma_est_mean"][m], res["gamma_true_mean"][m] = cols["gest"], cols["gtrue"]
            res["gamma_abs_dev_mean"][m] = cols["gdev"]
            res["error_median"][m] = cols["med"]
            res["unidentifiable_runs_pct"][m] = cols["unid"]
            res["error_mean_identifiable"][m] = cols["mu_id"]
    return res


def _below(grid, values, limit):
    """Largest grid value up to which every value is below ``limit`` (None: not even the
    first)."""
    up = None
    for g, v in zip(grid, values):
        if v is not None and v < limit:
            up = g
        else:
            break
    return up


def _bic_summary(experiment, recs, quick):
    grid = _grid(experiment, quick)
    bic = {m: np.array([[np.inf if v is None else v for v in r["bic"][m]] for r in recs],
                       float).reshape(len(recs), len(grid)) for m in MODELS}
    sel = np.array([r["selected"] for r in recs], dtype=object).reshape(len(recs), len(grid))
    majority = []
    for k in range(len(grid)):
        vals, cnt = np.unique(sel[:, k].astype(str), return_counts=True)
        majority.append(str(vals[np.argmax(cnt)]) if len(cnt) else None)
    out = ({"n": grid, "sigma_pos": 0.01} if experiment == "bic_n" else
           {"assumed_sigma_pos": grid, "true_sigma_pos": 0.002, "n": 50})
    out.update({"runs": len(recs),
                "bic_mean": {m: np.mean(np.where(np.isfinite(b), b, np.nan), axis=0).tolist()
                             for m, b in bic.items()},
                "failed": {m: (~np.isfinite(b)).sum(axis=0).tolist() for m, b in bic.items()},
                "selected": majority})
    return out


def report(lines: list[dict]) -> dict:
    """Every experiment's results from results-file lines (a run or ``--report-only``); a
    trial that raised is listed in ``errors`` (its runs count as failed)."""
    if not lines:
        raise ValueError("no trial records")
    settings = {(bool(ln["spec"]["params"]["quick"]), int(ln["spec"]["params"]["runs"]),
                 ln["spec"]["seed"]) for ln in lines}
    if len(settings) > 1:
        raise ValueError("the results file mixes settings (--quick, --runs or --seed "
                         f"differ: {sorted(settings)}); use one results file per setting")
    p0 = lines[0]["spec"]["params"]
    quick, runs = bool(p0["quick"]), int(p0["runs"])
    res = {"runs": runs, "seed": lines[0]["spec"]["seed"], "quick": quick}
    by: dict[str, dict] = {}
    raised: dict[str, set] = {}
    for ln in lines:
        p = ln["spec"]["params"]
        key = (p.get("model"), p.get("i", 0))
        if ln.get("error") is None:
            by.setdefault(p["experiment"], {})[key] = ln["record"]
        else:
            by.setdefault(p["experiment"], {})
            raised.setdefault(p["experiment"], set()).add(key)
    for e in ("noise", "outliers", "size"):
        if e not in by:
            continue
        grid = _grid(e, quick)
        r = _point_stats(e, by[e], grid, runs, raised.get(e, set()))
        if e == "noise":
            res[e] = {"sigma_pos": grid, **r, "runs_per_point": runs}
        elif e == "outliers":
            r["below_noise_up_to"] = {m: _below(grid, r["error_mean"][m], 0.01)
                                      for m in MODELS}
            res[e] = {"gamma": grid, "sigma_pos": 0.01, "runs_per_point": runs, **r,
                      "outlier_sampling": "exact" if next(
                          (ln["spec"]["params"]["exact"] for ln in lines
                           if ln["spec"]["params"]["experiment"] == e), True) else "bernoulli"}
        else:
            conv = {}
            for m in MODELS:
                conv[m] = next((n for n, v in zip(grid, r["error_mean"][m])
                                if v is not None and v < 0.05), None)
            res[e] = {"n": grid, "sigma_pos": 0.05, **r, "converged_n": conv,
                      "runs_per_point": runs}
    if "time" in by:
        grid = _grid("time", quick)
        recs = [by["time"].get((None, i)) for i in range(len(grid))]
        res["time"] = {"n": grid,
                       "seconds": {m: [float(np.median(r["seconds"][m])) if r else None
                                       for r in recs] for m in MODELS},
                       "all_four_seconds": [float(np.median(r["all_four_seconds"])) if r
                                            else None for r in recs]}
    for e in ("bic_n", "bic_noise"):
        if e in by:
            recs = [by[e][k] for k in sorted(by[e], key=lambda k: k[1])]
            res[e] = _bic_summary(e, recs, quick)
    if "table" in by:
        res["table"] = {TABLE_OBJECTS[i][0]: by["table"][(None, i)]
                        for i in range(len(TABLE_OBJECTS)) if (None, i) in by["table"]}
    if "selection" in by and by["selection"]:
        recs = [by["selection"][k] for k in sorted(by["selection"], key=lambda k: k[1])]
        res["selection"] = {"tracks": recs[0]["tracks"], "sigma_pos": recs[0]["sigma_pos"],
                            "variants": [r["row"] for r in recs],
                            "n_tracks": recs[0]["n_tracks"]}
    res["errors"] = [{"trial": ln["spec"].get("label") or ln["key"], "error": ln["error"]}
                     for ln in lines if ln.get("error") is not None]
    return res


def _plots(res, out_dir: Path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir.mkdir(parents=True, exist_ok=True)
    written = []

    def save(fig, name):
        p = out_dir / name
        fig.tight_layout()
        save_figure(fig, p, dpi=100)
        plt.close(fig)
        written.append(str(p))

    if "noise" in res:
        r = res["noise"]
        fig, ax = plt.subplots(figsize=(5, 3.5))
        for m in MODELS:
            mu = np.array([np.nan if v is None else v for v in r["error_mean"][m]])
            sd = np.array([np.nan if v is None else v for v in r["error_std"][m]])
            ax.plot(r["sigma_pos"], mu, "o-", label=m)
            ax.fill_between(r["sigma_pos"], mu - sd, mu + sd, alpha=0.15)
        ax.plot(r["sigma_pos"], r["sigma_pos"], "k--", lw=0.8, label="noise level")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("sigma_pos [m]")
        ax.set_ylabel("sample error [m]")
        ax.set_title("Fig. 4.20: error vs Gaussian noise")
        ax.legend(fontsize=7)
        save(fig, "fig4_20_noise.png")
    if "outliers" in res:
        r = res["outliers"]
        fig, ax = plt.subplots(figsize=(5, 3.5))
        for m in MODELS:
            ax.plot(r["gamma"], [np.nan if v is None else v for v in r["error_mean"][m]],
                    "o-", label=m)
        ax.axhline(r["sigma_pos"], color="k", ls="--", lw=0.8, label="noise level")
        ax.set_yscale("log")
        ax.set_xlabel("outlier ratio gamma")
        ax.set_ylabel("sample error [m]")
        ax.set_title("Fig. 4.21: error vs outlier ratio")
        ax.legend(fontsize=7)
        save(fig, "fig4_21_outliers.png")
        fig, ax = plt.subplots(figsize=(4.5, 4))
        for m in MODELS:
            ax.plot([np.nan if v is None else v for v in r["gamma_true_mean"][m]],
                    [np.nan if v is None else v for v in r["gamma_est_mean"][m]], "o-", label=m)
        ax.plot([0, 1], [0, 1], "k--", lw=0.8)
        ax.set_xlabel("true gamma")
        ax.set_ylabel("estimated gamma")
        ax.set_title("Fig. 4.22: estimated vs true outlier ratio")
        ax.legend(fontsize=7)
        save(fig, "fig4_22_gamma.png")
    if "size" in res:
        r = res["size"]
        fig, ax = plt.subplots(figsize=(5, 3.5))
        for m in MODELS:
            ax.plot(r["n"], [np.nan if v is None else v for v in r["error_mean"][m]], "o-",
                    label=m)
        ax.axhline(r["sigma_pos"], color="k", ls="--", lw=0.8, label="noise level")
        ax.set_yscale("log")
        ax.set_xlabel("training size n")
        ax.set_ylabel("sample error [m]")
        ax.set_title("Fig. 4.23: error vs training size")
        ax.legend(fontsize=7)
        save(fig, "fig4_23_size.png")
    if "time" in res:
        r = res["time"]
        fig, ax = plt.subplots(figsize=(5, 3.5))
        nan = lambda vs: [np.nan if v is None else v for v in vs]  # noqa: E731
        for m in MODELS:
            ax.plot(r["n"], nan(r["seconds"][m]), "o-", label=m)
        ax.plot(r["n"], nan(r["all_four_seconds"]), "k-", label="all four")
        ax.set_xlabel("training size n")
        ax.set_ylabel("time [s]")
        ax.set_title("Fig. 4.24: fit time")
        ax.legend(fontsize=7)
        save(fig, "fig4_24_time.png")
    for key, xk, title, fname in [("bic_n", "n", "Fig. 4.25: BIC vs n (roll-up door)",
                                   "fig4_25_bic_n.png"),
                                  ("bic_noise", "assumed_sigma_pos",
                                   "Fig. 4.26: BIC vs assumed noise (n = 50)",
                                   "fig4_26_bic_noise.png")]:
        if key not in res:
            continue
        r = res[key]
        fig, ax = plt.subplots(figsize=(5.5, 3.8))
        for m in MODELS:
            ax.plot(r[xk], r["bic_mean"][m], ".-", label=m)
        if key == "bic_noise":
            ax.set_xscale("log")
        ax.set_xlabel(xk)
        ax.set_ylabel("BIC")
        ax.set_title(title, fontsize=9)
        ax.legend(fontsize=7)
        save(fig, fname)
    return written


def _f(v, w, d):
    return " " * (w - 3) + "n/a" if v is None else f"{v:{w}.{d}f}"


def _print_failed(p, r, w):
    """The "failed" row under a table: runs whose fit raised, left out of the means."""
    for m in MODELS:
        p(f"{'  failed':9s} " + " ".join(f"{v:{w}d}" for v in r["failed"][m])
          + f"   ({m}: runs left out of the mean, of {r.get('runs_per_point', '?')})")


def _print(res, file=None):
    p = lambda *a: print(*a, file=file or sys.stdout)  # noqa: E731
    if "noise" in res:
        r = res["noise"]
        p("\nFig. 4.20  sample error [m] vs Gaussian noise sigma_pos (n = 100, gamma = 0)")
        p("sigma_pos " + " ".join(f"{s:>9.3f}" for s in r["sigma_pos"]))
        for m in MODELS:
            p(f"{m:9s} " + " ".join("      n/a" if v is None else f"{v:9.4f}"
                                    for v in r["error_mean"][m]))
        _print_failed(p, r, 9)
    if "outliers" in res:
        r = res["outliers"]
        p(f"\nFig. 4.21  sample error [m] vs outlier ratio (sigma_pos = {r['sigma_pos']} m)")
        p("gamma     " + " ".join(f"{g:>7.2f}" for g in r["gamma"]))
        for m in MODELS:
            p(f"{m:9s} " + " ".join(_f(v, 7, 4) for v in r["error_mean"][m])
              + f"   below noise up to gamma = {r['below_noise_up_to'][m]}")
        _print_failed(p, r, 7)
        p("median error / mean error over runs with more inliers than a minimal sample / "
          "% runs with at most a minimal sample of inliers (unidentifiable)")
        for m in MODELS:
            p(f"{m:9s} " + " ".join(_f(v, 7, 4) for v in r["error_median"][m]))
            p(f"{'  ident.':9s} " + " ".join(_f(v, 7, 4)
                                             for v in r["error_mean_identifiable"][m]))
            p(f"{'  % unid.':9s} " + " ".join(_f(v, 7, 1)
                                              for v in r["unidentifiable_runs_pct"][m]))
        p("\nFig. 4.22  estimated gamma (mean) / mean |estimated - true|")
        for m in MODELS:
            p(f"{m:9s} " + " ".join(_f(v, 7, 3) for v in r["gamma_est_mean"][m]))
            p(f"{'  |dev|':9s} " + " ".join(_f(v, 7, 3) for v in r["gamma_abs_dev_mean"][m]))
    if "size" in res:
        r = res["size"]
        p(f"\nFig. 4.23  sample error [m] vs training size (sigma_pos = {r['sigma_pos']} m)")
        p("n         " + " ".join(f"{n:>7d}" for n in r["n"]))
        for m in MODELS:
            p(f"{m:9s} " + " ".join("    n/a" if v is None else f"{v:7.4f}"
                                    for v in r["error_mean"][m])
              + f"   below noise from n = {r['converged_n'][m]}")
        _print_failed(p, r, 7)
    if "time" in res:
        r = res["time"]
        p("\nFig. 4.24  median fit time [ms] vs n")
        p("n         " + " ".join(f"{n:>7d}" for n in r["n"]))
        ms = lambda vs: " ".join("    n/a" if v is None else f"{1e3 * v:7.1f}"  # noqa: E731
                                 for v in vs)
        for m in MODELS:
            p(f"{m:9s} " + ms(r["seconds"][m]))
        p(f"{'all four':9s} " + ms(r["all_four_seconds"]))
    for key, xk, title in [("bic_n", "n", "Fig. 4.25  selection vs n (roll-up door)"),
                           ("bic_noise", "assumed_sigma_pos",
                            "Fig. 4.26  selection vs assumed sigma_pos (roll-up door, n = 50)")]:
        if key not in res:
            continue
        r = res[key]
        p(f"\n{title}")
        runs_ = []
        cur, start, prev = None, None, None
        for x, s in zip(r[xk], r["selected"]):
            if s != cur:
                if cur is not None:
                    runs_.append(f"{cur} [{start}..{prev}]")
                cur, start = s, x
            prev = x
        runs_.append(f"{cur} [{start}..{prev}]")
        p("  " + ", ".join(runs_))
        nf = {m: int(sum(v)) for m, v in r.get("failed", {}).items() if sum(v)}
        p(f"  candidate fits that failed (left out of the BIC means and the selection), of "
          f"{r['runs'] * len(r[xk])}: " + (", ".join(f"{m} {c}" for m, c in nf.items())
                                          if nf else "none"))
    if "selection" in res:
        r = res["selection"]
        p(f"\nSelection on {sum(r['n_tracks'].values())} real tracks {r['n_tracks']}: right "
          "joint per assumed sigma_pos (prismatic / revolute / gp), tracks selected rigid; "
          "Table 4.2 garage door (n = 20) selections; mean |gamma - 0.3| of a revolute link")
        for v in r["variants"]:
            p(f"  {v['label']}")
            for s_ in r["sigma_pos"]:
                rr = v["real"][str(s_)]
                p(f"    sigma {s_:<6g} " + "  ".join(f"{k} {rr[k]}" for k in sorted(rr))
                  + f"   rigid {v['rigid_at'][str(s_)]}"
                  + f"   failed {v.get('failed_at', {}).get(str(s_), 0)}")
            p(f"    garage door {v['garage_n20']}   |gamma - 0.3| "
              f"{v['gamma_abs_dev_at_0.3']:.3f}")
    if "table" in res:
        p("\nTable 4.2  held-out prediction error (vs noisy obs. | vs truth), 10-fold, n = 20;"
          " a candidate whose fit failed in a fold is left out of that fold's mean (folds "
          "used / skipped)")
        for obj, r in res["table"].items():
            p(f"{obj} (assumed sigma {r['sigma_pos']} m / {r['sigma_orient_deg']} deg, true "
              f"{r['true_sigma_pos']} m / {r['true_sigma_orient_deg']} deg), selected: "
              f"{r['selected_counts']}")
            for m in MODELS:
                a = r["models"].get(m, {})
                if not a.get("folds"):
                    continue
                p(f"  {m:9s} pos {a['pos']:.4f} | {a['pos_true']:.4f} m   orient "
                  f"{a['ori']:6.2f} | {a['ori_true']:6.2f} deg   gamma {a['gamma']:.3f}   "
                  f"folds {a['folds']} / skipped {a['skipped_folds']}")
            for m in MODELS:
                a = r["models"].get(m, {})
                if not a.get("folds"):
                    p(f"  {m:9s} fit failed in all {r['folds']} folds")
    for e in res.get("errors", []):
        p(f"error: trial {e['trial']} raised {e['error']} (its runs count as failed above)")


class ArticulationExperiments(Experiment):
    name = "articulation_experiments"
    description = ("Synthetic robustness / convergence analysis of the articulation models "
                   "(thesis Sec. 4.4.4, Fig. 4.20-4.26) and Table 4.2. Every table gives the "
                   "number of failed runs (left out of its means). The trials run through "
                   "the sweep runner (resumable, local processes or Ray). Exit status: 0 "
                   "every trial ran, 1 a trial raised an error, 2 bad input.")
    json_help = "print all results as JSON"
    desc = "articulation trials"

    def __init__(self):
        self._tracks = {}

    def add_arguments(self, ap):
        ap.add_argument("--runs", type=pos_int, default=100, help="repetitions (thesis: 100)")
        ap.add_argument("--quick", action="store_true", help="2 runs, small grids (seconds)")
        ap.add_argument("--only", type=name_list(EXPERIMENTS), default=list(EXPERIMENTS),
                        help=f"comma-separated subset of {','.join(EXPERIMENTS)}")
        ap.add_argument("--out-dir", default="articulation_experiments_out",
                        help="folder for the plots and the default results file ('' for no "
                             "plots; the results file then goes to the current folder)")
        ap.add_argument("--outliers", choices=("exact", "bernoulli"), default="exact",
                        help="outlier sampling of Fig. 4.21/4.22: exactly round(gamma n) "
                             "outliers per sequence (default) or each observation with "
                             "probability gamma")
        ap.add_argument("--tracks", default=None,
                        help="real track files or folder for --only selection (default: the "
                             "repository's tests/data copies)")

    def check(self, args):
        check_out_dir("--out-dir", args.out_dir)

    def _only(self, args) -> list:
        only = args.only
        only = [o.strip() for o in (only.split(",") if isinstance(only, str) else only)]
        bad = [o for o in only if o not in EXPERIMENTS]
        if bad:
            raise ValueError(f"unknown experiment(s) {bad}; choose from {EXPERIMENTS}")
        return only

    def _selection(self, args):
        """The real tracks of ``selection`` (read once) and their SHA-1."""
        if "selection" not in self._only(args):
            return None, ""
        if "data" not in self._tracks:
            data = selection_tracks(args.tracks)
            self._tracks.update(data=data, sha1=_tracks_sha1(data))
        return {"selection": self._tracks["data"]}, self._tracks["sha1"]

    def specs(self, args):
        if args.outliers not in ("exact", "bernoulli"):
            raise ValueError(f"outliers must be 'exact' or 'bernoulli', got {args.outliers!r}")
        runs = min(args.runs, 2) if args.quick else args.runs
        return trial_specs(only=self._only(args), runs=runs, seed=args.seed,
                           quick=args.quick, exact=(args.outliers == "exact"),
                           tracks_sha1=self._selection(args)[1])

    def shared(self, args):
        return self._selection(args)[0]

    def report(self, lines, args):
        if lines:
            return report(lines)
        return {"runs": min(args.runs, 2) if args.quick else args.runs, "seed": args.seed,
                "quick": args.quick, "errors": []}

    def finish(self, res, args):
        res["plots"] = _plots(res, Path(args.out_dir)) if args.out_dir else []
        return res

    def print_table(self, res, args):
        _print(res)
        if res["plots"]:
            print("\nplots: " + ", ".join(res["plots"]))

    def to_json(self, res):
        return json.dumps(res, indent=1, default=float)


def run(*, runs: int = 100, seed: int = 0, quick: bool = False, only=EXPERIMENTS,
        out_dir: str | None = "articulation_experiments_out", progress: bool = True,
        outliers: str = "exact", tracks: str | None = None, results: str | None = None,
        executor: str = "local", jobs: int | None = None,
        ray_address: str | None = None) -> dict:
    """Run the selected experiments; returns a dict of results (plus "plots": written
    files, "errors": trials that raised). ``outliers``: "exact" (exactly round(gamma n)
    outliers per training sequence) or "bernoulli" (each observation an outlier with
    probability gamma).

    The trials (:func:`trial_specs`) run through the sweep runner (``mmlearn.apps.common.sweep``):
    streamed to ``results`` (a JSON Lines file; None: a temporary one; trials already in it
    are not run again), ``executor`` "local" (``jobs`` processes, default all cores) or
    "ray" (``ray_address``: a cluster, None: a local Ray instance of ``jobs`` CPUs). The
    real tracks of ``selection`` are read here and sent once (``shared``)."""
    args = argparse.Namespace(runs=runs, seed=seed, quick=quick, only=only, out_dir=out_dir,
                              json=not progress, outliers=outliers, tracks=tracks)
    return experiment.run_experiment(ArticulationExperiments(), args, results=results,
                                     executor=executor, jobs=jobs, ray_address=ray_address)


def main(argv=None) -> int:
    return experiment.main(ArticulationExperiments(), argv)


if __name__ == "__main__":
    sys.exit(main())
