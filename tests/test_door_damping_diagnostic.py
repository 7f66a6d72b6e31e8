"""The door-damping diagnostic's contact measures (benchmarks/bench_door_damping_sources.py)."""

import importlib.util
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

_PATH = Path(__file__).resolve().parents[1] / "benchmarks" / "bench_door_damping_sources.py"


def _bench():
    spec = importlib.util.spec_from_file_location("bench_door_damping_sources", _PATH)
    mod = importlib.util.module_from_spec(spec)
    import sys

    sys.path.insert(0, str(_PATH.parent))  # (its _common helpers)
    try:
        spec.loader.exec_module(mod)
    finally:
        sys.path.remove(str(_PATH.parent))
    return mod


def test_contact_spread_is_measured_in_the_doors_frame():
    bench = _bench()
    rng = np.random.default_rng(3)
    axis, p_axis = np.array([0.0, 0.0, 1.0]), np.array([1.0, -0.5, 0.3])
    handle = np.array([0.0, 0.40, 0.20])  # bar's centre from the axis point, door shut
    q = np.linspace(0.0, 1.4, 400)
    # the contact moves along the handle's path (x when shut) by 0-20 mm, radially by 0-4
    across, along = rng.uniform(0, 0.020, q.size), rng.uniform(0, 0.004, q.size)
    local = handle + np.column_stack([across, along, np.zeros(q.size)])
    c = p_axis + Rotation.from_rotvec(np.outer(q, axis)).apply(local)
    rec = {"axis": axis, "p_axis": p_axis, "handle_offset": handle}
    n_mm, r_mm = bench.contact_spread(c, q, rec)
    assert abs(n_mm - 18.0) < 1.0 and abs(r_mm - 3.6) < 0.4, (n_mm, r_mm)
    # a contact fixed on the door does not move, however far the door turns
    fixed = p_axis + Rotation.from_rotvec(np.outer(q, axis)).apply(np.tile(handle, (q.size, 1)))
    assert max(bench.contact_spread(fixed, q, rec)) < 1e-9
