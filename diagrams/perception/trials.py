"""The front perception trial (thesis 5.2): the kitchen scene with a FrontDetector and a
FrontTracker while one front opens, scored against the ground truth.

:func:`track_fronts` runs one configuration (:class:`TrackFrontsConfig`) and returns its scores
(the keys are described in :mod:`mmlearn.apps.track_fronts`); :func:`fronts_trial` is the
registered trial of the experiments (``perception.fronts``), one :func:`track_fronts` with a
compact per-frame record. The metrics are :mod:`mmlearn.models.perception.evaluation`'s.
"""

from __future__ import annotations

import copy
import math
import time
from dataclasses import dataclass, field

import numpy as np

from mmlearn.diagrams.perception.diagram import FrontPerceptionConfig
from mmlearn.models.common.config import param, validate_fields
from mmlearn.models.common.trials import register_trial
from mmlearn.models.perception.depth_filter import DepthFilterConfig
from mmlearn.models.perception.detection import STAGES, FrontDetectorConfig
from mmlearn.models.perception.evaluation import front_visibility, match_front, moving_track

__all__ = ["EXPECTED_MODEL", "TrackFrontsConfig", "track_fronts", "fronts_trial"]

EXPECTED_MODEL = {"drawer": "prismatic", "door": "revolute"}


@dataclass
class TrackFrontsConfig:
    """What :func:`track_fronts` does.

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
            stands still, :mod:`mmlearn.models.perception.depth_filter`) between the camera and
            the detector, at the camera's frame rate (one filter update per frame).
        filter: its parameters (``depth_std_at_1m`` is set from the scene's noise model).
        camera_rate_hz: the camera's frame rate with the temporal filter, Hz (default 30, a
            structured-light camera's; the detector and tracker run at their own period,
            ``frames`` over the opening, and see the filter's mean of the frames up to then;
            0 = one camera frame per detector period). Without the filter the camera runs at
            the detector's period (nothing reads the frames between).
        refit_every: the tracker refits a track's model every this many observations.
        html_out: where the app writes the Meshcat recording ("" = no).
        meshcat: the app shows it live.
    """

    object: str = param("drawer", choices=tuple(EXPECTED_MODEL))
    distance: float = param(1.5, unit="m", gt=0.2)
    angle_deg: float = param(0.0, unit="deg")
    frames: int = param(40, integer=True, ge=2)
    seed: int = param(0, integer=True, ge=0)
    match_pos_m: float = param(0.05, unit="m", gt=0)
    match_angle_deg: float = param(10.0, unit="deg", gt=0)
    match_size_m: float = param(0.1, unit="m", gt=0, finite=False)
    max_incidence_deg: float = param(70.0, unit="deg")
    min_displacement_m: float = param(0.0, unit="m")
    open_displacement_m: float = param(0.02, unit="m")
    selection_step: int = param(1, integer=True, ge=1)
    scene: FrontPerceptionConfig = field(default_factory=FrontPerceptionConfig)
    detector: FrontDetectorConfig = field(default_factory=FrontDetectorConfig)
    temporal_filter: bool = True
    filter: DepthFilterConfig = field(default_factory=DepthFilterConfig)
    camera_rate_hz: float = param(30.0, unit="Hz; 0 = one frame per detector period", ge=0)
    refit_every: int = param(5, integer=True, ge=1)
    html_out: str = ""
    meshcat: bool = False

    def validate(self) -> "TrackFrontsConfig":
        """Raise ``ValueError`` naming the first bad field; return the config."""
        return validate_fields(self)


def _scene(cfg: TrackFrontsConfig):
    """The scene's configuration for the trial and the detector's period, s."""
    sc = copy.deepcopy(cfg.scene)
    sc.front = cfg.object
    sc.camera.distance = float(cfg.distance)
    sc.camera.angle_deg = float(cfg.angle_deg)
    sc.noise.seed = int(cfg.seed)
    period = sc.motion.duration() / (cfg.frames - 1)
    sc.camera.rate_hz = 1.0 / period  # one noise frame index per camera frame
    if cfg.temporal_filter and sc.add_noise and cfg.camera_rate_hz > 0:
        sc.camera.rate_hz = float(cfg.camera_rate_hz)  # the filter folds in every frame
        sc.point_cloud_rate_hz = 1.0 / period  # the cloud drawn with each detection
    sc.validate()
    return sc, period


def _filter_config(cfg: TrackFrontsConfig, sc) -> DepthFilterConfig | None:
    """The temporal filter's configuration (its noise from the scene's), or None."""
    if not (cfg.temporal_filter and sc.add_noise):
        return None
    from mmlearn.models.common.depth_noise import predicted_depth_std

    filt_cfg = copy.deepcopy(cfg.filter)
    filt_cfg.depth_std_at_1m = float(predicted_depth_std(1.0, sc.camera.intrinsics(), sc.noise))
    return filt_cfg.validate()


def _build(cfg: TrackFrontsConfig, sc, period, filt_cfg, meshcat):
    """The scene with the detector and the tracker (and their Meshcat drawing): (the
    perception diagram, {"det", "trk"[, "vis"]})."""
    from mmlearn.diagrams.perception.diagram import (AddFrontDetectorAndTracker,
                                                     MakeFrontPerceptionDiagram)
    from mmlearn.systems import FrontTrackerConfig, FrontTrackVisualizer

    parts = {}

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

    return MakeFrontPerceptionDiagram(sc, meshcat=meshcat, add_systems=add), parts


def _seen_face(d, ctx, thickness):
    """(true pose of the face the camera sees, outer face's pose, camera pose, inner seen):
    the outer face, or the inner one (``thickness`` behind it) once the door has turned past
    the camera's line of sight (off-axis views)."""
    X_outer = d.GetOutputPort("X_WR").Eval(ctx).GetAsMatrix4()
    X_WC = d.GetOutputPort("X_WC").Eval(ctx).GetAsMatrix4()
    inner = float(X_outer[:3, 2] @ (X_WC[:3, 3] - X_outer[:3, 3])) < 0.0
    X_true = X_outer.copy()
    if inner:
        X_true[:3, 3] -= thickness * X_outer[:3, 2]
    return X_true, X_outer, X_WC, inner


def _score_frame(cfg, P, rects, X_true, X_outer, X_WC, inner, thickness) -> dict:
    """One frame's record: visibility and eligibility, whether the front was found and the
    errors of its match (against the seen face, and against the outer face)."""
    w, h = P.kinematics.width, P.kinematics.height
    vis = front_visibility(X_true, w, h, X_WC, P.intrinsics, P.kinematics.X_WR0)
    eligible = (vis["in_view"] and vis["incidence_deg"] < cfg.max_incidence_deg
                and vis["displacement_m"] >= cfg.min_displacement_m)
    eligible_open = eligible and vis["displacement_m"] >= cfg.open_displacement_m
    m = match_front(rects, X_true, w, h, max_pos_m=cfg.match_pos_m,
                    max_angle_deg=cfg.match_angle_deg, max_size_m=cfg.match_size_m)
    m_outer = (m if not inner or m is None else
               match_front([rects[m["index"]]], X_outer, w, h,
                           max_pos_m=cfg.match_pos_m + thickness,
                           max_angle_deg=cfg.match_angle_deg, max_size_m=cfg.match_size_m))
    return {"rectangles": len(rects), "found": m is not None, "eligible": eligible,
            "eligible_open": eligible_open, **vis, "inner_face_seen": inner,
            **({"pos_error_outer_face_m": m_outer["pos_error_m"]} if m_outer else {}),
            **({k: m[k] for k in ("pos_error_m", "orient_error_deg", "size_error_m")}
               if m else {})}


def _run_frames(cfg, sc, period, P, parts, progress):
    """Step the simulation to every detector frame and score it: (per-frame records, truth
    by time, detector timings, detector CPU s, filter CPU s, frames averaged, wall s)."""
    from pydrake.systems.analysis import Simulator

    d = P.diagram
    det = parts["det"]
    sim = Simulator(d)
    ctx = sim.get_mutable_context()
    det_ctx = det.GetMyContextFromRoot(ctx)
    if P.visualizer is not None:
        P.visualizer.StartRecording(False)
    sim.Initialize()
    thickness = sc.kitchen.front_thickness
    frames, truth_by_time = [], {}
    timings, cpu, filt_cpu, averaged = [], [], [], []
    filt = (d.GetSubsystemByName("depth_temporal_filter")
            if d.HasSubsystemNamed("depth_temporal_filter") else None)
    filt_ctx = filt.GetMyContextFromRoot(ctx) if filt is not None else None
    wall0 = time.perf_counter()
    ks = range(cfg.frames) if progress is None else progress(range(cfg.frames))
    for k in ks:
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
        timings.append(np.asarray(det.get_timings_output_port().Eval(det_ctx), float))
        X_true, X_outer, X_WC, inner = _seen_face(d, ctx, thickness)
        q = float(d.GetOutputPort("front_joint").Eval(ctx)[0])
        truth_by_time[round(t, 6)] = (X_true, P.kinematics.width, P.kinematics.height)
        rec = _score_frame(cfg, P, rects, X_true, X_outer, X_WC, inner, thickness)
        frames.append({"time": t, "joint_value": q, **rec})
    # the tracker takes the frame at t at the start of the next step: one more half period
    sim.AdvanceTo((cfg.frames - 1) * period + 0.5 * period)
    wall = time.perf_counter() - wall0
    return frames, truth_by_time, timings, cpu, filt_cpu, averaged, wall, sim


def _model_selection(cfg, trk, tracks, models, truth_by_time):
    """The moving front's track and the model selection on its observations: (track,
    matched observations, selection vs n or None, selected model, the tracker's own)."""
    from mmlearn.models.perception.tracking import (front_observation_model,
                                                    selection_vs_observations)

    mt, n_matched = moving_track(tracks, truth_by_time, max_pos_m=cfg.match_pos_m,
                                 max_angle_deg=cfg.match_angle_deg, max_size_m=cfg.match_size_m)
    if mt is None:
        return mt, n_matched, None, None, None
    tmod = models.get(mt.track_id)
    tracker_selected = tmod.selected if tmod is not None else None
    ns = list(range(3, mt.n + 1, cfg.selection_step))
    if ns and ns[-1] != mt.n:
        ns.append(mt.n)
    tcfg = trk.config()
    sel = selection_vs_observations(
        mt.poses, expected=EXPECTED_MODEL[cfg.object], ns=ns, models=tcfg.model_names(),
        obs=front_observation_model(tcfg.sigma_pos_m, math.radians(tcfg.sigma_orient_deg)),
        seed=tcfg.seed)
    return mt, n_matched, sel, sel["selected"][-1], tracker_selected


def _rate(frames):
    return (sum(f["found"] for f in frames) / len(frames)) if frames else None


def _mean_of(frames, key):
    vals = [f[key] for f in frames if key in f]
    return float(np.mean(vals)) if vals else None


def _detection_scores(cfg, frames) -> dict:
    found = [f for f in frames if f["found"]]
    elig = [f for f in frames if f["eligible"]]
    elig_open = [f for f in frames if f["eligible_open"]]
    visible = [f for f in frames if f["in_view"]]
    return {
        "frames_found": len(found),
        "detection_rate": len(found) / cfg.frames,
        "frames_visible": len(visible),
        "detection_rate_visible": _rate(visible),
        "frames_eligible": len(elig),
        "detection_rate_eligible": _rate(elig),
        "frames_eligible_open": len(elig_open),
        "detection_rate_eligible_open": _rate(elig_open),
        "pos_error_m": _mean_of(found, "pos_error_m") if found else None,
        "pos_error_outer_face_m": _mean_of(found, "pos_error_outer_face_m"),
        "frames_inner_face_seen": int(sum(f["inner_face_seen"] for f in frames)),
        "orient_error_deg": _mean_of(found, "orient_error_deg") if found else None,
        "size_error_m": _mean_of(found, "size_error_m") if found else None,
    }


def _selection_scores(cfg, mt, n_matched, sel, selected, tracker_selected) -> dict:
    expected = EXPECTED_MODEL[cfg.object]
    return {
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
    }


def _timing_scores(timings, cpu, filt_cpu, averaged, drawn: bool) -> dict:
    from mmlearn.systems.perception.front_detector import TIMING_NAMES

    T = np.array(timings)  # (frames, stages + total), s; NaN rows: frame not processed
    ok_rows = T[np.all(np.isfinite(T), axis=1)] if T.size else T

    def med(col):
        return 1e3 * float(np.median(ok_rows[:, col])) if len(ok_rows) else None

    return {
        "ms_per_frame": med(len(TIMING_NAMES) - 1),
        "cpu_ms_per_frame": None if drawn or not cpu else 1e3 * float(np.median(cpu)),
        "filter_cpu_ms_per_frame": (None if drawn or not filt_cpu
                                    else 1e3 * float(np.median(filt_cpu))),
        "filter_frames_averaged": averaged or None,
        "stage_ms": {s: med(i) for i, s in enumerate(STAGES)},
        "frames_not_processed": int(len(T) - len(ok_rows)),
    }


def track_fronts(config: TrackFrontsConfig, *, meshcat=None, progress=None) -> dict:
    """Run the scene with the detector and the tracker over ``config.frames`` frames; returns
    the scores (a JSON-able dict; ``html_out`` None: writing the recording is the caller's).

    Args:
        config: the trial (validated here).
        meshcat: draw the scene, the detections, the tracks and their models there (None =
            no drawing).
        progress: None, or a function wrapping the iterable of frame indices (a progress bar).
    """
    cfg = config
    cfg.validate()
    sc, period = _scene(cfg)
    cfg.detector.validate()
    sc.point_cloud = meshcat is not None and sc.point_cloud
    P, parts = _build(cfg, sc, period, _filter_config(cfg, sc), meshcat)
    frames, truth_by_time, timings, cpu, filt_cpu, averaged, wall, sim = _run_frames(
        cfg, sc, period, P, parts, progress)
    ctx = sim.get_context()
    trk = parts["trk"]
    trk_ctx = trk.GetMyContextFromRoot(ctx)
    st = trk.state(trk_ctx)
    tracks = trk.get_tracks_output_port().Eval(trk_ctx)
    models = trk.get_models_output_port().Eval(trk_ctx)
    if "vis" in parts:
        parts["vis"].ForcedPublish(parts["vis"].GetMyContextFromRoot(ctx))
    if P.visualizer is not None:
        P.visualizer.StopRecording()
        P.visualizer.PublishRecording()
    selection = _model_selection(cfg, trk, tracks, models, truth_by_time)
    if meshcat is not None:
        from mmlearn.systems.common.meshcat_view import draw_legend
        from mmlearn.systems.perception.front_visualizer import front_legend

        mt = selection[0]
        draw_legend(meshcat, *front_legend(cfg.object, None if mt is None else mt.track_id,
                                           tracks, models, point_cloud=sc.point_cloud))
    timing = _timing_scores(timings, cpu, filt_cpu, averaged, meshcat is not None)
    return {
        "object": cfg.object, "distance_m": float(cfg.distance),
        "angle_deg": float(cfg.angle_deg), "seed": cfg.seed, "frames": cfg.frames,
        "period_s": period,
        "match": {"pos_m": cfg.match_pos_m, "angle_deg": cfg.match_angle_deg,
                  "size_m": cfg.match_size_m},
        "eligible_if": {"in_view": True, "incidence_below_deg": cfg.max_incidence_deg,
                        "displacement_at_least_m": cfg.min_displacement_m,
                        "open_displacement_at_least_m": cfg.open_displacement_m},
        **_detection_scores(cfg, frames),
        **_selection_scores(cfg, *selection),
        "tracks": len(st.tracking.tracks),
        "published_tracks": len(tracks),
        "track_models": {str(k): v.selected for k, v in sorted(models.items())},
        "ms_per_frame": timing["ms_per_frame"],
        "cpu_ms_per_frame": timing["cpu_ms_per_frame"],
        "filter_cpu_ms_per_frame": timing["filter_cpu_ms_per_frame"],
        "camera_rate_hz": float(sc.camera.rate_hz),
        "filter_frames_averaged": timing["filter_frames_averaged"],
        "stage_ms": timing["stage_ms"],
        "frames_not_processed": timing["frames_not_processed"],
        "wall_s": wall,
        "per_frame": frames,
        "html_out": None,
    }


@register_trial("perception.fronts", version=2, record={"experiment": str, "frame_found": list})
def fronts_trial(*, seed: int, experiment: str, object: str, distance: float,
                 angle: float = 0.0, frames: int = 60, temporal_filter: bool = True,
                 camera_rate_hz: float = 0.0, plane_method: str = "ransac", shared=None) -> dict:
    """One :func:`track_fronts` run; returns its scores without the per-frame list (plus the
    per-frame found / eligible flags and errors, compact). ``temporal_filter``: the
    DepthTemporalFilter between camera and detector; ``camera_rate_hz``: the camera's frame
    rate with it (0 = one frame per detector period); ``plane_method``: the detector's plane
    stage (``FrontDetectorConfig.plane_method``)."""
    r = track_fronts(TrackFrontsConfig(object=object, distance=float(distance),
                                       angle_deg=float(angle), frames=int(frames),
                                       seed=int(seed), temporal_filter=bool(temporal_filter),
                                       camera_rate_hz=float(camera_rate_hz),
                                       detector=FrontDetectorConfig(
                                           plane_method=str(plane_method)).validate()))
    pf = r.pop("per_frame")
    r["frame_found"] = [bool(f["found"]) for f in pf]
    r["frame_eligible"] = [bool(f["eligible"]) for f in pf]
    r["frame_eligible_open"] = [bool(f["eligible_open"]) for f in pf]
    r["frame_in_view"] = [bool(f["in_view"]) for f in pf]
    r["frame_joint"] = [float(f["joint_value"]) for f in pf]
    r["frame_incidence_deg"] = [float(f["incidence_deg"]) for f in pf]
    r["frame_pos_error_m"] = [f.get("pos_error_m") for f in pf]
    r["experiment"] = experiment
    return r
