"""Learn the body schema of a simulated arm by motor babbling (thesis ch. 3), in Drake.

The arm (Drake MultibodyPlant, implicit PD + gravity compensation) babbles to random
reachable, collision-free targets; a MarkerSensor observes its part markers with noise and
drop-outs; a SchemaLearner takes one sample per target (after the arm settled) and learns
the structure and the local GP models. Afterwards, on an independent test set of random
configurations: the prediction error of the learned forward kinematics (part poses relative
to the root part, against the plant's true marker poses), the observation noise of the
sensor on the same configurations, and the positioning error of a SchemaController driving
the end effector in the simulation to targets using the learned model.

    python -m mmlearn.apps.learn_body_schema --arm 2dof --samples 30 --noise 0.044 --json
    python -m mmlearn.apps.learn_body_schema --arm 7dof --occlude x4 --samples 60
"""

from __future__ import annotations

import json
import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mmlearn.apps.common.cli import (ArgumentParser, UsageError, check_out_file, fail,
                                     finish_viewing, make_meshcat, nonneg_float, nonneg_int,
                                     pos_int, progress, save_html)


@dataclass
class LearnBodySchemaConfig:
    """What :func:`run` does.

    Attributes:
        arm: "2dof", "4dof" or "7dof".
        samples: babbling samples to learn from.
        noise: RMS 3-D position noise of the marker observations, m.
        noise_orient_deg: RMS orientation noise of the marker observations, deg.
        occlude: parts never observed (e.g. ["x4"]).
        seed: seeds sensor noise, babbling and the test set.
        n_test: test configurations for the prediction error.
        n_control: targets for the control error (0 = skip).
        control_time: simulated seconds per control target.
        babble_fraction: fraction of each joint range babbled in.
        sensor: "ideal" (MarkerSensor: true poses + Gaussian noise) or "camera" (ArUco
            markers detected in rendered RGB images, see CameraMarkerSensor; ``noise`` and
            ``noise_orient_deg`` then only tell the learner what noise to assume).
        camera_depth: with ``sensor="camera"``, the depth images that resolve the markers'
            mirror ambiguity: "exact" (Drake's rendered depth), "noisy" (through a
            structured-light camera's noise model, ``DepthNoiseConfig()`` defaults:
            1.6 mm x z^2, 1/8 px disparity steps, missing pixels) or "none" (no depth:
            the reprojection ratio and the last report decide).
        html_out: write the Meshcat recording here ("" = no).
        meshcat: live Meshcat view.
    """

    arm: str = "2dof"
    samples: int = 50
    noise: float = 0.044
    noise_orient_deg: float = 0.0
    occlude: list[str] = field(default_factory=list)
    seed: int = 0
    n_test: int = 100
    n_control: int = 5
    control_time: float = 2.5
    babble_fraction: float = 0.6
    sensor: str = "ideal"
    camera_depth: str = "exact"
    html_out: str = ""
    meshcat: bool = False


def structure_rows(schema, parts) -> list[dict]:
    return [{"a": parts[m.i], "b": parts[m.j], "actions": [int(a) for a in m.Q]}
            for m in schema.tree]


def is_correct(keys, truth, n_nodes) -> bool:
    """The tree (a, b, Q) keys span ``n_nodes`` parts with the true action sets."""
    return len(keys) == n_nodes - 1 and all(
        frozenset(Q) == truth[(min(a, b), max(a, b))] for a, b, Q in keys)


def converged_at(history, truth, n_nodes):
    """First sample count after which the structure stayed correct (None if never)."""
    at = None
    for n, _valid, keys in history:
        if is_correct(keys, truth, n_nodes):
            at = n if at is None else at
        else:
            at = None
    return at


def sample_test_commands(bs, n, rng) -> np.ndarray:
    """``n`` random reachable, collision-free commands inside the babbling range."""
    lo, hi = bs.babbling._lo, bs.babbling._hi
    out = []
    for _ in range(50):
        Q = rng.uniform(lo, hi, size=(4 * n, lo.size))
        out += [q for q in Q if bs.babbling._accept(q)]
        if len(out) >= n:
            break
    return np.array(out[:n])


def prediction_error(bs, root, schema, Q):
    """Mean position (m) and rotation (deg) error of the learned FK of every tree part
    (relative to the root part) against the plant, over commands ``Q``."""
    from mmlearn.models.body_schema.local import pose_errors, se3_inv

    X = np.array([bs.true_poses(root, q) for q in Q])
    r = schema.root
    T_true = se3_inv(X[:, r:r + 1]) @ X
    T = schema.forward_kinematics(Q)
    parts = [p for p in schema.nodes if p != r]
    dp, dr = pose_errors(T[:, parts], T_true[:, parts])
    return float(dp.mean()), float(np.rad2deg(dr.mean()))


def observation_noise(bs, root, Q, seed) -> float:
    """Mean position error (m) of the scene's marker sensor (ideal or camera) at commands
    ``Q``, against the plant's true ``<part>_marker`` poses."""
    plant, sensor = bs.scene.plant, bs.scene.sensor
    ctx = bs.diagram.CreateDefaultContext()
    sctx = sensor.GetMyContextFromRoot(ctx)
    errs = []
    for k, q in enumerate(Q):
        bs.scene.set_joint_positions(ctx, q)
        if bs.failures is not None:
            src = plant.GetMyContextFromRoot(root)
            pc = plant.GetMyMutableContextFromRoot(ctx)
            qq = plant.GetPositions(pc)
            for j in bs.failures.joints:
                qq[j.position_start()] = plant.GetPositions(src)[j.position_start()]
            plant.SetPositions(pc, qq)
        obs = sensor.observe(sctx, frame=10_000_000 + 1000 * seed + k)
        pc = plant.GetMyContextFromRoot(ctx)
        true = [plant.GetFrameByName(f"{n}_marker", bs.scene.robot).CalcPoseInWorld(pc)
                for n in obs.marker_ids]
        errs += [np.linalg.norm(obs.poses[i].translation() - true[i].translation())
                 for i in range(len(true)) if obs.visible[i] and not obs.outlier[i]]
    return float(np.mean(errs)) if errs else float("nan")


def control_error(bs, simulator, Q, seconds, show_progress=True):
    """Drive the end effector with the SchemaController to the true end-effector
    positions of commands ``Q``; mean final true distance (m)."""
    root = simulator.get_mutable_context()
    plant, robot = bs.scene.plant, bs.scene.robot
    ee = plant.GetFrameByName(f"{bs.parts[bs.learner.end_effector]}_marker", robot)
    bs.controller.set_command(root, bs.diagram.GetOutputPort("command").Eval(root))
    bs.set_mode(root, "control")
    errs = []
    for q in progress(Q, desc="control", unit="target", enabled=show_progress):
        target = bs.true_poses(root, q)[bs.learner.end_effector, :3, 3]
        bs.set_target(root, target)
        simulator.AdvanceTo(root.get_time() + seconds)
        p = ee.CalcPoseInWorld(plant.GetMyContextFromRoot(root)).translation()
        errs.append(float(np.linalg.norm(p - target)))
    bs.set_mode(root, "babble")
    return float(np.mean(errs)) if errs else float("nan")


def babble(bs, simulator, n_samples, *, show_progress=True, desc="babbling"):
    """Advance until the learner has ``n_samples`` samples (more than before the call)."""
    root = simulator.get_mutable_context()
    start = bs.learner.state(root).n_samples
    bar = progress(range(n_samples), desc=desc, unit="sample", enabled=show_progress)
    it = iter(bar)
    got = 0
    limit = root.get_time() + 20 * n_samples * bs.config.babble_period + 5
    while got < n_samples and root.get_time() < limit:
        simulator.AdvanceTo(root.get_time() + 0.1)
        now = bs.learner.state(root).n_samples - start
        while got < now:
            got += 1
            next(it, None)
    if hasattr(bar, "close"):
        bar.close()
    return got


CAMERA_DEPTHS = ("exact", "noisy", "none")


def camera_config(camera_depth: str = "exact", seed: int = 0):
    """The camera marker sensor's configuration for ``camera_depth`` (see
    :class:`LearnBodySchemaConfig`); the depth noise is seeded with ``seed``."""
    from mmlearn.models.common.depth_noise import DepthNoiseConfig
    from mmlearn.systems.common.camera_marker_sensor import CameraMarkerSensorConfig

    if camera_depth == "exact":
        return CameraMarkerSensorConfig()
    if camera_depth == "noisy":
        return CameraMarkerSensorConfig(depth_noise=DepthNoiseConfig(seed=int(seed)))
    if camera_depth == "none":
        return CameraMarkerSensorConfig(use_depth=False)
    raise ValueError(f"camera_depth must be one of {', '.join(CAMERA_DEPTHS)}, got "
                     f"{camera_depth!r}")


def run(*, config: LearnBodySchemaConfig, meshcat=None, show_progress: bool = True) -> dict:
    """Learn, evaluate and return the results dict (see the module docstring)."""
    from pydrake.systems.analysis import Simulator

    from mmlearn.diagrams.body_schema.diagram import BodySchemaDiagramConfig, MakeBodySchemaDiagram

    cfg = config
    if cfg.samples < 1:
        raise ValueError(f"samples must be >= 1, got {cfg.samples}")
    if not (math.isfinite(cfg.noise) and cfg.noise >= 0):
        raise ValueError(f"noise must be >= 0 m, got {cfg.noise}")
    if cfg.n_test < 1 or cfg.n_control < 0 or not cfg.control_time > 0:
        raise ValueError("need n_test >= 1, n_control >= 0, control_time > 0")
    if cfg.camera_depth not in CAMERA_DEPTHS:
        raise ValueError(f"camera_depth must be one of {', '.join(CAMERA_DEPTHS)}, got "
                         f"{cfg.camera_depth!r}")
    t_start = time.perf_counter()
    if meshcat is None and (cfg.meshcat or cfg.html_out):
        meshcat = make_meshcat(announce=cfg.meshcat)
    dcfg = BodySchemaDiagramConfig(arm=cfg.arm, noise_pos=cfg.noise,
                                   noise_orient=math.radians(cfg.noise_orient_deg),
                                   occlude=list(cfg.occlude), seed=cfg.seed,
                                   babble_fraction=cfg.babble_fraction, sensor=cfg.sensor,
                                   camera=camera_config(cfg.camera_depth, cfg.seed))
    bs = MakeBodySchemaDiagram(dcfg, meshcat=meshcat)
    simulator = Simulator(bs.diagram)
    root = simulator.get_mutable_context()
    bs.prepare(root)
    if cfg.meshcat:
        simulator.set_target_realtime_rate(1.0)
    vis = bs.scene.visualizer
    if vis is not None:
        vis.StartRecording(False)
    simulator.Initialize()
    got = babble(bs, simulator, cfg.samples, show_progress=show_progress)
    st = bs.learner.state(root)
    schema = st.schema
    rng = np.random.default_rng([cfg.seed, 7])
    Q = sample_test_commands(bs, cfg.n_test, rng)
    n_nodes = len(schema.nodes) if schema.nodes else len(bs.parts)
    result = {
        "arm": cfg.arm,
        "sensor": cfg.sensor,
        "camera_depth": cfg.camera_depth if cfg.sensor == "camera" else None,
        "parts": bs.parts,
        "samples": int(st.n_samples),
        "structure": structure_rows(schema, bs.parts),
        "structure_correct": is_correct([(m.i, m.j, m.Q) for m in schema.tree], bs.truth,
                                        n_nodes),
        "converged_at": converged_at(st.history, bs.truth, n_nodes),
        "valid": bool(schema.valid),
        "pred_error_m": None,
        "pred_error_deg": None,
        "obs_noise_m": observation_noise(bs, root, Q[:30], cfg.seed),
        "ctrl_error_m": None,
        "update_ms_median": float(1000 * np.median(st.update_seconds)) if st.update_seconds
        else None,
        "update_ms_max": float(1000 * np.max(st.update_seconds)) if st.update_seconds
        else None,
        "dropped_frames": int(st.n_dropped),
    }
    if got < cfg.samples:
        result["warning"] = f"only {got} samples were taken"
    if schema.tree and len(schema.tree) == n_nodes - 1:
        result["pred_error_m"], result["pred_error_deg"] = prediction_error(
            bs, root, schema, Q)
        if cfg.n_control:
            result["ctrl_error_m"] = control_error(bs, simulator, Q[-cfg.n_control:],
                                                   cfg.control_time, show_progress)
    result["sim_seconds"] = float(root.get_time())
    result["seconds"] = round(time.perf_counter() - t_start, 3)
    result["html_out"] = None
    if vis is not None:
        vis.StopRecording()
        vis.PublishRecording()
        if cfg.html_out:
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
