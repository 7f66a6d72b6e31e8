"""Metrics of the imitation experiments (thesis 8.2), from a reproduction's hand path and the
objects' positions (plain numpy; the reproduction itself is
:func:`mmlearn.diagrams.imitation.trials.reproduce_task`).

Success (the task's goal met in the simulation):

* pick_place: the cup ends released, upright, on the target table (table B), its marker
  within :data:`PLACE_TOL` (horizontally) of the demonstrated spot, i.e. of the
  demonstrations' mean final cup-minus-table-B marker offset applied to this scene's table B
  (:func:`place_spot`);
* whiteboard: the area inside the four corner markers is covered: the share of a 1 cm grid
  of that area that the hand passed within :data:`SPONGE_RADIUS` of (in the board plane)
  while within the demonstrations' distance from the board (+2 cm) is at least 90 % of the
  demonstrations' own mean coverage (:func:`whiteboard_score`);
* obstacle / u_obstacle: the hand ends within :data:`REACH_TOL` of the demonstrated final
  spot relative to the target and the arm never touched the obstacle (:func:`reach_score`).

:func:`condition_table` summarises the reproductions of an experiment per condition.
"""

from __future__ import annotations

import json

import numpy as np
from scipy.spatial import cKDTree

__all__ = ["SPONGE_RADIUS", "PLACE_TOL", "REACH_TOL", "final_point", "coverage",
           "plane_distance", "densify", "place_spot", "whiteboard_score", "reach_score",
           "condition_table"]

SPONGE_RADIUS = 0.04  # m, the hand's cleaning radius on the board
PLACE_TOL = 0.02      # m
REACH_TOL = 0.03      # m


def final_point(track) -> np.ndarray:
    """Last finite row of a (T, D) track."""
    a = np.asarray(track, float)
    ok = np.all(np.isfinite(a), axis=1)
    return a[np.flatnonzero(ok)[-1]]


def coverage(hand, corners, *, plane_tol: float) -> float:
    """Share of a 1 cm grid of the quadrilateral ``corners`` (4, 3) the hand path passed
    within SPONGE_RADIUS of (in the board plane, x = const) while closer to the board than
    ``plane_tol``."""
    hand = np.asarray(hand, float)
    hand = hand[np.all(np.isfinite(hand), axis=1)]
    c = np.asarray(corners, float)
    x_board = float(np.mean(c[:, 0]))
    on = hand[np.abs(hand[:, 0] - x_board) <= plane_tol]
    ys = np.arange(c[:, 1].min(), c[:, 1].max() + 1e-9, 0.01)
    zs = np.arange(c[:, 2].min(), c[:, 2].max() + 1e-9, 0.01)
    Y, Z = np.meshgrid(ys, zs)
    grid = np.column_stack([Y.ravel(), Z.ravel()])
    if on.shape[0] == 0:
        return 0.0
    tree = cKDTree(on[:, 1:])
    d, _ = tree.query(grid)
    return float(np.mean(d <= SPONGE_RADIUS))


def plane_distance(demos) -> float:
    """Median distance of the demonstrations' hand from the board plane (x), m."""
    ds = []
    for d in demos:
        h = np.asarray(d.hand, float)
        c = np.array([final_point(d.objects[f"board_c{k}"]) for k in range(4)])
        h = h[np.all(np.isfinite(h), axis=1)]
        inside = ((h[:, 1] >= c[:, 1].min()) & (h[:, 1] <= c[:, 1].max())
                  & (h[:, 2] >= c[:, 2].min()) & (h[:, 2] <= c[:, 2].max()))
        if inside.any():
            ds.append(np.median(np.abs(h[inside, 0] - np.mean(c[:, 0]))))
    return float(np.median(ds)) if ds else 0.02


def densify(path, step=0.005):
    """Points every ``step`` m along a polyline (N, 3), so that fast strokes between samples
    count."""
    out = [path[:1]]
    for a, b in zip(path[:-1], path[1:]):
        n = max(int(np.linalg.norm(b - a) / step), 1)
        s = np.linspace(0, 1, n + 1)[1:, None]
        out.append(a + s * (b - a))
    return np.vstack(out)


def place_spot(demos, table_b) -> np.ndarray:
    """Where the cup should stand (3,): the demonstrations' mean final cup-minus-table-B
    offset applied to this scene's table B marker ``table_b`` (3,)."""
    offs = [final_point(d.objects["cup"]) - final_point(d.objects["table_b"]) for d in demos]
    return np.asarray(table_b, float) + np.mean(offs, axis=0)


def whiteboard_score(hand, objects: dict, demos) -> dict:
    """The whiteboard's coverage by the hand path ``hand`` (T, 3) of the area inside this
    scene's four corner markers (``objects["board_c0"]`` ..), beside the demonstrations' own
    mean coverage: {"coverage", "demo_coverage", "success"}."""
    plane = plane_distance(demos) + 0.02
    corners = np.array([objects[f"board_c{k}"] for k in range(4)])
    cov = coverage(densify(hand), corners, plane_tol=plane)
    demo_cov = []
    for d in demos:
        h = np.asarray(d.hand, float)
        h = h[np.all(np.isfinite(h), axis=1)]
        c = np.array([final_point(d.objects[f"board_c{k}"]) for k in range(4)])
        demo_cov.append(coverage(densify(h), c, plane_tol=plane))
    return {"coverage": cov, "demo_coverage": float(np.mean(demo_cov)),
            "success": bool(cov >= 0.9 * float(np.mean(demo_cov)))}


def reach_score(hand_end, target, demos, *, clearance: float | None) -> dict:
    """The reach's error: the hand's final position ``hand_end`` (3,) against the
    demonstrations' mean final hand-minus-target offset applied to this scene's ``target``
    (3,); a success within :data:`REACH_TOL` without touching the obstacle (``clearance``:
    the smallest signed distance to it, m, None without obstacle): {"reach_error_m",
    "success"}."""
    spot = np.mean([final_point(d.hand) - final_point(d.objects["target"]) for d in demos],
                   axis=0)
    err = float(np.linalg.norm(np.asarray(hand_end) - (np.asarray(target) + spot)))
    return {"reach_error_m": err,
            "success": bool(err <= REACH_TOL and (clearance is None or clearance > 0))}


def _label(spec: dict) -> str:
    """The condition of a results-file line's spec (its label without the seed)."""
    label = spec.get("label") or ""
    if " seed " in label:
        return label.rsplit(" seed ", 1)[0]
    return json.dumps(spec.get("params", {}), sort_keys=True)


def condition_table(lines: list[dict]) -> tuple[list[dict], list[dict]]:
    """Per-condition success, place error, clearance, coverage and reach error of the
    reproductions in results-file lines (the condition is a spec's label without its
    ``" seed N"``); returns (rows, errors): the trials that raised are counted under
    ``errors`` beside the means over those that ran."""
    rows: dict[str, dict] = {}
    errors = []
    for ln in lines:
        label = _label(ln["spec"])
        row = rows.setdefault(label, {"condition": label, "trials": 0, "errors": 0,
                                      "successes": 0, "records": []})
        if ln.get("error") is not None:
            row["errors"] += 1
            errors.append({"trial": ln["spec"].get("label") or ln["key"],
                           "error": ln["error"]})
            continue
        r = ln["record"]
        row["trials"] += 1
        row["successes"] += bool(r.get("success"))
        row["records"].append(r)
    return [_condition_row(row) for row in rows.values()], errors


def _condition_row(row: dict) -> dict:
    recs = row.pop("records")

    def stat(k, fn=np.mean):
        xs = [r[k] for r in recs if r.get(k) is not None]
        return (float(fn(xs)) if xs else None), len(xs)

    pe, n_pe = stat("place_error_m")
    pe_med, _ = stat("place_error_m", np.median)
    cl, n_cl = stat("min_obstacle_clearance_m", np.min)
    cl_pos = sum(1 for r in recs if (r.get("min_obstacle_clearance_m") or -1) > 0)
    cov, _ = stat("coverage")
    reach, _ = stat("reach_error_m")
    rs, _ = stat("reproduction_seconds")
    demos, _ = stat("demos")
    ls, _ = stat("learn_seconds")
    return {**row, "success_rate": row["successes"] / row["trials"] if row["trials"] else None,
            "mean_place_error_m": pe, "median_place_error_m": pe_med,
            "place_error_runs": n_pe, "min_clearance_m": cl,
            "positive_clearance": cl_pos, "clearance_runs": n_cl,
            "mean_coverage": cov, "mean_reach_error_m": reach,
            "mean_reproduction_seconds": rs, "mean_learn_seconds": ls,
            "mean_demos": demos, "demos_counts": _counts(r.get("demos") for r in recs),
            "asked_before_failing": sum(int(r.get("asked_before_failing") or 0) for r in recs),
            "failed_unflagged": sum(int(r.get("failed_unflagged") or 0) for r in recs),
            # success in the situation batch learning is tested in (interactive teaching's
            # final test; a batch reproduction's own)
            "test_successes": sum(bool(r["test_success"] if r.get("test_success") is not None
                                       else r.get("success")) for r in recs)}


def _counts(values) -> dict:
    """{value as text: how often} of the non-None ``values``, in increasing order."""
    xs = sorted(int(v) for v in values if v is not None)
    return {str(v): xs.count(v) for v in dict.fromkeys(xs)}
