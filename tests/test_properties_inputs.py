"""Property-based tests of the loaders of saved files and of the systems' arguments.

For any damaged document - a key deleted, any value replaced by anything JSON can hold, a
number made NaN - a saved link or object model, prior database or demonstration either
loads to exactly what was saved or raises a ValueError with a message; YAML configs, iCub
trial files and the systems' constructor arguments likewise. The "ci" profile of conftest.py
runs 1,000 inputs each (marked slow: about 2 minutes for the set on a loaded 2-core machine).
"""

import copy
import json
import math
import string

import numpy as np
import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, event, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from saved_files import _demos, _link, _object, _priors  # noqa: E402

SPECIAL = st.sampled_from([0.0, -1.0, 1e-300, 1e300, -1e300, math.nan, math.inf, -math.inf,
                           0, 1, -1, 2**40, True, False, None, "", "nu", "toaster", [], {}])
LEAF = st.one_of(SPECIAL, st.floats(allow_nan=True, allow_infinity=True),
                 st.integers(-10, 10), st.text(string.printable, max_size=8))
VALUE = st.recursive(LEAF, lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                   st.dictionaries(st.text(max_size=5), inner,
                                                                   max_size=3)),
                     max_leaves=6)


def _error_ok(e: Exception) -> None:
    assert isinstance(e, ValueError), f"{type(e).__name__}: {e}"
    assert str(e).strip() and "\n" not in str(e), repr(e)
    event("clear error")


def _paths(doc, prefix=()):
    """Every path (tuple of keys / indices) into a nested document."""
    out = [prefix] if prefix else []
    if isinstance(doc, dict):
        for k, v in doc.items():
            out += _paths(v, prefix + (k,))
    elif isinstance(doc, list):
        for i, v in enumerate(doc[:6]):
            out += _paths(v, prefix + (i,))
    return out


def _mutate(doc, path, action, value):
    d = copy.deepcopy(doc)
    *head, last = path
    parent = d
    for k in head:
        parent = parent[k]
    if action == "delete":
        if isinstance(parent, dict):
            del parent[last]
        else:
            parent.pop(last)
    else:
        parent[last] = value
    return d


@st.composite
def damaged(draw, doc):
    paths = _paths(doc)
    path = draw(st.sampled_from(paths))
    action = draw(st.sampled_from(["delete", "replace", "replace"]))
    return _mutate(doc, path, action, draw(VALUE))


def _roundtrip(doc):
    return json.loads(json.dumps(doc, allow_nan=True))


_DOCS = {}


def _docs():
    if not _DOCS:
        from mmlearn.models.articulation.io import model_to_dict

        _DOCS["link"] = _roundtrip(model_to_dict(_link("revolute", 0, 12)))
        _DOCS["object"] = _roundtrip(model_to_dict(_object()))
        _DOCS["priors"] = _roundtrip(_priors().to_dict())
        _DOCS["demo"] = _roundtrip(_demos()[0].to_dict())
    return _DOCS


# --------------------------------------------------------------------------- saved models
@pytest.mark.slow
@settings(suppress_health_check=list(HealthCheck))
@given(data=st.data(), kind=st.sampled_from(["link", "object"]))
def test_damaged_model_documents_load_the_same_or_fail_clearly(data, kind):
    from mmlearn.models.articulation.io import model_from_dict, model_to_dict

    doc = _docs()[kind]
    bad = data.draw(damaged(doc))
    try:
        m = model_from_dict(bad)
    except Exception as e:  # noqa: BLE001
        _error_ok(e)
        return
    event("loaded")
    assert _roundtrip(model_to_dict(m)) == doc  # never a silently different model


@pytest.mark.slow
@settings(suppress_health_check=list(HealthCheck))
@given(data=st.data())
def test_damaged_prior_databases_load_the_same_or_fail_clearly(data):
    from mmlearn.models.articulation.priors import PriorDatabase

    doc = _docs()["priors"]
    bad = data.draw(damaged(doc))
    try:
        db = PriorDatabase.from_dict(bad)
    except Exception as e:  # noqa: BLE001
        _error_ok(e)
        return
    event("loaded")
    assert _roundtrip(db.to_dict()) == doc


@pytest.mark.slow
@settings(suppress_health_check=list(HealthCheck))
@given(data=st.data())
def test_damaged_demonstrations_are_valid_or_fail_clearly(data):
    from mmlearn.models.imitation.types import Demonstration

    bad = data.draw(damaged(_docs()["demo"]))
    try:
        d = Demonstration.from_dict(bad)
    except Exception as e:  # noqa: BLE001
        _error_ok(e)
        return
    event("loaded")
    assert np.all(np.diff(d.t) > 0) and d.hand.shape[0] == d.t.shape[0]
    assert not np.any(np.isinf(d.hand))


# --------------------------------------------------------------------------- YAML configs
KEYS = st.sampled_from(["time_step", "kp_revolute", "arm", "tool", "sensor", "robot_pose",
                        "cabinet", "gravity_compensation", "camera_sensor", "toaster",
                        "mechanism", "kd_base"])
SENSOR_KEYS = st.sampled_from(["rate_hz", "sigma_pos", "gamma", "dropout", "seed", "cameras",
                               "workspace_min", "toaster"])


@st.composite
def scene_yaml(draw):
    d = draw(st.dictionaries(KEYS, VALUE, max_size=3))
    if draw(st.booleans()):
        d["sensor"] = draw(st.dictionaries(SENSOR_KEYS, VALUE, max_size=3))
    return d


@pytest.mark.slow
@settings(suppress_health_check=list(HealthCheck))
@given(doc=scene_yaml())
def test_yaml_configs_load_checked_or_fail_clearly(tmp_path_factory, doc):
    import yaml

    from mmlearn.apps.common.cli import load_config
    from mmlearn.diagrams.common.scene import SceneConfig
    from mmlearn.models.common.config import validate_tree

    p = tmp_path_factory.getbasetemp() / "scene.yaml"
    try:
        p.write_text(yaml.safe_dump(doc))
    except (yaml.YAMLError, ValueError):
        return
    try:
        cfg = load_config(p, SceneConfig)
    except Exception as e:  # noqa: BLE001
        _error_ok(e)
        assert str(p) in str(e)
        return
    event("loaded")
    validate_tree(cfg)  # whatever loads passes every check


# --------------------------------------------------------------------------- iCub files
_ICUB = None


@st.composite
def icub_texts(draw):
    global _ICUB
    if _ICUB is None:
        from pathlib import Path

        _ICUB = (Path(__file__).parent / "data" / "icub_grasp" / "blue_bear_1.txt"
                 ).read_text().splitlines()
    lines = list(_ICUB)
    for _ in range(draw(st.integers(0, 3))):
        i = draw(st.integers(0, len(lines) - 1))
        how = draw(st.sampled_from(["drop", "replace", "token", "cut"]))
        if how == "drop":
            lines.pop(i)
        elif how == "replace":
            lines[i] = draw(st.text(string.printable, max_size=40))
        elif how == "token":
            toks = lines[i].split() or ["0"]
            toks[draw(st.integers(0, len(toks) - 1))] = draw(st.sampled_from(
                ["nan", "inf", "-1", "1e309", "x", "256", "-10000", ""]))
            lines[i] = " ".join(toks)
        else:
            lines = lines[:i]
        if not lines:
            break
    return "\n".join(lines)


@pytest.mark.slow
@settings(suppress_health_check=list(HealthCheck))
@given(text=icub_texts())
def test_icub_reader_reads_or_fails_clearly(tmp_path_factory, text):
    from mmlearn.models.tactile.icub_grasp import read_icub_trial

    p = tmp_path_factory.getbasetemp() / "blue_bear_1.txt"
    p.write_text(text)
    try:
        t = read_icub_trial(p)
    except Exception as e:  # noqa: BLE001
        _error_ok(e)
        return
    event("read")
    assert t.n >= 1 and np.all(np.isfinite(t.encoders)) and np.all(np.isfinite(t.taxels))


# --------------------------------------------------------------------------- systems
NUMBER = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-5, 100),
                   st.sampled_from([0, -1, 1e-9, 1e9, math.nan, True, "3", None]))


@pytest.mark.slow
@settings(suppress_health_check=list(HealthCheck))
@given(rate=NUMBER, noise=NUMBER, seed=NUMBER)
def test_tactile_sensor_arguments(rate, noise, seed):
    from pydrake.math import RigidTransform

    from mmlearn.models.tactile.pad import PAD_PR2
    from mmlearn.systems.tactile.sensor import PadSpec, TactileSensor

    pads = [PadSpec("left", PAD_PR2, 1, RigidTransform(), ())]
    try:
        TactileSensor(pads=pads, rate_hz=rate, noise=noise, seed=seed)
    except Exception as e:  # noqa: BLE001
        _error_ok(e)
        return
    event("built")
    assert rate > 0 and noise >= 0 and seed >= 0 and not isinstance(seed, bool)


@pytest.mark.slow
@settings(suppress_health_check=list(HealthCheck))
@given(models=st.one_of(st.lists(st.sampled_from(["rigid", "prismatic", "revolute", "gp",
                                                  "toaster", "", 3]), max_size=3),
                        st.sampled_from(["rigid", "toaster", None, 5])),
       seed=NUMBER, period=NUMBER, refit=st.integers(-2, 30), mode=st.sampled_from(
           ["markers", "pose", "toaster"]))
def test_articulation_estimator_arguments(models, seed, period, refit, mode):
    from mmlearn.systems.articulation.estimator import ArticulationEstimator

    try:
        ArticulationEstimator(mode=mode, part_ids=["a", "b"], models=models, seed=seed,
                              period=period, refit_every=refit)
    except Exception as e:  # noqa: BLE001
        _error_ok(e)
        return
    event("built")
    assert mode in ("markers", "pose") and refit >= 1


GRASP_FIELDS = ["f_target", "v_target", "contact_force", "kp", "kd", "force_rate",
                "hold_time", "duration", "time_step", "sensor_rate", "taxel_noise",
                "encoder_noise", "seed", "mode", "pad", "wall_model", "palm_slide_damping"]


@pytest.mark.slow
@settings(suppress_health_check=list(HealthCheck))
@given(changes=st.dictionaries(st.sampled_from(GRASP_FIELDS),
                               st.one_of(NUMBER, st.sampled_from(["pr2", "force", "linear"])),
                               max_size=3))
def test_grasp_config_arguments(changes):
    from mmlearn.diagrams.tactile.grasp import TactileGraspConfig

    cfg = TactileGraspConfig(**changes)
    try:
        cfg.validate()
    except Exception as e:  # noqa: BLE001
        _error_ok(e)
        return
    event("valid")
    assert cfg.time_step <= 1.0 / cfg.sensor_rate and cfg.time_step <= cfg.duration
    assert all(math.isfinite(getattr(cfg, k)) for k in ("kp", "kd", "f_target", "duration"))


@pytest.mark.slow
@settings(suppress_health_check=list(HealthCheck))
@given(n=st.integers(1, 12), x=st.floats(allow_nan=True, allow_infinity=True),
       frame=st.integers(0, 10**6))
def test_marker_sensor_observes_any_number_of_body_poses(n, x, frame):
    """Fewer or more body poses than the plant has bodies, at any position: an
    observation (nothing seen when it cannot be computed), never an exception."""
    import warnings

    from pydrake.common.value import AbstractValue
    from pydrake.math import RigidTransform

    from mmlearn.systems import MarkerSensor

    if "sensor" not in _DOCS:
        from test_construction_checks import _arm

        plant, arm = _arm()
        _DOCS["sensor"] = (plant, MarkerSensor(plant=plant, model_instance=arm))
    plant, sensor = _DOCS["sensor"]
    ctx = sensor.CreateDefaultContext()
    poses = [RigidTransform([x, 0.0, 1.0])] * n
    sensor.get_body_poses_input_port().FixValue(ctx, AbstractValue.Make(poses))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        obs = sensor.observe(ctx, frame=frame)
    assert len(obs.marker_ids) == len(sensor.marker_ids)
    if n < plant.num_bodies():
        assert not np.any(obs.visible)
        event("too few poses: nothing seen")
