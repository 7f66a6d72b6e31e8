"""Scores of the front perception experiments (thesis 5.2) against the ground truth: which
detected rectangle is the true front (:func:`match_front`), whether the front is seen in a
frame (:func:`front_visibility`), and which track follows it (:func:`moving_track`)."""

from __future__ import annotations

import math

import numpy as np

from mmlearn.models.perception.fronts import FrontRectangle
from mmlearn.models.perception.tracking import align_rectangle, as_rectangle

__all__ = ["match_front", "front_visibility", "moving_track"]


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
        ``orient_error_deg``, ``size_error_m`` (max |width - true|, |height - true|, m),
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
