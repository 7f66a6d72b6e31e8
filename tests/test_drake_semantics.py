"""Drake semantics: a system keeps everything that changes in its Context.

For every diagram builder of ``mmlearn.diagrams`` (each ``Make*Diagram`` in its ``__all__``,
so a new builder is covered as soon as it is exported), the same Diagram object is simulated
once alone and then twice at the same time (two Simulators, one on a default context and one
on a clone of it, advanced alternately); both must reproduce the lone run exactly. A
context cloned in the middle of a run must not change while the original simulates on
(no state value shared and mutated in place). Short horizons keep this fast. A builder that
needs arguments has a case in ``CASES``; one without is built with its defaults.
"""

import math
from dataclasses import dataclass, fields, is_dataclass
from typing import Callable

import numpy as np
import pytest
from pydrake.common.value import AbstractValue
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder, LeafSystem, PortDataType

from mmlearn.diagrams.body_schema.diagram import BodySchemaDiagramConfig, MakeBodySchemaDiagram
from mmlearn.diagrams.common.object_tracks import cabinet_scenario
from mmlearn.diagrams.articulation.operate import MakeOperateDiagram, OperateConfig
from mmlearn.diagrams.common.scene import MakeSceneDiagram, SceneConfig
from mmlearn.models.articulation.link import ObservationModel
from mmlearn.models.articulation.priors import PriorDatabase
from mmlearn.systems import ArticulationEstimator, MarkerObservations, SchemaLearnerConfig
from mmlearn.systems.articulation.epc_controller import EpcConfig
from mmlearn.systems.articulation.model_visualizer import LearnedModelVisualizer
from mmlearn.systems.articulation.prior_selector import PriorModelSelector


def _snapshot(diagram, ctx, extra=None, ignore=None):
    """Every exported vector output (minus ``ignore`` = {port: indices}), every discrete
    state group, and ``extra(ctx)``."""
    out = {}
    for i in range(diagram.num_output_ports()):
        port = diagram.get_output_port(i)
        if port.get_data_type() != PortDataType.kVectorValued:
            continue
        v = np.array(port.Eval(ctx), float, copy=True)
        for k in (ignore or {}).get(port.get_name(), ()):
            v[k] = 0.0
        out[port.get_name()] = v
    for g in range(ctx.num_discrete_state_groups()):
        out[f"discrete_{g}"] = np.array(ctx.get_discrete_state(g).value(), copy=True)
    if extra is not None:
        out["extra"] = extra(ctx)
    return out


def _same(a, b, where):
    assert a.keys() == b.keys(), where
    for k in a:
        if isinstance(a[k], np.ndarray):
            np.testing.assert_array_equal(a[k], b[k], err_msg=f"{where}: {k}")
        else:
            assert a[k] == b[k], f"{where}: {k}"


def _check(diagram, prepare, times, *, extra=None, ignore=None):
    snap = lambda c: _snapshot(diagram, c, extra, ignore)  # noqa: E731
    # alone
    sim = Simulator(diagram)
    prepare(sim.get_mutable_context())
    sim.Initialize()
    alone = []
    for t in times:
        sim.AdvanceTo(t)
        alone.append(snap(sim.get_context()))
    # two simulators of the same diagram, interleaved; the second on a cloned context
    ctx_a = diagram.CreateDefaultContext()
    prepare(ctx_a)
    ctx_b = ctx_a.Clone()
    sim_a, sim_b = Simulator(diagram, ctx_a), Simulator(diagram, ctx_b)
    sim_a.Initialize()
    sim_b.Initialize()
    mid, mid_snap = None, None
    for k, t in enumerate(times):
        sim_a.AdvanceTo(t)
        sim_b.AdvanceTo(t)
        _same(snap(sim_a.get_context()), alone[k], f"simulator A at t={t}")
        _same(snap(sim_b.get_context()), alone[k], f"simulator B at t={t}")
        if k == len(times) // 2:
            mid = sim_a.get_context().Clone()
            mid_snap = snap(mid)
    # the clone taken halfway did not change while A simulated on
    _same(snap(mid), mid_snap, "context cloned halfway")
    return alone[-1]


# ----------------------------------------------------------------------------- every builder
@dataclass
class Case:
    """One builder's diagram and how to run it: ``prepare(root_context)`` before the run,
    the snapshot ``times``, ``extra(ctx)`` (what the exported vector ports and the discrete
    state do not show), ``ignore`` (see _snapshot) and ``check(last_snapshot)`` (that the
    run did something)."""

    diagram: object
    times: list
    prepare: Callable = lambda ctx: None
    extra: Callable | None = None
    ignore: dict | None = None
    check: Callable | None = None


def _canon(v):
    """A value as plain, exactly comparable data (arrays by their bytes, floats by hex)."""
    from pydrake.math import RigidTransform

    if isinstance(v, RigidTransform):
        v = v.GetAsMatrix4()
    if isinstance(v, np.ndarray):
        return (str(v.dtype), v.shape, v.tobytes())
    if isinstance(v, (float, np.floating)):
        return float(v).hex()
    if isinstance(v, dict):
        return tuple((k, _canon(x)) for k, x in sorted(v.items()))
    if isinstance(v, (list, tuple)):
        return tuple(_canon(x) for x in v)
    if is_dataclass(v):
        return tuple((f.name, _canon(getattr(v, f.name))) for f in fields(v))
    return v


def _values(c):
    """The array of ``_canon(array)``."""
    return np.frombuffer(c[2], dtype=c[0]).reshape(c[1])


def _logs(*loggers):
    """``extra`` that compares the samples the given VectorLogSinks recorded."""
    def extra(ctx):
        return tuple(_canon(lg.FindLog(ctx).data()) for lg in loggers)
    return extra


def _builders():
    import mmlearn.diagrams as D

    return sorted(n for n in D.__all__ if n.startswith("Make") and n.endswith("Diagram"))


def _scene_case():
    scene = MakeSceneDiagram(SceneConfig(arm="4dof", cabinet=True))
    mid = 0.5 * (scene.command_lower + scene.command_upper)
    q = mid + 0.3 * (scene.command_upper - mid)

    def prepare(ctx):
        scene.set_joint_positions(ctx, mid)
        scene.diagram.GetInputPort("command").FixValue(ctx, q)

    return Case(scene.diagram, [0.1, 0.2, 0.3], prepare,
                check=lambda end: end["marker_stats"][0] > 0)


def _operate_case():
    # long enough for the drive to the stance and the start of the IK-driven approach
    op = MakeOperateDiagram(OperateConfig(kind="left_door", seed=1,
                                          epc=EpcConfig(approach_time=0.5)))

    def extra(ctx):
        s = op.controller.state(op.controller.GetMyContextFromRoot(ctx))
        return (s.phase, tuple(np.round(s.q_to, 12)))

    return Case(op.diagram, [0.6, 1.2, 1.8, 2.4],
                lambda ctx: op.scene.set_joint_positions(ctx, op.start_command), extra,
                check=lambda end: end["extra"][0] >= 1)  # reached the approach (the IK)


def _body_schema_case():
    # fast babbling: a first valid structure within 6 s
    bs = MakeBodySchemaDiagram(BodySchemaDiagramConfig(
        arm="2dof", noise_pos=0.01, babble_period=0.5, babble_hold=0.7,
        learner=SchemaLearnerConfig(settle_time=0.2)))

    def extra(ctx):
        st = bs.learner.state(ctx)
        return (st.n_samples, st.n_dropped, st.history, st.sampled_since,
                tuple(st.X_WR.ravel()) if st.X_WR is not None else None)

    # learner_status[5] is the wall time of the last schema update
    return Case(bs.diagram, [1.5, 3.0, 4.5, 6.0], bs.prepare, extra,
                ignore={"learner_status": [5]},
                check=lambda end: end["extra"][0] >= 10 and end["extra"][2][-1][1])


def _front_perception_case():
    """The kitchen with the opening door, the depth camera and the noise (a small image):
    the noisy depth image is the same in every simulator at every time."""
    from mmlearn.diagrams.perception.diagram import FrontPerceptionConfig, MakeFrontPerceptionDiagram

    cfg = FrontPerceptionConfig(front="door")
    cfg.camera.width, cfg.camera.height_px = 160, 120
    P = MakeFrontPerceptionDiagram(cfg)

    def extra(ctx):
        d = np.array(P.diagram.GetOutputPort("depth_image").Eval(ctx).data)
        return (int(np.isnan(d).sum()), float(np.nansum(d)),
                tuple(np.round(P.diagram.GetOutputPort("X_WR").Eval(ctx).GetAsMatrix4()
                               .ravel(), 12)))

    return Case(P.diagram, [0.6, 1.4, 2.2], extra=extra,
                check=lambda end: end["front_joint"][0] > 0.1 and end["extra"][0] < 160 * 120)


def _tactile_grasp_case():
    """A container grasp (pressure walls, noisy taxels and encoders) up to the fingers'
    first contact and the switch to force control."""
    from mmlearn.diagrams.tactile.grasp import MakeTactileGraspDiagram, TactileGraspConfig
    from mmlearn.models.tactile.containers import sample_container

    inst = sample_container("odwalla", "full_closed", np.random.default_rng(3))
    d, parts = MakeTactileGraspDiagram(TactileGraspConfig(v_target=0.1, seed=2),
                                       container=inst)
    logs = [parts[k] for k in ("grasp_log", "taxel_log", "force_log")]
    return Case(d, [0.2, 0.4, 0.6], extra=_logs(*logs),
                check=lambda end: _values(end["extra"][2]).max() > 1.0)  # pad force, N


def _liquid_roll_case():
    """The liquid-detection scene (free container on a table, wrist lift and roll, the
    finger hold, the wrist force sensor) while the fingers close."""
    from mmlearn.diagrams.tactile.liquid_roll import LiquidRollConfig, MakeLiquidRollDiagram, \
        make_instance

    inst = make_instance("odwalla_half", np.random.default_rng(0))
    d, parts = MakeLiquidRollDiagram(LiquidRollConfig(grasp_height=inst.height / 2, seed=1),
                                     container=inst)
    logs = [parts[k] for k in ("taxel_log", "force_log", "wrist_log", "roll_log")]
    return Case(d, [0.2, 0.4, 0.6], extra=_logs(*logs),
                check=lambda end: np.abs(_values(end["extra"][2])).max() > 0.0)  # wrist force


def _teacher_case():
    """A demonstration's playback watched by the noisy marker sensor."""
    from mmlearn.diagrams.imitation.demonstrations import MakeTeacherDiagram, TeacherConfig

    td = MakeTeacherDiagram(TeacherConfig(task="obstacle", seed=1))
    port = td.diagram.GetOutputPort("observations")
    def extra(ctx):
        obs = port.Eval(ctx)
        return (_canon(obs), int(np.sum(obs.visible)))

    return Case(td.diagram, [0.5, 1.0, 1.5], extra=extra,
                check=lambda end: end["extra"][1] > 0)  # markers seen


def _imitation_case():
    """The 7-DOF arm reproducing a reach to a target marker (a small hand-made model)."""
    from mmlearn.diagrams.imitation.diagram import ImitationConfig, MakeImitationDiagram
    from mmlearn.models.imitation.scene import ImitationSceneSpec
    from mmlearn.models.imitation.types import TaskModel
    from mmlearn.systems.imitation.dbn_reproducer import DbnReproducerConfig

    S, offset = 12, np.array([0.10, 0.0, -0.15])  # mu = target - hand
    model = TaskModel(t=np.arange(S) * 0.2, constraints=["obj:target"],
                      mean={"obj:target": np.tile(offset, (S, 1))},
                      var={"obj:target": np.full((S, 3), 1e-4)}).validate()
    spec = ImitationSceneSpec(tables=False, cup=False, target=True,
                              target_position=[0.5, -0.2, 0.35])
    im = MakeImitationDiagram(ImitationConfig(task="obstacle", seed=3, scene=spec,
                                              reproducer=DbnReproducerConfig(settle_steps=5)),
                              model=model)
    return Case(im.diagram, [0.3, 0.6, 0.9], im.set_start,
                check=lambda end: end["status"][0] > 0)


#: builder name -> its case (builders not listed are called with their defaults)
CASES = {"MakeSceneDiagram": _scene_case, "MakeOperateDiagram": _operate_case,
         "MakeBodySchemaDiagram": _body_schema_case,
         "MakeFrontPerceptionDiagram": _front_perception_case,
         "MakeTactileGraspDiagram": _tactile_grasp_case,
         "MakeLiquidRollDiagram": _liquid_roll_case, "MakeTeacherDiagram": _teacher_case,
         "MakeImitationDiagram": _imitation_case}


def _default_case(name):
    import mmlearn.diagrams as D

    built = getattr(D, name)()
    diagram = built[0] if isinstance(built, tuple) else getattr(built, "diagram", built)
    return Case(diagram, [0.1, 0.2, 0.3])


def test_builders_are_found():
    assert set(_builders()) >= set(CASES)


#: the cases of more than a few seconds (the slow tier)
SLOW_CASES = {"MakeOperateDiagram", "MakeBodySchemaDiagram", "MakeTactileGraspDiagram",
              "MakeLiquidRollDiagram", "MakeImitationDiagram"}


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if n in SLOW_CASES
                                  else n for n in _builders()])
def test_two_simulators_match_one_alone(name):
    case = CASES[name]() if name in CASES else _default_case(name)
    end = _check(case.diagram, case.prepare, case.times, extra=case.extra, ignore=case.ignore)
    if case.check is not None:
        assert case.check(end), f"{name}: the run did not get far enough to test anything"


class _MarkerReplay(LeafSystem):
    """Replays an ObjectTrack as MarkerObservations, one sample per ``period``."""

    def __init__(self, track, period):
        super().__init__()
        self._track, self._period = track, period
        self.DeclareAbstractOutputPort(
            "observations", lambda: AbstractValue.Make(MarkerObservations()), self._calc,
            {self.time_ticket()})

    def _calc(self, context, out):
        from pydrake.common.eigen_geometry import Quaternion
        from pydrake.math import RigidTransform

        P = self._track.poses
        k = min(int(context.get_time() / self._period + 1e-9), P.shape[1] - 1)
        poses = [RigidTransform(Quaternion(P[i, k, 6], *P[i, k, 3:6]), P[i, k, :3])
                 for i in range(P.shape[0])]
        out.set_value(MarkerObservations(time=k * self._period,
                                         marker_ids=list(self._track.parts), poses=poses,
                                         visible=np.ones(P.shape[0], bool)))


class _PointReplay(LeafSystem):
    def __init__(self, P, period):
        super().__init__()
        self._P, self._period = P, period
        self.DeclareVectorOutputPort("p", 3, self._calc, {self.time_ticket()})

    def _calc(self, context, out):
        k = int(context.get_time() / self._period + 1e-9)
        out.SetFromVector(self._P[k] if k < len(self._P) else np.full(3, np.nan))


def _arc(r, a1, n, off=(0.0, 0.0, 0.0), z=0.7):
    a = np.linspace(0.0, a1, n)
    return np.c_[r * np.cos(a), r * np.sin(a), np.full(n, z)] + np.asarray(off)


@pytest.fixture(scope="module")
def meshcat():
    from pydrake.geometry import StartMeshcat

    return StartMeshcat()


@pytest.mark.slow
def test_object_tracks_estimators_two_simulators(meshcat):
    """The estimators and the prior selector on object tracks (diagrams/common/object_tracks.py
    builds tracks, not a Diagram: this wires them into one)."""
    track = cabinet_scenario(n_first=20, n_both=20, rng=0)
    rng = np.random.default_rng(1)
    db = PriorDatabase(obs=ObservationModel(sigma_pos=0.01, gamma_weight=1000.0))
    for k in range(3):
        db.add(_arc(0.4, 1.4, 40, rng.uniform(-0.2, 0.2, 3) * [1, 1, 0])
               + rng.normal(0, 0.002, (40, 3)), f"door{k}")
    door = _arc(0.4, 1.2, 60) + np.random.default_rng(2).normal(0, 0.003, (60, 3))
    builder = DiagramBuilder()
    src = builder.AddNamedSystem("markers", _MarkerReplay(track, 0.05))
    est = builder.AddNamedSystem("marker_estimator", ArticulationEstimator(
        part_ids=track.parts, period=0.05, refit_every=10, min_observations=10,
        obs=ObservationModel(sigma_pos=0.003, sigma_orient=math.radians(1)), seed=3))
    builder.Connect(src.get_output_port(), est.get_observations_input_port())
    hook = builder.AddNamedSystem("hook", _PointReplay(door, 0.03))
    pest = builder.AddNamedSystem("pose_estimator", ArticulationEstimator(
        mode="pose", pose_size=3, period=0.03, refit_every=10, min_observations=10,
        obs=ObservationModel(sigma_pos=0.01), models=("rigid", "prismatic", "revolute")))
    sel = builder.AddNamedSystem("prior_selector", PriorModelSelector(db=db, period=0.03))
    vis = builder.AddNamedSystem("visualizer", LearnedModelVisualizer(
        meshcat=meshcat, period=0.1, prefix="semantics_test"))
    builder.Connect(hook.get_output_port(), pest.get_pose_input_port())
    builder.Connect(hook.get_output_port(), sel.get_hook_position_input_port())
    builder.Connect(pest.get_object_model_output_port(), sel.get_object_model_input_port())
    builder.Connect(sel.GetOutputPort("object_model"), vis.get_object_model_input_port())
    for name, port in (("marker_stats", est.get_stats_output_port()),
                       ("marker_configuration", est.get_configuration_output_port()),
                       ("pose_stats", pest.get_stats_output_port()),
                       ("pose_configuration", pest.get_configuration_output_port()),
                       ("prior_cluster", sel.GetOutputPort("prior_cluster"))):
        builder.ExportOutput(port, name)
    diagram = builder.Build()

    def extra(ctx):
        m = est.get_selected_models_output_port().Eval(est.GetMyContextFromRoot(ctx))
        return tuple(sorted(m.items()))

    end = _check(diagram, lambda ctx: None, [0.5, 1.0, 1.5, 2.0], extra=extra)
    assert end["marker_stats"][2] == 2 and end["pose_stats"][2] == 1  # fitted models
    assert end["prior_cluster"][0] == 0  # the door was recognised
    assert meshcat.HasPath("semantics_test")


def test_motor_babbling_draws_its_targets_up_front():
    from mmlearn.systems import MotorBabbling

    calls = []

    def accept(q):
        calls.append(q.copy())
        return q[0] > 0.5

    b = MotorBabbling(lower=[0.0, 0.0], upper=[1.0, 1.0], period=0.5, seed=4, accept=accept,
                      n_targets=8)
    n_calls = len(calls)
    assert n_calls >= 8 and b.n_targets == 8
    assert all(b.target(k)[0] > 0.5 for k in range(1, 9))
    np.testing.assert_array_equal(b.target(9), b.target(1))  # the sequence repeats
    ctx = b.CreateDefaultContext()
    for t in np.linspace(0.0, 6.0, 50):
        ctx.SetTime(t)
        b.get_command_output_port().Eval(ctx)
    assert len(calls) == n_calls  # simulating never calls the predicate
    with pytest.raises(ValueError):
        MotorBabbling(lower=[0.0], upper=[1.0], n_targets=0)
