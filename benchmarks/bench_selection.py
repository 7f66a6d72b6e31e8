"""Link-model selection (rigid, prismatic, revolute, GP) of this checkout against a git
revision of it, side by side in one process (prints figures; never fails on time).

    python benchmarks/bench_selection.py [--baseline REV] [--repeats 9] [--real-dir DIR]
                                         [--quick] [--json [FILE]]

Speed: ``select_link_model`` on the speed benchmark's tracks (``bench_articulation.py``: a
simulated microwave door and a drawer, n = 30 and 200, sigma 2 mm / 2 deg), median process
CPU time over ``--repeats`` selections per side; with ``--baseline`` the revision's
selection runs too, the two alternating within each repeat (which one goes first alternates
as well), so that both see the same machine load; the table prints both and their ratio.

Equality (with ``--baseline``): both sides select on

- the real tracks of ``tests/data/articulation_logs`` (full poses) at sigma_pos 5, 20 and
  50 mm (sigma_orient 5 deg);
- with ``--real-dir DIR`` (the folder of Cody's recorded hook trajectories,
  ``mechanisms_iros_2010``: drawer, left_door, right_door, dishwasher; not shipped) each of
  its position-only tracks at sigma_pos 5, 20 and 50 mm;
- the peer benchmark's synthetic tracks with ground truth (``bench_peer_ripl.py``: door
  r = 0.5 m and drawer, sigma 0.005 / 0.02 / 0.05, ``--seeds`` seeds, n = 50 each): joint
  type right and axis error per side;

and the benchmark reports how many selections pick a different model, and the largest
difference of the selected model's BIC and parameters (theta, radius, axis angle) between
the two sides.

``--baseline REV`` extracts ``models/articulation`` and ``models/common`` of revision REV
(``git archive``) into a temporary directory and imports them as a package of their own
(``_baseline_models``), so both versions live in one interpreter.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import glob
import importlib
import math
import sys
import time
from pathlib import Path

import numpy as np

from mmlearn.models.articulation.link import ObservationModel
from mmlearn.models.articulation.sim import simulate_link
from mmlearn.models.articulation.structure import select_link_model
from mmlearn.models.common.track_io import read_track

from _common import add_output_arguments, emit_json, import_revision

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
TRACKS = REPO / "tests" / "data" / "articulation_logs"
OBS = ObservationModel(sigma_pos=0.002, sigma_orient=np.deg2rad(2.0))
SIGMAS = (0.005, 0.02, 0.05)
PKGS = ("models/articulation", "models/common")
REAL_KINDS = ("drawer", "left_door", "right_door", "dishwasher")


def load_baseline(rev: str):
    """(select_link_model, ObservationModel) of git revision ``rev`` of this repository,
    imported from a temporary copy as the package ``_baseline_models``. Raises SystemExit
    with a one-line message when it cannot."""
    import_revision(rev, list(PKGS), "models", "_baseline_models",
                    ("mmlearn.models.", "_baseline_models."))
    structure = importlib.import_module("_baseline_models.articulation.structure")
    link = importlib.import_module("_baseline_models.articulation.link")
    return structure.select_link_model, link.ObservationModel


def speed_rows(sides, repeats, sizes):
    """Median CPU ms per side on the speed benchmark's tracks."""
    rows = []
    for n in sizes:
        for kind in ("microwave", "drawer"):
            tr = simulate_link(kind, n, rng=0)
            cpu = {name: [] for name in sides}
            sel = {}
            for r in range(repeats + 1):  # the first round warms up (not counted)
                order = list(sides) if r % 2 == 0 else list(sides)[::-1]
                for name in order:
                    select, Obs = sides[name]
                    obs = Obs(sigma_pos=0.002, sigma_orient=np.deg2rad(2.0))
                    c0 = time.process_time()
                    s = select(tr.Z, obs=obs, rng=0)
                    if r:
                        cpu[name].append(time.process_time() - c0)
                    sel[name] = s.selected
            rows.append(dict(track=f"{kind}_n{n}", n=n,
                             **{f"{k}_cpu_ms": 1e3 * float(np.median(v)) for k, v in cpu.items()},
                             **{f"{k}_selected": v for k, v in sel.items()}))
    return rows


def _axis_err(a, b):
    c = abs(float(np.dot(a, b)) / (np.linalg.norm(a) * np.linalg.norm(b) + 1e-300))
    return math.degrees(math.acos(min(1.0, c)))


def _model_diff(a, b) -> dict:
    """Differences between two fitted models of the same kind: BIC, theta, radius, axis."""
    out = {"dbic": abs(float(a.bic_) - float(b.bic_))}
    ta, tb = np.asarray(a.theta, float), np.asarray(b.theta, float)
    if ta.size and ta.shape == tb.shape:
        out["dtheta"] = float(np.max(np.abs(ta - tb)))
    if hasattr(a, "radius"):
        out["dradius"] = abs(a.radius - b.radius)
    if hasattr(a, "axis") and a.dof:
        out["daxis_deg"] = _axis_err(a.axis, b.axis)
    return out


def equality_tracks(real_dir, seeds):
    """(label, track, sigma_pos, sigma_orient, kind or None, axis or None) of every track
    the two sides are compared on."""
    out = []
    for f in sorted(TRACKS.glob("*.log")):
        Z = read_track(f).poses
        for sp in SIGMAS:
            out.append(("tests/data", Z, sp, np.deg2rad(5.0), None, None))
    if real_dir:
        for kind in REAL_KINDS:
            for f in sorted(glob.glob(os.path.join(real_dir, kind, "*.log"))):
                P = read_track(f).poses[:, :3]
                for sp in SIGMAS:
                    out.append(("Cody", P, sp, np.deg2rad(5.0),
                                "prismatic" if kind == "drawer" else "revolute", None))
    if seeds:
        sys.path.insert(0, str(HERE))
        from bench_peer_ripl import _pose7, tracks

        for t in tracks(seeds, 50, ""):
            out.append((t["set"], _pose7(t["T"]), t["sigma"], t["sigma"] / 0.25, t["kind"],
                        t["axis"]))
    return out


def equality(sides, real_dir, seeds):
    """Select on every track with both sides; per track set: selections, how many differ,
    largest differences of the selected model, right type and median axis error per side."""
    sets = {}
    for label, Z, sp, so, kind, axis in equality_tracks(real_dir, seeds):
        res = {}
        for name, (select, Obs) in sides.items():
            res[name] = select(Z, obs=Obs(sigma_pos=sp, sigma_orient=so), rng=0)
        e = sets.setdefault(label, dict(selections=0, different=0, right={k: 0 for k in sides},
                                        axis_err={k: [] for k in sides}, dbic=0.0,
                                        dtheta=0.0, dradius=0.0, daxis_deg=0.0))
        e["selections"] += 1
        names = list(sides)
        a = res[names[0]]
        for name, s in res.items():
            if kind is not None and s.selected == kind:
                e["right"][name] += 1
                if axis is not None:
                    e["axis_err"][name].append(_axis_err(s.best.axis, axis))
        if len(names) > 1:
            b = res[names[1]]
            if a.selected != b.selected:
                e["different"] += 1
            else:
                for k, v in _model_diff(a.best, b.best).items():
                    e[k] = max(e[k], v)
    for e in sets.values():
        e["axis_err_median_deg"] = {k: (float(np.median(v)) if v else None)
                                    for k, v in e.pop("axis_err").items()}
    return sets


def main(argv=None):
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--baseline", default=None, metavar="REV",
                    help="also run the selection of this git revision, side by side")
    ap.add_argument("--repeats", type=int, default=9)
    ap.add_argument("--real-dir", default="", metavar="DIR",
                    help="folder of Cody's recorded tracks (mechanisms_iros_2010)")
    ap.add_argument("--seeds", type=int, default=10,
                    help="seeds per joint and sigma of the synthetic tracks (0: none)")
    add_output_arguments(ap, quick="3 repeats, n = 30 only, 2 seeds")
    a = ap.parse_args(argv)
    if a.repeats < 1 or a.seeds < 0:
        ap.error("--repeats must be >= 1 and --seeds >= 0")
    if a.real_dir and not os.path.isdir(a.real_dir):
        ap.error(f"--real-dir: no such folder: {a.real_dir}")
    repeats, seeds = (3, min(a.seeds, 2)) if a.quick else (a.repeats, a.seeds)
    sides = {"new": (select_link_model, ObservationModel)}
    if a.baseline is not None:
        sides["base"] = load_baseline(a.baseline)
    load0 = os.getloadavg()[0]
    rows = speed_rows(sides, repeats, (30,) if a.quick else (30, 200))
    sets = equality(sides, a.real_dir, seeds)
    figures = {f"select_{r['track']}_cpu_ms": r["new_cpu_ms"] for r in rows}
    if a.baseline is not None:
        figures.update({f"select_{r['track']}_ratio": r["new_cpu_ms"] / r["base_cpu_ms"]
                        for r in rows})
        figures["real_selections_different"] = sum(
            e["different"] for k, e in sets.items() if k in ("tests/data", "Cody"))
    doc = dict(baseline=a.baseline, load=[load0, os.getloadavg()[0]], rows=rows, sets=sets,
               figures=figures)
    if emit_json(a.json, doc):
        return
    base = a.baseline
    print(f"select 4 candidates (CPU ms, median of {repeats}; load {load0:.1f}"
          f" -> {os.getloadavg()[0]:.1f})")
    print(f"{'track':16s} {'new':>7s}" + ("" if base is None else
                                          f" {base[:10]:>10s} {'new/base':>9s}") + "  selected")
    for r in rows:
        line = f"{r['track']:16s} {r['new_cpu_ms']:7.1f}"
        if base is not None:
            line += f" {r['base_cpu_ms']:10.1f} {r['new_cpu_ms'] / r['base_cpu_ms']:9.2f}"
        print(line + f"  {r['new_selected']}")
    for label, e in sets.items():
        right = ", ".join(f"{k} {v}/{e['selections']}" for k, v in e["right"].items())
        ax = ", ".join(f"{k} {v:.2f}" for k, v in e["axis_err_median_deg"].items()
                       if v is not None)
        print(f"{label}: {e['selections']} selections"
              + ("" if base is None else
                 f", {e['different']} with a different model; largest |dBIC| "
                 f"{e['dbic']:.2g}, |dtheta| {e['dtheta']:.2g}, |dradius| {e['dradius']:.2g} m, "
                 f"axis {e['daxis_deg']:.2g} deg")
              + (f"; right type {right}" if label != "tests/data" else "")
              + (f"; median axis error (deg) {ax}" if ax else ""))


if __name__ == "__main__":
    main()
