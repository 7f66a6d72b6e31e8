"""Scores of the front perception experiments (thesis 5.2) against the ground truth: which
detected rectangle is the true front (:func:`match_front`), whether the front is seen in a
frame (:func:`front_visibility`), which track follows it (:func:`moving_track`), and the
experiments' results over many runs against the thesis and the targets
(:func:`fronts_report`)."""

from __future__ import annotations

import math

import numpy as np

from mmlearn.models.perception.fronts import FrontRectangle
from mmlearn.models.perception.tracking import align_rectangle, as_rectangle

__all__ = ["match_front", "front_visibility", "moving_track", "fronts_report", "FRONT_OBJECTS",
           "THESIS_STAGE_S", "TARGET_DETECTION", "TARGET_DISTANCE_M", "TARGET_POS_M",
           "TARGET_ORIENT_DEG", "TARGET_MS", "PREDICTION_N"]

#: the moving fronts of the experiments
FRONT_OBJECTS = ("drawer", "door")
#: thesis Sec. 5.2.2, seconds on one 2 GHz Pentium core (masks: per plane; sampling: per
#: candidate; the others per frame)
THESIS_STAGE_S = {"planes": 0.845, "masks": 0.008, "sampling": 0.010, "optimisation": 0.313,
                  "check": 0.0023}
#: targets of the front perception (detection rate, distance, errors, time per frame)
TARGET_DETECTION, TARGET_DISTANCE_M, TARGET_POS_M, TARGET_ORIENT_DEG, TARGET_MS = (
    0.90, 2.3, 0.01, 2.0, 100.0)
#: observations of the model whose prediction error is reported (thesis: 30)
PREDICTION_N = 30


def match_front(rectangles, X_true: np.ndarray, width: float, height: float, *,
                max_pos_m: float = 0.05, max_angle_deg: float = 10.0,
                max_size_m: float = math.inf):
    """The detected rectangle that is the true front, or None.

    Every rectangle is compared in the parameterisation closest to ``X_true`` (of its 8);
    candidates are those within ``max_pos_m`` (centre), ``max_angle_deg`` and ``max_size_m``
    (largest of the width and height errors, m); the one with the least
    ``d / max_pos + angle / max_angle`` wins.

    Returns:
        None or a dict with ``index`` (in ``rectangles``), ``pos_error_m``,
        ``orient_error_deg``, ``size_error_m`` (max ``|width - true|``, ``|height - true|``, m),
        ``width``, ``height`` (aligned, m).
    """
    X_true = np.asarray(X_true, float)
    best, best_cost = None, math.inf
    for i, raw in enumerate(rectangles or ()):
        r = as_rectangle(raw)
        if r is None:
            continue
        X, w, h, ang = align_rectangle(X_true, r.X_WR, r.width, r.height)
        d = float(np.linalg.norm(X[:3, 3] - X_true[:3, 3]))
        a = math.degrees(ang)
        if d > max_pos_m or a > max_angle_deg or max(abs(w - width), abs(h - height)) > max_size_m:
            continue
        cost = d / max_pos_m + a / max_angle_deg
        if cost < best_cost:
            best_cost = cost
            best = {"index": i, "pos_error_m": d, "orient_error_deg": a,
                    "size_error_m": max(abs(w - width), abs(h - height)),
                    "width": w, "height": h}
    return best


def front_visibility(X_true: np.ndarray, width: float, height: float, X_WC: np.ndarray, K,
                     X_closed: np.ndarray) -> dict:
    """Geometric visibility of the true front in one frame.

    Returns:
        ``in_view``: all 4 corners in front of the camera and inside the image;
        ``incidence_deg``: angle between the front's normal and the ray from its centre to
        the camera, deg; ``displacement_m``: the largest distance of a corner from the
        closed front's plane, m (how far the front stands out of the cabinet's face).
    """
    c = FrontRectangle(X_true, width, height).corners()
    R, p = X_WC[:3, :3], X_WC[:3, 3]
    pc = (c - p) @ R  # camera frame
    ok = bool(np.all(pc[:, 2] > 1e-6))
    if ok:
        u = K.fx * pc[:, 0] / pc[:, 2] + K.cx
        v = K.fy * pc[:, 1] / pc[:, 2] + K.cy
        ok = bool(np.all((u >= 0) & (u <= K.width - 1) & (v >= 0) & (v <= K.height - 1)))
    ray = p - X_true[:3, 3]
    cosi = abs(float(np.dot(X_true[:3, 2], ray))) / max(1e-12, float(np.linalg.norm(ray)))
    n0 = X_closed[:3, 2]
    disp = float(np.max(np.abs((c - X_closed[:3, 3]) @ n0)))
    return {"in_view": ok, "incidence_deg": math.degrees(math.acos(min(1.0, cosi))),
            "displacement_m": disp}


def moving_track(tracks, truth_by_time: dict, *, max_pos_m: float = 0.05,
                 max_angle_deg: float = 10.0, max_size_m: float = math.inf):
    """(track, matched count): the track with the most observations that match the true
    front at their observation times (``truth_by_time``: time rounded to 1 us -> (X_WR,
    width, height); the gates of :func:`match_front`); (None, 0) when none matches."""
    best, best_n = None, 0
    for t in tracks:
        n = 0
        for i in range(t.n):
            truth = truth_by_time.get(round(float(t.times[i]), 6))
            if truth is None:
                continue
            X, w, h = truth
            if match_front([t.rectangle(i)], X, w, h, max_pos_m=max_pos_m,
                           max_angle_deg=max_angle_deg, max_size_m=max_size_m) is not None:
                n += 1
        if n > best_n:
            best, best_n = t, n
    return best, best_n


# ----------------------------------------------------------------------------- experiments
def _mean(v):
    v = [x for x in v if x is not None and np.isfinite(x)]
    return float(np.mean(v)) if v else None


def _std(v):
    v = [x for x in v if x is not None and np.isfinite(x)]
    return float(np.std(v)) if v else None


def _group(recs, key):
    """Rows per (object, key value) with means and standard deviations over the runs."""
    rows = []
    for obj in FRONT_OBJECTS:
        vals = sorted({r[key] for r in recs if r["object"] == obj})
        for v in vals:
            rs = [r for r in recs if r["object"] == obj and r[key] == v]
            rows.append({
                "object": obj, key: v, "runs": len(rs),
                "detection_rate": _mean([r["detection_rate"] for r in rs]),
                "detection_rate_std": _std([r["detection_rate"] for r in rs]),
                "detection_rate_visible": _mean([r.get("detection_rate_visible") for r in rs]),
                "detection_rate_eligible": _mean([r["detection_rate_eligible"] for r in rs]),
                "detection_rate_eligible_open": _mean([r.get("detection_rate_eligible_open")
                                                       for r in rs]),
                "detection_rate_eligible_min": (min(r["detection_rate_eligible"] for r in rs
                                                    if r["detection_rate_eligible"] is not None)
                                                if any(r["detection_rate_eligible"] is not None
                                                       for r in rs) else None),
                "pos_error_m": _mean([r["pos_error_m"] for r in rs]),
                "pos_error_m_std": _std([r["pos_error_m"] for r in rs]),
                "orient_error_deg": _mean([r["orient_error_deg"] for r in rs]),
                "orient_error_deg_std": _std([r["orient_error_deg"] for r in rs]),
                "model_right": sum(bool(r["model_right"]) for r in rs),
                "selected": {m: sum(r["selected_model"] == m for r in rs)
                             for m in sorted({str(r["selected_model"]) for r in rs})},
                "model_right_from": _mean([r["model_right_from"] for r in rs]),
                "ms_per_frame": _mean([r["ms_per_frame"] for r in rs]),
            })
    return rows


def _selection(recs):
    """Per object: share of runs selecting each model on the first n observations, and the
    mean held-out prediction error of the selected model, against n."""
    out = {}
    for obj in FRONT_OBJECTS:
        rs = [r for r in recs if r["object"] == obj and r.get("selection_vs_n")]
        if not rs:
            continue
        n_max = max(max(r["selection_vs_n"]["n"]) for r in rs)
        ns = list(range(3, n_max + 1))
        share = {m: [] for m in ("rigid", "prismatic", "revolute", "gp")}
        ep, eo, runs_at = [], [], []
        for n in ns:
            sel, a, b = [], [], []
            for r in rs:
                s = r["selection_vs_n"]
                if n in s["n"]:
                    i = s["n"].index(n)
                    sel.append(s["selected"][i])
                    a.append(s["heldout_pos_error_m"][i])
                    b.append(s["heldout_orient_error_deg"][i])
            runs_at.append(len(sel))
            for m in share:
                share[m].append(sum(x == m for x in sel) / len(sel) if sel else None)
            ep.append(_mean(a))
            eo.append(_mean(b))
        # prediction error of the model learned from PREDICTION_N observations (or the
        # longest prefix leaving >= 5 later observations to predict)
        pe, oe, used = [], [], []
        for r in rs:
            s = r["selection_vs_n"]
            N = max(s["n"])
            n = min(PREDICTION_N, N - 5)
            if n < 3 or n not in s["n"]:
                continue
            i = s["n"].index(n)
            pe.append(s["heldout_pos_error_m"][i])
            oe.append(s["heldout_orient_error_deg"][i])
            used.append(n)
        out[obj] = {"n": ns, "runs": runs_at, "share": share, "heldout_pos_error_m": ep,
                    "heldout_orient_error_deg": eo,
                    "prediction_pos_error_m": _mean(pe), "prediction_orient_error_deg": _mean(oe),
                    "prediction_n": used,
                    "right_in_the_end": sum(bool(r["model_right"]) for r in rs),
                    "runs_total": len(rs),
                    "model_right_from_mean": _mean([r["model_right_from"] for r in rs]),
                    "model_right_from_max": (max(r["model_right_from"] for r in rs
                                                 if r["model_right_from"] is not None)
                                             if any(r["model_right_from"] is not None
                                                    for r in rs) else None)}
    return out


def _timing(recs):
    stages = {s: _mean([r["stage_ms"].get(s) for r in recs]) for s in THESIS_STAGE_S}
    return {"stage_ms": stages, "ms_per_frame": _mean([r["ms_per_frame"] for r in recs]),
            "cpu_ms_per_frame": _mean([r.get("cpu_ms_per_frame") for r in recs]),
            "cpu_ms_per_frame_max": max((r["cpu_ms_per_frame"] for r in recs
                                         if r.get("cpu_ms_per_frame") is not None),
                                        default=None),
            "ms_per_frame_max": max((r["ms_per_frame"] for r in recs
                                     if r["ms_per_frame"] is not None), default=None),
            "thesis_stage_ms": {k: 1e3 * v for k, v in THESIS_STAGE_S.items()}}


def _targets(dist_rows, recs):
    """The targets, each with its measured value and met / not met."""
    near = [r for r in recs if r["experiment"] == "distance"
            and r["distance_m"] <= TARGET_DISTANCE_M + 1e-9]
    out = {}
    for obj in FRONT_OBJECTS:
        rs = [r for r in near if r["object"] == obj]
        if not rs:
            continue
        rows = [x for x in dist_rows if x["object"] == obj
                and x["distance"] <= TARGET_DISTANCE_M + 1e-9]
        worst_all = min(x["detection_rate"] for x in rows)
        el = [x["detection_rate_eligible"] for x in rows
              if x["detection_rate_eligible"] is not None]
        worst_el = min(el) if el else None
        pe = _mean([r["pos_error_m"] for r in rs])
        oe = _mean([r["orient_error_deg"] for r in rs])
        right = sum(bool(r["model_right"]) for r in rs)
        out[obj] = {
            "detection_rate_all_frames_worst_distance": worst_all,
            "detection_rate_eligible_worst_distance": worst_el,
            "detection_met_all_frames": worst_all >= TARGET_DETECTION,
            "detection_met_eligible": worst_el is not None and worst_el >= TARGET_DETECTION,
            "pos_error_m": pe, "pos_met": pe is not None and pe < TARGET_POS_M,
            "orient_error_deg": oe, "orient_met": oe is not None and oe < TARGET_ORIENT_DEG,
            "model_right": f"{right}/{len(rs)}", "model_met": right == len(rs),
            "seeds_per_distance": min(x["runs"] for x in rows)}
    ms = [r["ms_per_frame"] for r in recs if r["ms_per_frame"] is not None]
    if ms:
        out["ms_per_frame_median_of_runs"] = float(np.median(ms))
    cpu = [r.get("cpu_ms_per_frame") for r in recs if r.get("cpu_ms_per_frame") is not None]
    if cpu:
        out["cpu_ms_per_frame_median_of_runs"] = float(np.median(cpu))
        out["cpu_ms_per_frame_worst_run"] = float(np.max(cpu))
        out["ms_met"] = float(np.max(cpu)) < TARGET_MS
    return out


def fronts_report(lines: list[dict]) -> dict:
    """The results of the front perception experiments from the results-file lines of
    :func:`~mmlearn.diagrams.perception.trials.fronts_trial` runs: per experiment
    (``distance``, ``angle``) its rows per object and setting (means and spreads over the
    runs), the model selection against the number of observations, the time per stage and
    the targets with their measured values. A file mixing settings is a ``ValueError``."""
    settings = {ln["spec"]["params"].get("frames") for ln in lines}
    if len(settings) > 1:
        raise ValueError(f"the results file mixes settings (frames {sorted(settings)}); use one "
                         "results file per setting")
    ok = [ln["record"] for ln in lines if ln.get("error") is None]
    res = {}
    for exp, key in (("distance", "distance_m"), ("angle", "angle_deg")):
        recs = [r for r in ok if r["experiment"] == exp]
        if not recs:
            continue
        rows = _group(recs, key)
        for r in rows:
            r[key.split("_")[0]] = r.pop(key)
        res[exp] = {"rows": rows}
    if ok:
        res["selection"] = _selection(ok)
        res["timing"] = _timing(ok)
        if "distance" in res:
            res["targets"] = _targets(res["distance"]["rows"], ok)
    return res
