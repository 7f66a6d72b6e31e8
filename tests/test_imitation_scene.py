"""The imitation scene (sdf/imitation.py): layout, variation, reachability, the free cup."""

import numpy as np
import pytest

from pydrake.multibody.inverse_kinematics import InverseKinematics
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph, MultibodyPlant
from pydrake.solvers import Solve
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from mmlearn.sdf.builders import arm_sdf
from mmlearn.models.imitation.scene import ROBOT_TCP_IN_X8, TEACHER_TCP_IN_X8, ImitationSceneSpec
from mmlearn.sdf.imitation import add_imitation_scene, add_teacher


def _goals(spec):
    """(TCP position, direction of the gripper axis) the tasks need."""
    goals = []
    if spec.cup:
        for p in (spec.cup_start(), spec.place_spot()):
            goals += [(p + [0, 0, 0.06], [0, 0, -1]), (p + [0, 0, 0.20], [0, 0, -1])]
    if spec.board:
        goals += [(c - [0.03, 0, 0], [1, 0, 0]) for c in spec.board_corners()]
    if spec.target:
        goals.append((np.asarray(spec.target_position) + [0, 0, 0.05], [0, 0, -1]))
    return goals


def _reachable(which, spec):
    plant = MultibodyPlant(0.0)
    if which == "robot":
        Parser(plant).AddModelsFromString(arm_sdf(7), "sdf")
        tcp = ROBOT_TCP_IN_X8
    else:
        add_teacher(plant)
        tcp = TEACHER_TCP_IN_X8
    plant.Finalize()
    x8 = plant.GetFrameByName("x8")
    out = []
    for p, d in _goals(spec):
        ik = InverseKinematics(plant)
        ik.AddPositionConstraint(x8, tcp, plant.world_frame(), p - 0.005, p + 0.005)
        ik.AddAngleBetweenVectorsConstraint(x8, [0, 0, 1], plant.world_frame(), d, 0.0, 0.2)
        q0 = np.zeros(plant.num_positions())
        q0[[1, 3, 5]] = [0.5, 1.0, 0.5]
        ik.prog().SetInitialGuess(ik.q(), q0)
        out.append(Solve(ik.prog()).is_success())
    return out


LAYOUTS = [dict(), dict(swap_tables=True),
           dict(board=True, tables=False, cup=False, board_scale=1.5),
           dict(board=True, tables=False, cup=False, board_scale=0.6),
           dict(target=True, obstacle="u", cup=False, tables=False),
           dict(target=True, obstacle="box", cup=False, tables=False)]


@pytest.mark.parametrize("kw", LAYOUTS)
def test_robot_and_teacher_reach_every_goal(kw):
    for seed in (11, 12):
        spec = ImitationSceneSpec(**kw).sampled(seed).resolved()
        assert all(_reachable("robot", spec)), (seed, kw)
        assert all(_reachable("teacher", spec)), (seed, kw)


def test_scene_parses_with_markers_and_cup_stands_still():
    spec = ImitationSceneSpec(board=True, target=True, obstacle="box",
                              board_centre=[0.75, 0.0, 0.9]).sampled(5)
    b = DiagramBuilder()
    plant, _ = AddMultibodyPlantSceneGraph(b, 0.001)
    scene = add_imitation_scene(plant, spec)
    plant.Finalize()
    assert set(scene.bodies) == {"cup", "table_a", "table_b", "board", "board_c0", "board_c1",
                                 "board_c2", "board_c3", "obstacle", "target"}
    for name in scene.bodies:
        assert plant.HasFrameNamed(name + "_marker", scene.model_instance)
    diagram = b.Build()
    sim = Simulator(diagram)
    ctx = plant.GetMyContextFromRoot(sim.get_mutable_context())
    cup = plant.GetBodyByName("cup")
    p0 = plant.EvalBodyPoseInWorld(ctx, cup).translation().copy()
    np.testing.assert_allclose(p0, spec.cup_start(), atol=1e-5)  # 6 digits in the SDF
    sim.AdvanceTo(0.5)
    p1 = plant.EvalBodyPoseInWorld(ctx, cup).translation()
    assert np.linalg.norm(p1 - p0) < 0.003, p1 - p0  # sinks into the top < 3 mm, stays put
    # corner markers: counter-clockwise seen from the robot (normal -x), from lower left
    X = [plant.CalcRelativeTransform(ctx, plant.world_frame(),
                                     plant.GetFrameByName(f"board_c{k}_marker"))
         for k in range(4)]
    P = np.array([x.translation() for x in X])
    np.testing.assert_allclose(P[:, 0] + 0.001, spec.board_corners()[:, 0], atol=1e-3)
    assert P[0, 1] > P[1, 1] and P[0, 2] < P[3, 2] and P[2, 1] < P[3, 1]
    for x in X:
        np.testing.assert_allclose(x.rotation().matrix()[:, 2], [-1, 0, 0], atol=1e-5)


def test_variation_is_seeded_and_swap_exchanges_tables():
    a, b = ImitationSceneSpec().sampled(3), ImitationSceneSpec().sampled(3)
    assert a == b
    c = ImitationSceneSpec().sampled(4)
    assert a.table_a != c.table_a
    s = ImitationSceneSpec(swap_tables=True)
    assert s.resolved().table_a == ImitationSceneSpec().table_b
    assert s.cup_start()[1] < 0 < s.place_spot()[1]


@pytest.mark.parametrize("kw, msg", [
    (dict(obstacle="triangle"), "obstacle"),
    (dict(table_a=[0.5]), "table_a"),
    (dict(board_scale=0.0), "board_scale"),
    (dict(board_scale=3.0), "does not fit"),
    (dict(cup_offset=[0.5, 0.0]), "off the table"),
    (dict(table_b=[0.55, 0.30]), "overlap"),
    (dict(board_centre=[0.6, float("nan"), 0.6]), "finite"),
])
def test_bad_spec_is_named(kw, msg):
    with pytest.raises(ValueError, match=msg):
        ImitationSceneSpec(**kw).validate()
