"""The measured lines of the design notes and deviation lists: the front detector's deviations
and its vertical-plane rule (docs/perception.md), the first-call cost of the compiled kernels
(docs/perception.md, docs/performance_articulation.md), the camera marker sensor's image
size (docs/body_schema.md), DTW's features (docs/imitation.md), what limits a door's
learned damping and how often the damping's reported deviation holds the true value
(docs/mechanism_dynamics.md), and the results files they are made from.

Imported by docs/make_tables.py like docs/tables_engineering.py: :data:`COMMANDS` is merged
into its own, and the blocks of :func:`page_blocks` are written between
``<!-- generated:NAME -->`` and ``<!-- /generated:NAME -->``. Every function takes ``load`` (a
results file's name -> its JSON, None when missing) and ``cmd`` (a results file's name -> its
command).
"""

from __future__ import annotations

from tables_common import missing as _missing

#: results file -> the command (from the repository root) that writes it
COMMANDS = {
    # the front detector with each departure from the thesis switched off in turn, on 90
    # rendered frames of the kitchen (about 2 CPU minutes)
    "detector_ablations.json": "python benchmarks/bench_detector_ablations.py --frames 15 "
                               "--distances 1.5,2.2,2.8 --seed 1 "
                               "--json docs/results/detector_ablations.json",
    # the first call of a process: compiling the detector's and the selection's kernels in a
    # fresh environment, then loading them from the cache (about 1 CPU minute)
    "first_call.json": "python benchmarks/bench_first_call.py --json docs/results/first_call.json",
    # the camera marker sensor's errors on the 2-DOF arm at two image sizes, and one marker's
    # detection against distance at 640 x 480 (about 1 CPU minute for the three)
    "camera_markers_1280.json": "python benchmarks/bench_camera_marker_sensor.py --arm 2dof "
                                "--poses 20 --width 1280 --seed 0 "
                                "--json docs/results/camera_markers_1280.json",
    "camera_markers_1920.json": "python benchmarks/bench_camera_marker_sensor.py --arm 2dof "
                                "--poses 20 --width 1920 --seed 0 "
                                "--json docs/results/camera_markers_1920.json",
    # DTW's phase error with derivative, position or both features on simulated
    # pick-and-place demonstrations (and the imitation model layer's quick timings; seconds)
    "imitation_alignment.json": "python benchmarks/bench_imitation.py --quick "
                                "--json docs/results/imitation_alignment.json",
    "camera_markers_640.json": "python benchmarks/bench_camera_marker_sensor.py --width 640 "
                               "--distances 1,1.5,2,2.5 --angles 0 --n 6 --seed 0 "
                               "--json docs/results/camera_markers_640.json",
    # a door's damping fitted from sources one step apart, from the simulator's truth to the
    # robot's estimate, over 24 door trials (about 5 CPU minutes)
    "door_damping_sources.json": "python benchmarks/bench_door_damping_sources.py --seed 600 "
                                 "--doors 24 --jobs 2 "
                                 "--json docs/results/door_damping_sources.json",
}

#: the results files here whose figures change with the detector's work
VOLATILE = ("detector_ablations", "first_call")  # (the camera's figures do not change with them)

#: variant of the ablation benchmark -> the deviation it switches off, as the page names it
ABLATIONS = (("thesis_costs", "Costs"), ("no_crossings", "Crossings"),
             ("no_own_pixel_refit", "Own-pixel refit"), ("no_reveals", "Reveals"),
             ("no_long_pass", "Reveals: the long pass"), ("no_region_starts", "Region starts"),
             ("no_layers", "Offset layers"), ("coarse_rotation", "Rotation polish"),
             ("cell_planes", "RANSAC planes (the cell grid's instead)"))


def _f(x, digits: int = 1) -> str:
    return "-" if x is None else f"{x:.{digits}f}"


def _fields(fields: dict) -> str:
    return ", ".join(f"`{k}: {v}`" for k, v in fields.items()) or "(the defaults)"


def _frames(d) -> str:
    s = d["settings"]
    dist = ", ".join(f"{x:g}" for x in s["distances"])
    return (f"{d['variants']['default']['frames']} rendered frames (a door and a drawer "
            f"opening, {s['frames_per_front_and_distance']} frames each at {dist} m, the first "
            "closed)")


def detector_ablations(load, cmd) -> str:
    """One row per departure from the thesis: the detector with it switched off against the
    default configuration, on the same frames."""
    d = load("detector_ablations.json")
    if not d:
        return _missing("detector_ablations.json")
    v = d["variants"]
    rows = []
    for key, name in (("default", "none (the default configuration)"),) + ABLATIONS:
        r = v.get(key)
        if r is None:
            continue
        rows.append([name, _fields(r["fields"]), f"{r['found']}/{r['frames']}",
                     f"{r['closed_found']}/{r['closed_frames']}",
                     f"{_f(r['width_err_mm_door'])} / {_f(r['width_err_mm_door_max'])}",
                     f"{_f(r['width_err_mm_drawer'])} / {_f(r['width_err_mm_drawer_max'])}",
                     _f(r["pos_err_mm"]), f"{r['same_as_default']}/{r['frames']}",
                     _f(r["cpu_ms_median"])])
    head = ["switched off", "configuration that switches it off", "found", "closed fronts found",
            "door width error mean / max (mm)", "drawer width error mean / max (mm)",
            "position error (mm)", "same rectangles as the default", "CPU ms per frame"]
    out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    out += ["| " + " | ".join(row) + " |" for row in rows]
    return ("\n".join(out) + f"\n\nOn {_frames(d)}, each configuration on every frame with "
            "the same seed; a front is found when the nearest rectangle is within 0.1 m, "
            "20 deg and 0.1 m of width and height of the true one; errors over the found "
            "fronts; CPU time the median per frame, the configurations alternating frame by "
            "frame. A reveal must be longer than `gap_min_length`, so 100 m drops every one "
            "(and with them the region starts); with `crossing_angle_deg: 90` no two planes "
            "cross, which also leaves the own-pixel refit nothing to refit. Made by "
            f"`{cmd('detector_ablations.json')}`.")


def planes_searched(load, cmd) -> str:
    """The rule "only vertical planes are searched" against every plane searched."""
    d = load("detector_ablations.json")
    if not d or "all_planes_searched" not in d["variants"]:
        return _missing("detector_ablations.json")
    a, b = d["variants"]["default"], d["variants"]["all_planes_searched"]
    ratio = (b["cpu_ms_median"] / a["cpu_ms_median"]
             if a["cpu_ms_median"] and b["cpu_ms_median"] else None)
    return (f"On {_frames(d)}: the front found in {a['found']} frames with the rule and in "
            f"{b['found']} with every plane searched (`front_max_tilt_deg: 90`), the "
            f"rectangles on vertical planes the same on {b['same_as_default']} of "
            f"{b['frames']} frames; CPU ms per frame (median) {_f(a['cpu_ms_median'])} with "
            f"the rule against {_f(b['cpu_ms_median'])} without"
            + ("" if ratio is None else f" ({ratio:.2f}x)")
            + f". Made by `{cmd('detector_ablations.json')}`.")


def _first_call(load, name):
    d = load("first_call.json")
    return None if not d else d["workloads"].get(name)


def first_call_detector(load, cmd) -> str:
    """The detector's first call: compiling its kernels, then loading them."""
    r = _first_call(load, "detector")
    if r is None:
        return _missing("first_call.json")
    return (f"The first call compiles them, once: {_f(r['compile_first_call_s'])} s of CPU for "
            "one synthetic frame in a fresh environment; the first call of every later process "
            f"loads them from the cache in the package's `__pycache__` "
            f"({_f(r['cached_first_call_s'], 2)} s), the calls after it take "
            f"{_f(1e3 * r['steady_call_s'])} ms (`{cmd('first_call.json')}`).")


def first_call_selection(load, cmd) -> str:
    """Link-model selection's first call: compiling its kernels, then loading them."""
    r = _first_call(load, "selection")
    if r is None:
        return "- " + _missing("first_call.json")
    return (f"- A fresh environment compiles the kernels on first use, once: the first "
            f"selection (a microwave door, n = 30) took {_f(r['compile_first_call_s'])} s of "
            f"CPU; the first selection of every later process loads them from the cache on "
            f"disk ({_f(r['cached_first_call_s'], 2)} s), the next ones take "
            f"{_f(1e3 * r['steady_call_s'])} ms (`{cmd('first_call.json')}`).")


def _span(xs, scale=1.0, digits=0) -> str:
    xs = [scale * x for x in xs if x is not None]
    if not xs:
        return "-"
    lo, hi = min(xs), max(xs)
    return _f(lo, digits) if round(lo, digits) == round(hi, digits) else \
        f"{_f(lo, digits)}-{_f(hi, digits)}"


def camera_markers(load, cmd) -> str:
    """The camera marker sensor's errors per image size (the arm's parts), and one marker's
    detection against distance at 640 x 480."""
    names = ("camera_markers_1280.json", "camera_markers_1920.json", "camera_markers_640.json")
    docs = [load(n) for n in names]
    if not all(docs):
        return "- " + " ".join(_missing(n) for n, d in zip(names, docs) if not d)
    arms, one = docs[:2], docs[2]
    sizes = []
    for d in arms:
        seen = [p for p in d["parts"] if p.get("visible")]
        sizes.append(f"{d['width']} x {d['height']}: median position error per part "
                     f"{_span([p['pos_med_m'] for p in seen], 1e3)} mm, orientations off by "
                     f"more than 20 deg {_span([p['ang_over_20deg'] for p in seen], 100)} %, "
                     f"{_f(d['wall_s_per_frame'], 2)} s per frame to render and detect")
    single = ", ".join(f"{round(r['rate'] * one['n'])}/{one['n']} at {r['dist']:g} m"
                       for r in one["rows"] if r["angle"] == 0)
    a = arms[0]
    return (f"- `CameraMarkerSensor`'s image size (`CameraMarkerSensorConfig.width`, "
            f"`height`): on {a['poses']} random babbling poses of the "
            f"{a['arm'].replace('dof', '-DOF')} arm, "
            f"{a['cameras']} cameras, "
            + "; ".join(sizes)
            + f" (wall-clock on a shared machine). At {one['width']} x "
              f"{one['width'] * 3 // 4} a single 0.04 m marker seen face-on was detected in "
              f"{single}. Made by "
            + ", ".join(f"`{cmd(n)}`" for n in names) + ".")


def dtw_features(load, cmd) -> str:
    """The imitation page's DTW deviation: the phase error per feature set."""
    d = load("imitation_alignment.json")
    if not d:
        return "- DTW on derivative and position features. " + _missing("imitation_alignment.json")
    e = {k: d.get(f"align_{k}", {}).get("mean_phase_error_segments")
         for k in ("derivative", "position", "both")}
    return ("- DTW on derivative and position features (derivative only is the thesis' choice): "
            f"mean phase error {_f(e['both'], 3)} segments with both, {_f(e['derivative'], 3)} "
            f"with the derivative only, {_f(e['position'], 3)} with the position only, on "
            "simulated pick-and-place demonstrations with varied segment timing and placement "
            f"(`{cmd('imitation_alignment.json')}`).")


#: the door-damping sources, in the benchmark's order, as the mechanism page names them
DOOR_SOURCES = (("contact", "the simulator's contact torque on the door, the door's own angle, "
                 "rate and acceleration"),
                ("contact_point", "noise-free wrist force at the hook's contact point on the "
                 "handle, true axis"),
                ("ideal", "noise-free wrist force, true lever arm at the handle bar's centre"),
                ("sensor", "the sensor's readings instead"),
                ("sensor_aligned", "each reading paired with the door's state one sensor "
                 "sample earlier"),
                ("learned_tangent", "the torque from the learned model's tangent"),
                ("learned_tangent_leak", "the same with the force across the door as a "
                 "nuisance term"),
                ("learned_kinematics", "the opening, rate and acceleration from the hook's "
                 "track along the learned model"),
                ("contact_point_track", "the reading at the contact point (a wrist torque "
                 "sensor) about the learned axis, the axis' offset as nuisance terms, the "
                 "hook's track"),
                ("robot", "the robot's estimate (its 25 ms samples)"))


def door_damping_sources(load, cmd) -> str:
    """The mechanism page's table of what limits a door's damping: per source, the doors
    within 25 % and the mean signed and absolute errors, light doors and the rest."""
    d = load("door_damping_sources.json")
    if not d:
        return _missing("door_damping_sources.json")
    s = d["summary"]
    rows = []
    for key, label in DOOR_SOURCES:
        cells = []
        for group in ("light", "heavier"):
            x = s[f"{key}_{group}"]
            cells.append("-" if not x["doors"] else
                         f"{x['within_25pct']}/{x['doors']} ({x['mean_error'] * 100:+.0f} %, "
                         f"{x['mean_abs_error'] * 100:.0f} %)")
        rows.append(f"| {label} | {cells[0]} | {cells[1]} |")
    light = f"{s['light_damping']:g}"
    heavier = ", ".join(f"{v:g}" for v in sorted(set(d["damping"])) if v != s["light_damping"])
    lo, hi = s["opening_scale"] or (None, None)
    rlo, rhi = s["radius_ratio"] or (None, None)
    spread = s.get("contact_spread_mm")
    moves = ("" if not spread else
             f"While pulled, the point where the hook touches the handle moves on the door by "
             f"up to {spread[0]:.0f} mm along the handle's path and {spread[1]:.0f} mm towards "
             "the hinge (5-95 % range, the largest over the doors). ")
    return (f"**A door's damping from each source** ({d['doors']} door trials, seeds "
            f"{d['seed']}-{d['seed'] + d['doors'] - 1}; within 25 % of the true value (mean "
            "signed error, mean absolute error))\n\n"
            f"| source | doors at {light} N m s/rad | doors at {heavier} N m s/rad |\n"
            "|---|---|---|\n" + "\n".join(rows) + "\n\n"
            f"The learned opening grows {_f(lo, 3)}-{_f(hi, 3)} times as fast as the door's "
            f"angle; the learned radius is {_f(rlo, 3)}-{_f(rhi, 3)} of the true one. "
            f"{moves}Made by `{cmd('door_damping_sources.json')}`.")


#: the damping sets whose trials the coverage of the reported deviations is counted on
DAMPING_SETS = ("mechanism_damping.json", "mechanism_damping_950.json",
                "mechanism_damping_980.json", "mechanism_damping_1010.json")


def damping_coverage(load, cmd) -> str:
    """The mechanism page's check of the damping's reported deviation: per kind, on the trials
    of the damping sets, how often the true value lies within two posterior deviations of
    the learned one, and the largest distance in deviations."""
    sets = [load(n) for n in DAMPING_SETS]
    if not all(sets):
        return _missing(", ".join(n for n, d in zip(DAMPING_SETS, sets) if not d))
    parts, light = [], ""
    seeds = ", ".join(f"{min(r['seed'] for r in d['rows'])}-{max(r['seed'] for r in d['rows'])}"
                      for d in sets)
    for kind, name in (("left_door", "doors"), ("drawer", "drawers")):
        rows = [r for d in sets for r in d["rows"]
                if r["group"] == "damping" and r["kind"] == kind
                and r["learned"].get("damping") is not None and r["learned"].get("damping_std")]
        z = [(r["learned"]["damping"] - r["value"]) / r["learned"]["damping_std"] for r in rows]
        if z:
            parts.append(f"{name} {sum(abs(x) <= 2.0 for x in z)}/{len(z)} (the farthest "
                         f"{max(abs(x) for x in z):.1f} deviations off)")
        if kind == "left_door" and rows:
            low = min(r["value"] for r in rows)
            lr = [(r, x) for r, x in zip(rows, z) if r["value"] == low]
            rel = [r["learned"]["damping_std"] / r["value"] for r, _ in lr]
            light = (f" The lightest doors' ({low:g} N m s/rad) deviations are "
                     f"{min(rel) * 100:.0f}-{max(rel) * 100:.0f} % of the true value, and "
                     f"{sum(abs(x) <= 2.0 for _, x in lr)}/{len(lr)} hold it within two.")
    return ("- **The reported deviation covers the regression's noise, not the learned "
            "model's errors.** A damping's +- is its posterior deviation: the force's noise over "
            "the spread of the rates. It leaves out the learned radius and the hook's track "
            "(\"Where a door's damping goes\"), so it is too narrow where those dominate: "
            "the true value lies within two deviations of the learned one for "
            + " and ".join(parts) + f" on the damping sets' trials (seeds {seeds}; a Gaussian "
            "deviation would hold 95 %)." + light)


def page_blocks(load, cmd) -> dict:
    """docs page -> {block name -> function of no arguments giving its text}."""
    return {"docs/perception.md": {"detector_ablations": lambda: detector_ablations(load, cmd),
                                   "planes_searched": lambda: planes_searched(load, cmd),
                                   "first_call_detector": lambda: first_call_detector(load, cmd)},
            "docs/performance_articulation.md": {
                "first_call_selection": lambda: first_call_selection(load, cmd)},
            "docs/body_schema.md": {"camera_markers": lambda: camera_markers(load, cmd)},
            "docs/imitation.md": {"dtw_features": lambda: dtw_features(load, cmd)},
            "docs/mechanism_dynamics.md": {
                "door_damping_sources": lambda: door_damping_sources(load, cmd),
                "damping_coverage": lambda: damping_coverage(load, cmd)}}
