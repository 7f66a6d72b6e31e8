"""Learn the body schema of a simulated arm by motor babbling (thesis ch. 3), in Drake.

The arm (Drake MultibodyPlant, implicit PD + gravity compensation) babbles to random
reachable, collision-free targets; a MarkerSensor observes its part markers with noise and
drop-outs; a SchemaLearner takes one sample per target (after the arm settled) and learns
the structure and the local GP models. Afterwards, on an independent test set of random
configurations: the prediction error of the learned forward kinematics (part poses relative
to the root part, against the plant's true marker poses), the observation noise of the
sensor on the same configurations, and the positioning error of a SchemaController driving
the end effector in the simulation to targets using the learned model.

Meshcat (``--meshcat`` live, ``--html-out`` recording): the arm and, beside it, the part
frames the learned schema predicts and the learned tree (green: a valid local model, red:
an invalid one), framed by the camera, with a legend giving the prediction error and the
number of samples.

    python -m mmlearn.apps.learn_body_schema --arm 2dof --samples 30 --noise 0.044 --json
    python -m mmlearn.apps.learn_body_schema --arm 7dof --occlude x4 --samples 60
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from mmlearn.apps.common.cli import (ArgumentParser, UsageError, check_out_file, fail,
                                     finish_viewing, make_meshcat, nonneg_float, nonneg_int,
                                     pos_int, save_html)
from mmlearn.diagrams.body_schema.trials import (CAMERA_DEPTHS, LearnBodySchemaConfig,
                                                 learn_body_schema)


def run(*, config: LearnBodySchemaConfig, meshcat=None, show_progress: bool = True) -> dict:
    """Learn, evaluate and return the results dict (see the module docstring;
    :func:`mmlearn.diagrams.body_schema.trials.learn_body_schema`), viewed live in Meshcat
    with ``config.meshcat`` and recorded as HTML to ``config.html_out``."""
    cfg = config
    if meshcat is None and (cfg.meshcat or cfg.html_out):
        meshcat = make_meshcat(announce=cfg.meshcat)
    result = learn_body_schema(config=cfg, meshcat=meshcat, show_progress=show_progress)
    if meshcat is not None and cfg.html_out:
        result["html_out"] = str(save_html(meshcat, cfg.html_out))
    return result


def main(argv=None) -> int:
    ap = ArgumentParser(
        prog="python -m mmlearn.apps.learn_body_schema",
        description="Learn an arm's body schema from motor babbling in the Drake simulation "
                    "and report structure, prediction, observation-noise and control errors "
                    "on an independent test set.")
    ap.add_argument("--arm", default="2dof", choices=["2dof", "4dof", "7dof"])
    ap.add_argument("--samples", type=pos_int, default=50, help="babbling samples (default 50)")
    ap.add_argument("--noise", type=nonneg_float, default=0.044,
                    help="RMS marker position noise, m (default 0.044)")
    ap.add_argument("--noise-orient", type=nonneg_float, default=0.0,
                    help="RMS marker orientation noise, deg (default 0)")
    ap.add_argument("--occlude", nargs="*", default=[], metavar="PART",
                    help="parts whose markers are never seen (e.g. x4)")
    ap.add_argument("--sensor", choices=["ideal", "camera"], default="ideal",
                    help="ideal: true marker poses + Gaussian noise (default); camera: ArUco "
                         "markers detected in rendered RGB images (slower, ~0.5 s per frame)")
    ap.add_argument("--camera-depth", choices=list(CAMERA_DEPTHS), default="exact",
                    help="with --sensor camera: the depth that resolves the markers' mirror "
                         "ambiguity: exact (rendered, default), noisy (a structured-light "
                         "camera's noise model) or none")
    ap.add_argument("--seed", type=nonneg_int, default=0)
    ap.add_argument("--n-test", type=pos_int, default=100, help="test configurations")
    ap.add_argument("--n-control", type=nonneg_int, default=5,
                    help="control targets (0 = skip)")
    ap.add_argument("--meshcat", action="store_true",
                    help="show the run live in Meshcat (prints the URL; real-time pacing)")
    ap.add_argument("--html-out", type=Path, help="save the Meshcat recording as HTML")
    ap.add_argument("--json", action="store_true", help="print the results as JSON")
    args = ap.parse_args(argv)
    try:
        check_out_file("--html-out", args.html_out)
    except UsageError as e:
        return fail(ap.prog, str(e))
    cfg = LearnBodySchemaConfig(arm=args.arm, samples=args.samples, noise=args.noise,
                                noise_orient_deg=args.noise_orient, occlude=args.occlude,
                                seed=args.seed, n_test=args.n_test, n_control=args.n_control,
                                sensor=args.sensor, camera_depth=args.camera_depth,
                                html_out=str(args.html_out or ""), meshcat=args.meshcat)
    try:
        r = run(config=cfg, show_progress=not args.json)
    except ValueError as e:
        return fail(ap.prog, str(e))
    if args.json:
        print(json.dumps(r))
    else:
        print(f"{r['arm']} arm, parts {r['parts']}: {r['samples']} samples, "
              f"{r['sim_seconds']:.1f} s simulated, {r['seconds']:.1f} s wall")
        print("structure (" + ("correct" if r["structure_correct"] else "NOT correct")
              + f", converged at sample {r['converged_at']}):")
        for e in r["structure"]:
            print(f"  {e['a']} - {e['b']}  actions {e['actions']}")
        f = (lambda v, u: "n/a" if v is None else f"{v:.4f} {u}")
        print(f"prediction error {f(r['pred_error_m'], 'm')} / {f(r['pred_error_deg'], 'deg')}"
              f"; observation noise {f(r['obs_noise_m'], 'm')}")
        print(f"control error {f(r['ctrl_error_m'], 'm')}; schema update median "
              f"{f(r['update_ms_median'], 'ms')}")
    finish_viewing(html_out=None if args.json else r["html_out"], live=args.meshcat)
    return 0


if __name__ == "__main__":
    sys.exit(main())
