"""Benchmark: noise of the CameraMarkerSensor (ArUco in rendered RGB images) against distance
and viewing angle, the rendering calibration, and the errors on the arm's own markers.
Prints tables; never fails on time.

    python benchmarks/bench_camera_marker_sensor.py [--width 1920] [--n 12] [--seed 0]
        [--distances 0.5,1,1.5,2,2.5,3] [--angles 0,20,40,60] [--depth exact,noisy,none]
        [--calibrate]
        [--arm 2dof --poses 25] [--plot OUT.png]
        [--babble SECONDS --rules none,ratio,normal,depth,normal-noisy,depth-noisy]
        [--json FILE]   (the noise table's rows, the calibration's figures, or with --arm
                         the per-part errors)

Default table: one 0.04 m marker (on a 0.10 m grey carrier, grey backdrop 6 m away) at each
distance (m, along the optical axis) and viewing angle (deg between the marker normal and
the line of sight), ``--n`` random poses per cell (random in-plane turn, random tilt
direction, random place in the middle 60 % of the image). Columns: detection rate,
position error (median, RMS, m) and orientation error (median deg, share > 20 deg).
``--calibrate``: mean offset of the refined corners from their projections with Drake's
documented principal point (the calibration the sensor applies). ``--arm``: per-part
visibility and errors of the default 3-camera scene on random babbling poses of an arm.
``--babble S``: the frames the learner sees while the arm babbles for S s (10 Hz), with each
rule for ambiguous (mirror) detections, exact and noisy depth, on the same renders:
visibility, position error and the rate of mirror flips (reported orientation off by more
than 20 degrees).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from _common import add_output_arguments, emit_json

def _rig(width, shift=None, min_side=None):
    from mmlearn.diagrams.common.marker_camera import MarkerRig
    from mmlearn.models.common.marker_detection import DetectorConfig
    from mmlearn.systems.common.camera_marker_sensor import CameraMarkerSensorConfig
    from mmlearn.systems.common.marker_sensor import CameraConfig

    kw = {}
    if shift is not None:
        kw["principal_point_shift_px"] = list(shift)
    if min_side is not None:
        kw["detector"] = DetectorConfig(min_side_px=min_side)
    cfg = CameraMarkerSensorConfig(
        cameras=[CameraConfig(position=[0, 0, 1], look_at=[1, 0, 1], fov_y_deg=55,
                              max_range=10)], width=width, height=width * 3 // 4, **kw)
    rig = MarkerRig(cfg)
    return cfg, rig, rig.diagram.CreateDefaultContext()


def _pose(rng, dist, angle_deg, fov_y_deg, aspect):
    """X_CM: a marker ``dist`` m ahead, its normal ``angle_deg`` off the line of sight."""
    from pydrake.math import RigidTransform, RotationMatrix

    ty = np.tan(np.radians(fov_y_deg) / 2) * 0.6
    p = np.array([rng.uniform(-1, 1) * ty * aspect * dist, rng.uniform(-1, 1) * ty * dist,
                  dist])
    # facing the camera centre, then tilted about a random in-plane axis, turned in-plane
    z = -p / np.linalg.norm(p)
    x = np.cross([0.0, -1.0, 0.0], z)
    x /= np.linalg.norm(x)
    R0 = RotationMatrix(np.column_stack([x, np.cross(z, x), z]))
    phi = rng.uniform(0, 2 * np.pi)
    axis = np.array([np.cos(phi), np.sin(phi), 0.0])
    from pydrake.common.eigen_geometry import AngleAxis

    tilt = RotationMatrix(AngleAxis(np.radians(angle_deg), axis))
    spin = RotationMatrix.MakeZRotation(rng.uniform(0, 2 * np.pi))
    return RigidTransform(R0 @ tilt @ spin, p)


DEPTHS = {"exact": {}, "noisy": {"noisy": True}, "none": {"use_depth": False}}


def noise_table(width, distances, angles, n, seed, depths=("exact",)):
    """The noise table, one block per depth mode in ``depths`` (keys of :data:`DEPTHS`: the
    depth that resolves the mirror ambiguity: exact render, the structured-light noise
    model, none), all on the same renders (one colour and depth image per pose, detected
    once)."""
    import dataclasses

    from mmlearn.models.common.depth_noise import DepthNoiseConfig, apply_depth_noise
    from mmlearn.models.common.camera import PinholeIntrinsics
    from mmlearn.systems.common.camera_marker_sensor import CameraMarkerSensor

    cfg, rig, ctx = _rig(width)
    X_WC = cfg.cameras[0].pose()
    cam = rig.rgbd[0]
    intr = PinholeIntrinsics.from_camera_info(cam.default_depth_render_camera().core()
                                              .intrinsics())
    sensors, noisy = {}, {}
    for dm in depths:
        kw = dict(DEPTHS[dm])
        noisy[dm] = bool(kw.pop("noisy", False))
        sensors[dm] = CameraMarkerSensor(marker_ids=rig.sensor.marker_ids,
                                         aruco_ids=rig.sensor.aruco_ids,
                                         cameras=rig.sensor.cameras,
                                         config=dataclasses.replace(cfg, **kw))
    rng = np.random.default_rng(seed)
    rows = []
    t_render, t_detect = [], []
    res = {dm: {} for dm in depths}
    sides = {}
    k = 0
    for d in distances:
        for a in angles:
            cell = {dm: ([], []) for dm in depths}
            sd = []
            for _ in range(n):
                X_CM = _pose(rng, d, a, cfg.cameras[0].fov_y_deg, cfg.width / cfg.height)
                X_WM = X_WC @ X_CM
                rig.set_poses(ctx, [X_WM])
                cc = cam.GetMyContextFromRoot(ctx)
                t0 = time.perf_counter()
                img = np.array(cam.color_image_output_port().Eval(cc).data)  # render (timed)
                t1 = time.perf_counter()
                depth = np.array(cam.depth_image_32F_output_port().Eval(cc).data)[..., 0]
                t2 = time.perf_counter()
                det = rig.sensor.detect(img, 0)
                t3 = time.perf_counter()
                t_render.append(t1 - t0)
                t_detect.append(t3 - t2)
                sd.append(cfg.intrinsics(cfg.cameras[0])[0, 0] * cfg.aruco.marker_size / d)
                nd = None
                if any(noisy.values()):
                    nd = apply_depth_noise(depth, intr, DepthNoiseConfig(seed=seed), frame=k)
                k += 1
                for dm in depths:
                    obs, _ = sensors[dm].observe_images(0.0, [img], [nd if noisy[dm] else depth],
                                                        detections=[det])
                    if obs.visible[0]:
                        X = obs.poses[0]
                        cell[dm][0].append(np.linalg.norm(X.translation() - X_WM.translation()))
                        cell[dm][1].append(np.degrees((X_WM.rotation().inverse() @ X.rotation())
                                                      .ToAngleAxis().angle()))
            sides[(d, a)] = float(np.mean(sd))
            for dm in depths:
                res[dm][(d, a)] = cell[dm]
    f = (lambda v, fmt: format(v, fmt) if np.isfinite(v) else "    nan")
    for dm in depths:
        print(f"depth {dm}: image {cfg.width}x{cfg.height}, fov_y {cfg.cameras[0].fov_y_deg} "
              f"deg, marker {cfg.aruco.marker_size} m ({cfg.aruco.dictionary}), {n} poses "
              "per cell")
        print(" dist_m  angle_deg  side_px  detected  pos_med_m  pos_rms_m  ang_med_deg  "
              "ang>20deg")
        for (d, a), (pe, ae) in res[dm].items():
            pe, ae = np.array(pe), np.array(ae)
            row = dict(depth=dm, dist=d, angle=a, rate=len(pe) / n,
                       pos_med=float(np.median(pe)) if len(pe) else np.nan,
                       pos_rms=float(np.sqrt(np.mean(pe ** 2))) if len(pe) else np.nan,
                       ang_med=float(np.median(ae)) if len(ae) else np.nan,
                       flips=float(np.mean(ae > 20)) if len(ae) else np.nan)
            rows.append(row)
            print(f"{d:7.2f}  {a:9.0f}  {sides[(d, a)]:7.1f}  {len(pe):3d}/{n:<4d}  "
                  f"{f(row['pos_med'], '9.4f')}  {f(row['pos_rms'], '9.4f')}  "
                  f"{f(row['ang_med'], '11.2f')}  {f(row['flips'], '9.2f')}")
    print(f"per image: render {1000 * np.median(t_render):.0f} ms (median; cached images are "
          f"excluded by moving the marker), detect+pose {1000 * np.median(t_detect):.1f} ms")
    return rows


def calibrate(width, n, seed):
    """Mean corner offset (px) from the projection with Drake's documented K."""
    cfg, rig, ctx = _rig(width, shift=(0.0, 0.0), min_side=4.0)
    X_WC = cfg.cameras[0].pose()
    K = rig.sensor.cameras[0].K
    rng = np.random.default_rng(seed)
    s = cfg.aruco.marker_size / 2
    obj = np.array([[-s, s, 0], [s, s, 0], [s, -s, 0], [-s, -s, 0]])
    X_MQ = cfg.aruco.X_MQ()
    off, side_err = [], []
    for _ in range(n):
        d = rng.uniform(0.6, 2.0)
        X_CM = _pose(rng, d, rng.uniform(0, 40), cfg.cameras[0].fov_y_deg,
                     cfg.width / cfg.height)
        rig.set_poses(ctx, [X_WC @ X_CM])
        cam = rig.rgbd[0]
        img = cam.color_image_output_port().Eval(cam.GetMyContextFromRoot(ctx)).data
        det = rig.sensor.detect(img, 0)
        if not len(det):
            continue
        X_CQ = X_CM @ X_MQ
        pc = (X_CQ.rotation().matrix() @ obj.T).T + X_CQ.translation()
        uv = (K @ pc.T).T
        uv = uv[:, :2] / uv[:, 2:]
        c = det.corners[0]
        off.append((c - uv).mean(axis=0))
        side_err.append(np.linalg.norm(c - np.roll(c, -1, 0), axis=1).mean()
                        - np.linalg.norm(uv - np.roll(uv, -1, 0), axis=1).mean())
    off = np.array(off)
    print(f"calibration at {cfg.width}x{cfg.height} over {len(off)} detections: corner offset "
          f"x {off[:, 0].mean():+.3f} +- {off[:, 0].std():.3f} px, y {off[:, 1].mean():+.3f} "
          f"+- {off[:, 1].std():.3f} px; side length error {np.mean(side_err):+.3f} px "
          f"(principal_point_shift_px default {cfg.__class__().principal_point_shift_px})")
    return dict(width=cfg.width, height=cfg.height, detections=len(off),
                corner_offset_mean_px=off.mean(axis=0), corner_offset_sd_px=off.std(axis=0),
                side_length_error_px=float(np.mean(side_err)))


def _score(obs, plant, plant_context, robot, vis, pe, ae) -> None:
    """Add one frame's visible markers to the per-part counts ``vis`` and the position (m)
    and angle (deg) error lists ``pe``, ``ae``, against the true marker poses."""
    for i, p in enumerate(obs.marker_ids):
        if obs.visible[i]:
            Xt = plant.GetFrameByName(p + "_marker", robot).CalcPoseInWorld(plant_context)
            vis[i] += 1
            pe[i].append(np.linalg.norm(obs.poses[i].translation() - Xt.translation()))
            ae[i].append(np.degrees((Xt.rotation().inverse() @ obs.poses[i].rotation())
                                    .ToAngleAxis().angle()))


def arm_errors(arm, poses, seed, width):
    """Per part of ``arm``'s default camera scene on ``poses`` random babbling poses: the
    share of frames it is seen, the median and 90th percentile position error (m), the median
    orientation error (deg) and the share off by more than 20 deg (printed and returned)."""
    from mmlearn.diagrams.body_schema.diagram import BodySchemaDiagramConfig, MakeBodySchemaDiagram
    from mmlearn.systems.common.camera_marker_sensor import CameraMarkerSensorConfig

    cam = CameraMarkerSensorConfig(width=width, height=width * 3 // 4)
    bs = MakeBodySchemaDiagram(BodySchemaDiagramConfig(arm=arm, sensor="camera",
                                                       babble_fraction=0.6, camera=cam))
    ctx = bs.diagram.CreateDefaultContext()
    bs.prepare(ctx)
    plant, sensor = bs.scene.plant, bs.scene.sensor
    rng = np.random.default_rng(seed)
    lo, hi = bs.babbling._lo, bs.babbling._hi
    vis = np.zeros(len(bs.parts))
    pe = [[] for _ in bs.parts]
    ae = [[] for _ in bs.parts]
    k = 0
    t0 = time.perf_counter()
    while k < poses:
        q = rng.uniform(lo, hi)
        if not bs.babbling._accept(q):
            continue
        k += 1
        bs.scene.set_joint_positions(ctx, q)
        obs = sensor.observe(sensor.GetMyContextFromRoot(ctx))
        _score(obs, plant, plant.GetMyContextFromRoot(ctx), bs.scene.robot, vis, pe, ae)
    dt = (time.perf_counter() - t0) / poses
    print(f"{arm} arm, {len(cam.cameras)} cameras {cam.width}x{cam.height}, {poses} random "
          f"babbling poses, {dt:.2f} s per frame (render + detect, all cameras)")
    print(" part  visible  pos_med_m  pos_p90_m  ang_med_deg  ang>20deg")
    parts = []
    for i, p in enumerate(bs.parts):
        e, a = np.array(pe[i]), np.array(ae[i])
        if len(e):
            print(f"{p:>5}  {vis[i] / poses:7.2f}  {np.median(e):9.4f}  "
                  f"{np.percentile(e, 90):9.4f}  {np.median(a):11.2f}  {np.mean(a > 20):9.2f}")
            parts.append(dict(part=p, visible=vis[i] / poses, pos_med_m=float(np.median(e)),
                              pos_p90_m=float(np.percentile(e, 90)),
                              ang_med_deg=float(np.median(a)),
                              ang_over_20deg=float(np.mean(a > 20))))
        else:
            print(f"{p:>5}  {0:7.2f}  never seen")
            parts.append(dict(part=p, visible=0.0))
    return dict(arm=arm, poses=poses, seed=seed, width=cam.width, height=cam.height,
                cameras=len(cam.cameras), wall_s_per_frame=dt, parts=parts)


VARIANTS = {
    # the sensor before the mirror-flip fix: always the better IPPE solution
    "none": dict(use_depth=False, min_unambiguous_ratio=1.0),
    # reprojection-error ratio + the last report, no depth
    "ratio": dict(use_depth=False),
    # the first depth rule: the normal of a plane fitted to the depth pixels, 15 deg gate
    "normal": dict(depth_test="normal"),
    # the default: each solution's plane against the depth pixels (noise-aware)
    "depth": dict(),
    # the same two on a structured-light camera's depth (models/common/depth_noise.py defaults)
    "normal-noisy": dict(depth_test="normal", noisy=True),
    "depth-noisy": dict(noisy=True),
}


def babble_flips(arm, seconds, variants, seed, width):
    """Per-frame errors of the camera sensor while the arm babbles (the frames the learner
    sees, 10 Hz), for each ambiguity rule in ``variants`` (keys of :data:`VARIANTS`):
    visibility, median position error and the share of reported orientations off by more
    than 20 degrees (mirror flips). All rules see the same renders: each frame's colour and
    exact depth images are rendered once, detected once, and every rule resolves the
    detections with its own sensor and its own last reports; the "-noisy" rules get the
    exact depth through ``apply_depth_noise`` (``DepthNoiseConfig()`` with seed ``seed +
    camera``, frame index k, as the ``depth_noise`` option's DepthNoise systems draw)."""
    import dataclasses

    from pydrake.systems.analysis import Simulator

    from mmlearn.diagrams.body_schema.diagram import BodySchemaDiagramConfig, MakeBodySchemaDiagram
    from mmlearn.models.common.depth_noise import DepthNoiseConfig, apply_depth_noise
    from mmlearn.models.common.camera import PinholeIntrinsics
    from mmlearn.systems.common.camera_marker_sensor import (CameraMarkerSensor,
                                                             CameraMarkerSensorConfig)

    base = CameraMarkerSensorConfig(width=width, height=width * 3 // 4)
    print(f"{arm} arm babbling {seconds:g} s (seed {seed}), {len(base.cameras)} cameras "
          f"{base.width}x{base.height}, frames at {base.rate_hz:g} Hz, rules "
          f"{', '.join(variants)} on the same renders")
    bs = MakeBodySchemaDiagram(BodySchemaDiagramConfig(arm=arm, sensor="camera",
                                                       camera=base, seed=seed))
    sim = Simulator(bs.diagram)
    root = sim.get_mutable_context()
    bs.prepare(root)
    plant, main_sensor, rgbd = bs.scene.plant, bs.scene.sensor, bs.scene.cameras
    intr = [PinholeIntrinsics.from_camera_info(c.default_depth_render_camera().core()
                                               .intrinsics()) for c in rgbd]
    noise_cfg = DepthNoiseConfig()
    sensors, tracks, noisy = {}, {}, {}
    for r in variants:
        kw = dict(VARIANTS[r])
        noisy[r] = bool(kw.pop("noisy", False))
        sensors[r] = CameraMarkerSensor(marker_ids=main_sensor.marker_ids,
                                        aruco_ids=main_sensor.aruco_ids,
                                        cameras=main_sensor.cameras,
                                        config=dataclasses.replace(base, **kw))
        tracks[r] = None
    n = int(round(seconds * base.rate_hz))
    m = len(bs.parts)
    vis = {r: np.zeros(m) for r in variants}
    pe = {r: [[] for _ in range(m)] for r in variants}
    ae = {r: [[] for _ in range(m)] for r in variants}
    t0 = time.perf_counter()
    t_render = t_detect = 0.0
    for k in range(n):
        # just after the frame at k / rate: the plant is where the images showed it
        sim.AdvanceTo(k / base.rate_hz + 1e-6)
        t = k / base.rate_hz
        ta = time.perf_counter()
        colors, depths = [], []
        for c in rgbd:
            cc = c.GetMyContextFromRoot(root)
            colors.append(np.array(c.color_image_output_port().Eval(cc).data))
            depths.append(np.array(c.depth_image_32F_output_port().Eval(cc).data)[..., 0])
        tb = time.perf_counter()
        dets = [main_sensor.detect(img, i) for i, img in enumerate(colors)]
        t_render += tb - ta
        t_detect += time.perf_counter() - tb
        noisy_depths = None
        if any(noisy.values()):
            noisy_depths = [apply_depth_noise(d, intr[i], dataclasses.replace(
                noise_cfg, seed=noise_cfg.seed + i), frame=k) for i, d in enumerate(depths)]
        pc = plant.GetMyContextFromRoot(root)
        for r in variants:
            obs, tracks[r] = sensors[r].observe_images(
                t, colors, noisy_depths if noisy[r] else depths, tracks[r], detections=dets)
            _score(obs, plant, pc, bs.scene.robot, vis[r], pe[r], ae[r])
    print(f"{n} frames, {time.perf_counter() - t0:.0f} s (render {t_render:.0f} s, "
          f"detect {t_detect:.0f} s)")
    print("         rule  part  visible  pos_med_m  ang_med_deg  flips(>20deg)")
    for r in variants:
        for i, p in enumerate(bs.parts):
            e, a = np.array(pe[r][i]), np.array(ae[r][i])
            if len(e):
                print(f"{r:>13}  {p:>4}  {vis[r][i] / n:7.2f}  {np.median(e):9.4f}  "
                      f"{np.median(a):11.2f}  {np.mean(a > 20):13.3f}")
            else:
                print(f"{r:>13}  {p:>4}  {0:7.2f}  never seen")
        a = np.concatenate([np.array(x) for x in ae[r]])
        if not len(a):
            print(f"{r:>13}   all  no reports")
            continue
        print(f"{r:>13}   all  {vis[r].sum() / (n * m):7.2f}  "
              f"{np.median(np.concatenate([np.array(x) for x in pe[r]])):9.4f}  "
              f"{np.median(a):11.2f}  {np.mean(a > 20):13.3f}   "
              f"({int((a > 20).sum())} of {len(a)} reports off by > 20 deg)")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--width", type=int, default=1920, help="image width, px (4:3 images)")
    ap.add_argument("--n", type=int, default=12, help="poses per table cell")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--distances", default="0.5,1,1.5,2,2.5,3")
    ap.add_argument("--angles", default="0,20,40,60")
    ap.add_argument("--calibrate", action="store_true", help="only the calibration")
    ap.add_argument("--arm", default=None, help="only the per-part errors of this arm")
    ap.add_argument("--poses", type=int, default=25, help="arm poses (--arm)")
    ap.add_argument("--babble", type=float, default=None, metavar="SECONDS",
                    help="only the per-frame errors and mirror flips while --arm (default "
                         "2dof) babbles this long, for each of --rules")
    ap.add_argument("--rules", default=",".join(VARIANTS),
                    help="ambiguity rules for --babble (all on the same renders): none "
                         "(always the better IPPE solution, the sensor before the fix), "
                         "ratio (reprojection ratio + last report), normal (the first depth "
                         "rule: fitted normal, 15 deg gate), depth (the default: each "
                         "solution's plane against the depth pixels), normal-noisy and "
                         "depth-noisy (the same on a structured-light camera's depth)")
    ap.add_argument("--depth", default="exact",
                    help="comma-separated depth modes for the noise table (same renders): "
                         "exact (rendered), noisy (structured-light noise model), none")
    ap.add_argument("--plot", default=None, help="save a plot of the table (PNG)")
    add_output_arguments(ap)
    a = ap.parse_args(argv)
    if a.json is not None and a.babble is not None:
        ap.error("--json: the noise table, --arm and --calibrate only")
    if a.calibrate:
        emit_json(a.json, calibrate(a.width, a.n * 3, a.seed))
        return 0
    if a.babble is not None:
        rules = a.rules.split(",")
        bad = [r for r in rules if r not in VARIANTS]
        if bad:
            ap.error(f"--rules: unknown {bad}; choose from {sorted(VARIANTS)}")
        babble_flips(a.arm or "2dof", a.babble, rules, a.seed, a.width)
        return 0
    if a.arm:
        if a.json == "-":
            ap.error("--json: with --arm give a FILE (the table goes to standard output)")
        doc = arm_errors(a.arm, a.poses, a.seed, a.width)
        emit_json(a.json, doc)
        return 0
    depths = a.depth.split(",")
    bad = [d for d in depths if d not in DEPTHS]
    if bad:
        ap.error(f"--depth: unknown {bad}; choose from {sorted(DEPTHS)}")
    rows = noise_table(a.width, [float(x) for x in a.distances.split(",")],
                       [float(x) for x in a.angles.split(",")], a.n, a.seed, depths)
    emit_json(a.json, dict(width=a.width, n=a.n, seed=a.seed, rows=rows))
    if a.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(1, 3, figsize=(13, 3.8))
        for ang in sorted({r["angle"] for r in rows}):
            rr = [r for r in rows if r["angle"] == ang and r["depth"] == depths[0]]
            d = [r["dist"] for r in rr]
            ax[0].plot(d, [r["rate"] for r in rr], "o-", label=f"{ang:.0f} deg")
            ax[1].plot(d, [r["pos_med"] for r in rr], "o-", label=f"{ang:.0f} deg")
            ax[2].plot(d, [r["ang_med"] for r in rr], "o-", label=f"{ang:.0f} deg")
        for x, t in zip(ax, ("detection rate", "median position error [m]",
                             "median orientation error [deg]")):
            x.set_xlabel("distance [m]")
            x.set_title(t)
        ax[0].legend(title="viewing angle")
        fig.tight_layout()
        fig.savefig(a.plot, dpi=100)
        print(f"plot: {a.plot}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
