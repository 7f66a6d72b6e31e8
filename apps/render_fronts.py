"""Render depth frames of the kitchen cabinet while its door or drawer opens (thesis ch. 5
scenes): the noisy depth image, the clean render, the label image and the ground truth
(camera intrinsics and pose, the true front pose) of each frame, saved to a folder.

    python -m mmlearn.apps.render_fronts --out-dir frames --front door,drawer \\
        --distance 1.0,1.8,2.5 --frames 4 --seed 0 [--config scene.yaml] --json

Per frame ``<front>_d<distance>_a<angle>_f<k>``: ``..._depth.npy`` (float32 (H, W), metres
along the optical axis, NaN = no measurement), ``..._clean.npy`` (the noise-free render, inf
= nothing), ``..._label.npy`` (int16 render labels) and ``....json`` with ``intrinsics``
(width, height, fx, fy, cx, cy), ``X_WC`` (4x4 camera pose, Drake camera frame: x right,
y down, z forward), ``X_WR`` (4x4 true pose of the moving front's outer-face centre: x along
the width, y along the height, z the outward normal), ``width``/``height`` of the front (m),
``joint_value`` (rad or m), ``time`` (s), ``frame`` (noise frame index), ``seed``,
``front_labels`` (the moving front's render labels in the label image), ``closed_fronts``
(name -> ``X_WR``, ``width``, ``height``, ``labels`` of every front that stays closed: the
neighbours' and the other one of door / drawer).
"""


import json
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mmlearn.apps.common.cli import (ArgumentParser, UsageError, check_in_file, check_out_dir,
                                     check_out_file, fail, finish_viewing, float_list, json_clean,
                                     load_config, make_meshcat, name_list, nonneg_int, pos_int,
                                     progress, save_html)
from mmlearn.models.common.config import param, validate_fields
from mmlearn.diagrams.perception.diagram import FrontPerceptionConfig, MakeFrontPerceptionDiagram


@dataclass
class RenderFrontsConfig:
    """What :func:`run` renders.

    Attributes:
        fronts: moving fronts, each of "door", "drawer".
        distances: camera distances to the closed front's centre, m.
        angles_deg: camera azimuths off the front's normal, deg.
        frames: frames per (front, distance, angle), evenly over the opening profile
            (the first closed, the last fully open).
        seed: the noise seed.
        out_dir: folder to save the frames in ("" = do not save).
        scene: the rest of the scene / camera / noise configuration.
        html_out: write a Meshcat recording of the first run ("" = no).
        meshcat: show it live.
    """

    fronts: list[str] = field(default_factory=lambda: ["door", "drawer"])
    distances: list[float] = param([1.0, 1.8, 2.5], unit="m", elements=True, factory=True)
    angles_deg: list[float] = param([0.0], unit="deg", elements=True, factory=True)
    frames: int = param(3, integer=True, ge=1)
    seed: int = param(0, integer=True, ge=0)
    out_dir: str = ""
    scene: FrontPerceptionConfig = field(default_factory=FrontPerceptionConfig)
    html_out: str = ""
    meshcat: bool = False

    def validate(self) -> "RenderFrontsConfig":
        """Raise ``ValueError`` naming the first bad field; return the config."""
        validate_fields(self)
        for k in ("fronts", "distances", "angles_deg"):
            if not getattr(self, k):
                raise ValueError(f"RenderFrontsConfig: {k} must not be empty")
        for d in self.distances:
            self.scene.check_distance(d, "distance")
        return self


def _save(folder: Path, name: str, depth, clean, label, meta: dict) -> None:
    """One frame's arrays and metadata, each file written atomically (the metadata last: a
    frame whose ``.json`` exists is complete)."""
    from mmlearn.models.common.fileio import atomic_output, atomic_write_text

    for kind, arr in (("depth", depth), ("clean", clean), ("label", label)):
        with atomic_output(folder / f"{name}_{kind}.npy") as f:
            np.save(f, arr)
    atomic_write_text(folder / f"{name}.json", json.dumps(json_clean(meta), indent=1))


def run(*, config: RenderFrontsConfig, meshcat=None, show_progress: bool = True) -> dict:
    """Render (and save) the frames; returns a summary with per-frame statistics
    (``ms_per_frame``: median wall time to simulate to a frame's time and evaluate its noisy
    image, i.e. VTK render + DepthNoise (+ the Meshcat point cloud when shown))."""
    import copy

    from pydrake.systems.analysis import Simulator

    cfg = config.validate()
    folder = Path(cfg.out_dir) if cfg.out_dir else None
    if meshcat is None and (cfg.meshcat or cfg.html_out):
        meshcat = make_meshcat(announce=cfg.meshcat)
    records = []
    runs = [(f, d, a) for f in cfg.fronts for d in cfg.distances for a in cfg.angles_deg]
    t_render = []
    for i, (front, dist, ang) in enumerate(progress(runs, desc="rendering", unit="run",
                                                    enabled=show_progress)):
        sc = copy.deepcopy(cfg.scene)
        sc.front, sc.camera.distance, sc.camera.angle_deg = front, float(dist), float(ang)
        sc.noise.seed = cfg.seed
        P = MakeFrontPerceptionDiagram(sc, meshcat=meshcat if i == 0 else None)
        d = P.diagram
        sim = Simulator(d)
        ctx = sim.get_mutable_context()
        if P.visualizer is not None:
            P.visualizer.StartRecording(False)
        sim.Initialize()
        times = np.linspace(0.0, P.duration, cfg.frames) if cfg.frames > 1 else [0.0]
        for t in times:
            t0 = time.perf_counter()
            sim.AdvanceTo(float(t))
            depth = np.array(d.GetOutputPort("depth_image").Eval(ctx).data)[..., 0]
            t_render.append(time.perf_counter() - t0)
            clean = np.array(d.GetOutputPort("clean_depth").Eval(ctx).data)[..., 0]
            label = np.array(d.GetOutputPort("label_image").Eval(ctx).data)[..., 0]
            K = P.intrinsics
            k = P.noise.frame_index(float(t)) if P.noise is not None else 0
            meta = {
                "front": front, "distance": float(dist), "angle_deg": float(ang),
                "time": float(t), "frame": k, "seed": cfg.seed,
                "intrinsics": {"width": K.width, "height": K.height, "fx": K.fx, "fy": K.fy,
                               "cx": K.cx, "cy": K.cy},
                "X_WC": d.GetOutputPort("X_WC").Eval(ctx).GetAsMatrix4(),
                "X_WR": d.GetOutputPort("X_WR").Eval(ctx).GetAsMatrix4(),
                "width": P.kinematics.width, "height": P.kinematics.height,
                "joint_value": float(d.GetOutputPort("front_joint").Eval(ctx)[0]),
                "front_labels": P.front_labels,
                "closed_fronts": {n: {"X_WR": r.X_WR, "width": r.width, "height": r.height,
                                      "labels": P.closed_front_labels[n]}
                                  for n, r in P.closed_fronts.items()},
            }
            name = f"{front}_d{dist:.1f}_a{ang:+.0f}_f{k:03d}"
            if folder is not None:
                _save(folder, name, depth.astype(np.float32), clean.astype(np.float32),
                      label.astype(np.int16), meta)
            front_px = np.isin(label, P.front_labels)
            records.append({"name": name, "front": front, "distance": float(dist),
                            "angle_deg": float(ang), "time": float(t),
                            "joint_value": meta["joint_value"],
                            "missing_ratio": float(np.isnan(depth).mean()),
                            "front_pixels": int(front_px.sum()),
                            "front_pixels_measured": int((front_px & np.isfinite(depth)).sum())})
        if P.visualizer is not None:
            P.visualizer.StopRecording()
            P.visualizer.PublishRecording()
    result = {"frames": len(records), "out_dir": str(folder) if folder else None,
              "ms_per_frame": 1e3 * float(np.median(t_render)),
              "records": records, "html_out": None}
    if cfg.html_out and meshcat is not None:
        result["html_out"] = str(save_html(meshcat, cfg.html_out))
    return result


def main(argv=None) -> int:
    ap = ArgumentParser(
        prog="python -m mmlearn.apps.render_fronts",
        description="Render noisy depth frames of the kitchen cabinet while its door or "
                    "drawer opens, with the ground truth, into a folder.")
    ap.add_argument("--front", type=name_list(["door", "drawer"]), default=["door", "drawer"],
                    help="comma-separated moving fronts (door, drawer)")
    ap.add_argument("--distance", type=float_list, default=[1.0, 1.8, 2.5],
                    help="comma-separated camera distances, m")
    ap.add_argument("--angle", type=float_list, default=[0.0],
                    help="comma-separated camera angles off the front's normal, deg, positive "
                         "towards the kitchen's +y (write --angle=-30,30 for a leading minus)")
    ap.add_argument("--frames", type=pos_int, default=3, help="frames per run")
    ap.add_argument("--seed", type=nonneg_int, default=0)
    ap.add_argument("--config", type=Path,
                    help="YAML file of a FrontPerceptionConfig (keys: kitchen, motion, camera, "
                         "noise, add_noise, ...); --front, --distance, --angle and --seed "
                         "override its front, camera distance / angle and noise seed")
    ap.add_argument("--out-dir", type=Path, help="folder to save the frames in")
    ap.add_argument("--meshcat", action="store_true", help="show the first run live")
    ap.add_argument("--html-out", type=Path, help="save the first run's Meshcat recording")
    ap.add_argument("--json", action="store_true", help="print the results as JSON")
    args = ap.parse_args(argv)
    try:
        check_in_file("--config", args.config)
        check_out_dir("--out-dir", args.out_dir)
        check_out_file("--html-out", args.html_out)
    except UsageError as e:
        return fail(ap.prog, str(e))
    try:
        scene = (load_config(args.config, FrontPerceptionConfig) if args.config
                 else FrontPerceptionConfig())
    except (OSError, RuntimeError, ValueError) as e:
        return fail(ap.prog, f"--config: {e}")
    cfg = RenderFrontsConfig(scene=scene, fronts=args.front, distances=args.distance, angles_deg=args.angle,
                             frames=args.frames, seed=args.seed,
                             out_dir=str(args.out_dir or ""),
                             html_out=str(args.html_out or ""), meshcat=args.meshcat)
    try:
        result = run(config=cfg, show_progress=not args.json)
    except ValueError as e:
        return fail(ap.prog, str(e))
    if args.json:
        print(json.dumps(json_clean(result)))
    else:
        for r in result["records"]:
            print(f"{r['name']}: q = {r['joint_value']:.3f}, "
                  f"missing {100 * r['missing_ratio']:.1f}%"
                  f", front pixels {r['front_pixels_measured']}/{r['front_pixels']} measured")
        print(f"{result['frames']} frames; {result['ms_per_frame']:.0f} ms per frame (median: "
              f"simulate, render, noise, and the Meshcat cloud if shown)"
              + (f"; saved in {result['out_dir']}" if result["out_dir"] else ""))
    finish_viewing(html_out=None if args.json else result["html_out"], live=args.meshcat)
    return 0


if __name__ == "__main__":
    sys.exit(main())
