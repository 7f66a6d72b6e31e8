"""Link-model estimation side by side with ``ripl-articulation`` (Buchanan et al., ICRA 2024: one
screw model fitted with a factor graph on gtsam) on the same tracks (prints figures; never fails
on time or accuracy).

    python benchmarks/bench_peer_ripl.py --peer-python /tmp/peer_ripl/bin/python
                                         [--seeds 10] [--n 50] [--quick] [--json [FILE]]

The peer is never imported here: its source headers say GPL-3.0 and it pins numpy <= 1.26.4 and
needs gtsam, so it lives in its own environment, and this benchmark runs it in a subprocess of
that environment's interpreter (``--peer-python``) on the same tracks, sent as JSON. The peer
fits B(t) = A exp(xi theta(t)) to pose pairs; A is each track's first pose (the reference a
tracker has), B every pose. Set it up
once with::

    python3.11 -m venv /tmp/peer_ripl && /tmp/peer_ripl/bin/pip install ripl-articulation

Without ``--peer-python`` (or when the peer does not import there) the peer's columns say why
and only mmlearn's side is measured.

Tracks:

- synthetic, with ground truth: a door of radius 0.5 m about a vertical axis opened 0-90 deg,
  and a drawer pulled 0-0.4 m along a horizontal axis, both in a tilted base frame; ``--n``
  relative poses each (full 6-D poses), position noise sigma = 0.005 / 0.02 / 0.05 m per axis
  and orientation noise sigma / 0.25 rad (the pose noise of a marker 0.25 m across),
  ``--seeds`` seeds per (joint, sigma);
- real: the 30 position-only hook trajectories of Cody (drawers, left and right cabinet doors,
  dishwashers: ``shared/data/articulation_logs/mechanisms_iros_2010``, ``--real-dir``),
  fitted at sigma = 0.05 m as in the thesis (the robot's base localisation); the peer gets
  them with a rotation noise of 10 rad (no orientation measured).

Figures per track set: joint type right (mmlearn: the selected model among rigid, prismatic,
revolute, GP; the peer: its twist is revolute when its rotation over the track,
|omega| (theta_max - theta_min), exceeds 10 deg, else prismatic), the axis error of the right
types against the truth (deg; mmlearn: the model's ``axis``; the peer: omega's direction for a
revolute twist, v's for a prismatic one; synthetic tracks only), and the CPU time per track
(process time of the fit alone, each side in its own process, one BLAS thread).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import argparse
import glob
import json
import math
import subprocess
import sys
import tempfile
import time

import numpy as np
from scipy.spatial.transform import Rotation

from _common import add_output_arguments, emit_json

from mmlearn.models.articulation.link import ObservationModel
from mmlearn.models.articulation.structure import select_link_model
from mmlearn.models.common.track_io import read_track

SIGMAS = (0.005, 0.02, 0.05)
REAL_DIR = ""  # the recorded Cody tracks are not shipped: --real-dir names their folder
REAL_KIND = {"drawer": "prismatic", "left_door": "revolute", "right_door": "revolute",
             "dishwasher": "revolute"}
_BASE = Rotation.from_euler("xyz", [0.1, -0.15, 0.4])
_REVOLUTE_MIN_DEG = 10.0

# the peer's side: run by the peer's interpreter, reads the tracks as JSON on stdin, writes
# per track the twist, the thetas and the CPU time of the fit
PEER_SCRIPT = r"""
import json, sys, time
import numpy as np
import gtsam
from ripl_articulation import solve_articulation_from_poses
for t in json.load(sys.stdin):
    B = np.array(t["poses"], float)
    A = np.repeat(B[:1], len(B), axis=0)  # the first observation: the reference frame
    s = [t["rot_sigma"]] * 3 + [t["pos_sigma"]] * 3
    c0 = time.process_time()
    xi, th = solve_articulation_from_poses(
        A, B, pose_noise_model=gtsam.noiseModel.Diagonal.Sigmas(np.array(s)))
    print(json.dumps(dict(xi=np.asarray(xi).tolist(), thetas=np.asarray(th).tolist(),
                          cpu=time.process_time() - c0)), flush=True)
"""


def door_track(n, sigma, rng, radius=0.5):
    """(poses (n, 4, 4), axis) of a door opened 0-90 deg: the handle's frame on a circle of
    ``radius`` about the base frame's z axis."""
    q = rng.uniform(0.0, math.pi / 2, n)
    R = Rotation.from_euler("z", q[:, None])
    P = R.apply(np.array([radius, 0.0, 0.0]))
    return _noisy(R, P, sigma, rng), _BASE.apply([0.0, 0.0, 1.0])


def drawer_track(n, sigma, rng):
    """(poses, axis) of a drawer pulled 0-0.4 m along the base frame's x axis."""
    q = rng.uniform(0.0, 0.4, n)
    P = np.outer(q, [1.0, 0.0, 0.0])
    return _noisy(Rotation.identity(n), P, sigma, rng), _BASE.apply([1.0, 0.0, 0.0])


def _noisy(R, P, sigma, rng):
    n = len(P)
    Rn = Rotation.from_rotvec(rng.normal(0.0, sigma / 0.25, (n, 3))) * _BASE * R
    T = np.repeat(np.eye(4)[None], n, axis=0)
    T[:, :3, :3] = Rn.as_matrix()
    T[:, :3, 3] = _BASE.apply(P) + np.array([0.4, -0.2, 0.7]) + rng.normal(0.0, sigma, (n, 3))
    return T


def _pose7(T):
    return np.hstack([T[:, :3, 3], Rotation.from_matrix(T[:, :3, :3]).as_quat()])


def _axis_err(a, b):
    c = abs(float(np.dot(a, b)) / (np.linalg.norm(a) * np.linalg.norm(b) + 1e-300))
    return math.degrees(math.acos(min(1.0, c)))


def tracks(seeds, n, real_dir):
    """The synthetic and real tracks: dicts (set, kind, poses (n, 4, 4) or positions (n, 3),
    axis or None, sigma)."""
    out = []
    for kind, make in (("revolute", door_track), ("prismatic", drawer_track)):
        for sigma in SIGMAS:
            for seed in range(seeds):
                rng = np.random.default_rng([seed, int(1e4 * sigma), len(kind)])
                T, axis = make(n, sigma, rng)
                out.append(dict(set=f"{'door r=0.5' if kind == 'revolute' else 'drawer'} "
                                    f"sigma={sigma:g}", kind=kind, T=T, axis=axis, sigma=sigma))
    if real_dir and os.path.isdir(real_dir):
        for name, kind in REAL_KIND.items():
            for f in sorted(glob.glob(os.path.join(real_dir, name, "*.log"))):
                P = read_track(f).poses[:, :3]
                T = np.repeat(np.eye(4)[None], len(P), axis=0)
                T[:, :3, 3] = P
                out.append(dict(set="real (Cody, sigma=0.05)", kind=kind, T=T, axis=None,
                                sigma=0.05, position_only=True))
    return out


def run_ours(trs):
    res = []
    if trs:  # one selection untimed: a process's first one loads the compiled kernels
        select_link_model(_pose7(trs[0]["T"]), rng=0)
    for t in trs:
        obs = ObservationModel(sigma_pos=t["sigma"], sigma_orient=t["sigma"] / 0.25)
        Z = t["T"][:, :3, 3] if t.get("position_only") else _pose7(t["T"])
        c0 = time.process_time()
        sel = select_link_model(Z, obs=obs, rng=0)
        cpu = time.process_time() - c0
        best = sel.best
        err = (_axis_err(best.axis, t["axis"]) if t["axis"] is not None
               and best.name == t["kind"] else None)
        res.append(dict(kind=best.name, axis_err=err, cpu=cpu))
    return res


def run_peer(python, trs, timeout):
    """The peer's results per track (None for the tracks it did not finish within
    ``timeout``), or (None, why) when it cannot run at all."""
    if not python:
        return None, "no --peer-python given"
    payload = [dict(poses=t["T"].tolist(), pos_sigma=t["sigma"],
                    rot_sigma=10.0 if t.get("position_only") else t["sigma"] / 0.25)
               for t in trs]
    with tempfile.NamedTemporaryFile("w", suffix=".py", delete=False) as f:
        f.write(PEER_SCRIPT)
    why = None
    try:
        p = subprocess.run([python, f.name], input=json.dumps(payload), capture_output=True,
                           text=True, timeout=timeout,
                           env=dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1"))
        lines, err = p.stdout, p.stderr
        if p.returncode != 0:
            why = (err.strip().splitlines() or [f"exit status {p.returncode}"])[-1]
    except subprocess.TimeoutExpired as e:  # keep the tracks it finished
        lines = e.stdout.decode() if isinstance(e.stdout, bytes) else (e.stdout or "")
        why = f"stopped after {timeout:.0f} s"
    except OSError as e:
        return None, f"{type(e).__name__}: {e}"
    finally:
        os.unlink(f.name)
    done = [json.loads(x) for x in lines.splitlines() if x.startswith("{")]
    if not done:
        return None, why or "no output"
    out = []
    for t, r in zip(trs, done + [None] * (len(trs) - len(done))):
        if r is None:
            out.append(None)
            continue
        xi, th = np.array(r["xi"]), np.array(r["thetas"])
        R0 = t["T"][0, :3, :3]  # the twist is in the first observation's frame
        w, v = R0 @ xi[:3], R0 @ xi[3:]
        turn = math.degrees(np.linalg.norm(w) * float(np.ptp(th))) if len(th) else 0.0
        kind = "revolute" if turn > _REVOLUTE_MIN_DEG else "prismatic"
        err = None
        if t["axis"] is not None and kind == t["kind"]:
            err = _axis_err(w if kind == "revolute" else v, t["axis"])
        out.append(dict(kind=kind, axis_err=err, cpu=r["cpu"]))
    return out, None


def summarise(trs, res):
    rows = {}
    for t, r in zip(trs, res):
        if r is None:  # (not run)
            continue
        e = rows.setdefault(t["set"], dict(n=0, right=0, err=[], cpu=[]))
        e["n"] += 1
        e["right"] += int(r["kind"] == t["kind"])
        if r["axis_err"] is not None:
            e["err"].append(r["axis_err"])
        e["cpu"].append(r["cpu"])
    return {k: dict(tracks=v["n"], right=v["right"],
                    axis_err_mean_deg=float(np.mean(v["err"])) if v["err"] else None,
                    axis_err_max_deg=float(np.max(v["err"])) if v["err"] else None,
                    cpu_ms_median=1e3 * float(np.median(v["cpu"])))
            for k, v in rows.items()}


def _cell(s):
    if s is None:
        return f"{'-':>8s} {'-':>13s} {'-':>8s}"
    err = "-" if s["axis_err_mean_deg"] is None else (f"{s['axis_err_mean_deg']:.1f}/"
                                                      f"{s['axis_err_max_deg']:.1f}")
    return f"{s['right']:3d}/{s['tracks']:<4d} {err:>13s} {s['cpu_ms_median']:8.1f}"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--peer-python", default=None, metavar="PYTHON",
                    help="interpreter of an environment with ripl-articulation installed")
    ap.add_argument("--seeds", type=int, default=10, help="seeds per joint and sigma")
    ap.add_argument("--n", type=int, default=50, help="poses per synthetic track")
    ap.add_argument("--real-dir", default=REAL_DIR,
                    help="folder of the recorded Cody tracks (the thesis data's "
                    "articulation_logs/mechanisms_iros_2010, one folder per mechanism); "
                    "default: skip them")
    ap.add_argument("--timeout", type=float, default=3600.0,
                    help="for the peer's run, s (the tracks it has not finished then are "
                         "left out of its column)")
    add_output_arguments(ap, quick="2 seeds, no real tracks")
    a = ap.parse_args(argv)
    if a.seeds < 1 or a.n < 5:
        ap.error("--seeds must be >= 1 and --n >= 5")
    if a.quick:
        a.seeds, a.real_dir = 2, ""
    trs = tracks(a.seeds, a.n, a.real_dir)
    ours = summarise(trs, run_ours(trs))
    peer_res, why = run_peer(a.peer_python, trs, a.timeout)
    if peer_res is not None and any(r is None for r in peer_res):
        why = f"{why}: {sum(r is None for r in peer_res)} tracks not run"
    peer = None if peer_res is None else summarise(trs, peer_res)
    figures = {}
    for k, s in ours.items():
        tag = k.replace(" ", "_").replace("=", "")
        figures[f"mmlearn_{tag}_right"] = s["right"] / s["tracks"]
        figures[f"mmlearn_{tag}_cpu_ms"] = s["cpu_ms_median"]
        if peer is not None and k in peer:
            figures[f"ripl_{tag}_right"] = peer[k]["right"] / peer[k]["tracks"]
            figures[f"ripl_{tag}_cpu_ms"] = peer[k]["cpu_ms_median"]
    if emit_json(a.json, dict(mmlearn=ours, ripl=peer, ripl_skipped=why, figures=figures)):
        return
    print(f"{'tracks':26s} | {'mmlearn: right':>13s} {'axis mean/max':>13s} {'CPU ms':>8s} | "
          f"{'ripl: right':>10s} {'axis mean/max':>13s} {'CPU ms':>8s}")
    for k, s in ours.items():
        print(f"{k:26s} | {_cell(s)}      | {_cell(None if peer is None else peer.get(k))}")
    print("axis error: deg, of the tracks whose type is right; CPU ms: median per track")
    if why is not None:
        print(f"ripl-articulation: {why}" if peer is not None
              else f"ripl-articulation column skipped: {why}")


if __name__ == "__main__":
    main()
