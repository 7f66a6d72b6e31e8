"""Record a teacher's demonstrations of a task, observed by the marker sensor (thesis ch. 8).

    python -m mmlearn.apps.record_demos --task pick_place|whiteboard|obstacle|u_obstacle \\
        --demos N --seed S --out FILE.json [--swap-tables] [--board-scale S] \\
        [--with-obstacle] [--meshcat] [--html-out F] [--json]

A human-like teacher arm (other link lengths than the robot's) performs the task in the
imitation scene (:mod:`mmlearn.sdf.imitation`) with seeded variation of the layout, its
timing, speed and via points; the project's MarkerSensor observes its hand, fingers and the
objects at 5 Hz with 5 mm noise and occlusions (:mod:`mmlearn.diagrams.imitation.demonstrations`).
The demonstrations are saved with :func:`mmlearn.models.imitation.types.save_demonstrations`
(JSON: per demonstration ``t``, ``hand``, ``objects``, ``gripper``, ``meta``; null = the
marker was not seen). The same seed gives the same file.

Printed (and with ``--json``): per demonstration its duration, frame count and the share of
frames in which the hand and each object were seen; the time spent recording.
Meshcat (``--meshcat`` live, ``--html-out`` recording): the last demonstration's playback
and every demonstration's observed hand track.
"""

import json
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mmlearn.apps.common.cli import (ArgumentParser, UsageError, check_out_file, fail,
                                     finish_viewing, json_clean, make_meshcat, nonneg_int,
                                     pos_float, pos_int, progress_bar, save_html)
from mmlearn.models.common.config import param, validate_fields
from mmlearn.models.imitation.teacher import TASKS

__all__ = ["RecordDemosConfig", "run", "main"]


@dataclass
class RecordDemosConfig:
    """What :func:`run` does.

    Attributes:
        task: one of pick_place, whiteboard, obstacle, u_obstacle.
        demos: number of demonstrations (>= 1).
        seed: seed of the demonstrations (demonstration i uses ``seed * 1000 + i``).
        out: JSON file to write ("" = do not save).
        swap_tables: exchange the two tables (pick_place).
        board_scale: scale of the area inside the board's corner markers (whiteboard).
        with_obstacle: keep the obstacle in the demonstrations (obstacle tasks; the thesis
            demonstrated without it).
        html_out: write the Meshcat recording here ("" = no).
        meshcat: show it live.
    """

    task: str = param("pick_place", choices=TASKS)
    demos: int = param(4, integer=True, ge=1)
    seed: int = param(0, integer=True, ge=0, lt=2147483)
    out: str = param("")
    swap_tables: bool = param(False)
    board_scale: float = param(1.0, gt=0)
    with_obstacle: bool = param(False)
    html_out: str = param("")
    meshcat: bool = param(False)

    def validate(self) -> None:
        validate_fields(self)


def run(*, config: RecordDemosConfig, show_progress: bool = False) -> dict:
    """Record, save and summarise the demonstrations; returns the JSON-able result."""
    from mmlearn.diagrams.imitation.demonstrations import record_demonstrations
    from mmlearn.models.imitation.types import save_demonstrations
    from mmlearn.models.imitation.teacher import task_scene

    cfg = config
    cfg.validate()
    scene = task_scene(cfg.task, swap_tables=cfg.swap_tables, board_scale=cfg.board_scale)
    meshcat = make_meshcat(announce=cfg.meshcat) if (cfg.meshcat or cfg.html_out) else None
    bar = progress_bar(cfg.demos, desc=f"recording {cfg.task}", unit="demo",
                       enabled=show_progress)
    t0 = time.perf_counter()
    try:
        demos = record_demonstrations(cfg.task, cfg.demos, seed=cfg.seed, scene=scene,
                                      with_obstacle=cfg.with_obstacle, meshcat=meshcat,
                                      progress=lambda i: bar.update(1))
    finally:
        bar.close()
    seconds = time.perf_counter() - t0
    out = {"task": cfg.task, "demos": cfg.demos, "seed": cfg.seed,
           "swap_tables": cfg.swap_tables, "board_scale": cfg.board_scale,
           "with_obstacle": cfg.with_obstacle, "record_seconds": seconds,
           "out": None, "html_out": None, "demonstrations": []}
    for d in demos:
        out["demonstrations"].append({
            "duration_s": d.duration, "frames": d.T,
            "hand_seen": float(np.isfinite(d.hand).all(axis=1).mean()),
            "gripper_seen": float(np.isfinite(d.gripper).mean()) if d.gripper is not None
            else None,
            "objects_seen": {k: float(np.isfinite(v).all(axis=1).mean())
                             for k, v in d.objects.items()}})
    if cfg.out:
        out["out"] = str(save_demonstrations(cfg.out, demos))
    if cfg.html_out and meshcat is not None:
        out["html_out"] = str(save_html(meshcat, cfg.html_out))
    return out


def _summary(r: dict) -> str:
    lines = [f"{r['demos']} demonstration(s) of {r['task']} (seed {r['seed']}"
             + (", tables swapped" if r["swap_tables"] else "")
             + (f", board scale {r['board_scale']}" if r["task"] == "whiteboard" else "")
             + f") recorded in {r['record_seconds']:.1f} s"]
    for i, d in enumerate(r["demonstrations"]):
        seen = ", ".join(f"{k} {100 * v:.0f} %" for k, v in d["objects_seen"].items())
        lines.append(f"  {i}: {d['duration_s']:.1f} s, {d['frames']} frames; seen: hand "
                     f"{100 * d['hand_seen']:.0f} %, {seen}")
    if r["out"]:
        lines.append(f"saved to {r['out']}")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = ArgumentParser(
        prog="python -m mmlearn.apps.record_demos",
        description="Record a teacher's demonstrations of a manipulation task as the marker "
                    "sensor observes them, and save them as JSON.")
    ap.add_argument("--task", choices=TASKS, default="pick_place", help="the task")
    ap.add_argument("--demos", type=pos_int, default=4, help="number of demonstrations")
    ap.add_argument("--seed", type=nonneg_int, default=0, help="seed of the demonstrations")
    ap.add_argument("--out", type=Path, help="JSON file to save the demonstrations to")
    ap.add_argument("--swap-tables", action="store_true",
                    help="exchange the places of the two tables (pick_place)")
    ap.add_argument("--board-scale", type=pos_float, default=1.0,
                    help="scale of the area inside the board's corner markers (whiteboard)")
    ap.add_argument("--with-obstacle", action="store_true",
                    help="keep the obstacle in the demonstrations (obstacle tasks)")
    ap.add_argument("--meshcat", action="store_true", help="show it live in Meshcat")
    ap.add_argument("--html-out", type=Path, help="save the Meshcat recording (HTML)")
    ap.add_argument("--json", action="store_true", help="print the results as JSON")
    args = ap.parse_args(argv)
    try:
        if args.seed >= 2147483:
            raise UsageError(f"--seed must be < 2147483, got {args.seed}")
        check_out_file("--out", args.out)
        check_out_file("--html-out", args.html_out)
    except UsageError as e:
        return fail(ap.prog, str(e))
    cfg = RecordDemosConfig(task=args.task, demos=args.demos, seed=args.seed,
                            out=str(args.out or ""), swap_tables=args.swap_tables,
                            board_scale=args.board_scale, with_obstacle=args.with_obstacle,
                            html_out=str(args.html_out or ""), meshcat=args.meshcat)
    from mmlearn.diagrams.imitation.demonstrations import TeacherIKError

    try:
        result = run(config=cfg, show_progress=not args.json)
    except (ValueError, TeacherIKError) as e:  # e.g. a board larger than the teacher's reach
        return fail(ap.prog, str(e))
    if args.json:
        print(json.dumps(json_clean(result)))
    else:
        print(_summary(result))
    finish_viewing(html_out=None if args.json else result["html_out"], live=args.meshcat)
    return 0


if __name__ == "__main__":
    sys.exit(main())
