"""The FrontTracker LeafSystem (systems/perception/front_tracker.py): tracks and link models from a stream
of detected rectangles, under a Simulator; bad inputs; Drake semantics (state in the Context)."""

import numpy as np
import pytest
from pydrake.common.value import AbstractValue
from pydrake.common.yaml import yaml_load_typed
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder, LeafSystem

from mmlearn.models.perception.tracking import FrontTrackingConfig, simulate_front_rectangles
from mmlearn.systems.perception.front_tracker import FrontTracker, FrontTrackerConfig

PERIOD = 0.1


class RectangleReplay(LeafSystem):
    """Outputs frames[k] (a list of rectangles, or any object) at t in [k, k+1) * PERIOD."""

    def __init__(self, frames):
        super().__init__()
        self._frames = frames
        self.DeclareAbstractOutputPort("rectangles", lambda: AbstractValue.Make(list()),
                                       self._calc, {self.time_ticket()})

    def _calc(self, context, out):
        k = int(context.get_time() / PERIOD + 1e-9)
        out.set_value(self._frames[k] if k < len(self._frames) else [])


def _diagram(frames, config=None):
    b = DiagramBuilder()
    src = b.AddNamedSystem("replay", RectangleReplay(frames))
    trk = b.AddNamedSystem("tracker", FrontTracker(config=config or FrontTrackerConfig(
        period_s=PERIOD)))
    b.Connect(src.get_output_port(), trk.get_rectangles_input_port())
    b.ExportOutput(trk.get_stats_output_port(), "stats")
    return b.Build(), trk


def _scene(n=45, seed=0):
    """A moving drawer, a door and a still background front, detections in random
    parameterisations, some frames with gaps, NaN rectangles and junk."""
    rng = np.random.default_rng(seed)
    drawer = simulate_front_rectangles("drawer", n, rng=rng, travel=0.35)
    X = np.eye(4)
    X[:3, 3] = [1.0, 0.0, 0.4]
    door = simulate_front_rectangles("door", n, rng=rng, X_WO=X, travel=1.3)
    X = np.eye(4)
    X[:3, 3] = [-0.8, 0.2, 0.0]
    wall = simulate_front_rectangles("rigid", n, rng=rng, X_WO=X, width=0.6, height=0.9)

    class NaNRect:
        X_WR = np.full((4, 4), np.nan)
        width = height = 0.4

    frames = []
    for i in range(n):
        f = [drawer[i], door[i], wall[i]]
        if i % 9 == 4:
            f.append(NaNRect())
        if i % 11 == 7:
            f = [door[i]]  # the drawer and the wall not detected
        frames.append(f)
    frames[20] = []
    frames[21] = None
    frames[22] = "not a list"
    return frames


def test_tracker_learns_prismatic_and_revolute_under_a_simulator():
    frames = _scene()
    diagram, trk = _diagram(frames)
    sim = Simulator(diagram)
    sim.AdvanceTo(PERIOD * (len(frames) - 0.5))
    ctx = trk.GetMyContextFromRoot(sim.get_context())
    tracks = trk.get_tracks_output_port().Eval(ctx)
    models = trk.get_models_output_port().Eval(ctx)
    stats = trk.get_stats_output_port().Eval(ctx)
    assert len(tracks) == 3, [t.n for t in tracks]
    by_x = sorted(tracks, key=lambda t: t.poses[0, 0])  # wall, drawer, door
    assert [models[t.track_id].selected for t in by_x] == ["rigid", "prismatic", "revolute"]
    door = models[by_x[2].track_id].model
    assert door.radius == pytest.approx(0.395 / 2, abs=0.03)
    assert abs(door.axis[2]) > np.cos(np.radians(5))  # hinge axis vertical
    drawer = models[by_x[1].track_id].model
    assert abs(drawer.axis[1]) > np.cos(np.radians(5))  # pulled along the normal
    # frames: 45 updates; the NaN rectangles counted, junk input counted, nothing raised
    assert stats[2] == len(frames)
    assert stats[3] == 3  # NaNRect at i = 4, 13, 31 (22 is junk, 40 holds the door only)
    assert stats[6] == 1  # "not a list"
    assert stats[5] == 0  # no fit failed


def test_same_frame_twice_is_added_once_and_inputs_unconnected_do_not_crash():
    rects = simulate_front_rectangles("drawer", 3, rng=0, travel=0.05)
    # every frame held for two tracker periods
    frames = [[rects[k // 2]] for k in range(6)]
    diagram, trk = _diagram(frames)
    sim = Simulator(diagram)
    sim.AdvanceTo(0.55)
    st = trk.state(trk.GetMyContextFromRoot(sim.get_context()))
    assert [t.n for t in st.tracking.tracks] == [3]
    # an unconnected input: counted as a bad input, the simulation goes on
    lone = FrontTracker(config=FrontTrackerConfig(period_s=PERIOD))
    sim = Simulator(lone)
    sim.AdvanceTo(0.25)
    assert lone.get_stats_output_port().Eval(sim.get_context())[6] == 3


def test_config_from_yaml_and_validation():
    cfg = yaml_load_typed(schema=FrontTrackerConfig, data="""
period_s: 0.2
sigma_pos_m: 0.01
tracking: {max_distance_m: 0.15, min_observations: 8}
""")
    assert cfg.tracking.max_distance_m == 0.15 and cfg.tracking.min_observations == 8
    FrontTracker(config=cfg)
    with pytest.raises(Exception, match="max_distanc"):
        yaml_load_typed(schema=FrontTrackerConfig, data="tracking: {max_distanc_m: 0.2}")
    for bad, match in [(dict(period_s=0.0), "period_s"), (dict(models="rigid,hinge"), "hinge"),
                       (dict(refit_every=0), "refit_every"),
                       (dict(tracking=FrontTrackingConfig(max_angle_deg=30)), None)]:
        if match is None:
            FrontTracker(config=FrontTrackerConfig(**bad))
            continue
        with pytest.raises(ValueError, match=match):
            FrontTracker(config=FrontTrackerConfig(**bad))
    cfg = FrontTrackerConfig()
    cfg.tracking.max_size_diff_m = -1.0
    with pytest.raises(ValueError, match="max_size_diff_m"):
        FrontTracker(config=cfg)


@pytest.mark.slow
def test_two_simulators_and_a_clone_reproduce_a_lone_run():
    from test_drake_semantics import _check

    frames = _scene(n=25, seed=1)
    diagram, trk = _diagram(frames, FrontTrackerConfig(period_s=PERIOD, refit_every=4))

    def extra(ctx):
        c = trk.GetMyContextFromRoot(ctx)
        st = trk.state(c)
        tracks = tuple((t.track_id, t.poses.tobytes()) for t in st.tracking.tracks)
        models = tuple(sorted((k, m.selected, m.n, round(m.model.bic_, 9))
                              for k, m in trk.get_models_output_port().Eval(c).items()))
        return tracks, models

    end = _check(diagram, lambda ctx: None, [0.6, 1.2, 1.8, 2.45], extra=extra)
    assert len(end["extra"][1]) == 3  # three published, fitted tracks


def test_visualizer_draws_detections_tracks_and_models():
    from pydrake.geometry import StartMeshcat

    from mmlearn.systems.perception.front_visualizer import FrontTrackVisualizer

    meshcat = StartMeshcat()
    frames = _scene(n=30, seed=2)
    b = DiagramBuilder()
    src = b.AddNamedSystem("replay", RectangleReplay(frames))
    trk = b.AddNamedSystem("tracker", FrontTracker(config=FrontTrackerConfig(period_s=PERIOD)))
    vis = b.AddNamedSystem("vis", FrontTrackVisualizer(meshcat=meshcat, period=PERIOD,
                                                       prefix="front_test"))
    b.Connect(src.get_output_port(), trk.get_rectangles_input_port())
    b.Connect(src.get_output_port(), vis.get_rectangles_input_port())
    b.Connect(trk.get_tracks_output_port(), vis.get_tracks_input_port())
    b.Connect(trk.get_models_output_port(), vis.get_models_input_port())
    diagram = b.Build()
    sim = Simulator(diagram)
    sim.AdvanceTo(PERIOD * 13.5)  # frame 13: drawer, door, wall and a NaN rectangle
    ctx = trk.GetMyContextFromRoot(sim.get_context())
    models = trk.get_models_output_port().Eval(ctx)
    assert len(models) == 3
    for k in range(3):
        assert meshcat.HasPath(f"front_test/detections/{k}")
    assert not meshcat.HasPath("front_test/detections/3")  # the NaN one is not drawn
    for tid, m in models.items():
        assert meshcat.HasPath(f"front_test/tracks/{tid}/rectangle")
        assert meshcat.HasPath(f"front_test/tracks/{tid}/model/"
                               + {"revolute": "axis", "prismatic": "range"}.get(
                                   m.selected, "position"))
    # unconnected inputs: nothing drawn, no error
    lone = FrontTrackVisualizer(meshcat=meshcat, prefix="front_lone")
    c = lone.CreateDefaultContext()
    lone.ForcedPublish(c)
    assert not meshcat.HasPath("front_lone/tracks/0")


class NoisyTrueFront(LeafSystem):
    """A detector stand-in: the scene's true front rectangle with 0.01 m / 2 deg noise, in one
    of the 4 parameterisations with z towards the camera (drawn per frame, seeded by the
    time: the same frame gives the same rectangle)."""

    def __init__(self):
        super().__init__()
        self._in = self.DeclareAbstractInputPort("front", AbstractValue.Make(None))
        self.DeclareAbstractOutputPort("rectangles", lambda: AbstractValue.Make(list()),
                                       self._calc)

    def _calc(self, context, out):
        from scipy.spatial.transform import Rotation

        from mmlearn.models.perception.tracking import RECTANGLE_SYMMETRIES, SWAPS_SIZE
        from mmlearn.models.perception.fronts import FrontRectangle

        r = self._in.Eval(context)
        rng = np.random.default_rng(int(round(context.get_time() * 1000)))
        X = r.X_WR.copy()
        X[:3, 3] += rng.normal(0.0, 0.01, 3)
        dR = Rotation.from_rotvec(rng.normal(0.0, np.radians(2.0), 3)).as_matrix()
        X[:3, :3] = dR @ X[:3, :3]
        j = int(rng.integers(0, 4))
        X[:3, :3] = X[:3, :3] @ RECTANGLE_SYMMETRIES[j]
        w, h = (r.height, r.width) if SWAPS_SIZE[j] else (r.width, r.height)
        out.set_value([FrontRectangle(X, w, h)])


@pytest.mark.parametrize("front", ["door", "drawer"])
def test_tracker_in_the_kitchen_scene_learns_the_true_joint(front):
    from mmlearn.diagrams.perception.diagram import FrontPerceptionConfig, MakeFrontPerceptionDiagram

    parts = {}

    def add(builder, p):
        src = builder.AddNamedSystem("detector_stand_in", NoisyTrueFront())
        trk = builder.AddNamedSystem("tracker", FrontTracker(
            config=FrontTrackerConfig(period_s=0.2)))
        builder.Connect(p.ports["front"], src.get_input_port())
        builder.Connect(src.get_output_port(), trk.get_rectangles_input_port())
        parts["tracker"] = trk

    d = MakeFrontPerceptionDiagram(FrontPerceptionConfig(front=front, point_cloud=False),
                                   add_systems=add)
    sim = Simulator(d.diagram)
    sim.AdvanceTo(d.duration)
    trk = parts["tracker"]
    ctx = trk.GetMyContextFromRoot(sim.get_context())
    tracks = trk.get_tracks_output_port().Eval(ctx)
    models = trk.get_models_output_port().Eval(ctx)
    assert len(tracks) == 1 and tracks[0].n == int(round(d.duration / 0.2))  # 0, ..., 12.8 s
    tm = models[tracks[0].track_id]
    kin = d.kinematics
    m = tm.model
    assert abs(float(np.dot(m.axis, kin.axis_W))) > np.cos(np.radians(3.0))
    if front == "door":
        assert tm.selected == "revolute"
        assert m.radius == pytest.approx(0.5 * kin.width, abs=0.02)
        # the hinge line: the true hinge point lies on the learned axis (within 2 cm)
        v = np.asarray(kin.point_W) - np.asarray(m.center)
        assert np.linalg.norm(v - np.dot(v, m.axis) * np.asarray(m.axis)) < 0.02
    else:
        assert tm.selected == "prismatic"
        assert m.q_max[0] - m.q_min[0] == pytest.approx(0.30, abs=0.03)


@pytest.mark.slow
def test_detector_and_tracker_learn_the_door_from_depth_images():
    """End to end: rendered noisy depth -> FrontDetector -> FrontTracker (door at 1.5 m)."""
    from mmlearn.diagrams.perception.diagram import (AddFrontDetectorAndTracker, FrontPerceptionConfig,
                                                     MakeFrontPerceptionDiagram)

    parts = {}

    def add(builder, p):
        _, parts["tracker"] = AddFrontDetectorAndTracker(
            builder, p, seed=1, tracker_config=FrontTrackerConfig(period_s=0.2))

    cfg = FrontPerceptionConfig(front="door", point_cloud=False)
    cfg.camera.distance = 1.5
    cfg.noise.seed = 1
    d = MakeFrontPerceptionDiagram(cfg, add_systems=add)
    sim = Simulator(d.diagram)
    sim.AdvanceTo(d.duration)
    trk = parts["tracker"]
    ctx = trk.GetMyContextFromRoot(sim.get_context())
    tracks = {t.track_id: t for t in trk.get_tracks_output_port().Eval(ctx)}
    models = trk.get_models_output_port().Eval(ctx)
    kin = d.kinematics
    door = [k for k, t in tracks.items()
            if abs(t.sizes[:, 0].mean() - kin.width) < 0.03 and models[k].selected == "revolute"]
    assert len(door) == 1, {k: (models[k].selected, t.sizes.mean(0)) for k, t in tracks.items()}
    m = models[door[0]].model
    assert abs(float(np.dot(m.axis, kin.axis_W))) > np.cos(np.radians(3.0))
    assert m.radius == pytest.approx(0.5 * kin.width, abs=0.03)
    v = np.asarray(kin.point_W) - np.asarray(m.center)
    assert np.linalg.norm(v - np.dot(v, m.axis) * np.asarray(m.axis)) < 0.04
    # the still fronts and walls stay rigid; no track turns about another axis
    for k, tm in models.items():
        if tm.selected == "revolute":
            assert abs(float(np.dot(tm.model.axis, kin.axis_W))) > np.cos(np.radians(5.0)), k
    assert sum(tm.selected == "rigid" for tm in models.values()) >= 3


class _LoggedAnimation:
    """A MeshcatAnimation stand-in that logs the keyed properties (frame = round(t * fps))."""

    def __init__(self, fps):
        self.fps, self.keys = fps, {}

    def frame(self, t):
        return int(round(t * self.fps))

    def SetProperty(self, frame, path, prop, value):
        self.keys.setdefault((path, prop), {})[frame] = value


def test_visualizer_records_each_frame_at_its_time():
    """With a recording, each publish draws its own group, keyed visible at its time only
    (the recording plays the rectangles as they were, not the final state)."""
    from pydrake.geometry import MeshcatAnimation, StartMeshcat

    from mmlearn.systems.perception.front_visualizer import FrontTrackVisualizer

    meshcat = StartMeshcat()
    frames = _scene(n=30, seed=4)
    anim = _LoggedAnimation(fps=64.0)
    b = DiagramBuilder()
    src = b.AddNamedSystem("replay", RectangleReplay(frames))
    trk = b.AddNamedSystem("tracker", FrontTracker(config=FrontTrackerConfig(period_s=PERIOD)))
    vis = b.AddNamedSystem("vis", FrontTrackVisualizer(meshcat=meshcat, period=PERIOD,
                                                       prefix="front_rec", recording=anim))
    b.Connect(src.get_output_port(), trk.get_rectangles_input_port())
    b.Connect(src.get_output_port(), vis.get_rectangles_input_port())
    b.Connect(trk.get_tracks_output_port(), vis.get_tracks_input_port())
    b.Connect(trk.get_models_output_port(), vis.get_models_input_port())
    sim = Simulator(b.Build())
    sim.AdvanceTo(PERIOD * 10.5)  # publishes at k = 0 .. 10
    for k in range(11):
        g = f"front_rec/frames/{k}"
        assert meshcat.HasPath(f"{g}/detections/0")
        keys = anim.keys[(g, "visible")]
        f = anim.frame(k * PERIOD)
        assert keys[f] is True
        if k > 0:
            assert keys[0] is False  # hidden before its time
        if k < 10:
            assert keys[anim.frame((k + 1) * PERIOD)] is False  # hidden at the next one
        else:
            assert max(keys) == f  # the last one stays
    assert not meshcat.HasPath("front_rec/detections")  # no undated drawing
    # the real MeshcatAnimation takes the same calls
    real = MeshcatAnimation(64.0)
    lone = FrontTrackVisualizer(meshcat=meshcat, period=PERIOD, prefix="front_rec2",
                                recording=real)
    c = lone.CreateDefaultContext()
    c.SetTime(3 * PERIOD)
    lone.ForcedPublish(c)
    # ... and so does a getter, called at each publish (the scene visualizer's bound
    # get_mutable_recording: a reference taken before StartRecording can dangle)
    calls = []
    got = FrontTrackVisualizer(meshcat=meshcat, period=PERIOD, prefix="front_rec3",
                               recording=lambda: calls.append(1) or anim)
    c = got.CreateDefaultContext()
    c.SetTime(2 * PERIOD)
    got.ForcedPublish(c)
    assert calls == [1] and anim.keys[("front_rec3/frames/2", "visible")][anim.frame(
        2 * PERIOD)] is True
    with pytest.raises(ValueError, match="MeshcatAnimation"):
        FrontTrackVisualizer(meshcat=meshcat, recording=object())
