"""LASA handwriting data, its leave-one-out metrics, the naive baseline, the thesis' method on
one development shape, and the imitate_lasa app."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from conftest import bad_usage, run_main
from mmlearn.models.imitation.lasa import (DEVELOPMENT_SHAPES, LASA_SHAPES, MULTI_MODE_SHAPES,
                                           ThesisReproducer, baseline_reproducer, end_error_mm,
                                           evaluate_shape, leave_one_out, load_shape, naive_baseline,
                                           rmse_mm, with_start_marker)


def test_load_shape_is_millimetres_ending_at_the_target(capsys):
    demos = load_shape("Line")
    assert capsys.readouterr().out == ""          # the wheel's import print is avoided
    assert len(demos) == 7 and len(LASA_SHAPES) == 30
    for i, d in enumerate(demos):
        assert d.D == 2 and d.T == 1000 and d.t[0] == 0.0 and np.all(np.diff(d.t) > 0)
        assert d.meta == {"source": "LASA", "shape": "Line", "index": i, "units": "mm"}
        assert np.allclose(d.objects["target"], 0.0)
        assert np.linalg.norm(d.hand[-1]) < 1e-6            # every demonstration ends at the origin
        assert 20.0 < np.linalg.norm(d.hand[0]) < 100.0      # tens of mm away at the start
    assert not np.allclose(demos[0].hand, demos[1].hand)
    assert set(DEVELOPMENT_SHAPES) <= set(LASA_SHAPES) and set(MULTI_MODE_SHAPES) <= set(LASA_SHAPES)


def test_load_shape_needs_no_network(monkeypatch):
    import socket

    def no_net(*a, **k):
        raise AssertionError("network access")

    monkeypatch.setattr(socket, "socket", no_net)
    monkeypatch.setattr(socket, "create_connection", no_net)
    assert len(load_shape("Angle")) == 7


def test_load_shape_bad_name():
    with pytest.raises(ValueError, match="unknown LASA shape 'Sshpe'.*Sshape"):
        load_shape("Sshpe")


def test_load_shape_missing_or_broken_file(tmp_path):
    from mmlearn.models.imitation.types import ImitationDataError

    with pytest.raises(FileNotFoundError, match="Line.mat: LASA data file not found"):
        load_shape("Line", data_dir=tmp_path)
    (tmp_path / "Line.mat").write_bytes(b"not a mat file")
    with pytest.raises(ImitationDataError, match="Line.mat: not a readable LASA .mat file"):
        load_shape("Line", data_dir=tmp_path)


def test_metrics_by_hand():
    x = np.linspace(0.0, 10.0, 1001)
    held = np.stack([x, np.zeros_like(x)], axis=1)
    assert rmse_mm(held, held) == 0.0
    rep = np.stack([x[::10], np.r_[np.full(50, 1.0), np.full(51, 2.0)]], axis=1)
    assert rmse_mm(rep, held) == pytest.approx(np.sqrt((50 * 1 + 51 * 4) / 101))
    assert end_error_mm(rep, held) == pytest.approx(2.0)
    with pytest.raises(ValueError, match="reproduction: NaN"):
        rmse_mm(np.where(rep == 2.0, np.nan, rep), held)
    with pytest.raises(ValueError, match=r"expected an \(N, 2\) array"):
        rmse_mm(rep[:, :1], held)
    with pytest.raises(ValueError, match="held_out"):
        end_error_mm(rep, np.zeros((0, 2)))


def test_leave_one_out_and_baseline():
    demos = load_shape("Sshape")
    folds = list(leave_one_out(demos))
    assert [k for k, _, _ in folds] == list(range(7))
    for k, train, held in folds:
        assert len(train) == 6 and held is demos[k] and all(d is not held for d in train)
    # the baseline starts at the held-out start and ends at the training mean's end (the origin)
    _, train, held = folds[3]
    b = naive_baseline(train, held.hand[0], held.t)
    assert b.shape == held.hand.shape
    assert np.allclose(b[0], held.hand[0]) and np.linalg.norm(b[-1]) < 1e-6
    # identical training demonstrations and a held-out copy: reproduced exactly
    same = naive_baseline([held] * 6, held.hand[0], held.t)
    assert rmse_mm(same, held.hand) < 1e-9
    with pytest.raises(ValueError, match="no training"):
        naive_baseline([], held.hand[0], held.t)
    with pytest.raises(ValueError, match="start"):
        naive_baseline(train, [np.nan, 0.0], held.t)


@pytest.mark.slow
def test_thesis_method_beats_baseline_on_a_development_shape():
    """heee (a development shape): the DTW-aligned DBN keeps the loop that the index-wise
    mean of the baseline blurs; reproductions start at the held-out start and end at the
    target."""
    demos = load_shape("heee")
    ours = evaluate_shape("heee", ThesisReproducer(), demos=demos)
    base = evaluate_shape("heee", baseline_reproducer, demos=demos)
    assert len(ours.folds) == 7
    for f in ours.folds:
        assert np.allclose(f.reproduction[0], demos[f.index].hand[0])
        assert f.end_error_mm < 0.5
    assert ours.rmse_mm < 0.8 * base.rmse_mm, (ours.rmse_mm, base.rmse_mm)
    # the target constraint alone follows the learned mean from the first step: on Line (whose
    # demonstrations fan out from the origin) far worse than with the start marker
    line = load_shape("Line")
    target_only = evaluate_shape("Line", ThesisReproducer(objects=("target",)), demos=line, folds=[0, 1])
    both = evaluate_shape("Line", ThesisReproducer(), demos=line, folds=[0, 1])
    assert target_only.rmse_mm > 2 * both.rmse_mm, (target_only.rmse_mm, both.rmse_mm)


def test_start_marker_and_reproducer_settings():
    d = load_shape("Line")[0]
    s = with_start_marker(d)
    assert np.allclose(s.objects["start"], d.hand[0]) and "target" in s.objects
    with pytest.raises(ValueError, match="objects"):
        ThesisReproducer(objects=("start",))
    with pytest.raises(ValueError, match="h must be"):
        ThesisReproducer(h=0.0)
    with pytest.raises(ValueError, match="gain"):
        ThesisReproducer(gain=1.5)


@pytest.mark.slow
def test_app_json_and_plot(tmp_path, capsys):
    from mmlearn.apps.imitate_lasa import main

    png = tmp_path / "lasa.png"
    rc, out, err = run_main(main, ["--shapes", "Line,Saeghe", "--folds", "0,3", "--json",
                                   "--plot", str(png)], capsys)
    assert rc == 0, err
    d = json.loads(out)
    assert [s["name"] for s in d["shapes"]] == ["Line", "Saeghe"]
    for s in d["shapes"]:
        assert len(s["fold_rmse_mm"]) == 2 and s["development"] and not s["multi_mode"]
        assert 0 < s["rmse_mm"] < 3 and 0 <= s["end_error_mm"] < 0.5
        assert s["baseline_rmse_mm"] > 0
    assert d["mean_rmse_mm"] == pytest.approx(np.mean([s["rmse_mm"] for s in d["shapes"]]))
    assert d["n_shapes_multi_mode"] == 0 and d["mean_rmse_mm_multi_mode"] is None
    assert d["baseline"]["mean_rmse_mm"] == pytest.approx(np.mean([s["baseline_rmse_mm"] for s in d["shapes"]]))
    assert png.stat().st_size > 10_000


def test_app_html_out(tmp_path, capsys):
    from mmlearn.apps.common.cli import make_meshcat
    from mmlearn.apps.imitate_lasa import LasaConfig, main, run

    html = tmp_path / "lasa.html"
    rc, out, err = run_main(main, ["--shapes", "Line", "--folds", "0", "--json", "--html-out", str(html)], capsys)
    assert rc == 0, err
    assert json.loads(out)["html_out"] == str(html) and html.stat().st_size > 100_000
    mc = make_meshcat(announce=False)
    run(config=LasaConfig(shapes=["Line"], folds=[0, 2], progress=False), meshcat=mc)
    for p in ("/lasa/Line/demos/6", "/lasa/Line/thesis/2", "/lasa/Line/baseline/0",
              "/lasa/Line/learned/mean", "/lasa/Line/learned/sigma/0", "/lasa/Line/pen"):
        assert mc.HasPath(p), p
    assert not mc.HasPath("/lasa/Line/thesis/1")


def test_app_bad_input(tmp_path, capsys):
    from mmlearn.apps.imitate_lasa import main, parse_shapes

    assert parse_shapes("multi-mode,Line") == list(MULTI_MODE_SHAPES) + ["Line"]
    assert len(parse_shapes("all")) == 30 and len(parse_shapes("held-back")) == 17
    bad_usage(main, ["--shapes", "Sshape,Lien"], capsys, "--shapes", "'Lien'")
    bad_usage(main, ["--shapes", ","], capsys, "--shapes")
    bad_usage(main, ["--folds", "7"], capsys, "--folds")
    bad_usage(main, ["--objects", "start"], capsys, "--objects")
    bad_usage(main, ["--objects", "target,cup"], capsys, "--objects", "'cup'")
    bad_usage(main, ["--objects", "target,frame"], capsys, "--objects", "frame needs start")
    bad_usage(main, ["--objects", "target,frame_scale"], capsys, "--objects", "frame needs start")
    bad_usage(main, ["--shrinkage", "1.5"], capsys, "shrinkage must be in [0, 1]")
    bad_usage(main, ["--shrinkage", "nan"], capsys, "shrinkage")
    bad_usage(main, ["--gain", "2"], capsys, "--gain")
    bad_usage(main, ["--h", "nan"], capsys, "--h")
    bad_usage(main, ["--plot", str(tmp_path / "missing" / "x.png")], capsys, "--plot", "does not exist")
    bad_usage(main, ["--html-out", str(tmp_path)], capsys, "--html-out", "is a folder")


def test_app_help_subprocess():
    r = subprocess.run([sys.executable, "-m", "mmlearn.apps.imitate_lasa", "--help"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and "--shapes" in r.stdout and "held-back" in r.stdout


def _similar_drawings(n=7, T=300, rotate=True):
    """``n`` drawings of one curve ending at the origin, each rotated (unless not ``rotate``)
    and scaled about it."""
    from mmlearn.models.imitation.types import Demonstration

    s = np.linspace(0.0, 1.0, T)
    base = np.stack([40 * (1 - s) + 8 * np.sin(2 * np.pi * s), 15 * np.sin(np.pi * s) * (1 - s)], axis=1)
    out = []
    for g in range(n):
        a, sc = 0.25 * (g - 3) * rotate, 1.0 + 0.08 * (g - 3)
        R = sc * np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
        hand = base @ R.T
        out.append(Demonstration(t=np.linspace(0.0, 2.0, T), hand=hand,
                                 objects={"target": np.zeros_like(hand)}).validate())
    return out


def test_start_frame_maps_and_learns():
    from mmlearn.models.imitation.lasa import learn_start_frame, place_start_frame, start_frame, to_start_frame

    S = start_frame([0.0, 30.0])                       # x-axis towards the start, unit 30 mm
    assert np.allclose(S @ [1.0, 0.0], [0.0, 30.0]) and np.allclose(S @ [0.0, 1.0], [-30.0, 0.0])
    assert np.allclose(start_frame([13.0, 4.0], target=[10.0, 0.0]), [[3.0, -4.0], [4.0, 3.0]])
    with pytest.raises(ValueError, match="start is on the target"):
        start_frame([0.0, 0.0])
    with pytest.raises(ValueError, match="finite 2-D"):
        start_frame([np.nan, 1.0])
    demos = _similar_drawings()
    fr = to_start_frame(with_start_marker(demos[2]))
    assert np.allclose(fr.hand[0], [1.0, 0.0]) and np.allclose(fr.hand[-1], 0.0)
    with pytest.raises(ValueError, match="'target' and 'start'"):
        to_start_frame(demos[2])
    # every drawing is the same curve in its own start frame: the learned spread is far below
    # the world constraint's (what is left comes from the DTW warps) and, placed at a
    # held-out start, the mean is that drawing (in mm)
    rep = ThesisReproducer()
    train = [with_start_marker(d) for j, d in enumerate(demos) if j != 5]
    from mmlearn.models.imitation.dbn import align_demonstrations
    al = align_demonstrations(train, dt=0.02)
    fm, fv = learn_start_frame(al, h=0.02)
    assert fm.shape == (al[0].T, 2) and fv.shape == (al[0].T, 2, 2)
    model = place_start_frame(rep.learn([demos[j] for j in range(7) if j != 5]), fm, fv, demos[5].hand[0])
    assert "obj:frame" in model.constraints and model.objects[-1] == "frame"
    spread = {c: np.median(np.trace(model.var[c], axis1=1, axis2=2)) for c in ("obj:frame", "obj:target")}
    assert spread["obj:frame"] < 0.1 * spread["obj:target"], spread           # mm^2
    assert rmse_mm(-model.mean["obj:frame"], demos[5].hand) < 0.3
    assert rmse_mm(-model.mean["obj:target"], demos[5].hand) > 5.0


def test_start_frame_constraint_follows_a_rotated_scaled_drawing():
    """Drawings that differ by a rotation and scaling about the target: the start-frame
    constraint reproduces a held-out one almost exactly, the world constraints cannot."""
    demos = _similar_drawings()
    tsf = ("target", "start", "frame")
    both = evaluate_shape("similar", ThesisReproducer(objects=tsf, shrinkage=0.0), demos=demos, folds=[1, 5])
    world = evaluate_shape("similar", ThesisReproducer(objects=("target", "start"), shrinkage=0.0),
                           demos=demos, folds=[1, 5])
    assert both.rmse_mm < 0.15 and both.end_error_mm < 0.5, both.rmse_mm
    assert world.rmse_mm > 5 * both.rmse_mm, (world.rmse_mm, both.rmse_mm)
    # the default (plus the scale-only frame, covariances shrunk half-way to the diagonal) keeps
    # most of it: the scale-only frame and the shrunk world constraints pull a little
    default = evaluate_shape("similar", ThesisReproducer(), demos=demos, folds=[1, 5])
    assert default.rmse_mm < 0.35 and world.rmse_mm > 2.5 * default.rmse_mm, (default.rmse_mm, world.rmse_mm)
    with pytest.raises(ValueError, match="'frame' needs 'start'"):
        ThesisReproducer(objects=("target", "frame"))


def test_start_frame_modes_and_the_scale_only_frame():
    """The scale-only start frame; drawings that differ only by their size are reproduced by
    the scale-only frame constraint, not by the world constraints."""
    from mmlearn.models.imitation.lasa import FRAME_MODES, OBJECTS, start_frame, to_start_frame

    assert set(FRAME_MODES) == {"similarity", "scale", "duration"} and OBJECTS[0] == "target"
    assert np.allclose(start_frame([13.0, 4.0], target=[10.0, 0.0], mode="scale"), 5.0 * np.eye(2))
    with pytest.raises(ValueError, match="mode must be one of"):
        start_frame([3.0, 4.0], mode="affine")
    d = with_start_marker(_similar_drawings(rotate=False)[6])
    s0 = d.hand[0]
    assert np.allclose(to_start_frame(d, mode="scale").hand[0], s0 / np.linalg.norm(s0))
    assert np.allclose(to_start_frame(d).hand[0], [1.0, 0.0])
    demos = _similar_drawings(rotate=False)
    scale = evaluate_shape("scaled", ThesisReproducer(objects=("target", "start", "frame_scale")),
                           demos=demos, folds=[0, 5])
    world = evaluate_shape("scaled", ThesisReproducer(objects=("target", "start")), demos=demos, folds=[0, 5])
    assert scale.rmse_mm < 0.3 and scale.end_error_mm < 0.5, scale.rmse_mm
    assert world.rmse_mm > 2 * scale.rmse_mm, (world.rmse_mm, scale.rmse_mm)
    m = ThesisReproducer(objects=("target", "start", "frame_scale")).learn(demos[1:], start=demos[0].hand[0])
    assert m.objects == ["target", "start", "frame_scale"]
    with pytest.raises(ValueError, match="'frame' needs 'start'"):
        ThesisReproducer(objects=("target", "frame_scale"))
    with pytest.raises(ValueError, match="objects must be"):
        ThesisReproducer(objects=("target", "start", "frame_rotation"))


def test_shrinkage_moves_the_covariances_towards_their_diagonal():
    """shrink_covariance by hand; the reproducer's shrinkage applies it to every learned
    covariance (0 keeps the full ones)."""
    from mmlearn.models.imitation.lasa import shrink_covariance

    C = np.array([[[4.0, 1.0], [1.0, 2.0]]])
    assert np.allclose(shrink_covariance(C, 0.5), [[[4.0, 0.5], [0.5, 2.0]]])
    assert np.allclose(shrink_covariance(C, 1.0), [[[4.0, 0.0], [0.0, 2.0]]])
    with pytest.raises(ValueError, match="shrinkage"):
        shrink_covariance(C, 1.5)
    demos = load_shape("Sshape")
    train, start = demos[1:], demos[0].hand[0]
    ts = ("target", "start")
    plain = ThesisReproducer(objects=ts, shrinkage=0.0).learn(train, start=start)
    half = ThesisReproducer(objects=ts, shrinkage=0.5).learn(train, start=start)
    for c in ("obj:target", "obj:start"):
        assert np.allclose(half.var[c], shrink_covariance(plain.var[c], 0.5))
        assert not np.allclose(half.var[c], plain.var[c])
    with pytest.raises(ValueError, match="shrinkage must be in"):
        ThesisReproducer(shrinkage=-0.1)


def _timed_drawings(n=7, T=300):
    """``n`` drawings from a start at ~50 mm (distance and direction not tied to the duration)
    to the origin: a straight stroke plus a sideways bulge of 6 mm per second of the drawing's
    duration (2.0-3.8 s, shuffled): a slower drawing is a larger one."""
    from mmlearn.models.imitation.types import Demonstration

    rng = np.random.default_rng(3)
    durs = rng.permutation(2.0 + 0.3 * np.arange(n))
    s = np.linspace(0.0, 1.0, T)
    out = []
    for g in range(n):
        d, a = 50.0 + rng.uniform(-5, 5), rng.uniform(-0.3, 0.3)
        u = np.stack([d * (1 - s), 6.0 * durs[g] * np.sin(np.pi * s)], axis=1)
        hand = u @ np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]]).T
        out.append(Demonstration(t=np.linspace(0.0, durs[g], T), hand=hand,
                                 objects={"target": np.zeros_like(hand)}).validate())
    return out


@pytest.mark.slow
def test_duration_frame_follows_a_drawing_sized_by_its_duration():
    """The duration start frame (x-axis towards the start, unit = the drawing's duration)
    maps and errs like the other frames, and on drawings whose bulge grows with their duration
    (not with their start) the default with it reproduces a held-out drawing far better than
    without it; the learned model places it only when given the reproduction's duration."""
    from mmlearn.models.imitation.lasa import learn_start_frame, start_frame, to_start_frame

    S = start_frame([0.0, 30.0], mode="duration", duration=2.5)   # unit 2.5 s, x towards the start
    assert np.allclose(S @ [1.0, 0.0], [0.0, 2.5]) and np.allclose(S @ [0.0, 1.0], [-2.5, 0.0])
    for bad in (None, 0.0, np.nan):
        with pytest.raises(ValueError, match="needs the drawing's duration"):
            start_frame([0.0, 30.0], mode="duration", duration=bad)
    demos = _timed_drawings()
    d = with_start_marker(demos[0])
    u = to_start_frame(d, mode="duration").hand                  # default: the demo's own duration
    assert np.allclose(u[0], [np.linalg.norm(d.hand[0]) / d.duration, 0.0])
    assert np.allclose(to_start_frame(d, mode="duration", duration=1.0).hand[0], [np.linalg.norm(d.hand[0]), 0.0])
    # the learned frame's sideways bulge, in mm per second: 6 at mid-drawing (the alignment puts
    # every demonstration on the reference's time base, so the durations are passed)
    from mmlearn.models.imitation.dbn import align_demonstrations
    al = align_demonstrations([with_start_marker(x) for x in demos], dt=0.02)
    fm, _ = learn_start_frame(al, h=0.02, mode="duration", durations=[x.duration for x in demos])
    assert abs(-fm[len(fm) // 2, 1] - 6.0) < 0.6, fm[len(fm) // 2]
    with pytest.raises(ValueError, match="durations"):
        learn_start_frame(al, h=0.02, mode="duration", durations=[1.0])
    with pytest.raises(ValueError, match="durations"):
        learn_start_frame(al, h=0.02, mode="duration", durations=[-1.0] * 7)
    with_dur = evaluate_shape("timed", ThesisReproducer(), demos=demos)          # all 7 folds, ~1 s
    without = evaluate_shape("timed", ThesisReproducer(objects=("target", "start", "frame", "frame_scale")),
                             demos=demos)
    assert with_dur.end_error_mm < 0.5, with_dur.end_error_mm
    assert with_dur.rmse_mm < 0.6 * without.rmse_mm, (without.rmse_mm, with_dur.rmse_mm)     # 1.32 vs 2.62 mm
    rep = ThesisReproducer()
    assert "frame_duration" not in rep.learn(demos[1:], start=demos[0].hand[0]).objects
    m = rep.learn(demos[1:], start=demos[0].hand[0], duration=demos[0].duration)
    assert m.objects[-1] == "frame_duration"
    with pytest.raises(ValueError, match="duration must be a finite time"):
        rep.learn(demos[1:], start=demos[0].hand[0], duration=0.0)
    with pytest.raises(ValueError, match="'frame' needs 'start'"):
        ThesisReproducer(objects=("target", "frame_duration"))
