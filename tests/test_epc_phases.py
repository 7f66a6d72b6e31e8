"""EpcController's phases one period at a time: the controller built on its own (the robot's
plant, no scene, no mechanism), its inputs fixed, its state set to the phase under test."""

import copy
import dataclasses

import numpy as np
import pytest

from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.analysis import Simulator

from mmlearn.sdf import add_package
from mmlearn.sdf.builders import arm_sdf, arm_spec
from mmlearn.systems.articulation.epc_controller import (DEPTH, DONE, DRIVE, PREHOOK, PULL,
                                                         RELEASE, SLIDE, EpcConfig,
                                                         EpcController, EpcTask,
                                                         hook_rotation)
from mmlearn.systems.articulation.epc_state import EpcState

NORMAL = np.array([-1.0, 0.0, 0.0])  # the front faces the robot (which looks along +x)
SIDE = np.array([0.0, 1.0, 0.0])
CFG = EpcConfig()


def _plant():
    plant = MultibodyPlant(0.0)
    parser = Parser(plant)
    add_package(parser)
    robot = parser.AddModelsFromString(
        arm_sdf("7dof", tool="hook", mobile_base=True, model_name="robot"), "sdf")[0]
    plant.Finalize()
    names = ["base_x", "base_y", "base_yaw"] + list(arm_spec("7dof", tool="hook").actions)
    return plant, robot, names


@pytest.fixture(scope="module")
def grip():
    """The grip point at the robot's default configuration (its measured state below)."""
    plant, robot, names = _plant()
    task = EpcTask(handle=[1, 0, 1], normal=NORMAL, bar=[0, 0, 1], pull=NORMAL, side=SIDE)
    ctrl = EpcController(plant=plant, robot=robot, task=task, command_names=names)
    return ctrl.grip_pose(np.zeros(len(names))).translation()


class Rig:
    """The controller with the handle at ``handle``, fed a fixed robot state (the default
    configuration) and a fixed wrist force; :meth:`step` runs one control period from a
    given state and returns the next."""

    def __init__(self, handle, *, pull=NORMAL):
        plant, robot, names = _plant()
        self.task = EpcTask(handle=handle, normal=NORMAL, bar=[0, 0, 1], pull=pull, side=SIDE)
        self.ctrl = EpcController(plant=plant, robot=robot, task=self.task, config=CFG,
                                  command_names=names)
        self.n = len(names)
        self.sim = Simulator(self.ctrl)
        ctx = self.sim.get_mutable_context()
        nx = plant.num_positions(robot) + plant.num_velocities(robot)
        self.ctrl.get_robot_state_input_port().FixValue(ctx, np.zeros(nx))
        self.ctrl.get_object_model_input_port().FixValue(ctx, None)
        self.force(np.zeros(3))
        self.sim.Initialize()
        self.G = self.ctrl.measured_grip_pose(ctx).translation()

    def force(self, F):
        self.ctrl.get_force_input_port().FixValue(self.sim.get_mutable_context(),
                                                  np.asarray(F, float))

    def step(self, **state) -> EpcState:
        """One period (the update at the context's time) from ``EpcState(**state)``."""
        ctx = self.sim.get_mutable_context()
        q = np.zeros(self.n)
        s = EpcState(**{"q_from": q, "q_to": q, "t_cmd": ctx.get_time(), "start": self.G,
                        "t_phase": ctx.get_time(), **state})
        ctx.get_mutable_abstract_state(0).set_value(s)
        self.sim.AdvanceTo(ctx.get_time() + CFG.period)  # the update at its start
        return self.ctrl.state(ctx)


def test_the_state_is_immutable_and_shared_not_copied():
    s = EpcState(q_from=[0.0, 1.0], cep=[1.0, 2.0, 3.0])
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.phase = PULL
    with pytest.raises(ValueError):
        s.cep[0] = 5.0  # read-only arrays
    assert copy.deepcopy(s) is s
    t = dataclasses.replace(s, phase=PULL)
    # a replace shares the old state's read-only arrays, and copies the arrays it is given
    assert t.phase == PULL and s.phase == DRIVE and t.cep is s.cep
    given = np.array([4.0, 5.0, 6.0])
    u = dataclasses.replace(t, cep=given)
    given[0] = -1.0
    np.testing.assert_array_equal(u.cep, [4.0, 5.0, 6.0])
    assert u.q_from is s.q_from and not u.cep.flags.writeable
    view = np.zeros(3)[:]  # a read-only view of a writeable array is copied too
    view.setflags(write=False)
    assert dataclasses.replace(t, cep=view).cep is not view


def test_drive_ends_at_the_stance_then_approach(grip):
    rig = Rig(grip + [0.8, 0.0, 0.0])
    s = rig.step(phase=DRIVE, start=np.zeros(rig.n), t_phase=-0.5)
    assert s.phase == DRIVE and np.any(s.q_to[:3] != 0.0)  # the base is on its way
    s = rig.step(phase=DRIVE, start=np.zeros(rig.n), t_phase=-100.0)
    assert s.phase == PREHOOK
    np.testing.assert_allclose(s.start, rig.G)


def test_approach_goes_in_front_of_the_handle_beside_the_bar(grip):
    rig = Rig(grip + 0.1 * SIDE)
    s = rig.step(phase=PREHOOK, t_phase=-0.5 * CFG.approach_time)  # half-way
    assert s.phase == PREHOOK and not np.array_equal(s.q_to, np.zeros(rig.n))
    goal = rig.task.handle + CFG.prehook_distance * NORMAL + CFG.side_offset * SIDE
    # the commanded grip point moves from the start towards the goal
    p = rig.ctrl.grip_pose(s.q_to).translation()
    assert np.linalg.norm(p - goal) < np.linalg.norm(rig.G - goal)
    s = rig.step(phase=PREHOOK, t_phase=-10.0)
    assert s.phase == DEPTH
    np.testing.assert_allclose(s.start, goal)


def test_hook_touches_the_front_slides_behind_the_bar_and_starts_pulling(grip):
    # the grip point 3 cm behind the clicked handle: a contact there is the front
    rig = Rig(grip + 0.03 * NORMAL)
    rig.force(2 * CFG.depth_contact_force * NORMAL)
    s = rig.step(phase=DEPTH)
    assert s.phase == SLIDE and s.retries == 0
    np.testing.assert_allclose(s.start, rig.G + CFG.front_backoff * NORMAL)
    # the rod meets the bar (a side force near the clicked bar): the pull begins there
    rig = Rig(grip)
    rig.force(2 * CFG.slide_contact_force * SIDE)
    s = rig.step(phase=SLIDE)
    assert s.phase == PULL
    np.testing.assert_allclose(s.cep, rig.G)
    np.testing.assert_allclose(s.direction, NORMAL)


def test_a_slide_stopped_by_a_knob_stem_pulls_at_the_finger_tip(grip):
    from mmlearn.systems.articulation.epc_controller import HOOK_FINGER_TIP, P_HOOK_GRIP

    # the rod stops 4.4 cm short of the clicked handle, the hook lagging its slide: the
    # finger's tip met the knob's stem; the reference point moves there
    rig = Rig(grip - 0.044 * SIDE)
    rig.force(2 * CFG.slide_contact_force * SIDE)
    s = rig.step(phase=SLIDE, t_phase=-1.0)
    assert s.phase == PULL
    np.testing.assert_allclose(s.grip, [HOOK_FINGER_TIP + CFG.tip_handle_offset, 0.0,
                                        P_HOOK_GRIP[2]])
    ctx = rig.sim.get_mutable_context()
    np.testing.assert_allclose(s.cep, rig.ctrl.measured_grip_pose(ctx).translation())
    # (the rig's hook is not turned to the handle: the tip lies 4.4 cm along its finger)
    assert np.linalg.norm(s.cep - rig.G) == pytest.approx(HOOK_FINGER_TIP + CFG.tip_handle_offset
                                                          - P_HOOK_GRIP[0])
    # stopped by the bar where it was clicked: the seat stays the reference point
    rig = Rig(grip - 0.01 * SIDE)
    rig.force(2 * CFG.slide_contact_force * SIDE)
    s = rig.step(phase=SLIDE, t_phase=-1.0)
    assert s.phase == PULL
    np.testing.assert_allclose(s.grip, P_HOOK_GRIP)
    np.testing.assert_allclose(s.cep, rig.G)


@pytest.mark.parametrize("where, force, shift, backoff", [
    # a contact 2 cm in front of the clicked handle: the bar, not the front
    (0.02, True, CFG.retry_side_shift, CFG.retry_backoff),
    # no contact 5 cm deeper than the front can be: the finger passed the front's edge
    (-(CFG.edge_depth + CFG.depth_margin + 0.05), False, -CFG.retry_side_shift,
     CFG.edge_retry_backoff + CFG.depth_margin)])
def test_retry_backs_out_and_corrects_the_side_offset(grip, where, force, shift, backoff):
    rig = Rig(grip - where * NORMAL)
    if force:
        rig.force(2 * CFG.depth_contact_force * NORMAL)
    s = rig.step(phase=DEPTH, retries=1, side_extra=0.01)
    assert s.phase == PREHOOK and s.retries == 2
    assert s.side_extra == pytest.approx(0.01 + shift)
    np.testing.assert_allclose(s.start, rig.G + backoff * NORMAL)
    # out of retries: the hooking goes on regardless
    s = rig.step(phase=DEPTH, retries=CFG.max_retries, t_phase=-100.0)
    assert s.phase == SLIDE and s.retries == CFG.max_retries


def test_a_slide_past_the_bar_retries_taking_that_depth_for_the_bar(grip):
    rig = Rig(grip + CFG.slide_reach * SIDE)  # the slide's goal is where the grip point is
    start = rig.G + CFG.slide_reach * SIDE
    s = rig.step(phase=SLIDE, start=start, t_phase=-100.0)
    assert s.phase == PREHOOK and s.retries == 1
    assert s.bar_depth == pytest.approx(np.dot(start - rig.task.handle, NORMAL)
                                        - CFG.front_backoff)


def test_pull_advances_the_equilibrium_point_and_stops(grip):
    rig = Rig(grip + 0.05 * SIDE)
    pulling = dict(phase=PULL, cep=rig.G, direction=NORMAL, R=hook_rotation(NORMAL, SIDE),
                   trail_G=rig.G, motion=NORMAL)
    # the handle presses on the rod with the target force: the point moves by step
    rig.force(CFG.force_target * SIDE)
    s = rig.step(**pulling)
    assert s.phase == PULL and s.slack == 0 and s.stalled == 0
    np.testing.assert_allclose(s.cep - rig.G, CFG.step * NORMAL, atol=1e-12)
    # no force on the hook for slack_periods: the handle is lost
    rig.force(np.zeros(3))
    s = rig.step(**pulling, slack=CFG.slack_periods - 1)
    assert s.phase == RELEASE and s.outcome == "lost the handle"
    # held back against the pull without advancing: the end of the range
    rig.force(-2 * CFG.stop_force * NORMAL)
    s = rig.step(**pulling, stalled=CFG.stall_periods - 1, stall_G=rig.G)
    assert s.phase == RELEASE and s.outcome == "end of the configuration range"
    # out of time
    rig.force(CFG.force_target * SIDE)
    s = rig.step(**pulling, t_phase=-CFG.max_pull_time - 1.0)
    assert s.phase == RELEASE and s.outcome == "timeout"


def test_without_a_revolute_model_the_pull_follows_the_handles_motion(grip):
    """Before a revolute model, the point advances along the handle's observed motion and
    the hook turns with it (by at most max_turn per period), the rod pressing on towards
    the handle even when the hook lags along the path by more than max_lead."""
    rig = Rig(grip + 0.05 * SIDE)
    a = 0.3  # the handle's motion turned by 0.3 rad about z (a door opening) ...
    turned_by_door = np.array([-np.cos(a), -np.sin(a), 0.0])
    # ... and the hook slid up its (vertical) bar: that part is not the handle's motion
    motion = turned_by_door + [0, 0, 0.2]
    motion /= np.linalg.norm(motion)
    R0 = hook_rotation(NORMAL, SIDE)
    rig.force(CFG.force_target * SIDE)
    s = rig.step(phase=PULL, cep=rig.G, direction=NORMAL, R=R0, trail_G=rig.G - motion,
                 motion=motion)
    np.testing.assert_allclose(s.direction, turned_by_door, atol=1e-12)
    # turned about the bar only
    np.testing.assert_allclose((s.R @ R0.T)[:, 2], [0, 0, 1.0], atol=1e-12)
    turned = np.arccos(np.clip((np.trace(s.R @ R0.T) - 1) / 2, -1, 1))
    assert turned == pytest.approx(CFG.max_turn, abs=1e-9)
    # the hook lags: the point is far ahead along the path, and no force on the rod
    rig.force(np.zeros(3))
    far = rig.G + 3 * CFG.max_lead * NORMAL
    s = rig.step(phase=PULL, cep=far, direction=NORMAL, R=R0, trail_G=rig.G,
                 motion=NORMAL)
    lead = s.cep - rig.G
    u = -SIDE  # the rod presses the bar towards -side
    along = lead - np.dot(lead, u) * u
    assert np.linalg.norm(along) == pytest.approx(CFG.max_lead, rel=1e-9)
    # the pressing term is kept whole (a bound on the whole lead would shrink it)
    press = min(CFG.step, CFG.force_gain * CFG.force_target)
    assert np.dot(lead, u) == pytest.approx(press, rel=1e-9)


def test_release_ends_done_and_done_holds(grip):
    rig = Rig(grip)
    s = rig.step(phase=RELEASE, motion=NORMAL, R=hook_rotation(NORMAL, SIDE), t_phase=-10.0)
    assert s.phase == DONE
    q = np.linspace(0.0, 0.1, rig.n)
    s = rig.step(phase=DONE, q_from=q, q_to=q)
    assert s.phase == DONE
    np.testing.assert_allclose(s.q_to, q)
