"""The articulation capability's experiments in numpy: the metrics of an opening trial
(thesis 4.4.2) and the synthetic analysis of the link models (Sec. 4.4.4, Fig. 4.20-4.26,
Table 4.2, and the observation-model variants on real tracks), as trials of the sweep runner
(:func:`link_experiment_trial`, registered as ``articulation.experiment``) and the report of
their records (:func:`link_experiments_report`); the app ``articulation_experiments``
describes each experiment."""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from mmlearn.models.articulation.link import ObservationModel, make_model
from mmlearn.models.articulation.sim import simulate_link
from mmlearn.models.articulation.structure import select_link_model
from mmlearn.models.common.trials import register_trial

__all__ = ["SUCCESS_ANGLE", "SUCCESS_DISTANCE", "evaluate_model", "right_kind",
           "operate_error_record", "operate_records", "summarize_operate",
           "operate_report", "LINK_EXPERIMENTS", "LINK_MODELS", "SELECTION_VARIANTS",
           "SELECTION_SIGMAS", "GROUND_TRUTH", "TABLE_OBJECTS", "link_grid",
           "noise_point", "outliers_point", "size_point", "time_point", "bic_run",
           "table_object", "default_track_dir", "selection_tracks", "selection_variant",
           "link_experiment_trial", "tracks_sha1", "link_experiments_report",
           "sensor_stats", "sensor_line", "STRUCTURE_EXPERIMENTS",
           "STRUCTURE_SCENARIOS", "yardstick_summary", "dof_progress_summary",
           "search_vs_n_summary", "structure_report"]

SUCCESS_ANGLE = math.radians(60)  # thesis: opened > 60 deg (revolute) ...
SUCCESS_DISTANCE = 0.3            # ... or > 0.3 m (prismatic)


def _angle_between(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    c = abs(float(np.dot(a, b) / (np.linalg.norm(a) * np.linalg.norm(b))))
    return math.degrees(math.acos(min(1.0, c)))


def evaluate_model(link, spec) -> dict:
    """Compare the learned link model with the mechanism's true joint: axis direction and,
    for a revolute joint, the radius of the handle bar's circle (the hook's seat, which the
    estimator tracks, holds the bar's centre)."""
    axis_true, point = spec.axis_world()
    out = {"learned_model": None if link is None else link.name, "radius_m": None,
           "true_radius_m": None, "radius_error_m": None, "axis_error_deg": None}
    if link is None:
        return out
    if link.name in ("revolute", "prismatic"):
        out["axis_error_deg"] = _angle_between(link.axis, axis_true)
    if link.name == "revolute" and spec.is_revolute:
        d = spec.handle_world(0.0)[0] - point
        r_true = float(np.linalg.norm(d - np.dot(d, axis_true) * axis_true))
        out.update(radius_m=float(link.radius), true_radius_m=r_true,
                   radius_error_m=abs(float(link.radius) - r_true))
    return out


def right_kind(model_log, right: str) -> tuple[bool, float | None]:
    """Whether the model at the end of a trial was the right kind, and from which opening on.

    ``model_log``: the trial's records ``(time s, true opening, model kind or None)`` in time
    order; ``right``: the true kind ("revolute" or "prismatic"). Returns ``(ok, opening)``:
    ``ok`` is True when the last record has the right kind, ``opening`` the true opening at
    the first record of the final unbroken run of right-kind records (None when not ok)."""
    if not model_log or model_log[-1][2] != right:
        return False, None
    k = len(model_log) - 1
    while k > 0 and model_log[k - 1][2] == right:
        k -= 1
    return True, float(model_log[k][1])


# ---------------------------------------------------------------------------- opening trials

def operate_error_record(kind: str, seed: int, error: str) -> dict:
    """The table's record of a trial that raised: an error (not a failed opening), with its
    reason."""
    revolute = kind in ("left_door", "right_door", "dishwasher")
    return {"object": kind, "seed": seed, "success": False, "opened": None,
            "unit": "deg" if revolute else "m", "outcome": f"error: {error}", "error": error,
            "learned_model": None, "radius_error_m": None, "axis_error_deg": None,
            "right_kind": False, "right_model_at": None,
            "true_kind": "revolute" if revolute else "prismatic",
            "model_log": [], "sim_seconds": 0.0, "wall_seconds": 0.0}


def operate_records(lines: list[dict]) -> list[dict]:
    """Table records from results-file lines: a trial that raised becomes an error record."""
    out = []
    for ln in lines:
        if ln.get("error") is None:
            out.append(ln["record"])
        else:
            p = ln["spec"]["params"]
            name = (f"{str(p['model']).replace(chr(92), '/').rsplit('/', 1)[-1]}:{p.get('joint')}"
                    if p.get("model") else p.get("kind", "?"))
            out.append(operate_error_record(name, ln["spec"]["seed"], ln["error"]))
    return out


def summarize_operate(trials: list[dict]) -> dict:
    """Per-object success rate, mean opening, radius and axis errors, and how many trials
    ended with the right kind of model (and the mean opening from which it held). Trials
    that raised (``"error"`` in the record) are counted in ``errors`` and left out of every
    mean and of ``trials``/``successes``/``right_kind``; ``radius_runs`` / ``axis_runs`` /
    ``right_model_runs`` say how many trials each mean is over."""
    def mean(xs):
        return float(np.mean(xs)) if xs else None

    def largest(xs):
        return float(np.max(xs)) if xs else None

    table = {}
    for kind in dict.fromkeys(t["object"] for t in trials):
        mine = [t for t in trials if t["object"] == kind]
        ts = [t for t in mine if not t.get("error")]
        radius = [t["radius_error_m"] for t in ts if t.get("radius_error_m") is not None]
        right_at = [t["right_model_at"] for t in ts if t.get("right_model_at") is not None]
        axis = [t["axis_error_deg"] for t in ts if t.get("axis_error_deg") is not None]
        handle = [t["handle_error_m"] for t in ts if t.get("handle_error_m") is not None]
        table[kind] = {
            "trials": len(ts),
            "errors": len(mine) - len(ts),
            "successes": sum(t["success"] for t in ts),
            "radius_runs": len(radius), "axis_runs": len(axis), "right_model_runs": len(right_at),
            "mean_opened": mean([t["opened"] for t in ts]),
            "unit": mine[0]["unit"],
            "mean_radius_error_m": mean(radius),
            "max_radius_error_m": largest(radius),
            "mean_axis_error_deg": mean(axis),
            "no_front": sum(t.get("front_found") is False for t in ts),
            "mean_handle_error_m": mean(handle), "max_handle_error_m": largest(handle),
            "right_kind": sum(bool(t.get("right_kind")) for t in ts),
            "success_and_right_kind": sum(bool(t["success"] and t.get("right_kind"))
                                          for t in ts),
            "mean_right_model_at": mean(right_at),
            "max_right_model_at": largest(right_at),
            "models": {m: sum(t["learned_model"] == m for t in ts)
                       for m in dict.fromkeys(t["learned_model"] for t in ts)},
        }
    return table


def operate_report(lines: list[dict]) -> dict:
    """The results of opening trials (thesis 4.4.2) from results-file lines: every trial's
    record, the success and right-kind rates, :func:`summarize_operate`'s table."""
    results = operate_records(lines)
    n_ok = sum(bool(r["success"]) for r in results)
    n_err = sum(1 for r in results if r.get("error"))
    n_run = len(results) - n_err
    n_kind = sum(bool(r.get("right_kind")) for r in results if not r.get("error"))
    first = next((r for r in results if "sigma_pos" in r), {})
    return {"trials": results, "success_rate": n_ok / n_run if n_run else None,
            "successes": n_ok, "errors": n_err, "total": n_run,
            "right_kind": n_kind, "right_kind_rate": n_kind / n_run if n_run else None,
            "per_object": summarize_operate(results),
            "sigma_pos": first.get("sigma_pos"),
            "base_noise": first.get("base_noise"),
            "perception": first.get("perception", "click"),
            "trial_seconds": round(sum(ln.get("wall_s") or 0.0 for ln in lines), 1),
            "wall_seconds": None}


# ---------------------------------------------------------------------------- link models

#: the experiments of the app articulation_experiments
LINK_EXPERIMENTS = ("noise", "outliers", "gamma", "size", "time", "bic_n", "bic_noise",
                    "table", "selection")
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
LINK_MODELS = ("rigid", "prismatic", "revolute", "gp")




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
    return np.random.default_rng([int(seed), LINK_EXPERIMENTS.index(experiment), *map(int, index)])


def link_grid(experiment: str, quick: bool) -> list:
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
    per = {m: [] for m in LINK_MODELS}
    tot = []
    for _ in range(runs):
        tr = simulate_link("revolute", n, rng=rng)
        t_all = 0.0
        for m in LINK_MODELS:
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
    grid = link_grid(experiment, quick)
    so = np.deg2rad(2.0)
    bic = {m: [] for m in LINK_MODELS}
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
        for m in LINK_MODELS:
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
           for m in LINK_MODELS}
    selected = []
    for _ in range(folds):
        idx = rng.permutation(200)
        tr_i, te_i = idx[:20], idx[20:]
        s = select_link_model(data.Z[tr_i], obs=obs, rng=rng)
        selected.append(s.selected)
        for m in LINK_MODELS:
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
    root = Path(__file__).resolve().parents[2] / "tests" / "data"
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
def link_experiment_trial(*, seed: int, experiment: str, quick: bool = False, runs: int = 2,
                          model: str | None = None, i: int = 0, x=None, exact: bool = True,
                          tracks_sha1: str = "", shared=None) -> dict:
    """One trial of the link-model experiments (the sweep's trial function), with its own
    random stream (:func:`_rng`): ``runs`` fits of ``model`` at grid point ``i`` (value ``x``) of noise /
    outliers / size, the fit times at one n (time), one run of bic_n / bic_noise (run
    ``i``), one object of Table 4.2 (``i``) or one observation-model variant of selection
    (``i``; the real tracks in ``shared``, named by ``tracks_sha1``)."""
    rng = _rng(seed, experiment, LINK_MODELS.index(model) if model else 0, i)
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
    raise ValueError(f"unknown experiment {experiment!r}; choose from {LINK_EXPERIMENTS}")


def tracks_sha1(data) -> str:
    import hashlib

    h = hashlib.sha1()
    for f, kind, t in data:
        h.update(f"{Path(f).name}:{kind}:".encode())
        h.update(np.ascontiguousarray(t, float).tobytes())
    return h.hexdigest()


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
    for m in LINK_MODELS:
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
    grid = link_grid(experiment, quick)
    bic = {m: np.array([[np.inf if v is None else v for v in r["bic"][m]] for r in recs],
                       float).reshape(len(recs), len(grid)) for m in LINK_MODELS}
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


def link_experiments_report(lines: list[dict]) -> dict:
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
        grid = link_grid(e, quick)
        r = _point_stats(e, by[e], grid, runs, raised.get(e, set()))
        if e == "noise":
            res[e] = {"sigma_pos": grid, **r, "runs_per_point": runs}
        elif e == "outliers":
            r["below_noise_up_to"] = {m: _below(grid, r["error_mean"][m], 0.01)
                                      for m in LINK_MODELS}
            res[e] = {"gamma": grid, "sigma_pos": 0.01, "runs_per_point": runs, **r,
                      "outlier_sampling": "exact" if next(
                          (ln["spec"]["params"]["exact"] for ln in lines
                           if ln["spec"]["params"]["experiment"] == e), True) else "bernoulli"}
        else:
            conv = {}
            for m in LINK_MODELS:
                conv[m] = next((n for n, v in zip(grid, r["error_mean"][m])
                                if v is not None and v < 0.05), None)
            res[e] = {"n": grid, "sigma_pos": 0.05, **r, "converged_n": conv,
                      "runs_per_point": runs}
    if "time" in by:
        grid = link_grid("time", quick)
        recs = [by["time"].get((None, i)) for i in range(len(grid))]
        res["time"] = {"n": grid,
                       "seconds": {m: [float(np.median(r["seconds"][m])) if r else None
                                       for r in recs] for m in LINK_MODELS},
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


# ---------------------------------------------------------------------------- structure

def sensor_stats(track) -> dict:
    """What the sensor saw of a track: per part the share of samples with a pose, the
    median position error (m) and the share of orientations off by > 20 deg, against the
    true marker poses."""
    from scipy.spatial.transform import Rotation

    out = {}
    for k, part in enumerate(track.parts):
        P, Pt = track.poses[k], track.poses_true[k]
        ok = np.isfinite(P).all(axis=1)
        rec = {"seen": float(ok.mean()), "pos_median_m": None, "flipped": None}
        if ok.any():
            rec["pos_median_m"] = float(np.median(np.linalg.norm(P[ok, :3] - Pt[ok, :3],
                                                                 axis=1)))
            ang = (Rotation.from_quat(Pt[ok, 3:]).inv() * Rotation.from_quat(P[ok, 3:])
                   ).magnitude()
            rec["flipped"] = float(np.mean(ang > np.radians(20)))
        out[part] = rec
    return out


def sensor_line(name, stats) -> str:
    """One table line of :func:`sensor_stats` of the track ``name``."""
    return f"camera ({name}): " + "; ".join(
        f"{p} seen {r['seen']:.2f}" + ("" if r["pos_median_m"] is None else
                                        f", {1000 * r['pos_median_m']:.1f} mm, "
                                        f"{100 * r['flipped']:.0f} % > 20 deg")
        for p, r in stats.items())


#: the structure experiments of the app structure_experiments
STRUCTURE_EXPERIMENTS = ("fig48", "fig49", "fig411", "garage", "fig416", "fig417", "fig418")
#: the structure experiments that are one trial each (their table is the trial's record)
STRUCTURE_SCENARIOS = ("fig48", "fig49", "fig411", "garage")


def yardstick_summary(rows):
    """Fig. 4.16's summary and table lines from the runs of :func:`yardstick_row`."""
    rows = sorted(rows, key=lambda r: (r["closed"], r["seed"]))
    seeds = len({r["seed"] for r in rows})
    n = rows[0]["n"] if rows else 0
    summ = {}
    for closed, want in ((False, 3), (True, 1)):
        rr = [r for r in rows if r["closed"] == closed]
        if not rr:
            continue
        t_l = np.mean([r["search_seconds_local"] for r in rr])
        t_x = np.mean([r["search_seconds_exhaustive"] for r in rr])
        t_f = np.mean([r["fit_seconds"] for r in rr])
        c_l = np.mean([r["search_cpu_seconds_local"] for r in rr])
        c_x = np.mean([r["search_cpu_seconds_exhaustive"] for r in rr])
        c_f = np.mean([r["fit_cpu_seconds"] for r in rr])
        summ["closed" if closed else "open"] = {
            "right_dof": int(sum(r["dof_local"] == want for r in rr)), "runs": len(rr),
            "expected_dof": want,
            "mean_gap_local_pct": float(np.mean([r["gap_local_pct"] for r in rr])),
            "max_gap_local_pct": float(np.max([r["gap_local_pct"] for r in rr])),
            "mean_gap_tree_pct": float(np.mean([r["gap_tree_pct"] for r in rr])),
            "local_optimal_pct": 100.0 * float(np.mean([r["local_optimal"] for r in rr])),
            "search_seconds_local": float(t_l), "search_seconds_exhaustive": float(t_x),
            "pair_fit_seconds": float(t_f),
            "speedup_search": float(t_x / t_l), "speedup_total": float((t_x + t_f) / (t_l + t_f)),
            # CPU time of the trial's process (wall time counts other processes' load on a
            # shared machine); the thesis' "82.6% less time" (Fig. 4.18) compares the graph
            # search alone: both searches need every pair's link model (the spanning tree
            # of Eq. 4.40 starts from all of them)
            "search_cpu_seconds_local": float(c_l), "search_cpu_seconds_exhaustive": float(c_x),
            "pair_fit_cpu_seconds": float(c_f),
            "speedup_search_cpu": float(c_x / c_l),
            "speedup_total_cpu": float((c_x + c_f) / (c_l + c_f)),
            "graphs_local_mean": float(np.mean([r["graphs_local"] for r in rr])),
            "graphs_exhaustive_mean": float(np.mean([r["graphs_exhaustive"] for r in rr])),
            "loops_selected": int(sum(r["has_loop"] for r in rr)),
            "mean_gap_true_graph_pct": float(np.mean(
                [100 * (r["bic_true_graph"] - r["bic_exhaustive"]) / abs(r["bic_exhaustive"])
                 for r in rr])),
            "true_graph_right_dof": int(sum(r["dof_true_graph"] == want for r in rr)),
        }
    lines = [f"Fig. 4.16  yardstick, n = {n}, {seeds} seeds, local search with DOF reduction",
             "object  right DOF  loop sel.  gap local/exh. (mean/max %)  gap tree %  "
             "local optimal %  search s local/exh.  speed-up search/total"]
    for key, s in summ.items():
        lines.append(f"{key:6s}  {s['right_dof']:4d}/{s['runs']:<4d}  {s['loops_selected']:9d}  "
                     f"{s['mean_gap_local_pct']:12.2f} / {s['max_gap_local_pct']:6.2f}  "
                     f"{s['mean_gap_tree_pct']:10.2f}  {s['local_optimal_pct']:15.0f}  "
                     f"{s['search_seconds_local']:8.2f} / {s['search_seconds_exhaustive']:6.2f}  "
                     f"{s['speedup_search']:8.1f} / {s['speedup_total']:4.1f}")
    lines.append("CPU time (the trial's process): search local / exhaustive s, pair fits s, "
                 "speed-up search / total, graphs evaluated local / exhaustive")
    for key, s in summ.items():
        lines.append(f"{key:6s}  {s['search_cpu_seconds_local']:6.2f} / "
                     f"{s['search_cpu_seconds_exhaustive']:6.2f}  {s['pair_fit_cpu_seconds']:6.2f}"
                     f"  {s['speedup_search_cpu']:5.1f} / {s['speedup_total_cpu']:4.1f}  "
                     f"{s['graphs_local_mean']:5.1f} / {s['graphs_exhaustive_mean']:4.1f}")
    for key, s in summ.items():
        lines.append(f"{key}: true graph (chain{' + loop' if key == 'closed' else ''}) with "
                     f"PCA DOFs: right DOF {s['true_graph_right_dof']}/{s['runs']}, BIC "
                     f"{s['mean_gap_true_graph_pct']:.2f} % above the exhaustive optimum")
    for r in rows:
        if r.get("sensor_stats"):
            lines.append(sensor_line(f"{'closed' if r['closed'] else 'open'} seed "
                                      f"{r['seed']}", r["sensor_stats"]))
    ex = [r for r in rows if r["closed"]]
    if ex:
        lines.append("closed, seed %d: %s" % (ex[0]["seed"], ", ".join(
            f"{m}({a},{b})" for a, b, m in ex[0]["edges_local"])))
    return {"runs": rows, "summary": summ}, lines


def dof_progress_summary(by_key: dict):
    """Fig. 4.17's result and table lines from {"open_staged" / "closed": dofs}."""
    step = 20
    out = {k: by_key[k] for k in ("open_staged", "closed") if k in by_key}
    lines = [f"Fig. 4.17  estimated DOFs while the data arrive (every {step} samples)"]
    for key, dofs in out.items():
        lines.append(f"{key:12s} " + "  ".join(f"n={m}:{d}" for m, d in dofs))
    return out, lines


def search_vs_n_summary(rows):
    """Fig. 4.18's result and table lines from the rows of :func:`search_vs_n_row`."""
    rows = sorted(rows, key=lambda r: r["n"])
    lines = ["Fig. 4.18  closed yardstick: BIC and search time vs n",
             "   n   BIC tree    BIC local   BIC exh.   t tree  t local  t exh. [s]  t pairs"]
    for r in rows:
        lines.append(f"{r['n']:4d}  {r['tree']['bic']:9.0f}  {r['local']['bic']:9.0f}  "
                     f"{r['exhaustive']['bic']:9.0f}  {r['tree']['seconds']:6.2f}  "
                     f"{r['local']['seconds']:6.2f}  {r['exhaustive']['seconds']:6.2f}  "
                     f"{r['fit_seconds']:8.2f}")
    return {"rows": rows}, lines


def structure_report(lines: list[dict], *, only=None) -> tuple[dict, list[str]]:
    """Every structure experiment's result and table lines from results-file lines of
    ``articulation.structure`` trials, in the order of ``only`` (default: :data:`STRUCTURE_EXPERIMENTS`). Trials that
    raised are listed in ``results["errors"]`` and left out of their experiment."""
    settings = {(bool(ln["spec"]["params"].get("quick")),
                 ln["spec"]["params"].get("n") if ln["spec"]["params"]["experiment"] == "fig416"
                 else None, ln["spec"]["params"].get("sensor", "ideal")) for ln in lines}
    if (len({q for q, _, _ in settings}) > 1 or len({n for _, n, _ in settings} - {None}) > 1
            or len({s for _, _, s in settings}) > 1):
        raise ValueError("the results file mixes settings (--quick or not, fig416 with "
                         "different --n, --sensor); use one results file per setting")
    ok = [ln for ln in lines if ln.get("error") is None]
    by = {}
    for ln in ok:
        by.setdefault(ln["record"]["experiment"], []).append(ln)
    results, text = {}, []
    for k in (only or STRUCTURE_EXPERIMENTS):
        mine = by.get(k)
        if not mine:
            continue
        recs = [ln["record"] for ln in mine]
        if k in STRUCTURE_SCENARIOS:
            res, tab = dict(recs[0]["result"]), recs[0]["lines"]
        elif k == "fig416":
            res, tab = yardstick_summary([r["row"] for r in recs])
        elif k == "fig417":
            res, tab = dof_progress_summary({("closed" if r["closed"] else "open_staged"):
                                             r["dofs"] for r in recs})
        else:
            res, tab = search_vs_n_summary([r["row"] for r in recs])
        res["seconds"] = float(sum(ln.get("wall_s") or 0.0 for ln in mine))
        results[k] = res
        text.append("\n".join(tab) + "\n")
    results["errors"] = [{"trial": ln["spec"].get("label") or ln["key"], "error": ln["error"]}
                         for ln in lines if ln.get("error") is not None]
    for e in results["errors"]:
        text.append(f"error: trial {e['trial']} raised {e['error']} (left out above)")
    return results, text
