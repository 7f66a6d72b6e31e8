"""Detect and track a cabinet front in noisy depth images and learn its articulation
(thesis ch. 5: FrontDetector -> FrontTracker -> link model), scored against the ground truth.

    python -m mmlearn.apps.track_fronts --object drawer --distance 1.5 --frames 40 --seed 3 \\
        [--angle DEG] [--camera-rate HZ] [--no-temporal-filter] [--meshcat] [--html-out F] \\
        [--json]

The kitchen scene of :mod:`mmlearn.diagrams.perception.diagram` (RgbdSensor + DepthNoise) with a
:class:`~mmlearn.systems.FrontDetector` and a :class:`~mmlearn.systems.FrontTracker` added;
the moving front opens in the scene's stepped profile and ``--frames`` detector frames are
taken evenly over it (the first closed, the last fully open). The camera and the
DepthTemporalFilter run at ``--camera-rate`` (30 Hz, a structured-light camera's rate; 0 = one
camera frame per detector frame): each detector frame sees the filter's mean of the camera
frames up to its time.

Scoring (printed, and in ``--json``):

* ``detection_rate``: share of frames in which the moving front was *found*: some detected
  rectangle whose centre is within ``match_pos_m`` (0.05 m) of the true front's centre and
  whose orientation, in the closest of its 8 parameterisations (corner / side ambiguity,
  thesis 5.1.3), is within ``match_angle_deg`` (10 deg) of the true front's;
  and whose width and height are within ``match_size_m`` (0.1 m) of the true ones (a
  rectangle of several merged closed fronts whose centre happens to lie near the front's is
  not the front);
* ``detection_rate_visible``: the same over the frames in which the true front is wholly in
  the image (the thesis' definition, 5.2.1: "whether the drawer was fully visible");
* ``detection_rate_eligible``: the target measure, the same over the *eligible* frames: the
  true front wholly in the image and seen at an incidence below ``max_incidence_deg``
  (70 deg), closed fronts included (the thesis counted the frames in which its drawer was
  fully visible, 5.2.1; a door opened to 90 deg is seen edge-on from the front);
  ``min_displacement_m`` (default 0) also requires the front to stand out of the closed
  cabinet face by that much;
* ``detection_rate_eligible_open``: over the eligible frames in which the front stands out of
  the closed cabinet face by at least ``open_displacement_m`` (0.02 m): the opened front only
  (the earlier eligibility rule, written when closed fronts, flush with their neighbours
  behind a 5 mm reveal, could not be found);
* ``pos_error_m`` / ``orient_error_deg``: mean over the frames in which it was found of the
  found rectangle's centre distance / rotation angle to the true pose of the face the camera
  sees (the best match of the frame): the outer face, or the inner face (``front_thickness``
  behind it) in the frames in which the door has turned past the camera's line of sight
  (``frames_inner_face_seen``; only off-axis views); ``pos_error_outer_face_m``: the same
  against the outer face always (then 19 mm larger on those frames);
  ``size_error_m``: mean of the larger of |width - true| and |height - true| (after the
  alignment);
* ``moving_track``: the published track with the most observations matched to the true front
  at their times; ``selected_model``: the model selected on all of that track's observations
  (the tracker's candidates and noise); ``tracker_selected_model``: the tracker's own model of
  that track at the end (refitted every ``refit_every`` observations, so it may lag);
  ``expected_model``: prismatic (drawer) / revolute (door); ``model_right_from``: the least n
  from which the selection on the track's first n observations (every n from 3 to all, the
  tracker's candidates and noise) stays the expected model (None when the last is wrong);
  ``online_selections``: the tracker's own selections of that track as it refitted, (n,
  model);
* ``ms_per_frame``: median wall time of the whole detector per frame (the detector's own
  clock); ``stage_ms``: median per stage (planes, masks, sampling, optimisation, check);
  ``cpu_ms_per_frame``: median CPU time of this thread while the detector's output is
  computed (the rendered noisy image and the temporal filter are evaluated before; None with
  Meshcat, whose drawing evaluates the detector first): what one core spends, less sensitive
  to a loaded machine; ``filter_cpu_ms_per_frame``: the same for the DepthTemporalFilter;
* ``camera_rate_hz``: the camera's frame rate; ``filter_frames_averaged``: per detector frame,
  the median over the image's pixels of the camera frames in the filter's mean
  (1 / noise_scale^2; None without the filter).

Meshcat (``--meshcat`` live, ``--html-out`` recording): the scene, the noisy point cloud, the
detected rectangles of the current frame (grey), each track's latest rectangle and centre path
and its learned model (axis and range) in the track's colour
(:class:`~mmlearn.systems.FrontTrackVisualizer`). The scene's motion is an animation of the
recording, and so are the rectangles, tracks and models: each camera frame's drawing is shown
at its time (its own Meshcat group, keyed visible / hidden in the animation).
"""

import copy
import json
import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mmlearn.apps.common.cli import (ArgumentParser, UsageError, check_in_file, check_out_file,
                                     fail, finish_viewing, json_clean, load_config, make_meshcat,
                                     nonneg_int, pos_int, progress, save_html)
from mmlearn.diagrams.perception.diagram import FrontPerceptionConfig
from mmlearn.models.perception.detection import STAGES, FrontDetectorConfig
from mmlearn.models.perception.depth_filter import DepthFilterConfig

__all__ = ["TrackFrontsConfig", "run", "match_front", "main", "EXPECTED_MODEL"]

EXPECTED_MODEL = {"drawer": "prismatic", "door": "revolute"}


@dataclass
class TrackFrontsConfig:
    """What :func:`run` does.

    Attributes:
        object: the moving front, "drawer" or "door".
        distance: camera distance to the closed front's centre, m.
        angle_deg: camera azimuth off the front's normal, deg.
        frames: camera frames over the opening (>= 2).
        seed: seed of the depth noise and the detector's random draws.
        match_pos_m: a detection is the moving front when its centre is within this of the
            true centre, m.
        match_angle_deg: ... and its orientation (closest parameterisation) within this, deg.
        match_size_m: ... and its width and height within this of the true ones, m.
        max_incidence_deg: a frame is *eligible* (counted in ``detection_rate_eligible``)
            when the front is wholly in the image, seen at an incidence below this, deg
            (default: where the depth noise model starts dropping grazing pixels) ...
        min_displacement_m: ... and stands out of the closed cabinet face by at least this,
            m (default 0: closed fronts count, as in the thesis' count).
        open_displacement_m: ``detection_rate_eligible_open`` counts the eligible frames in
            which the front stands out of the closed face by at least this, m (default twice
            the detector's 0.01 m inlier distance: the opened front only).
        selection_step: model_right_from evaluates the prefixes n = 3, 3 + step, ..., all
            (1 = every n).
        scene: the rest of the scene / camera / noise configuration (its front, distance,
            angle and noise seed are set from the fields above).
        detector: the FrontDetector's parameters.
        temporal_filter: put a DepthTemporalFilter (per-pixel running mean where the scene
            stands still, :mod:`mmlearn.models.perception.depth_filter`) between the camera and the
            detector, at the camera's frame rate (one filter update per frame).
        filter: its parameters (``depth_std_at_1m`` is set from the scene's noise model).
        camera_rate_hz: the camera's frame rate with the temporal filter, Hz (default 30, a
            structured-light camera's; the detector and tracker run at their own period,
            ``frames`` over the opening, and see the filter's mean of the frames up to then;
            0 = one camera frame per detector period, as before). Without the filter the
            camera runs at the detector's period (nothing reads the frames between).
        refit_every: the tracker refits a track's model every this many observations.
        html_out: write the Meshcat recording here ("" = no).
        meshcat: show it live.
    """

    object: str = "drawer"
    distance: float = 1.5
    angle_deg: float = 0.0
    frames: int = 40
    seed: int = 0
    match_pos_m: float = 0.05
    match_angle_deg: float = 10.0
    match_size_m: float = 0.1
    max_incidence_deg: float = 70.0
    min_displacement_m: float = 0.0
    open_displacement_m: float = 0.02
    selection_step: int = 1
    scene: FrontPerceptionConfig = field(default_factory=FrontPerceptionConfig)
    detector: FrontDetectorConfig = field(default_factory=FrontDetectorConfig)
    temporal_filter: bool = True
    filter: DepthFilterConfig = field(default_factory=DepthFilterConfig)
    camera_rate_hz: float = 30.0
    refit_every: int = 5
    html_out: str = ""
    meshcat: bool = False

    def validate(self) -> None:
        if self.object not in EXPECTED_MODEL:
            raise ValueError(f"object must be one of {', '.join(EXPECTED_MODEL)}, got "
                             f"{self.object!r}")
        for k in ("distance", "angle_deg", "match_pos_m", "match_angle_deg",
                  "max_incidence_deg", "min_displacement_m", "open_displacement_m",
                  "camera_rate_hz"):
            v = getattr(self, k)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValueError(f"{k} must be a finite number, got {v!r}")
        if self.camera_rate_hz < 0:
            raise ValueError(f"camera_rate_hz must be >= 0 (Hz; 0 = one frame per detector "
                             f"period), got {self.camera_rate_hz}")
        if not self.distance > 0.2:
            raise ValueError(f"distance must be > 0.2 m, got {self.distance}")
        if not (self.match_pos_m > 0 and self.match_angle_deg > 0):
            raise ValueError("match_pos_m and match_angle_deg must be > 0")
        if (isinstance(self.match_size_m, bool) or not isinstance(self.match_size_m, (int, float))
                or not self.match_size_m > 0):
            raise ValueError(f"match_size_m must be a number > 0 (m), got {self.match_size_m!r}")
        for k, lo in (("frames", 2), ("selection_step", 1), ("refit_every", 1), ("seed", 0)):
            v = getattr(self, k)
            if isinstance(v, bool) or not isinstance(v, int) or v < lo:
                raise ValueError(f"{k} must be an integer >= {lo}, got {v!r}")


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
    from mmlearn.models.perception.tracking import align_rectangle, as_rectangle

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
    from mmlearn.models.perception.fronts import FrontRectangle

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


def _moving_track(tracks, truth_by_time: dict, cfg: TrackFrontsConfig):
    """(track, matched count): the track with the most observations matching the true front
    at their observation times."""
    best, best_n = None, 0
    for t in tracks:
        n = 0
        for i in range(t.n):
            truth = truth_by_time.get(round(float(t.times[i]), 6))
            if truth is None:
                continue
            X, w, h = truth
            if match_front([t.rectangle(i)], X, w, h, max_pos_m=cfg.match_pos_m,
                           max_angle_deg=cfg.match_angle_deg,
                           max_size_m=cfg.match_size_m) is not None:
                n += 1
        if n > best_n:
            best, best_n = t, n
    return best, best_n


def run(*, config: TrackFrontsConfig, meshcat=None, show_progress: bool = True) -> dict:
    """Run the scene with the detector and the tracker over ``config.frames`` frames; returns
    the scores described in the module docstring (a JSON-able dict)."""
    from pydrake.systems.analysis import Simulator

    from mmlearn.diagrams.perception.diagram import AddFrontDetectorAndTracker, MakeFrontPerceptionDiagram
    from mmlearn.models.perception.tracking import selection_vs_observations
    from mmlearn.systems import FrontTrackerConfig, FrontTrackVisualizer
    from mmlearn.systems.perception.front_detector import TIMING_NAMES

    cfg = config
    cfg.validate()
    sc = copy.deepcopy(cfg.scene)
    sc.front = cfg.object
    sc.camera.distance = float(cfg.distance)
    sc.camera.angle_deg = float(cfg.angle_deg)
    sc.noise.seed = int(cfg.seed)
    duration = sc.motion.duration()
    period = duration / (cfg.frames - 1)
    sc.camera.rate_hz = 1.0 / period  # one noise frame index per camera frame
    if cfg.temporal_filter and sc.add_noise and cfg.camera_rate_hz > 0:
        sc.camera.rate_hz = float(cfg.camera_rate_hz)  # the filter folds in every frame
        sc.point_cloud_rate_hz = 1.0 / period  # the cloud drawn with each detection
    sc.validate()
    cfg.detector.validate()
    if meshcat is None and (cfg.meshcat or cfg.html_out):
        meshcat = make_meshcat(announce=cfg.meshcat)
    sc.point_cloud = meshcat is not None and sc.point_cloud
    parts = {}
    filt_cfg = None
    if cfg.temporal_filter and sc.add_noise:
        from mmlearn.models.common.depth_noise import predicted_depth_std

        filt_cfg = copy.deepcopy(cfg.filter)
        filt_cfg.depth_std_at_1m = float(predicted_depth_std(1.0, sc.camera.intrinsics(),
                                                             sc.noise))
        filt_cfg.validate()

    def add(builder, p):
        det, trk = AddFrontDetectorAndTracker(
            builder, p, detector_config=cfg.detector, seed=cfg.seed,
            tracker_config=FrontTrackerConfig(period_s=period, refit_every=cfg.refit_every),
            temporal_filter=filt_cfg, camera_rate_hz=sc.camera.rate_hz)
        if meshcat is not None:
            from pydrake.geometry import MeshcatVisualizer
            scene_vis = next((s for s in builder.GetSystems()
                              if isinstance(s, MeshcatVisualizer)), None)
            vis = builder.AddNamedSystem("front_visualizer", FrontTrackVisualizer(
                meshcat=meshcat, period=period,
                recording=None if scene_vis is None else scene_vis.get_mutable_recording))
            builder.Connect(det.get_rectangles_output_port(), vis.get_rectangles_input_port())
            builder.Connect(trk.get_tracks_output_port(), vis.get_tracks_input_port())
            builder.Connect(trk.get_models_output_port(), vis.get_models_input_port())
            parts["vis"] = vis
        parts["det"], parts["trk"] = det, trk

    P = MakeFrontPerceptionDiagram(sc, meshcat=meshcat, add_systems=add)
    d = P.diagram
    det, trk = parts["det"], parts["trk"]
    sim = Simulator(d)
    ctx = sim.get_mutable_context()
    det_ctx = det.GetMyContextFromRoot(ctx)
    trk_ctx = trk.GetMyContextFromRoot(ctx)
    if P.visualizer is not None:
        P.visualizer.StartRecording(False)
    sim.Initialize()
    w_true, h_true = P.kinematics.width, P.kinematics.height
    frames, truth_by_time = [], {}
    timings, cpu, filt_cpu, averaged = [], [], [], []
    filt = (d.GetSubsystemByName("depth_temporal_filter")
            if d.HasSubsystemNamed("depth_temporal_filter") else None)
    filt_ctx = filt.GetMyContextFromRoot(ctx) if filt is not None else None
    wall0 = time.perf_counter()
    for k in progress(range(cfg.frames), desc=f"{cfg.object} frames", unit="frame",
                      enabled=show_progress):
        t = k * period
        sim.AdvanceTo(t)
        d.GetOutputPort("depth_image").Eval(ctx)  # render + noise first: not timed below
        if filt is not None:  # the temporal filter: timed on its own
            c0 = time.thread_time()
            scale = np.asarray(filt.get_noise_scale_output_port().Eval(filt_ctx).data)
            filt_cpu.append(time.thread_time() - c0)
            s_ok = scale[np.isfinite(scale) & (scale > 0)]
            averaged.append(float(np.median(1.0 / s_ok ** 2)) if s_ok.size else 1.0)
        c0 = time.thread_time()
        rects = det.get_rectangles_output_port().Eval(det_ctx)
        cpu.append(time.thread_time() - c0)
        tm = np.asarray(det.get_timings_output_port().Eval(det_ctx), float)
        X_outer = d.GetOutputPort("X_WR").Eval(ctx).GetAsMatrix4()
        X_WC = d.GetOutputPort("X_WC").Eval(ctx).GetAsMatrix4()
        # the face the camera sees: the outer one, or the inner one (thickness behind it) once
        # the door has turned past the camera's line of sight (off-axis views)
        inner = float(X_outer[:3, 2] @ (X_WC[:3, 3] - X_outer[:3, 3])) < 0.0
        X_true = X_outer.copy()
        if inner:
            X_true[:3, 3] -= sc.kitchen.front_thickness * X_outer[:3, 2]
        vis = front_visibility(X_true, w_true, h_true, X_WC, P.intrinsics, P.kinematics.X_WR0)
        eligible = (vis["in_view"] and vis["incidence_deg"] < cfg.max_incidence_deg
                    and vis["displacement_m"] >= cfg.min_displacement_m)
        eligible_open = eligible and vis["displacement_m"] >= cfg.open_displacement_m
        q = float(d.GetOutputPort("front_joint").Eval(ctx)[0])
        truth_by_time[round(t, 6)] = (X_true, w_true, h_true)
        m = match_front(rects, X_true, w_true, h_true, max_pos_m=cfg.match_pos_m,
                        max_angle_deg=cfg.match_angle_deg, max_size_m=cfg.match_size_m)
        m_outer = (m if not inner or m is None else
                   match_front([rects[m["index"]]], X_outer, w_true, h_true,
                               max_pos_m=cfg.match_pos_m + sc.kitchen.front_thickness,
                               max_angle_deg=cfg.match_angle_deg, max_size_m=cfg.match_size_m))
        timings.append(tm)
        frames.append({"time": t, "joint_value": q, "rectangles": len(rects),
                       "found": m is not None, "eligible": eligible,
                       "eligible_open": eligible_open, **vis,
                       "inner_face_seen": inner,
                       **({"pos_error_outer_face_m": m_outer["pos_error_m"]} if m_outer else {}),
                       **({k2: m[k2] for k2 in ("pos_error_m", "orient_error_deg",
                                                "size_error_m")} if m else {})})
    # the tracker takes the frame at t at the start of the next step: one more half period
    sim.AdvanceTo((cfg.frames - 1) * period + 0.5 * period)
    wall = time.perf_counter() - wall0
    st = trk.state(trk_ctx)
    tracks = trk.get_tracks_output_port().Eval(trk_ctx)
    models = trk.get_models_output_port().Eval(trk_ctx)
    if "vis" in parts:
        parts["vis"].ForcedPublish(parts["vis"].GetMyContextFromRoot(ctx))
    if P.visualizer is not None:
        P.visualizer.StopRecording()
        P.visualizer.PublishRecording()
    expected = EXPECTED_MODEL[cfg.object]
    mt, n_matched = _moving_track(tracks, truth_by_time, cfg)
    selected = tracker_selected = None
    sel = None
    if mt is not None:
        tmod = models.get(mt.track_id)
        tracker_selected = tmod.selected if tmod is not None else None
        ns = list(range(3, mt.n + 1, cfg.selection_step))
        if ns and ns[-1] != mt.n:
            ns.append(mt.n)
        tcfg = trk.config()
        from mmlearn.models.perception.tracking import front_observation_model
        sel = selection_vs_observations(
            mt.poses, expected=expected, ns=ns, models=tcfg.model_names(),
            obs=front_observation_model(tcfg.sigma_pos_m, math.radians(tcfg.sigma_orient_deg)),
            seed=tcfg.seed)
        selected = sel["selected"][-1]
    found = [f for f in frames if f["found"]]
    elig = [f for f in frames if f["eligible"]]
    elig_open = [f for f in frames if f["eligible_open"]]
    visible = [f for f in frames if f["in_view"]]
    T = np.array(timings)  # (frames, stages + total), s; NaN rows: frame not processed
    ok_rows = T[np.all(np.isfinite(T), axis=1)] if T.size else T

    def med(col):
        return 1e3 * float(np.median(ok_rows[:, col])) if len(ok_rows) else None

    out = {
        "object": cfg.object, "distance_m": float(cfg.distance),
        "angle_deg": float(cfg.angle_deg), "seed": cfg.seed, "frames": cfg.frames,
        "period_s": period,
        "match": {"pos_m": cfg.match_pos_m, "angle_deg": cfg.match_angle_deg,
                  "size_m": cfg.match_size_m},
        "eligible_if": {"in_view": True, "incidence_below_deg": cfg.max_incidence_deg,
                        "displacement_at_least_m": cfg.min_displacement_m,
                        "open_displacement_at_least_m": cfg.open_displacement_m},
        "frames_found": len(found),
        "detection_rate": len(found) / cfg.frames,
        "frames_visible": len(visible),
        "detection_rate_visible": ((sum(f["found"] for f in visible) / len(visible))
                                   if visible else None),
        "frames_eligible": len(elig),
        "detection_rate_eligible": (sum(f["found"] for f in elig) / len(elig)) if elig else None,
        "frames_eligible_open": len(elig_open),
        "detection_rate_eligible_open": ((sum(f["found"] for f in elig_open) / len(elig_open))
                                         if elig_open else None),
        "pos_error_m": float(np.mean([f["pos_error_m"] for f in found])) if found else None,
        "pos_error_outer_face_m": (float(np.mean([f["pos_error_outer_face_m"] for f in found
                                                  if "pos_error_outer_face_m" in f]))
                                   if any("pos_error_outer_face_m" in f for f in found)
                                   else None),
        "frames_inner_face_seen": int(sum(f["inner_face_seen"] for f in frames)),
        "orient_error_deg": (float(np.mean([f["orient_error_deg"] for f in found]))
                             if found else None),
        "size_error_m": float(np.mean([f["size_error_m"] for f in found])) if found else None,
        "expected_model": expected,
        "selected_model": selected,
        "tracker_selected_model": tracker_selected,
        "model_right": selected == expected,
        "model_right_from": sel["model_right_from"] if sel else None,
        "moving_track": (None if mt is None else
                         {"track_id": mt.track_id, "observations": mt.n,
                          "matched_observations": n_matched}),
        "selection_vs_n": (None if sel is None else
                           {"n": sel["n"], "selected": sel["selected"],
                            "heldout_pos_error_m": sel["heldout_pos_error_m"],
                            "heldout_orient_error_deg":
                                [None if v is None or not np.isfinite(v) else math.degrees(v)
                                 for v in sel["heldout_orient_error_rad"]]}),
        "tracks": len(st.tracking.tracks),
        "published_tracks": len(tracks),
        "track_models": {str(k): v.selected for k, v in sorted(models.items())},
        "ms_per_frame": med(len(TIMING_NAMES) - 1),
        "cpu_ms_per_frame": (None if meshcat is not None or not cpu
                             else 1e3 * float(np.median(cpu))),
        "filter_cpu_ms_per_frame": (None if meshcat is not None or not filt_cpu
                                    else 1e3 * float(np.median(filt_cpu))),
        "camera_rate_hz": float(sc.camera.rate_hz),
        "filter_frames_averaged": averaged or None,
        "stage_ms": {s: med(i) for i, s in enumerate(STAGES)},
        "frames_not_processed": int(len(T) - len(ok_rows)),
        "wall_s": wall,
        "per_frame": frames,
        "html_out": None,
    }
    if cfg.html_out and meshcat is not None:
        out["html_out"] = str(save_html(meshcat, cfg.html_out))
    return out


def _summary(r: dict) -> str:
    def f(v, fmt):
        return "n/a" if v is None else format(v, fmt)

    lines = [
        f"{r['object']} at {r['distance_m']:.2f} m, {r['angle_deg']:+.0f} deg, seed {r['seed']}: "
        f"found in {r['frames_found']}/{r['frames']} frames "
        f"(detection rate {100 * r['detection_rate']:.0f} %, match within "
        f"{r['match']['pos_m']} m / {r['match']['angle_deg']} deg / size "
        f"{r['match']['size_m']} m); in {f(r['detection_rate_visible'], '.0%')} of the "
        f"{r['frames_visible']} frames in which it is wholly in view; in "
        f"{f(r['detection_rate_eligible'], '.0%')} of the {r['frames_eligible']} frames in "
        f"which it is in view at < {r['eligible_if']['incidence_below_deg']} deg incidence "
        f"(the target measure; {f(r['detection_rate_eligible_open'], '.0%')} of the "
        f"{r['frames_eligible_open']} of them with the front out of the cabinet face by >= "
        f"{r['eligible_if']['open_displacement_at_least_m']} m)",
        f"  pose error of the found front: {f(r['pos_error_m'], '.4f')} m, "
        f"{f(r['orient_error_deg'], '.2f')} deg (size {f(r['size_error_m'], '.3f')} m)",
        f"  moving front's track: {r['moving_track']}; selected {r['selected_model']} "
        f"(expected {r['expected_model']}; the tracker's own: {r['tracker_selected_model']}), "
        f"right from n = {r['model_right_from']}",
        f"  {r['published_tracks']} published tracks: {r['track_models']}",
        f"  detector: {f(r['ms_per_frame'], '.1f')} ms per frame (median wall; CPU "
        f"{f(r['cpu_ms_per_frame'], '.1f')} ms); per stage: "
        + ", ".join(f"{k} {f(v, '.1f')}" for k, v in r["stage_ms"].items()) + " ms",
    ]
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = ArgumentParser(
        prog="python -m mmlearn.apps.track_fronts",
        description="Detect and track a cabinet's drawer or door in noisy depth images while "
                    "it opens, learn its articulation and score it against the ground truth.")
    ap.add_argument("--object", choices=sorted(EXPECTED_MODEL), default="drawer",
                    help="the moving front")
    ap.add_argument("--distance", type=_finite_float, default=1.5,
                    help="camera distance to the front, m")
    ap.add_argument("--angle", type=_finite_float, default=0.0,
                    help="camera angle off the front's normal, deg (--angle=-30 for a minus)")
    ap.add_argument("--frames", type=pos_int, default=40, help="camera frames (>= 2)")
    ap.add_argument("--seed", type=nonneg_int, default=0, help="noise and detector seed")
    ap.add_argument("--config", type=Path,
                    help="YAML file of a FrontPerceptionConfig (kitchen, motion, camera, "
                         "noise, ...); --object, --distance, --angle and --seed override it")
    ap.add_argument("--no-temporal-filter", action="store_true",
                    help="no DepthTemporalFilter between camera and detector (each frame on "
                         "its own)")
    ap.add_argument("--camera-rate", type=_finite_float, default=30.0,
                    help="camera frames per second with the temporal filter, Hz (default 30; "
                         "0 = one frame per detector period)")
    ap.add_argument("--selection-step", type=pos_int, default=1,
                    help="model_right_from: evaluate every this many prefix lengths")
    ap.add_argument("--meshcat", action="store_true", help="show it live in Meshcat")
    ap.add_argument("--html-out", type=Path, help="save the Meshcat recording (HTML)")
    ap.add_argument("--json", action="store_true", help="print the results as JSON")
    args = ap.parse_args(argv)
    try:
        if args.frames < 2:
            raise UsageError(f"--frames must be >= 2, got {args.frames}")
        if args.distance <= 0.2:
            raise UsageError(f"--distance must be > 0.2 m, got {args.distance}")
        if abs(args.angle) > 80:
            raise UsageError(f"--angle must be within +-80 deg, got {args.angle}")
        if args.camera_rate < 0:
            raise UsageError(f"--camera-rate must be >= 0 Hz, got {args.camera_rate}")
        check_in_file("--config", args.config)
        check_out_file("--html-out", args.html_out)
    except UsageError as e:
        return fail(ap.prog, str(e))
    try:
        scene = (load_config(args.config, FrontPerceptionConfig) if args.config
                 else FrontPerceptionConfig())
    except (OSError, RuntimeError, ValueError) as e:
        return fail(ap.prog, f"--config: {e}")
    cfg = TrackFrontsConfig(object=args.object, distance=args.distance, angle_deg=args.angle,
                            frames=args.frames, seed=args.seed,
                            selection_step=args.selection_step, scene=scene,
                            temporal_filter=not args.no_temporal_filter,
                            camera_rate_hz=args.camera_rate,
                            html_out=str(args.html_out or ""), meshcat=args.meshcat)
    try:
        result = run(config=cfg, show_progress=not args.json)
    except ValueError as e:
        return fail(ap.prog, str(e))
    if args.json:
        print(json.dumps(json_clean(result)))
    else:
        print(_summary(result))
    finish_viewing(html_out=None if args.json else result["html_out"], live=args.meshcat)
    return 0


def _finite_float(text):
    import argparse

    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return v


if __name__ == "__main__":
    sys.exit(main())
