"""Tests of the ArticulationEstimator LeafSystem."""

import os

os.environ.setdefault("DRAKE_ALLOW_NETWORK", "meshcat")

import numpy as np
import pytest
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import BasicVector, DiagramBuilder, LeafSystem

from mmlearn.models.articulation.link import ObservationModel
from mmlearn.systems.articulation.estimator import ArticulationEstimator
from mmlearn.systems.common.observations import MarkerObservations

RADIUS = 0.35
RATE = 0.4  # rad/s


def door_pose(t):
    q = RATE * t
    p = np.array([0.6 + RADIUS * np.cos(q), 0.1 + RADIUS * np.sin(q), 0.8])
    return q, p, np.array([0, 0, np.sin(q / 2), np.cos(q / 2)])


class DoorPoseSource(LeafSystem):
    """End-effector pose on a door (7-vector); NaN at every 10th sample."""

    def __init__(self, rng):
        super().__init__()
        self._rng = rng
        self.DeclareVectorOutputPort("pose", 7, self._calc)

    def _calc(self, context, out):
        t = context.get_time()
        _, p, q = door_pose(t)
        v = np.r_[p + self._rng.normal(0, 0.002, 3), q]
        if int(round(t / 0.05)) % 10 == 5:
            v[0] = np.nan
        out.SetFromVector(v)


class CabinetMarkers(LeafSystem):
    """MarkerObservations of a cabinet and a drawer; the drawer is hidden at some frames and
    one frame carries a NaN pose."""

    def __init__(self):
        super().__init__()
        self._rng = np.random.default_rng(0)
        self.DeclareAbstractOutputPort("observations",
                                       lambda: AbstractValue.Make(MarkerObservations()),
                                       self._calc)

    def _calc(self, context, out):
        t = context.get_time()
        k = int(round(t / 0.05))
        base = RigidTransform(RotationMatrix.MakeZRotation(0.3), [1.0, 0.5, 0.3])
        d = 0.1 * t
        drawer = base.multiply(RigidTransform([0.1 + d + self._rng.normal(0, 0.002), 0, 0]))
        poses = [base, drawer]
        if k == 17:
            poses[1] = RigidTransform(RotationMatrix(), [np.nan, 0, 0])
        vis = np.array([True, k % 6 != 3])
        out.set_value(MarkerObservations(time=t, marker_ids=["cabinet", "drawer"],
                                         poses=poses, visible=vis,
                                         outlier=np.zeros(2, bool)))


def test_estimator_pose_mode_learns_revolute_and_counts_drops():
    b = DiagramBuilder()
    src = b.AddSystem(DoorPoseSource(np.random.default_rng(1)))
    est = b.AddSystem(ArticulationEstimator(
        mode="pose", pose_size=7, period=0.05, refit_every=20, min_observations=10,
        obs=ObservationModel(0.003, np.deg2rad(3)), seed=0))
    b.Connect(src.get_output_port(0), est.get_pose_input_port())
    diagram = b.Build()
    sim = Simulator(diagram)
    sim.AdvanceTo(3.0)
    ctx = est.GetMyContextFromRoot(sim.get_context())
    sel = est.get_selected_models_output_port().Eval(ctx)
    assert sel == {"fixed->moving": "revolute"}
    model = est.get_object_model_output_port().Eval(ctx)
    assert abs(model.edges[0].model.radius - RADIUS) < 0.01
    stats = est.get_stats_output_port().Eval(ctx)
    assert stats[1] == 6  # NaN samples dropped and counted (t = 0.25, 0.75, ... 2.75)
    assert stats[0] + stats[1] in (60, 61) and stats[2] == 1
    q = est.get_configuration_output_port().Eval(ctx)
    # q = 0 at the first observation: the opening angle since t = 0
    t_last = ctx.get_abstract_state(0).get_value().times[-1]
    assert q[0] == pytest.approx(RATE * t_last, abs=0.02)
    J = est.get_jacobian_output_port().Eval(ctx)
    assert J.shape == (6, 1)
    assert np.linalg.norm(J[:3, 0]) == pytest.approx(RADIUS, abs=0.01)


def test_estimator_marker_mode_drawer_with_gaps():
    b = DiagramBuilder()
    src = b.AddSystem(CabinetMarkers())
    est = b.AddSystem(ArticulationEstimator(
        part_ids=["cabinet", "drawer"], period=0.05, refit_every=10,
        obs=ObservationModel(0.003, np.deg2rad(2)), seed=0))
    b.Connect(src.get_output_port(0), est.get_observations_input_port())
    sim = Simulator(b.Build())
    sim.AdvanceTo(2.0)
    ctx = est.GetMyContextFromRoot(sim.get_context())
    assert est.get_selected_models_output_port().Eval(ctx) == {"cabinet->drawer": "prismatic"}
    stats = est.get_stats_output_port().Eval(ctx)
    assert stats[1] == 1  # the NaN frame
    m = est.get_object_model_output_port().Eval(ctx).edges[0].model
    assert abs(abs(m.axis[0]) - 1.0) < 0.01  # along the cabinet's x axis


def test_estimator_rejects_bad_configuration():
    with pytest.raises(ValueError, match="part_ids"):
        ArticulationEstimator(mode="markers")
    with pytest.raises(ValueError, match="pose_size"):
        ArticulationEstimator(mode="pose", pose_size=4)


def test_port_accessors_follow_the_sensor_pattern_and_old_name_is_deprecated():
    """get_<name>_input_port() / get_<name>_output_port() for every port (as MarkerSensor);
    the old get_input_port_observations() still works, with a DeprecationWarning."""
    markers = ArticulationEstimator(part_ids=["a", "b"])
    pose = ArticulationEstimator(mode="pose", pose_size=3)
    for est, inp in ((markers, "observations"), (pose, "pose")):
        assert getattr(est, f"get_{inp}_input_port")().get_name() == inp
        for name in ("object_model", "selected_models", "configuration", "jacobian",
                     "stats"):
            port = getattr(est, f"get_{name}_output_port")()
            assert port.get_name() == name and port.get_index() == est.GetOutputPort(
                name).get_index()
        with pytest.warns(DeprecationWarning, match="get_input_port_observations"):
            assert est.get_input_port_observations().get_name() == inp
    with pytest.raises(RuntimeError, match="get_pose_input_port"):
        pose.get_observations_input_port()
    with pytest.raises(RuntimeError, match="get_observations_input_port"):
        markers.get_pose_input_port()


class _ArcThenNothing(LeafSystem):
    """A hook on a door's arc (x y z) until ``t_end``, NaN (nothing held) after it."""

    def __init__(self, t_end):
        super().__init__()
        self._t_end = t_end
        self.DeclareVectorOutputPort("p", 3, self._calc, {self.time_ticket()})

    def _calc(self, context, out):
        t = context.get_time()
        _, p, _ = door_pose(t)
        out.SetFromVector(p if t <= self._t_end + 1e-9 else np.full(3, np.nan))


def _refit_counts(refit_fraction, t_end=5.0, t_stop=6.0):
    """The observation counts at which a pose-mode estimator refitted (every 0.05 s) and its
    final state."""
    b = DiagramBuilder()
    src = b.AddSystem(_ArcThenNothing(t_end))
    est = b.AddSystem(ArticulationEstimator(
        mode="pose", pose_size=3, period=0.05, refit_every=5, min_observations=10,
        obs=ObservationModel(0.003), models=("rigid", "revolute"), seed=0,
        refit_fraction=refit_fraction))
    b.Connect(src.get_output_port(0), est.get_pose_input_port())
    sim = Simulator(b.Build())
    ctx = est.GetMyContextFromRoot(sim.get_context())
    counts = []
    for k in range(1, int(round(t_stop / 0.05)) + 1):
        sim.AdvanceTo(k * 0.05)
        last = ctx.get_abstract_state(0).get_value().last_fit_count
        if last and (not counts or counts[-1] != last):
            counts.append(last)
    return counts, ctx.get_abstract_state(0).get_value()


def test_a_refit_fraction_spaces_the_refits_with_the_track_and_refits_at_its_end():
    every, _ = _refit_counts(0.0)
    grown, s = _refit_counts(0.25)
    # refit_every alone: every 5 observations, the track's last one left out of the model
    assert every == list(range(10, 101, 5))
    # a quarter of the track fitted last, at least 5; then the whole track, refit_every
    # periods (0.25 s) after it ended
    assert grown == [10, 15, 20, 25, 32, 40, 50, 63, 79, 99, 101]
    assert s.total == s.last_fit_count == 101
    assert s.model.edges[0].model.name == "revolute"
    for bad in (-0.1, 1.5, float("nan"), True):
        with pytest.raises(ValueError, match="refit_fraction"):
            ArticulationEstimator(mode="pose", pose_size=3, refit_fraction=bad)
