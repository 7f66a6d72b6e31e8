"""Simulated articulated objects (sdf/objects.py) parse in Drake and move as specified."""

import numpy as np
import pytest

from mmlearn.sdf.objects import (OBJECTS, WINDOW_GUIDE_RADIUS, YARDSTICK_SEGMENT, add_object,
                                 garage_door_configuration, object_parts, object_sdf,
                                 yardstick_closed_configuration)


def _plant(name):
    from pydrake.multibody.plant import DiscreteContactApproximation, MultibodyPlant

    plant = MultibodyPlant(time_step=1e-3)
    plant.set_discrete_contact_approximation(DiscreteContactApproximation.kSap)
    inst, cons = add_object(plant, name)
    plant.Finalize()
    return plant, inst, cons


@pytest.mark.parametrize("name", list(OBJECTS))
def test_object_parses_with_marker_frames(name):
    plant, inst, cons = _plant(name)
    ctx = plant.CreateDefaultContext()
    for part in object_parts(name):
        f = plant.GetFrameByName(f"{part}_marker", inst)
        assert f.body().name() == part
        assert np.all(np.isfinite(f.CalcPoseInWorld(ctx).translation()))
    assert plant.num_positions(inst) >= 2
    assert (len(cons) == 1) == (name == "yardstick_closed")


def test_closed_yardstick_constraint_holds_on_the_loop():
    from mmlearn.diagrams.common.object_tracks import ObjectKinematics

    kin = ObjectKinematics("yardstick_closed")
    plant, ctx = kin.plant, kin.context
    seg1 = plant.GetBodyByName("seg1", kin.instance)
    seg4 = plant.GetBodyByName("seg4", kin.instance)
    assert plant.num_constraints() == 1 and len(kin.constraints) == 1

    def gap(q):
        plant.SetPositions(ctx, kin.instance, q)
        p4 = plant.EvalBodyPoseInWorld(ctx, seg4).multiply(np.array([YARDSTICK_SEGMENT, 0, 0]))
        p1 = plant.EvalBodyPoseInWorld(ctx, seg1).translation()
        return np.linalg.norm(p4 - p1)

    for th in (0.5, 1.2, 2.5):
        assert gap(yardstick_closed_configuration(th)[0]) < 1e-9
    assert gap(np.array([0.3, 0.3, 0.3])) > 0.1


def test_window_moves_on_a_circle_of_radius_1_9():
    from mmlearn.diagrams.common.object_tracks import ObjectKinematics

    kin = ObjectKinematics("car_door")
    q = np.zeros((30, 2))
    q[:, 1] = np.linspace(0, -0.24, 30)
    P = kin.marker_poses(q)[2, :, :3]
    # fit a circle in the plane x = const (the guide's axis is x)
    assert np.ptp(P[:, 0]) < 1e-9
    y, z = P[:, 1], P[:, 2]
    A = np.stack([y, z, np.ones_like(y)], 1)
    c = np.linalg.lstsq(A, y**2 + z**2, rcond=None)[0]
    r = np.sqrt(c[2] + (c[0] / 2) ** 2 + (c[1] / 2) ** 2)
    assert r == pytest.approx(WINDOW_GUIDE_RADIUS, abs=0.02)


def test_garage_door_path_is_continuous_and_neither_line_nor_circle():
    s = np.linspace(0, 2.2, 200)
    q = garage_door_configuration(s)
    assert np.abs(np.diff(q[:, :2], axis=0)).max() < 0.02
    assert q[0, 1] == 0 and q[-1, 1] == pytest.approx(1.5)
    assert q[-1, 2] == pytest.approx(-np.pi / 2)


def test_unknown_object():
    with pytest.raises(ValueError, match="unknown object"):
        object_sdf("wardrobe")
    assert '<model name="table">' in object_sdf("table")
    assert '<model name="table_2">' in object_sdf("table", model_name="table_2")


def test_closed_yardstick_loop_holds_in_simulation():
    """Gravity in the yardstick's plane folds the rhombus; the ball constraint keeps the
    loop closed and the object moves along its 1-DOF manifold q = (t, pi - t, t)."""
    from pydrake.multibody.plant import AddMultibodyPlant, MultibodyPlantConfig
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder

    builder = DiagramBuilder()
    plant, _ = AddMultibodyPlant(MultibodyPlantConfig(time_step=1e-3,
                                                      discrete_contact_approximation="sap"),
                                 builder)
    inst, cons = add_object(plant, "yardstick_closed")
    plant.mutable_gravity_field().set_gravity_vector([0.0, -9.81, 0.0])
    plant.Finalize()
    diagram = builder.Build()
    sim = Simulator(diagram)
    ctx = plant.GetMyMutableContextFromRoot(sim.get_mutable_context())
    q0 = yardstick_closed_configuration(1.2)[0]
    plant.SetPositions(ctx, inst, q0)
    sim.AdvanceTo(0.3)
    q = plant.GetPositions(ctx, inst)
    assert abs(q[0] - q0[0]) > 0.05  # it moved
    assert abs(q[0] + q[1] - np.pi) < 0.02 and abs(q[2] - q[0]) < 0.02
