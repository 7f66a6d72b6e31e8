"""Property-based tests of the input boundaries: the track and CSV loaders, the link-model
fit and selection, the structure search and the marker sensor's inputs.

For any input - NaN, inf, duplicates, collinear or coincident samples, tiny and huge
scales, one to three observations - the result is either a value or a ValueError with a
message; never another exception. The "ci" profile of conftest.py runs 1,000 inputs each.
"""

import math
import string

import numpy as np
import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, event, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

# numbers an input file or array may hold: ordinary, tiny, huge, NaN, inf
SPECIAL = st.sampled_from([0.0, -0.0, 1e-300, -1e-300, 1e-12, 1e12, 1e300, -1e300,
                           math.nan, math.inf, -math.inf])
FLOAT = st.one_of(st.floats(-10, 10, allow_nan=False), SPECIAL,
                  st.floats(allow_nan=True, allow_infinity=True))


def _error_ok(e: Exception) -> None:
    assert isinstance(e, ValueError), f"{type(e).__name__}: {e}"
    assert str(e).strip(), "a ValueError without a message"
    event("clear error")


# --------------------------------------------------------------------------- track files
TOKEN = st.one_of(FLOAT.map(repr), FLOAT.map(lambda v: f"{v:.6g}"),
                  st.sampled_from(["nan", "NaN", "inf", "-inf", "1e999", "x", "1,5", "--1",
                                   "0x10", "", "#", "1e-400"]))
LINE = st.one_of(
    st.lists(TOKEN, min_size=0, max_size=10).map(" ".join),
    st.lists(st.floats(-2, 2, allow_nan=False), min_size=3, max_size=3).map(
        lambda v: " ".join(map(repr, v))),
    st.lists(st.floats(-2, 2, allow_nan=False), min_size=7, max_size=7).map(
        lambda v: " ".join(map(repr, v))),
    st.just("# a comment"), st.just(""), st.just("0 0 0 0 0 0 0"),
    st.text(string.printable, max_size=30))


@st.composite
def track_files(draw):
    """Mostly well-formed files (3 or 7 columns, 1-8 rows, comments), some with one line
    replaced by anything; or plain garbage lines."""
    if draw(st.integers(0, 3)) == 0:
        return draw(st.lists(LINE, min_size=0, max_size=8))
    cols = draw(st.sampled_from([3, 7, 9]))
    n = draw(st.integers(1, 8))
    rows = draw(st.lists(st.lists(st.floats(-3, 3, allow_nan=False), min_size=cols,
                                  max_size=cols), min_size=n, max_size=n))
    scale = draw(st.sampled_from([1.0, 1.0, 1e-9, 1e5, 1e7]))
    lines = [" ".join(repr(v * (scale if j < 3 else 1.0)) for j, v in enumerate(r))
             for r in rows]
    if draw(st.booleans()):
        lines.insert(draw(st.integers(0, len(lines))), "# comment")
    if draw(st.integers(0, 2)) == 0:
        lines[draw(st.integers(0, len(lines) - 1))] = draw(LINE)
    return lines


@pytest.mark.slow
@given(lines=track_files(), dup=st.booleans())
def test_read_track_never_crashes(tmp_path_factory, lines, dup):
    from mmlearn.models.common.track_io import read_track

    if dup and lines:
        lines = lines + lines  # duplicated observations
    p = _tmp(tmp_path_factory) / "t.log"
    p.write_text("\n".join(lines) + "\n")
    try:
        tr = read_track(p)
    except Exception as e:  # noqa: BLE001 - the property: only ValueError
        _error_ok(e)
        return
    assert tr.poses.shape[1] in (3, 7) and tr.n >= 3
    event("result")
    assert np.isfinite(tr.poses).all()


_TMP = {}


def _tmp(factory):
    if "d" not in _TMP:
        _TMP["d"] = factory.mktemp("prop")
    return _TMP["d"]


# --------------------------------------------------------------------------- parts CSV
CSV_ROW = st.one_of(
    st.tuples(st.sampled_from(["0", "0.1", "0.2", "nan", "inf", "x", "1e300"]),
              st.sampled_from(["a", "b", "c", "", " a "]),
              st.lists(TOKEN, min_size=7, max_size=7)).map(
        lambda r: ",".join([r[0], r[1], *r[2]])),
    st.lists(TOKEN, min_size=0, max_size=11).map(",".join),
    st.text(string.printable, max_size=40))
HEADER = st.sampled_from(["t,part,x,y,z,qx,qy,qz,qw", "T, Part ,x,y,z,qx,qy,qz,qw",
                          "t,part,x,y,z", "", "time,part,x,y,z,qx,qy,qz,qw"])


@st.composite
def csv_rows(draw):
    """Mostly well-formed rows (1-3 parts, 1-5 time steps, some parts unobserved, times
    possibly duplicated), some with one row replaced by anything."""
    if draw(st.integers(0, 3)) == 0:
        return draw(st.lists(CSV_ROW, min_size=0, max_size=8))
    parts = ["a", "b", "c"][:draw(st.integers(1, 3))]
    T = draw(st.integers(1, 5))
    rows = []
    for t in range(T):
        for p in parts:
            if draw(st.integers(0, 5)) == 0:
                continue  # not observed
            v = draw(st.lists(st.floats(-2, 2, allow_nan=False), min_size=7, max_size=7))
            rows.append(",".join([repr(0.1 * t), p, *map(repr, v)]))
    if rows and draw(st.integers(0, 3)) == 0:
        rows.append(rows[draw(st.integers(0, len(rows) - 1))])  # a duplicate row
    if rows and draw(st.integers(0, 2)) == 0:
        rows[draw(st.integers(0, len(rows) - 1))] = draw(CSV_ROW)
    return rows


@pytest.mark.slow
@given(header=st.one_of(st.just("t,part,x,y,z,qx,qy,qz,qw"), HEADER), rows=csv_rows())
def test_read_parts_csv_never_crashes(tmp_path_factory, header, rows):
    from mmlearn.models.articulation.graph import read_parts_csv

    p = _tmp(tmp_path_factory) / "parts.csv"
    p.write_text("\n".join([header, *rows]) + "\n")
    try:
        names, times, Y = read_parts_csv(p)
    except Exception as e:  # noqa: BLE001
        _error_ok(e)
        return
    assert Y.shape == (len(names), len(times), 7)
    event("result")
    obs = np.isfinite(Y).all(axis=2)
    assert obs.any() and np.isfinite(times).all()


# --------------------------------------------------------------------------- tracks as arrays
@st.composite
def tracks(draw, max_n=8):
    """(n, 3) or (n, 7) arrays: random, collinear, coincident, duplicated, scaled, with
    NaN / inf sprinkled in; 1 to max_n observations."""
    n = draw(st.one_of(st.integers(1, 3), st.integers(min(3, max_n), max_n)))
    cols = draw(st.sampled_from([3, 7]))
    kind = draw(st.sampled_from(["random", "collinear", "coincident", "duplicates",
                                 "circle"]))
    seed = draw(st.integers(0, 2**16))
    rng = np.random.default_rng(seed)
    if kind == "random":
        P = rng.normal(size=(n, 3))
    elif kind == "collinear":
        P = np.outer(rng.normal(size=n), rng.normal(size=3)) + rng.normal(size=3)
    elif kind == "coincident":
        P = np.tile(rng.normal(size=3), (n, 1))
    elif kind == "duplicates":
        P = np.repeat(rng.normal(size=(max(1, n // 2), 3)), 2, axis=0)[:n]
        P = np.vstack([P, P[:n - len(P)]]) if len(P) < n else P
    else:
        a = rng.uniform(0, 1.5, n)
        P = np.column_stack([np.cos(a), np.sin(a), np.zeros(n)])
    P = P * draw(st.sampled_from([1.0, 1.0, 1.0, 0.1, 1e-9, 1e-4, 1e4, 1e9, 1e150]))
    Z = P
    if cols == 7:
        Q = rng.normal(size=(n, 4))
        if draw(st.booleans()):
            Q[:] = [0, 0, 0, 1]
        Z = np.hstack([P, Q])
    k = draw(st.sampled_from([0, 0, 0, 0, 1, 2]))
    for _ in range(k):  # sprinkle special values
        Z[draw(st.integers(0, n - 1)), draw(st.integers(0, cols - 1))] = draw(SPECIAL)
    return Z


@pytest.mark.slow
@settings(suppress_health_check=list(HealthCheck))
@given(Z=tracks(), name=st.sampled_from(["rigid", "prismatic", "revolute"]),
       seed=st.integers(0, 100))
def test_link_model_fit_never_crashes(Z, name, seed):
    from mmlearn.models.articulation.link import ObservationModel, make_model

    try:
        m = make_model(name, obs=ObservationModel(sigma_pos=0.01), n_hypotheses=8)
        m.fit(Z, rng=seed)
    except Exception as e:  # noqa: BLE001
        _error_ok(e)
        return
    assert np.isfinite(m.bic_) and 0 <= m.gamma <= 1
    event("result")
    repr(m)


@pytest.mark.slow
@settings(suppress_health_check=list(HealthCheck), max_examples=1000)
@given(Z=tracks(max_n=6), seed=st.integers(0, 100))
def test_link_model_selection_never_crashes(Z, seed):
    from mmlearn.models.articulation.link import ObservationModel
    from mmlearn.models.articulation.structure import select_link_model

    try:
        s = select_link_model(Z, models=["rigid", "prismatic", "revolute", "gp"],
                              obs=ObservationModel(sigma_pos=0.01), rng=seed, n_hypotheses=8)
    except Exception as e:  # noqa: BLE001
        _error_ok(e)
        return
    assert s.best.name in s.candidates and np.isfinite(s.best.bic_)
    event("result")


# --------------------------------------------------------------------------- structure search
@st.composite
def part_tracks(draw):
    """(p, T, 7) part poses: a fixed base and 0-2 parts moving on simulated rigid /
    prismatic / revolute links (T = 1..7), or arbitrary tracks; with unobserved (NaN)
    entries, coincident parts and special values."""
    T = draw(st.one_of(st.integers(1, 5), st.integers(5, 9)))
    if draw(st.integers(0, 3)) == 0:
        p = draw(st.integers(1, 3))
        parts = [draw(tracks(max_n=T)) for _ in range(p)]
        parts = [np.hstack([z, np.tile([0, 0, 0, 1.0], (len(z), 1))]) if z.shape[1] == 3
                 else z for z in parts]
        T = min(len(z) for z in parts)
        Y = np.stack([z[:T] for z in parts])
    else:
        from mmlearn.models.articulation.sim import simulate_link

        kinds = draw(st.lists(st.sampled_from(["rigid", "prismatic", "revolute"]),
                              min_size=1, max_size=2))
        rng = np.random.default_rng(draw(st.integers(0, 2**16)))
        Y = np.zeros((1 + len(kinds), T, 7))
        Y[0, :, 6] = 1.0
        for k, kind in enumerate(kinds):
            Y[k + 1] = simulate_link(kind, T, sigma_pos=0.002, sigma_orient=0.01, rng=rng).Z
        if draw(st.integers(0, 4)) == 0:
            Y[-1] = Y[0]  # coincident parts
    p = Y.shape[0]
    for _ in range(draw(st.sampled_from([0, 0, 1, 2]))):  # unobserved entries
        Y[draw(st.integers(0, p - 1)), draw(st.integers(0, T - 1))] = np.nan
    if draw(st.integers(0, 5)) == 0:
        Y[draw(st.integers(0, p - 1)), draw(st.integers(0, T - 1)), draw(st.integers(0, 6))] \
            = draw(SPECIAL)
    return Y


@pytest.mark.slow
@settings(suppress_health_check=list(HealthCheck))
@given(Y=part_tracks(), search=st.sampled_from(["tree", "local", "exhaustive"]),
       seed=st.integers(0, 100))
def test_structure_search_never_crashes(Y, search, seed):
    from mmlearn.models.articulation.link import ObservationModel
    from mmlearn.models.articulation.graph import fit_structure

    try:
        r = fit_structure(Y, search=search, models=["rigid", "prismatic", "revolute"],
                          obs=ObservationModel(sigma_pos=0.01), rng=seed, n_hypotheses=8)
    except Exception as e:  # noqa: BLE001
        _error_ok(e)
        return
    assert r.best is not None
    event("result")


# --------------------------------------------------------------------------- marker sensor
_SENSOR = {}


def _sensor_parts():
    """A 2-DOF arm plant, built once."""
    if not _SENSOR:
        from pydrake.multibody.parsing import Parser
        from pydrake.multibody.plant import MultibodyPlant

        from mmlearn.sdf import add_package

        plant = MultibodyPlant(time_step=0.001)
        parser = Parser(plant)
        add_package(parser)
        arm = parser.AddModels(url="package://mmlearn/arm_2dof.sdf")[0]
        plant.Finalize()
        _SENSOR.update(plant=plant, arm=arm)
    return _SENSOR["plant"], _SENSOR["arm"]


FIELDS = ("rate_hz", "sigma_pos", "sigma_orient", "gamma", "dropout", "max_view_angle_deg",
          "occlusion_step", "fov", "max_range", "seed")


@pytest.mark.slow
@settings(suppress_health_check=list(HealthCheck))
@given(bad=st.one_of(st.none(), st.sampled_from(FIELDS)),
       bad_value=st.one_of(FLOAT, st.integers(-3, 2**70)),
       rate=st.floats(0.1, 100), sp=st.floats(0, 0.5), so=st.floats(0, 3.2),
       gamma=st.floats(0, 0.99), dropout=st.floats(0, 0.99), view=st.floats(1, 180),
       step=st.floats(0.005, 1), fov=st.floats(1, 179), max_range=st.floats(0.1, 10),
       seed=st.integers(0, 2**40), cams=st.integers(0, 2), cam_at_target=st.booleans(),
       pose=st.lists(st.tuples(FLOAT, FLOAT, FLOAT), min_size=1, max_size=8),
       rot=st.lists(st.floats(-10, 10, allow_nan=False), min_size=3, max_size=3),
       frame=st.integers(0, 10**6))
def test_marker_sensor_inputs(bad, bad_value, rate, sp, so, gamma, dropout, view, step, fov,
                              max_range, seed, cams, cam_at_target, pose, rot, frame):
    """Bad configs are ValueErrors naming the field; a valid sensor observes any body
    poses (NaN, inf, huge) without raising."""
    from pydrake.common.value import AbstractValue
    from pydrake.math import RigidTransform, RotationMatrix

    from mmlearn.systems import MarkerSensor, MarkerSensorConfig
    from mmlearn.systems.common.marker_sensor import CameraConfig

    plant, arm = _sensor_parts()
    v = dict(rate_hz=rate, sigma_pos=sp, sigma_orient=so, gamma=gamma, dropout=dropout,
             max_view_angle_deg=view, occlusion_step=step, fov=fov, max_range=max_range,
             seed=seed)
    if bad is not None:
        v[bad] = bad_value if bad == "seed" or not isinstance(bad_value, int) \
            else float(bad_value)
    cam = [CameraConfig(fov_x_deg=v["fov"], fov_y_deg=v["fov"], max_range=v["max_range"],
                        look_at=[2.2, 0.0, 1.2] if cam_at_target else [0.0, 0.0, 0.6])
           for _ in range(cams)]
    cfg = MarkerSensorConfig(rate_hz=v["rate_hz"], sigma_pos=v["sigma_pos"],
                             sigma_orient=v["sigma_orient"], gamma=v["gamma"],
                             dropout=v["dropout"], max_view_angle_deg=v["max_view_angle_deg"],
                             occlusion_step=v["occlusion_step"], cameras=cam, seed=v["seed"])
    try:
        sensor = MarkerSensor(plant=plant, model_instance=arm, config=cfg)
    except Exception as e:  # noqa: BLE001
        _error_ok(e)
        assert "MarkerSensor" in str(e) or "CameraConfig" in str(e)
        return
    ctx = sensor.CreateDefaultContext()
    R = RotationMatrix.MakeXRotation(rot[0]) @ RotationMatrix.MakeZRotation(rot[1])
    X = [RigidTransform(R, np.array(p, float)) for p in pose]
    X = (X * plant.num_bodies())[:plant.num_bodies()]
    sensor.get_body_poses_input_port().FixValue(ctx, AbstractValue.Make(X))
    obs = sensor.observe(ctx, frame=frame)
    event("result")
    assert len(obs.marker_ids) == len(sensor.marker_ids)
    arr = obs.as_array()
    assert arr.shape == (len(sensor.marker_ids), 7)
