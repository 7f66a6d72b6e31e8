"""Run the scene: an arm "motor babbling" in front of the cabinet, observed by the marker
sensor. Headless by default; ``--meshcat`` shows it live, ``--html_out`` saves the Meshcat
recording as a standalone HTML page.

    python -m mmlearn.apps.view_scene --arm 7dof --duration 10 --json
"""

from __future__ import annotations

import json
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mmlearn.apps.common.cli import (ArgumentParser, UsageError, check_in_file, check_out_file,
                                     fail, finish_viewing, load_config, make_meshcat, nonneg_int,
                                     pos_float, progress, save_html)
from mmlearn.diagrams import MakeSceneDiagram, SceneConfig


@dataclass
class ViewSceneConfig:
    """What :func:`run` does.

    Attributes:
        duration: simulated time, s.
        seed: seeds the babbling targets and the sensor noise.
        babble_period: seconds per random target.
        babble_fraction: fraction of each joint's range the targets are drawn from.
        scene: the scene (arm, cabinet, sensor ...); its sensor seed is replaced by ``seed``.
        html_out: write the Meshcat recording to this HTML file ("" = no).
        meshcat: show the simulation live in Meshcat (paced at real time).
    """

    duration: float = 10.0
    seed: int = 0
    babble_period: float = 1.5
    babble_fraction: float = 0.6
    scene: SceneConfig = field(default_factory=SceneConfig)
    html_out: str = ""
    meshcat: bool = False


def run(*, config: ViewSceneConfig, meshcat=None, show_progress: bool = True) -> dict:
    """Simulate and return counts and timings (see the module docstring)."""
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder

    from mmlearn.systems import MotorBabbling

    cfg = config
    if not cfg.duration > 0:
        raise ValueError(f"duration must be > 0 s, got {cfg.duration}")
    if not 0 < cfg.babble_fraction <= 1:
        raise ValueError(f"babble_fraction must be in (0, 1], got {cfg.babble_fraction}")
    cfg.scene.validate()
    if cfg.scene.time_step >= cfg.duration:
        raise ValueError(f"time_step {cfg.scene.time_step:g} s (--config) is not shorter than "
                         f"the run (--duration {cfg.duration:g} s): the plant would not move")
    cfg.scene.sensor.seed = cfg.seed
    if meshcat is None and (cfg.meshcat or cfg.html_out):
        meshcat = make_meshcat(announce=cfg.meshcat)
    scene = MakeSceneDiagram(cfg.scene, meshcat=meshcat)
    builder = DiagramBuilder()
    sd = builder.AddNamedSystem("scene", scene.diagram)
    mid = 0.5 * (scene.command_lower + scene.command_upper)
    half = 0.5 * (scene.command_upper - scene.command_lower) * cfg.babble_fraction
    babbling = builder.AddNamedSystem("motor_babbling", MotorBabbling(
        lower=mid - half, upper=mid + half, period=cfg.babble_period, seed=cfg.seed))
    builder.Connect(babbling.get_command_output_port(), sd.GetInputPort("command"))
    diagram = builder.Build()
    simulator = Simulator(diagram)
    root = simulator.get_mutable_context()
    scene.set_joint_positions(root, babbling.command(0.0))
    if cfg.meshcat:
        simulator.set_target_realtime_rate(1.0)
    if scene.visualizer is not None:
        scene.visualizer.StartRecording(False)
    simulator.Initialize()
    t0 = time.perf_counter()
    steps = max(1, int(np.ceil(cfg.duration / 0.25)))
    for k in progress(range(1, steps + 1), desc="simulating", unit="step",
                      enabled=show_progress):
        simulator.AdvanceTo(min(cfg.duration, k * 0.25))
    wall = time.perf_counter() - t0
    sctx = sd.GetMyContextFromRoot(root)
    frames, observations, visible = sd.GetOutputPort("marker_stats").Eval(sctx)
    result = {
        "arm": cfg.scene.arm,
        "seed": cfg.seed,
        "sim_seconds": float(simulator.get_context().get_time()),
        "wall_seconds": round(wall, 3),
        "realtime_factor": round(float(cfg.duration / wall), 2),
        "frames": int(frames),
        "markers": len(scene.sensor.marker_ids),
        "marker_observations": int(observations),
        "visible": int(visible),
        "visible_ratio": round(float(visible / observations), 3) if observations else 0.0,
        "html_out": None,
    }
    if scene.visualizer is not None:
        scene.visualizer.StopRecording()
        scene.visualizer.PublishRecording()
        if cfg.html_out:
            result["html_out"] = str(save_html(meshcat, cfg.html_out))
    return result


def main(argv=None) -> int:
    ap = ArgumentParser(
        prog="python -m mmlearn.apps.view_scene",
        description="Motor babbling of an arm with markers in front of a cabinet; counts "
                    "the marker observations.")
    ap.add_argument("--arm", default="7dof", choices=["2dof", "4dof", "7dof"])
    ap.add_argument("--duration", type=pos_float, default=10.0, help="simulated seconds")
    ap.add_argument("--seed", type=nonneg_int, default=0)
    ap.add_argument("--config", type=Path,
                    help="YAML file of a SceneConfig (keys: arm, tool, cabinet, sensor, ...)")
    ap.add_argument("--meshcat", action="store_true",
                    help="show the run live in Meshcat (prints the URL; real-time pacing)")
    ap.add_argument("--html-out", type=Path, help="save the Meshcat recording as HTML")
    ap.add_argument("--json", action="store_true", help="print the results as JSON")
    args = ap.parse_args(argv)
    try:
        check_in_file("--config", args.config)
        check_out_file("--html-out", args.html_out)
    except UsageError as e:
        return fail(ap.prog, str(e))
    try:
        scene_cfg = load_config(args.config, SceneConfig) if args.config else SceneConfig()
    except (OSError, RuntimeError, ValueError) as e:
        return fail(ap.prog, f"--config: {e}")
    if args.config is None or args.arm != "7dof":
        scene_cfg.arm = args.arm
    cfg = ViewSceneConfig(duration=args.duration, seed=args.seed, scene=scene_cfg,
                          html_out=str(args.html_out or ""), meshcat=args.meshcat)
    try:
        result = run(config=cfg, show_progress=not args.json)
    except ValueError as e:
        return fail(ap.prog, str(e))
    if args.json:
        print(json.dumps(result))
    else:
        print(f"{result['arm']} arm, {result['sim_seconds']:.1f} s simulated in "
              f"{result['wall_seconds']:.1f} s (real-time factor {result['realtime_factor']})")
        print(f"{result['frames']} frames x {result['markers']} markers = "
              f"{result['marker_observations']} marker observations, {result['visible']} "
              f"visible ({100 * result['visible_ratio']:.0f}%)")
    finish_viewing(html_out=None if args.json else result["html_out"], live=args.meshcat)
    return 0


if __name__ == "__main__":
    sys.exit(main())
