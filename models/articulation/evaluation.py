"""The articulation capability's experiments in numpy: the metrics of an opening trial
(thesis 4.4.2) and the synthetic analysis of the link models (Sec. 4.4.4, Table 4.2)."""

from __future__ import annotations

import math

import numpy as np

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
            out.append(operate_error_record(p.get("kind", "?"), ln["spec"]["seed"], ln["error"]))
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
