"""Whiteboard coverage of the reproduction against the teacher's area-size variation
(``TeacherStyle.board_scale_jitter``; 0 = every demonstration on the same area).

    OPENBLAS_NUM_THREADS=1 python benchmarks/diag_board_coverage.py --seeds 1,2,3 \
        --scales 0.8,1.0,1.25 --jitter 0,0.25 [--h 0.2] [--jobs 2]
    OPENBLAS_NUM_THREADS=1 python benchmarks/diag_board_coverage.py --teacher-ceiling

``--h`` overrides the whiteboard's Parzen window (s; the default is
``mmlearn.apps.imitate.PARZEN_H``). ``--teacher-ceiling`` prints instead the coverage of the
teacher's own zig-zag planned on each area scale (the best a perfectly scaled imitation could
reach, seeds 1-8).

Prints, per jitter and area scale, each seed's coverage, the demonstrations' own and the
success (coverage >= 90 % of the demonstrations')."""
from __future__ import annotations

import argparse
from concurrent.futures import ProcessPoolExecutor

import numpy as np


def one(args):
    jitter, scale, seed, h = args
    import mmlearn.apps.imitate as im
    if h is not None:
        im.PARZEN_H["whiteboard"] = h
    from mmlearn.diagrams.imitation.demonstrations import record_demonstrations
    from mmlearn.models.imitation.teacher import TeacherStyle, task_scene

    def rec(task, n, *, seed, board_scale=1.0, placement=im.PLACEMENT):
        return record_demonstrations(
            task, n, seed=seed, scene=task_scene(task, board_scale=board_scale),
            style=TeacherStyle(placement=placement, board_scale_jitter=jitter))

    im.record_demos = rec
    r = im.run(task="whiteboard", seed=seed, board_scale=scale, show_progress=False)
    return jitter, scale, seed, r["coverage"], r["demo_coverage"], r["success"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--scales", default="0.8,1.0,1.25")
    ap.add_argument("--jitter", default="0,0.25")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--h", type=float, default=None)
    ap.add_argument("--teacher-ceiling", action="store_true")
    a = ap.parse_args()
    if a.teacher_ceiling:
        return ceiling([float(s) for s in a.scales.split(",")])
    seeds = [int(s) for s in a.seeds.split(",")]
    scales = [float(s) for s in a.scales.split(",")]
    jit = [float(s) for s in a.jitter.split(",")]
    todo = [(j, s, k, a.h) for j in jit for s in scales for k in seeds]
    with ProcessPoolExecutor(a.jobs) as ex:
        res = list(ex.map(one, todo))
    for j in jit:
        for s in scales:
            rs = [r for r in res if r[0] == j and r[1] == s]
            cov = np.array([r[3] for r in rs])
            print(f"jitter {j:g} scale {s:g}: success {sum(r[5] for r in rs)}/{len(rs)} "
                  f"coverage mean {cov.mean():.3f} [{' '.join(f'{c:.2f}' for c in cov)}] "
                  f"demos {np.mean([r[4] for r in rs]):.3f}", flush=True)


def ceiling(scales):
    from mmlearn.apps.imitate import _coverage
    from mmlearn.models.imitation.teacher import TeacherStyle, plan_demonstration, task_scene

    for s in scales:
        cs = []
        for seed in range(1, 9):
            p = plan_demonstration("whiteboard", seed=seed,
                                   scene=task_scene("whiteboard", board_scale=s),
                                   style=TeacherStyle(board_scale_jitter=0))
            x = p.hand_position(np.linspace(0, p.duration, 2000))
            cs.append(_coverage(x, p.scene.board_corners(), plane_tol=0.03))
        print(f"teacher's zig-zag on area scale {s:g}: coverage mean {np.mean(cs):.3f} "
              f"[{' '.join(f'{c:.2f}' for c in cs)}]")


if __name__ == "__main__":
    main()
