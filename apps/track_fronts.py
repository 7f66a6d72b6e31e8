"""Detect and track a cabinet front in noisy depth images and learn its articulation
(thesis ch. 5: FrontDetector -> FrontTracker -> link model), scored against the ground truth.

    python -m mmlearn.apps.track_fronts --object drawer --distance 1.5 --frames 40 --seed 3 \\
        [--angle DEG] [--camera-rate HZ] [--no-temporal-filter] [--meshcat] [--html-out F] \\
        [--json]

The kitchen scene of :mod:`mmlearn.diagrams.perception.diagram` (RgbdSensor + DepthNoise) with a
:class:`~mmlearn.systems.FrontDetector` and a :class:`~mmlearn.systems.FrontTracker` added;
the moving front opens in the scene's stepped profile and ``--frames`` detector frames are
taken evenly over it (the first closed, the last fully open); by default the detector sees every
camera frame (13 s of motion at 30 Hz: 391 frames; :func:`every_camera_frame`). The camera and the
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
  (closed fronts, flush with their neighbours behind a 5 mm reveal, left out);
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
at its time (its own Meshcat group, keyed visible / hidden in the animation). A legend
(:func:`~mmlearn.systems.front_legend`) names each drawn thing: the moving front's track with
its learned model and numbers, the other tracks' models by kind, the detections, the camera
and its point cloud.
"""

import json
import math
import sys
from pathlib import Path

from mmlearn.apps.common.cli import (ArgumentParser, UsageError, check_in_file, check_out_file,
                                     fail, finish_viewing, json_clean, load_config, make_meshcat,
                                     nonneg_int, pos_int, progress, save_html)
from mmlearn.diagrams.perception.diagram import FrontPerceptionConfig
from mmlearn.diagrams.perception.trials import EXPECTED_MODEL, TrackFrontsConfig, track_fronts

__all__ = ["run", "main"]


def run(*, config: TrackFrontsConfig, meshcat=None, show_progress: bool = True) -> dict:
    """:func:`mmlearn.diagrams.perception.trials.track_fronts` with the app's Meshcat (made
    when ``config.meshcat`` or ``config.html_out`` asks for one), progress bar and recording
    (written to ``config.html_out``); returns the scores described in the module docstring."""
    config.validate()
    if meshcat is None and (config.meshcat or config.html_out):
        meshcat = make_meshcat(announce=config.meshcat)
    out = track_fronts(config, meshcat=meshcat, progress=lambda ks: progress(
        ks, desc=f"{config.object} frames", unit="frame", enabled=show_progress))
    if config.html_out and meshcat is not None:
        out["html_out"] = str(save_html(meshcat, config.html_out))
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
        f"  detector: {f(r['ms_per_frame'], '.1f')} ms per frame (median wall"
        + ("" if r["cpu_ms_per_frame"] is None
           else f"; CPU {r['cpu_ms_per_frame']:.1f} ms") + "); per stage: "
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
    ap.add_argument("--frames", type=pos_int, default=None,
                    help="detector frames over the opening (>= 2; default: every camera frame "
                         "at --camera-rate, or 40 with --camera-rate 0 or without the filter)")
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
        if args.frames is not None and args.frames < 2:
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
    frames = args.frames or every_camera_frame(scene, args.camera_rate,
                                               not args.no_temporal_filter)
    cfg = TrackFrontsConfig(object=args.object, distance=args.distance, angle_deg=args.angle,
                            frames=frames, seed=args.seed,
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


def every_camera_frame(scene, camera_rate_hz: float, temporal_filter: bool = True) -> int:
    """Detector frames for the detector to see every camera frame of ``scene``'s motion at
    ``camera_rate_hz`` (one at its start and one per camera period after it); 40 without a
    camera rate (0) or without the temporal filter (no camera frames between detections)."""
    if camera_rate_hz <= 0 or not temporal_filter or not scene.add_noise:
        return 40
    return max(2, int(round(scene.motion.duration() * camera_rate_hz)) + 1)


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
