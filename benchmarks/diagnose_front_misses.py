"""Why is a front missed? Per eligible frame of saved renders in which the detector does not find
the moving front: its opening, incidence, visible pixels, the plane found for it (if any), the
true rectangle's precision / recall on that plane's grid, the best candidate near the truth and
the test that rejected it (prints a table; a development tool, not a test).

    python benchmarks/diagnose_front_misses.py --frames-dir DIR [--all] [--json OUT]

Frames: ``*.json`` + ``*_depth.npy`` (+ ``*_label.npy``) of ``python -m
mmlearn.apps.render_fronts ... --out-dir DIR``. The detector runs with the default config and
the seed ``[0, frame]``; the match and the eligibility (wholly in view, incidence < 70 deg, the
inner face once the door turned past the camera's line of sight) follow ``apps/track_fronts``.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import glob
import json
import math

import numpy as np

import mmlearn.models.perception.detection as fd
from mmlearn.apps.track_fronts import TrackFrontsConfig, front_visibility, match_front
from mmlearn.models.common.camera import PinholeIntrinsics
from mmlearn.models.perception.fronts import FrontRectangle


def _truth(meta, thickness=0.019):
    X_outer = np.asarray(meta["X_WR"], float)
    X_WC = np.asarray(meta["X_WC"], float)
    inner = float(X_outer[:3, 2] @ (X_WC[:3, 3] - X_outer[:3, 3])) < 0.0
    X = X_outer.copy()
    if inner:
        X[:3, 3] -= thickness * X_outer[:3, 2]
    return X, X_WC, inner


def _grid_rect(g, X_CR, w, h):
    """The true rectangle as grid cells [x0, x1, y0, y1] of grid ``g`` (axis-aligned bound of
    its corners projected on the grid's axes)."""
    c = X_CR[:3, 3]
    corners = [c + sx * 0.5 * w * X_CR[:3, 0] + sy * 0.5 * h * X_CR[:3, 1]
               for sx in (-1, 1) for sy in (-1, 1)]
    a = np.array([(p - g.o) @ g.e1 for p in corners])
    b = np.array([(p - g.o) @ g.e2 for p in corners])
    x = (a - g.u0) / g.c
    y = (b - g.v0) / g.c
    H, W = g.shape
    return [int(np.clip(round(x.min()), 0, W)), int(np.clip(round(x.max()), 0, W)),
            int(np.clip(round(y.min()), 0, H)), int(np.clip(round(y.max()), 0, H))]


def diagnose(path, cfg, all_frames=False):
    meta = json.load(open(path))
    base = path[:-5]
    depth = np.load(base + "_depth.npy")
    lab_path = base + "_label.npy"
    K = PinholeIntrinsics(**meta["intrinsics"])
    X, X_WC, inner = _truth(meta)
    w, h = meta["width"], meta["height"]
    vis = front_visibility(X, w, h, X_WC, K, X)
    tcfg = TrackFrontsConfig()
    eligible = vis["in_view"] and vis["incidence_deg"] < tcfg.max_incidence_deg
    log = {"pr": [], "grids": []}
    orig_pr, orig_grid = fd._precision_recall, fd._make_grid

    def pr(g, R, c):
        p, r = orig_pr(g, R, c)
        log["pr"].append((g, tuple(int(v) for v in R), p, r))
        return p, r

    def mg(*a, **k):
        g = orig_grid(*a, **k)
        if g is not None:
            log["grids"].append(g)
        return g

    fd._precision_recall, fd._make_grid = pr, mg
    try:
        rects, _ = fd.detect_fronts(depth, K, X_WC, cfg, np.random.default_rng([0, meta["frame"]]))
    finally:
        fd._precision_recall, fd._make_grid = orig_pr, orig_grid
    m = match_front(rects, X, w, h, max_pos_m=tcfg.match_pos_m,
                    max_angle_deg=tcfg.match_angle_deg, max_size_m=tcfg.match_size_m)
    row = {"name": os.path.basename(base), "q": meta["joint_value"], "inc": vis["incidence_deg"],
           "inner": inner, "eligible": eligible, "found": m is not None, "n_rects": len(rects)}
    if m is not None and not all_frames:
        return row
    if not eligible and not all_frames:
        return row
    # visible pixels of the front
    if os.path.exists(lab_path):
        lab = np.load(lab_path)
        fl = meta.get("front_labels", [])
        own = np.isin(lab, fl)
        row["px_render"] = int(own.sum())
        row["px_measured"] = int((own & np.isfinite(depth) & (depth > 0)).sum())
    # plane of the front (camera frame)
    X_CW = np.linalg.inv(X_WC)
    X_CR = X_CW @ X
    n_t, c_t = X_CR[:3, 2], X_CR[:3, 3]
    best = None
    for g in log["grids"]:
        ang = math.degrees(math.acos(min(1.0, abs(float(g.n @ n_t)))))
        dist = abs(float(g.n @ c_t + g.d))
        if ang < 10 and dist < 0.03 and (best is None or ang + 100 * dist < best[0]):
            best = (ang + 100 * dist, g, ang, dist)
    if best is None:
        row["plane"] = None
        return row
    _, g, ang, dist = best
    row["plane"] = {"angle_deg": round(ang, 2), "dist_mm": round(1000 * dist, 1),
                    "in_plane_cells": int((g.labels == fd.IN_PLANE).sum())}
    R = _grid_rect(g, X_CR, w, h)
    p, r = orig_pr(g, R, cfg)
    sub = g.labels[R[2]:R[3], R[0]:R[1]]
    counts = {nm: int((sub == v).sum()) for nm, v in (
        ("in", fd.IN_PLANE), ("free", fd.FREE), ("occ", fd.OCCLUDED), ("unk", fd.UNKNOWN),
        ("out", fd.OUTSIDE), ("off", fd.OFF_SURFACE), ("gap", fd.GAP))}
    row["true_rect"] = {"R": R, "prec": round(p, 3), "rec": round(r, 3), "cells": counts}
    # candidates of that grid near the truth
    cands = []
    for gg, RR, pp, rr in log["pr"]:
        if gg is not g and gg.plane_index != g.plane_index:
            continue
        cen, e1, e2, ww, hh = fd._rect_camera(gg, RR)
        dcen = float(np.linalg.norm(cen - c_t))
        cands.append((dcen, RR, pp, rr, ww, hh,
                      fd._inside_border(cen, e1, e2, ww, hh, K, cfg.border_margin_px)))
    cands.sort(key=lambda t: t[0])
    row["near_candidates"] = [
        {"d_mm": round(1000 * c[0], 1), "w": round(c[4], 3), "h": round(c[5], 3),
         "prec": round(c[2], 3), "rec": round(c[3], 3), "inside": c[6],
         "rejected_by": ("precision" if c[2] < cfg.min_precision else
                         "recall" if c[3] < cfg.min_recall else
                         "border" if not c[6] else "later (polish / edges / duplicate)")}
        for c in cands[:3]]
    row["rects"] = [{"d_mm": round(1000 * float(np.linalg.norm(
        (X_CW @ r.X_WR)[:3, 3] - c_t)), 1), "w": round(r.width, 3), "h": round(r.height, 3)}
        for r in rects]
    return row


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames-dir", required=True)
    ap.add_argument("--all", action="store_true", help="diagnose found frames too")
    ap.add_argument("--pattern", default="*.json")
    ap.add_argument("--json", default=None, help="write all rows to this file")
    ap.add_argument("--set", action="append", default=[],
                    help="config override KEY=VALUE (Python literal), repeatable")
    a = ap.parse_args(argv)
    import ast
    cfg = fd.FrontDetectorConfig(**{k: ast.literal_eval(v) for k, v in
                                    (kv.split("=", 1) for kv in a.set)})
    rows = []
    for path in sorted(glob.glob(os.path.join(a.frames_dir, a.pattern))):
        row = diagnose(path, cfg, a.all)
        rows.append(row)
        if row["eligible"] and (not row["found"] or a.all):
            print(json.dumps(row), flush=True)
    el = [r for r in rows if r["eligible"]]
    print(f"eligible {len(el)}, found {sum(r['found'] for r in el)}, frames {len(rows)}")
    if a.json:
        json.dump(rows, open(a.json, "w"), indent=1)


if __name__ == "__main__":
    main()
