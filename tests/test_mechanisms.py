import math

import numpy as np
import pytest
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
from pydrake.multibody.tree import ForceElementIndex
from pydrake.systems.framework import DiagramBuilder

from mmlearn.sdf.mechanisms import KINDS, MechanismSpec, mechanism_sdf, sample_mechanism


def _plant(spec):
    plant, _ = AddMultibodyPlantSceneGraph(DiagramBuilder(), 0.001)
    mi = Parser(plant).AddModelsFromString(mechanism_sdf(spec), "sdf")[0]
    plant.Finalize()
    return plant, mi


@pytest.mark.parametrize("kind", KINDS)
def test_handle_pose_matches_the_spec_and_opening_moves_it_as_expected(kind):
    spec = sample_mechanism(kind, 3)
    plant, mi = _plant(spec)
    ctx = plant.CreateDefaultContext()
    joint = plant.GetJointByName("mechanism", mi)
    assert joint.position_lower_limits()[0] == 0.0
    assert joint.position_upper_limits()[0] == pytest.approx(spec.limit, rel=1e-5)
    frame = plant.GetFrameByName("handle", mi)
    for q in (0.0, 0.3):
        plant.SetPositions(ctx, mi, [q])
        X = frame.CalcPoseInWorld(ctx)
        p, n, b = spec.handle_world(q)
        np.testing.assert_allclose(X.translation(), p, atol=1e-4)
        np.testing.assert_allclose(X.rotation().matrix()[:, 0], n, atol=1e-4)
    p0, n0, _ = spec.handle_world(0.0)
    p1, _, _ = spec.handle_world(0.3)
    if kind == "sliding_door":
        assert abs(np.dot(p1 - p0, n0)) < 1e-6 and np.linalg.norm(p1 - p0) == pytest.approx(0.3)
    else:
        assert np.dot(p1 - p0, n0) > 0.05  # opening pulls the handle towards the robot


def test_sampling_is_reproducible_and_in_range():
    a, b = sample_mechanism("left_door", 7), sample_mechanism("left_door", 7)
    assert a == b
    widths = [sample_mechanism("right_door", s).width for s in range(30)]
    assert 0.3 <= min(widths) and max(widths) <= 0.6 and np.ptp(widths) > 0.15
    drawers = [sample_mechanism("drawer", s) for s in range(20)]
    assert all(d.limit > 0.44 for d in drawers)  # long enough to pull out 0.45 m


def test_dishwasher_has_a_counterbalance_spring():
    plant, _ = _plant(sample_mechanism("dishwasher", 1))
    kinds = [type(plant.get_force_element(ForceElementIndex(i))).__name__
             for i in range(plant.num_force_elements())]
    assert "RevoluteSpring" in kinds


def test_bad_specs():
    with pytest.raises(ValueError, match="kind"):
        MechanismSpec(kind="trapdoor")
    with pytest.raises(ValueError, match="width"):
        MechanismSpec(width=0.0)
    with pytest.raises(ValueError, match="kind"):
        sample_mechanism("garage", 0)
    with pytest.raises(ValueError, match="pose"):
        MechanismSpec(pose=[0, 0])
    assert math.isfinite(MechanismSpec().limit)
