import dataclasses
import json
import math
import re
import subprocess
import sys

import numpy as np
import pytest

from pydrake.common.yaml import yaml_dump_typed, yaml_load_typed

from mmlearn.apps import open_cabinet, operate_trials
from mmlearn.diagrams.articulation.operate import MakeOperateDiagram, OperateConfig
from mmlearn.models.articulation.evaluation import summarize_operate
from mmlearn.systems.articulation.epc_controller import EpcConfig, EpcTask, hook_rotation


def test_hook_rotation_points_the_rod_into_the_front_and_the_finger_behind_the_bar():
    n, side = np.array([1.0, 0, 0]), np.array([0, 1.0, 0])
    R = hook_rotation(n, side)
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)
    np.testing.assert_allclose(R[:, 2], -n)      # rod
    np.testing.assert_allclose(R[:, 0], -side)   # finger


def test_task_and_config_validation():
    ok = dict(handle=[0, 0, 1], normal=[2, 0, 0], bar=[0, 0, 1], pull=[1, 0, 0], side=[0, 1, 0])
    t = EpcTask(**ok)
    np.testing.assert_allclose(t.normal, [1, 0, 0])  # normalised
    with pytest.raises(ValueError, match="handle"):
        EpcTask(**{**ok, "handle": [0, np.nan, 1]})
    with pytest.raises(ValueError, match="side"):
        EpcTask(**{**ok, "side": [0, 0, 0]})
    with pytest.raises(ValueError, match="step"):
        EpcConfig(step=-0.01).validate()


@pytest.mark.slow
@pytest.mark.parametrize("kind,seed", [("left_door", 2), ("drawer", 1)])
def test_opens_with_the_learned_model(kind, seed):
    # the exact base pose (base noise 0): the controller and the learning alone, at the
    # thesis' sigma_pos = 0.05 m with the GP candidate on
    r = open_cabinet.run(kind=kind, seed=seed, show_progress=False, base_noise=0.0)
    assert r["success"], r
    assert r["right_kind"] and r["right_model_at"] is not None
    if kind == "left_door":
        assert r["learned_model"] == "revolute"
        assert r["opened"] > 70.0                 # degrees
        assert r["radius_error_m"] < 0.03         # measured 0.017 (0.008 at sigma 0.01)
        assert r["axis_error_deg"] < 3.0
    else:
        assert r["learned_model"] == "prismatic"
        assert r["opened"] > 0.45                 # metres
        assert r["axis_error_deg"] < 3.0
    # the controller stopped by itself (target or end of the range), not by the time limit
    assert r["outcome"] in ("target reached", "end of the configuration range")
    assert r["sim_seconds"] < 40


@pytest.mark.slow
def test_open_cabinet_cli(tmp_path):
    r = subprocess.run([sys.executable, "-m", "mmlearn.apps.open_cabinet", "--help"],
                       capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 0 and "--object" in r.stdout and "sliding_door" in r.stdout
    r = subprocess.run([sys.executable, "-m", "mmlearn.apps.open_cabinet", "--object",
                        "sliding_door", "--seed", "1", "--json"], capture_output=True,
                       text=True, cwd=tmp_path, timeout=600)
    assert r.returncode == 0, r.stderr
    res = json.loads(r.stdout)
    for key in ("object", "success", "opened", "unit", "learned_model", "axis_error_deg",
                "sim_seconds", "wall_seconds"):
        assert key in res
    assert res["object"] == "sliding_door" and res["unit"] == "m"
    assert res["success"] and res["opened"] > 0.3
    r = subprocess.run([sys.executable, "-m", "mmlearn.apps.open_cabinet", "--object",
                        "trapdoor"], capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 2 and "trapdoor" in r.stderr


def test_trials_summary_table():
    trials = [
        {"object": "left_door", "seed": 0, "success": True, "opened": 80.0, "unit": "deg",
         "outcome": "target reached", "learned_model": "revolute", "radius_error_m": 0.004,
         "axis_error_deg": 0.2},
        {"object": "left_door", "seed": 1, "success": False, "opened": 20.0, "unit": "deg",
         "outcome": "lost the handle", "learned_model": "prismatic", "radius_error_m": None,
         "axis_error_deg": 3.0},
    ]
    s = summarize_operate(trials)["left_door"]
    assert s["successes"] == 1 and s["mean_opened"] == pytest.approx(50.0)
    assert s["mean_radius_error_m"] == pytest.approx(0.004)
    assert s["models"] == {"revolute": 1, "prismatic": 1}
    text = operate_trials.format_table({"trials": trials, "per_object": {"left_door": s},
                                        "successes": 1, "total": 2, "success_rate": 0.5,
                                        "wall_seconds": 1.0})
    assert "1/2" in text and "lost the handle" in text
    with pytest.raises(ValueError, match="unknown object"):
        operate_trials.run(objects=["trapdoor"], trials=1)
    assert math.isclose(summarize_operate(trials)["left_door"]["mean_axis_error_deg"], 1.6)


@pytest.mark.slow
def test_priors_from_an_earlier_trial_select_the_right_model_earlier(tmp_path):
    from mmlearn.models.articulation.link import ObservationModel
    from mmlearn.models.articulation.priors import PriorDatabase
    from mmlearn.models.common.track_io import read_track

    track = tmp_path / "drawer_first.log"
    first = open_cabinet.run(kind="drawer", seed=0, mechanism_seed=5, save_track=str(track),
                             show_progress=False)
    assert first["success"] and track.is_file()
    db = PriorDatabase(obs=ObservationModel(sigma_pos=0.01))
    db.add(read_track(track).poses, "first")
    db_path = tmp_path / "priors.json"
    db.save(db_path)
    scratch = open_cabinet.run(kind="drawer", seed=1, mechanism_seed=5, show_progress=False)
    with_priors = open_cabinet.run(kind="drawer", seed=1, mechanism_seed=5,
                                   priors=str(db_path), show_progress=False)
    assert with_priors["success"] and with_priors["priors"] == str(db_path)
    # the same drawer: the prior model is the right one after a few centimetres
    assert with_priors["right_model_at"] < 0.75 * scratch["right_model_at"]


def _config_docs() -> dict[str, str]:
    """EpcConfig's ``Attributes:`` entries, name -> text."""
    doc = EpcConfig.__doc__.split("Attributes:", 1)[1]
    entries, name = {}, None
    for line in doc.splitlines():
        m = re.match(r"^ {8}(\w+): (.*)$", line)
        if m:
            name = m.group(1)
            assert name not in entries, f"{name} documented twice"
            entries[name] = m.group(2)
        elif line.startswith(" " * 12) and name:
            entries[name] += " " + line.strip()
    return entries


_UNIT = re.compile(r"(\b(m|s|N|rad|m/s|m/rad)\b|m per N per period|dimensionless|\(count\))")


def test_every_epc_config_field_is_documented_with_its_unit():
    docs = _config_docs()
    names = [f.name for f in dataclasses.fields(EpcConfig)]
    assert sorted(docs) == sorted(names)
    for name in names:
        text = docs[name]
        assert len(text.split()) >= 4, f"EpcConfig.{name}: say what it does ({text!r})"
        assert _UNIT.search(text), f"EpcConfig.{name}: no unit in {text!r}"


def test_epc_config_yaml_round_trip():
    cfg = EpcConfig(stop_force=30.0, max_retries=2, edge_depth=0.07,
                    ready_arm_q=[0.0, 0.4, 0.0, 1.5, 0.0, -0.4])
    text = yaml_dump_typed(cfg)
    for f in dataclasses.fields(EpcConfig):
        assert f"{f.name}:" in text
    back = yaml_load_typed(schema=EpcConfig, data=text)
    assert back == cfg
    assert yaml_load_typed(schema=EpcConfig, data="{}") == EpcConfig()
    # as the section of the operate diagram's config
    op = yaml_load_typed(schema=OperateConfig, data="epc: {slack_periods: 20, step: 0.012}")
    assert op.epc == EpcConfig(slack_periods=20, step=0.012)
    with pytest.raises(RuntimeError, match="stop_forse"):     # misspelled key
        yaml_load_typed(schema=EpcConfig, data="stop_forse: 30")


def _bad_value(f):
    if f.type is int or f.type == "int":
        return -1
    if f.name == "ready_arm_q":
        return [0.0, math.nan]
    return math.nan


@pytest.mark.parametrize("name", [f.name for f in dataclasses.fields(EpcConfig)])
def test_epc_config_bad_value_raises_naming_the_field(name):
    f = next(f for f in dataclasses.fields(EpcConfig) if f.name == name)
    with pytest.raises(ValueError, match=rf"EpcConfig: {name}\b"):
        EpcConfig(**{name: _bad_value(f)})


def test_epc_config_bad_values():
    with pytest.raises(ValueError, match=r"EpcConfig: stop_force must be > 0 \(N\)"):
        EpcConfig(stop_force=-35.0)
    with pytest.raises(ValueError, match=r"EpcConfig: force_target must be >= 0 \(N\)"):
        EpcConfig(force_target=-1.0)
    with pytest.raises(ValueError, match=r"EpcConfig: stall_periods must be an integer"):
        EpcConfig(stall_periods=2.5)
    with pytest.raises(ValueError, match=r"EpcConfig: stall_lead_fraction must be in \(0, 1\]"):
        EpcConfig(stall_lead_fraction=1.5)
    with pytest.raises(ValueError, match=r"release_slide_start < release_backoff_start"):
        EpcConfig(release_slide_start=0.7)
    # yaml_load_typed sets the fields of a default config: validate() (which the controller
    # runs when it is built) catches what the YAML said
    cfg = yaml_load_typed(schema=EpcConfig, data="slide_contact_force: -3.0")
    with pytest.raises(ValueError, match=r"EpcConfig: slide_contact_force"):
        cfg.validate()


def test_ready_arm_q_must_match_the_arm():
    with pytest.raises(ValueError, match=r"EpcConfig\.ready_arm_q needs 6"):
        MakeOperateDiagram(OperateConfig(epc=EpcConfig(ready_arm_q=[0.0] * 5)))


def _ik_reference(ctrl, plant_context, q0, p_des, R_des, *, base, grip):
    """The controller's damped least squares written with the plant's full position vector
    and numpy's norm and clip (the reference its IK must give to the last bit)."""
    from pydrake.math import RotationMatrix
    from pydrake.multibody.tree import JacobianWrtVariable

    cfg, plant = ctrl._cfg, ctrl._plant
    q = np.array(q0, float)
    w = np.ones(q.size)
    w[:3] = cfg.base_weight if base else 1e6
    Winv = 1.0 / w
    wr = cfg.ik_rotation_weight
    for _ in range(cfg.ik_iterations):
        full = plant.GetPositions(plant_context)
        full[ctrl._qidx] = q
        plant.SetPositions(plant_context, full)
        X = plant.CalcRelativeTransform(plant_context, plant.world_frame(), ctrl._hook)
        p, R = X @ grip, X.rotation().matrix()
        e_p = p_des - p
        e_R = RotationMatrix(R_des @ R.T).ToAngleAxis()
        e = np.concatenate([wr * (e_R.axis() * e_R.angle()), e_p])
        if (np.linalg.norm(e_p) < cfg.ik_position_tolerance
                and e_R.angle() < cfg.ik_angle_tolerance):
            break
        J = plant.CalcJacobianSpatialVelocity(
            plant_context, JacobianWrtVariable.kQDot, ctrl._hook, grip, plant.world_frame(),
            plant.world_frame())[:, ctrl._qidx]
        J[:3] *= wr
        JW = J * Winv
        lam = cfg.ik_damping
        dq = JW.T @ np.linalg.solve(JW @ J.T + lam * lam * np.eye(6), e)
        n = np.linalg.norm(dq[3:])
        if n > cfg.ik_max_step:
            dq *= cfg.ik_max_step / n
        q = np.clip(q + dq, ctrl._lo, ctrl._hi)
    return q


def test_kinematics_give_the_full_vector_reference_to_the_last_bit():
    """The controller's IK and measured grip point (the robot's positions set in one call)
    equal the reference with the plant's whole position vector, bit for bit."""
    from pydrake.systems.analysis import Simulator

    from mmlearn.systems.articulation.epc_controller import P_HOOK_GRIP

    op = MakeOperateDiagram(OperateConfig(kind="left_door", seed=2))
    sim = Simulator(op.diagram)
    ctx = sim.get_mutable_context()
    op.scene.set_joint_positions(ctx, op.start_command)
    sim.Initialize()
    sim.AdvanceTo(0.3)
    ctrl = op.controller
    cc = ctrl.GetMyContextFromRoot(ctx)
    assert ctrl._all_commanded
    np.testing.assert_array_equal(ctrl._measured_grip_point(cc),
                                  ctrl.measured_grip_pose(cc).translation())
    plant = op.scene.plant
    ref_context = plant.CreateDefaultContext()
    q0 = ctrl._measured_q(cc)
    G = ctrl.measured_grip_pose(cc)
    rng = np.random.default_rng(1)
    grip_tip = np.array([0.07, 0.0, P_HOOK_GRIP[2]])
    for base, grip in ((False, P_HOOK_GRIP), (True, P_HOOK_GRIP), (True, grip_tip)):
        p_des = G.translation() + rng.normal(0.0, 0.05, 3)
        R_des = hook_rotation(op.task.normal, op.task.side)
        q = ctrl._ik(cc, q0, p_des, R_des, base=base, grip=grip)
        ref = _ik_reference(ctrl, ref_context, q0, p_des, R_des, base=base, grip=grip)
        assert np.abs(q - q0).max() > 1e-3
        np.testing.assert_array_equal(q, ref)
