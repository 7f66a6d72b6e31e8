"""Systems and configs check their arguments when they are built; a running simulation keeps
going through a bad observation."""

import warnings

import numpy as np
import pytest


def _arm():
    from pydrake.multibody.parsing import Parser
    from pydrake.multibody.plant import MultibodyPlant

    from mmlearn.sdf import add_package

    plant = MultibodyPlant(time_step=0.001)
    parser = Parser(plant)
    add_package(parser)
    arm = parser.AddModels(url="package://mmlearn/arm_2dof.sdf")[0]
    plant.Finalize()
    return plant, arm


def test_marker_sensor_with_too_few_body_poses_keeps_simulating():
    from pydrake.common.value import AbstractValue
    from pydrake.math import RigidTransform
    from pydrake.systems.analysis import Simulator

    from mmlearn.systems import MarkerSensor

    plant, arm = _arm()
    sensor = MarkerSensor(plant=plant, model_instance=arm)
    ctx = sensor.CreateDefaultContext()
    sensor.get_body_poses_input_port().FixValue(ctx, AbstractValue.Make([RigidTransform()]))
    with pytest.raises(ValueError, match="body_poses holds 1 poses"):
        sensor.true_marker_poses(ctx)
    sim = Simulator(sensor, ctx)
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        sim.AdvanceTo(0.2)  # never an IndexError from inside the simulator
    assert any("sees nothing" in str(x.message) for x in w)
    obs = sensor.get_observations_output_port().Eval(sim.get_context())
    assert not np.any(obs.visible)


@pytest.mark.parametrize("seed", [-1, 1.5, "3", True])
def test_tactile_sensor_seed_is_checked(seed):
    from pydrake.math import RigidTransform

    from mmlearn.models.tactile.pad import PAD_PR2
    from mmlearn.systems.tactile.sensor import PadSpec, TactileSensor

    pads = [PadSpec("left", PAD_PR2, 1, RigidTransform(), ())]
    with pytest.raises(ValueError, match="TactileSensor: seed must be an integer >= 0"):
        TactileSensor(pads=pads, seed=seed)
    TactileSensor(pads=pads, seed=3)


@pytest.mark.parametrize("models,message", [("toaster", "unknown link model 'toaster'"),
                                            (("rigid", "toaster"), "unknown link model"),
                                            ((), "at least one"), (5, "list of link model"),
                                            ((1,), "expected link model names")])
def test_articulation_estimator_models_are_checked(models, message):
    from mmlearn.systems.articulation.estimator import ArticulationEstimator

    with pytest.raises(ValueError, match=message):
        ArticulationEstimator(part_ids=["a", "b"], models=models)
    with pytest.raises(ValueError, match="seed must be an integer"):
        ArticulationEstimator(part_ids=["a", "b"], seed=-1)
    ArticulationEstimator(part_ids=["a", "b"], models="revolute")


@pytest.mark.parametrize("change,message", [
    (dict(time_step=0.5), "time_step 0.5 s is longer than a sensor frame"),
    (dict(time_step=0.01, sensor_rate=1, duration=0.005), "longer than the run"),
    (dict(kp=float("nan")), "kp must be finite"),
    (dict(mode="toaster"), "mode must be one of"),
    (dict(seed=-1), "seed must be an integer"),
    (dict(pad="toaster"), "pad must be one of"),
])
def test_grasp_config_is_checked_before_the_simulation(change, message):
    from mmlearn.diagrams.tactile.grasp import MakeTactileGraspDiagram, TactileGraspConfig

    cfg = TactileGraspConfig(**change)
    with pytest.raises(ValueError, match=message):
        MakeTactileGraspDiagram(cfg)
    TactileGraspConfig().validate()


def test_yaml_config_values_are_checked(tmp_path):
    from mmlearn.apps.common.cli import load_config
    from mmlearn.diagrams.common.scene import SceneConfig
    from mmlearn.diagrams.perception.diagram import FrontPerceptionConfig

    cases = [(FrontPerceptionConfig, "front: toaster\n", "front must be one of door, drawer"),
             (SceneConfig, "kp_revolute: .nan\n", "kp_revolute must be finite"),
             (SceneConfig, "sensor:\n  sigma_pos: .inf\n", "sigma_pos must be finite"),
             (SceneConfig, "- 1\n", "expected a mapping"),
             (FrontPerceptionConfig, "camera:\n  width: -3\n", "width")]
    for i, (cls, text, message) in enumerate(cases):
        p = tmp_path / f"c{i}.yaml"
        p.write_text(text)
        with pytest.raises(ValueError, match=message) as e:
            load_config(p, cls)
        assert str(p) in str(e.value) and "\n" not in str(e.value)
    p = tmp_path / "bin.yaml"
    p.write_bytes(b"\xff\xfe\x00binary")
    with pytest.raises(ValueError, match="not a text file"):
        load_config(p, SceneConfig)


def test_validate_tree_names_the_dotted_field():
    from dataclasses import dataclass, field

    from mmlearn.models.common.config import param, validate_tree

    @dataclass
    class Inner:
        gain: float = 1.0  # declared without param: still must be finite
        values: list = field(default_factory=lambda: [1.0, 2.0])

    @dataclass
    class Outer:
        inner: Inner = field(default_factory=Inner)
        rate: float = param(1.0, gt=0)
        free: float = param(float("inf"), finite=False)

    validate_tree(Outer())
    with pytest.raises(ValueError, match=r"inner.gain must be finite, got nan"):
        validate_tree(Outer(inner=Inner(gain=float("nan"))))
    with pytest.raises(ValueError, match=r"inner.values\[1\] must be finite"):
        validate_tree(Outer(inner=Inner(values=[1.0, float("inf")])))
    with pytest.raises(ValueError, match="rate must be > 0"):
        validate_tree(Outer(rate=-1.0))
