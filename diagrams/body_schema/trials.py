"""The body-schema capability's Drake trials (thesis ch. 3): learning an arm's body schema by
motor babbling in the simulation (:func:`learn_body_schema`) and the runs of the experiments
of Sec. 3.4 (:func:`body_schema_trial`, registered as ``body_schema.experiment``: Fig. 3.10,
the noise-free accuracy, the 7-DOF arm with an occluded part, Tables 3.1 and 3.2; the tables'
many-run statistics in the numpy simulation of :mod:`mmlearn.models.body_schema.evaluation`)."""

from __future__ import annotations

import copy
import math
import time
from dataclasses import dataclass, field

import numpy as np

from mmlearn.models.body_schema.evaluation import converged_at, correct_from, is_correct
from mmlearn.models.common.progress import progress
from mmlearn.models.common.trials import register_trial

__all__ = ["LearnBodySchemaConfig", "CAMERA_DEPTHS", "camera_config", "structure_rows",
           "sample_test_commands", "prediction_error", "observation_noise", "control_error",
           "babble", "learn_body_schema", "make_body_schema_sim", "positioning_error",
           "drake_accuracy", "drake_recovery", "drake_control", "BLOCKS",
           "body_schema_trial"]


@dataclass
class LearnBodySchemaConfig:
    """What :func:`learn_body_schema` does.

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
        html_out: write the Meshcat recording here ("" = no; the app does).
        meshcat: live Meshcat view (real-time pacing).
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
    """The learned tree as rows ``{"a": part, "b": part, "actions": [joint indices]}``."""
    return [{"a": parts[m.i], "b": parts[m.j], "actions": [int(a) for a in m.Q]}
            for m in schema.tree]


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


def learn_body_schema(*, config: LearnBodySchemaConfig, meshcat=None,
                      show_progress: bool = True) -> dict:
    """Learn the body schema of a simulated arm by motor babbling in Drake and evaluate it
    (thesis ch. 3): the arm babbles to random reachable, collision-free targets, a marker
    sensor observes its parts, the SchemaLearner learns the structure and the local models.
    Afterwards, on an independent test set of random configurations: the prediction error
    of the learned forward kinematics (part poses relative to the root part, against the
    plant's true marker poses), the sensor's observation noise on the same configurations
    and the positioning error of the SchemaController driving the end effector to targets
    with the learned model. ``meshcat``: draw and record the run there (published at the
    end; real-time pacing with ``config.meshcat``). Returns the results dict."""
    cfg = config
    _check_config(cfg)
    t_start = time.perf_counter()
    bs, simulator, root = _learning_simulation(cfg, meshcat)
    got = babble(bs, simulator, cfg.samples, show_progress=show_progress)
    st = bs.learner.state(root)
    schema = st.schema
    rng = np.random.default_rng([cfg.seed, 7])
    Q = sample_test_commands(bs, cfg.n_test, rng)
    n_nodes = len(schema.nodes) if schema.nodes else len(bs.parts)
    result = _learned_record(cfg, bs, st, n_nodes)
    result["obs_noise_m"] = observation_noise(bs, root, Q[:30], cfg.seed)
    result.update(_update_times(st))
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
    vis = bs.scene.visualizer
    if vis is not None:
        vis.StopRecording()
        vis.PublishRecording()
    if meshcat is not None:
        _frame_and_legend(meshcat, bs, root, Q[:30], cfg, result)
    return result


def _frame_and_legend(meshcat, bs, root, Q, cfg, result) -> None:
    """Frame the arm over the test configurations ``Q`` and the learned schema drawn beside
    it; draw a legend with what was learned (``result``)."""
    from pydrake.geometry import Rgba

    from mmlearn.systems.common.meshcat_view import draw_legend, frame_camera

    off = np.asarray(bs.config.draw_offset, float)
    P = np.concatenate([bs.true_poses(root, q)[:, :3, 3] for q in Q])
    frame_camera(meshcat, np.concatenate([P, P + off]),
                 view_from=np.cross(off, [0.0, 0.0, 1.0]) + [0.0, 0.0, 0.6])
    n_tree = len(result["structure"])
    pe, pd = result.get("pred_error_m"), result.get("pred_error_deg")
    err = ("not evaluated (no complete tree)" if pe is None
           else f"{1000 * pe:.0f} mm / {pd:.1f} deg mean on {cfg.n_test} test poses")
    rows = [
        (Rgba(0.9, 0.55, 0.1, 1), "box", f"the real arm ({cfg.arm}, {len(bs.parts)} parts with "
                                         f"markers, noise {cfg.noise:g} m)"),
        (Rgba(0.9, 0.1, 0.1, 1), "line", f"part frames predicted by the learned schema, "
                                         f"drawn {np.linalg.norm(off):.2f} m beside the arm"),
        (None, "", "    (x red, y green, z blue; a dark dot at each origin)"),
        (Rgba(0.1, 0.7, 0.2, 1), "line", f"learned local models in the tree ({n_tree}), "
                                         f"valid"),
        (Rgba(0.9, 0.1, 0.1, 1), "thin", "a local model that is invalid (none at the end)"
         if result.get("valid") else "a local model that is invalid"),
        (None, "", f"prediction error of the learned kinematics: {err}"),
        (None, "", "structure " + ("right" if result.get("structure_correct") else "WRONG")
         + f" after {result['samples']} samples"),
    ]
    draw_legend(meshcat, f"Body schema learned by motor babbling ({cfg.arm} arm)", rows)


def _check_config(cfg: LearnBodySchemaConfig) -> None:
    if cfg.samples < 1:
        raise ValueError(f"samples must be >= 1, got {cfg.samples}")
    if not (math.isfinite(cfg.noise) and cfg.noise >= 0):
        raise ValueError(f"noise must be >= 0 m, got {cfg.noise}")
    from mmlearn.systems.common.marker_sensor import MarkerSensorConfig

    ws = MarkerSensorConfig()
    side = float(np.min(np.subtract(ws.workspace_max, ws.workspace_min)))
    if cfg.noise >= side:
        raise ValueError(f"noise {cfg.noise:g} m is not smaller than the workspace the markers "
                         f"move in ({side:g} m, its smallest side): every observation would "
                         "be noise")
    if not (math.isfinite(cfg.noise_orient_deg) and 0 <= cfg.noise_orient_deg <= 180):
        raise ValueError(f"noise_orient_deg must be in [0, 180] deg, got {cfg.noise_orient_deg}")
    if cfg.n_test < 1 or cfg.n_control < 0 or not cfg.control_time > 0:
        raise ValueError("need n_test >= 1, n_control >= 0, control_time > 0")
    if cfg.camera_depth not in CAMERA_DEPTHS:
        raise ValueError(f"camera_depth must be one of {', '.join(CAMERA_DEPTHS)}, got "
                         f"{cfg.camera_depth!r}")


def _learning_simulation(cfg: LearnBodySchemaConfig, meshcat):
    """The body-schema diagram of ``cfg``, its simulator (initialised, recording when
    drawn in ``meshcat``) and root context."""
    from pydrake.systems.analysis import Simulator

    from mmlearn.diagrams.body_schema.diagram import BodySchemaDiagramConfig, MakeBodySchemaDiagram

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
    if bs.scene.visualizer is not None:
        bs.scene.visualizer.StartRecording(False)
    simulator.Initialize()
    return bs, simulator, root


def _learned_record(cfg: LearnBodySchemaConfig, bs, st, n_nodes: int) -> dict:
    """What was learned: the structure against the true one (errors filled in later)."""
    schema = st.schema
    return {
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
        "obs_noise_m": None,
        "ctrl_error_m": None,
    }


def _update_times(st) -> dict:
    """The learner's update times (median, largest; ms) and its dropped frames."""
    u = st.update_seconds
    return {"update_ms_median": float(1000 * np.median(u)) if u else None,
            "update_ms_max": float(1000 * np.max(u)) if u else None,
            "dropped_frames": int(st.n_dropped)}


def make_body_schema_sim(arm, noise, seed, **kw):
    """A body-schema diagram of ``arm`` (marker noise ``noise`` m), its simulator and root
    context, initialised."""
    from pydrake.systems.analysis import Simulator

    from mmlearn.diagrams.body_schema.diagram import BodySchemaDiagramConfig, MakeBodySchemaDiagram

    # noise-free runs need a floor on the learner's noise level for the 3-sigma validity
    # test: 1 cm
    kw.setdefault("search_min_pos", 0.01)
    bs = MakeBodySchemaDiagram(BodySchemaDiagramConfig(
        arm=arm, noise_pos=noise, noise_orient=0.0, seed=seed, babble_fraction=0.6, **kw))
    sim = Simulator(bs.diagram)
    root = sim.get_mutable_context()
    bs.prepare(root)
    sim.Initialize()
    return bs, sim, root


def positioning_error(bs, root, schema, Q):
    """Mean true distance of the end effector (relative to the root part) to targets, at
    the commands the SchemaController's solver finds on ``schema``."""
    ee, r = bs.learner.end_effector, schema.root
    start = 0.5 * (bs.controller._lo + bs.controller._hi)
    errs = []
    for q in Q:
        X = bs.true_poses(root, q)
        tgt = (np.linalg.inv(X[r]) @ X[ee])[:3, 3]
        qs = bs.controller._solve(schema, start, tgt)
        Xs = bs.true_poses(root, qs)
        errs.append(np.linalg.norm((np.linalg.inv(Xs[r]) @ Xs[ee])[:3, 3] - tgt))
    return float(np.mean(errs))


def drake_accuracy(arm, noise, sizes, *, seed, n_test, n_control, occlude=(), show=True):
    """Gather max(sizes) samples in Drake, then fit the schema on the first n of them."""
    from mmlearn.models.body_schema.schema import BodySchema

    bs, sim, root = make_body_schema_sim(arm, noise, seed, occlude=list(occlude))
    t0 = time.perf_counter()
    babble(bs, sim, max(sizes), show_progress=show, desc=f"{arm} babbling")
    st = bs.learner.state(root)
    A, P = st.schema.buffer()
    rng = np.random.default_rng([seed, 99])
    Q = sample_test_commands(bs, n_test, rng)
    obs = observation_noise(bs, root, Q[:30], seed)
    rows = []
    for n in sizes:
        sch = BodySchema(len(bs.parts), A.shape[1], search=bs.learner._cfg.search)
        row = dict(n=int(n))
        try:
            res = sch.fit(A[:n], P[:n])
        except ValueError as e:
            rows.append({**row, "correct": False, "error": str(e)})
            continue
        keys = [(m.i, m.j, m.Q) for m in res.tree]
        row["correct"] = bool(res.complete and is_correct(keys, bs.truth, len(res.nodes)))
        if res.complete:
            row["pred_error_m"], row["pred_error_deg"] = prediction_error(bs, root, sch, Q)
            if n_control:
                row["positioning_error_m"] = positioning_error(bs, root, sch,
                                                                Q[:n_control])
        rows.append(row)
    n_nodes = len(st.schema.nodes) or len(bs.parts)
    return dict(arm=arm, noise=noise, occluded=list(occlude), parts=bs.parts,
                obs_noise_m=obs, rows=rows,
                online_converged_at=converged_at(st.history, bs.truth, n_nodes),
                update_ms_median=float(1000 * np.median(st.update_seconds)),
                sim_seconds=float(root.get_time()), seconds=time.perf_counter() - t0)


def drake_recovery(failure, *, n_block, seed, arm="2dof", n_first=30, show=True):
    """Table 3.1 protocol in Drake: block 1 learns from scratch (intact; at least
    ``n_first`` samples), blocks 2 and 4
    with the failure (joint q2 stuck at 0.5 rad / a tool 0.10 m longer and tilted by
    30 deg), block 3 restored; samples without a valid spanning tree per block."""
    bs, sim, root = make_body_schema_sim(arm, 0.01, seed)
    invalid = []
    for b in range(4):
        broken = b % 2 == 1
        if failure == "joint":
            if broken:
                bs.blocker.block(root, 1, value=0.5)  # q2 stuck at 0.5 rad, both times
            else:
                bs.blocker.unblock(root)
        else:
            if broken:
                bs.failures.change_tool(root, 0.10, math.radians(30))
            else:
                bs.failures.reset_tool(root)
        n_inv = 0
        n = max(n_block, n_first) if b == 0 else n_block  # block 1 also learns the schema
        for _ in progress(range(n), desc=f"{failure} block {b + 1}", unit="sample",
                          enabled=show):
            babble(bs, sim, 1, show_progress=False)
            n_inv += not bs.learner.state(root).schema.valid
        invalid.append(n_inv)
    return dict(steps_invalid=invalid, first=invalid[1], restore=invalid[2],
                second=invalid[3], events=[e for _, e in bs.learner.state(root).schema.events])


def _guarded(fn, kwargs):
    """fn(**kwargs, show=False); a run that raises ValueError, RuntimeError or LinAlgError
    becomes ``{"failed": reason}`` (a failed run of the robot / learner: counted in the
    tables, never silently dropped)."""
    try:
        return fn(**kwargs, show=False)
    except (ValueError, RuntimeError, np.linalg.LinAlgError) as e:
        return {"failed": f"{type(e).__name__}: {e}"}


def drake_control(*, n_learn, n_adapt, n_waypoints, seed, show=True):
    """Table 3.2 in Drake: 4-DOF arm, x3 bent by 45 deg in the plant."""
    bs, sim, root = make_body_schema_sim("4dof", 0.005, seed)
    babble(bs, sim, n_learn, show_progress=show, desc="4dof learning")
    static = copy.deepcopy(bs.learner.state(root).schema)
    rng = np.random.default_rng([seed, 5])
    # a smooth trajectory of way points inside the babbling range
    lo, hi = bs.babbling._lo, bs.babbling._hi
    s_ = np.linspace(0, 1, n_waypoints)[:, None]
    Qw = 0.5 * (lo + hi) + 0.35 * (hi - lo) * np.sin(2 * np.pi * s_ +
                                                     rng.uniform(0, 2 * np.pi, lo.size))
    out = dict(intact_static=positioning_error(bs, root, static, Qw))
    bs.failures.bend_link(root, math.pi / 4)
    out["bent_static"] = positioning_error(bs, root, static, Qw)
    babble(bs, sim, n_adapt, show_progress=show, desc="4dof adapting")
    sch = bs.learner.state(root).schema
    out["bent_adaptive"] = positioning_error(bs, root, sch, Qw)
    out["valid_after"] = bool(sch.valid)
    return out


def _numpy_recovery(*, failure, visibility, show=False, **kw):
    from mmlearn.models.body_schema.evaluation import recovery_experiment
    from mmlearn.models.body_schema.kinematic_sim import make_arm_7dof

    return recovery_experiment(make_arm_7dof, failure, visibility=visibility, **kw)


def _numpy_control(*, show=False, **kw):
    from mmlearn.models.body_schema.evaluation import control_experiment
    from mmlearn.models.body_schema.kinematic_sim import make_arm_4dof

    return control_experiment(make_arm_4dof, **kw)


#: the experiments' blocks: (trial function, its runs raising ValueError / RuntimeError /
#: LinAlgError are failed runs counted in the tables (True) or trial errors (False))
BLOCKS = {"fig_3_10": ("accuracy", False), "noise_free": ("accuracy", False),
          "7dof_occluded": ("accuracy", False), "7dof_structure": ("accuracy", False),
          "table_3_1_numpy": ("numpy_recovery", True), "table_3_2_numpy": ("numpy_control", True),
          "table_3_1_drake": ("recovery", True), "table_3_2_drake": ("control", True)}


@register_trial("body_schema.experiment")
def body_schema_trial(*, seed: int, block: str, run: int = 0, kwargs: dict,
                      quick: bool = False, shared=None) -> dict:
    """One run of one body-schema experiment (the sweep's trial function):
    ``block`` names the experiment (:data:`BLOCKS`), ``run`` the run's index in it,
    ``kwargs`` the keyword arguments of its function (:func:`drake_accuracy`,
    :func:`drake_recovery`, :func:`drake_control` or the numpy simulation's
    ``recovery_experiment`` / ``control_experiment``). A Table 3.1 / 3.2 run that raises
    returns ``{"failed": reason}`` (counted in the table); ``quick`` only names the setting."""
    if block not in BLOCKS:
        raise ValueError(f"unknown block {block!r}; choose from {', '.join(BLOCKS)}")
    fn = {"accuracy": drake_accuracy, "recovery": drake_recovery, "control": drake_control,
          "numpy_recovery": _numpy_recovery, "numpy_control": _numpy_control}[BLOCKS[block][0]]
    kw = dict(kwargs, seed=seed)
    if BLOCKS[block][1]:
        return _guarded(fn, kw)
    if fn is drake_accuracy:
        kw = dict(kw, sizes=list(kw["sizes"]))
        arm, noise, sizes = kw.pop("arm"), kw.pop("noise"), kw.pop("sizes")
        out = drake_accuracy(arm, noise, sizes, show=False, **kw)
        if block == "7dof_structure":
            out["correct_from"] = correct_from(out["rows"])
        return out
    return fn(**kw, show=False)
