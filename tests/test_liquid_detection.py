"""Liquid detection (thesis Sec. 7.3): the roll scene, the finger hold, the app."""

import json

import numpy as np
import pytest

from mmlearn.apps import liquid_detection as app
from mmlearn.diagrams.tactile.liquid_roll import (LIQUID_CONTAINERS, LiquidRollConfig, make_instance,
                                                  roll_trajectory)
from mmlearn.models.tactile.containers import sample_container
from mmlearn.models.tactile.evaluation import roll_record
from mmlearn.models.tactile.types import TactileDataError


def test_finger_hold_passes_then_latches():
    from pydrake.systems.analysis import Simulator

    from mmlearn.systems.tactile.finger_hold import FingerPositionHold

    hold = FingerPositionHold(num_fingers=2, t_latch=0.5, period=0.01)
    sim = Simulator(hold)
    ctx = sim.get_mutable_context()
    port = hold.get_input_port_desired()
    port.FixValue(ctx, [0.01, 0.02, 0.1, 0.1])
    sim.AdvanceTo(0.3)
    np.testing.assert_allclose(hold.get_output_port_desired().Eval(ctx), [0.01, 0.02, 0.1, 0.1])
    port.FixValue(ctx, [0.011, 0.021, 0.0, 0.0])
    sim.AdvanceTo(0.6)
    port.FixValue(ctx, [0.03, 0.04, 0.5, 0.5])  # after the latch: ignored
    sim.AdvanceTo(0.8)
    np.testing.assert_allclose(hold.get_output_port_desired().Eval(ctx), [0.011, 0.021, 0, 0])
    with pytest.raises(ValueError, match="t_latch"):
        FingerPositionHold(t_latch=float("nan"))


@pytest.mark.parametrize("tau", [0.0, 0.1])
def test_roll_trajectory_is_a_triangle_wave(tau):
    c = LiquidRollConfig(roll_amplitude=0.5, roll_hz=0.5, roll_cycles=1.0, reversal_time=tau,
                         roll_profile="triangle")
    tr = roll_trajectory(c)
    q = lambda t: tr.value(t)[0, 0]  # noqa: E731
    assert q(c.t_roll - 0.2) == pytest.approx(0.0, abs=1e-9)
    assert q(c.t_roll + 0.5) == pytest.approx(0.5, abs=1e-9)  # the first reversal
    assert q(c.t_roll + 1.0) == pytest.approx(0.0, abs=1e-9)
    assert q(c.t_roll + 1.5) == pytest.approx(-0.5, abs=1e-9)
    assert q(c.t_roll + 2.0) == pytest.approx(0.0, abs=1e-9)
    rate = tr.derivative(1).value(c.t_roll + 0.75)[0, 0]
    # amplitude / (quarter period - tau / 4): the blend keeps the peak at the amplitude
    assert rate == pytest.approx(-0.5 / (0.5 - tau / 4), rel=1e-6)


def test_instances_weigh_what_they_hold():
    from pydrake.multibody.parsing import Parser
    from pydrake.multibody.plant import MultibodyPlant

    from mmlearn.sdf.tactile import container_sdf

    for label in ("odwalla_half", "odwalla_empty", "water_quarter", "dummy"):
        inst = make_instance(label, np.random.default_rng(3))
        plant = MultibodyPlant(0.0)
        mi = Parser(plant).AddModelsFromString(container_sdf(inst), "sdf")[0]
        plant.Finalize()
        total = sum(plant.get_body(b).default_mass() for b in plant.GetBodyIndices(mi))
        assert total == pytest.approx(inst.mass, abs=1e-5), label  # SDF keeps 6 digits
        assert (inst.slosh_mass > 0) == (LIQUID_CONTAINERS.get(label, ("", None))[1] is not None)


def test_bad_inputs():
    with pytest.raises(ValueError, match="roll_hz"):
        LiquidRollConfig(roll_hz=-1.0)
    with pytest.raises(ValueError, match="t_latch"):
        LiquidRollConfig(t_latch=3.0)
    with pytest.raises(ValueError, match="unknown 'teapot'"):
        make_instance("teapot", np.random.default_rng(0))
    with pytest.raises(ValueError, match="fill"):
        sample_container("odwalla", "full_closed", np.random.default_rng(0), fill=1.5)
    rec = {"t": [0.0, 0.1], "taxels": [[0.0]] * 3, "wrist_force": [[0, 0, 0]] * 2,
           "roll_window": [0, 1], "weight_window": [0, 1], "liquid": True, "container": "x"}
    with pytest.raises(TactileDataError, match="unequal length"):
        roll_record(rec)


def _rc(argv):
    try:
        return app.main(argv)
    except SystemExit as e:  # argparse's own errors
        return e.code


def test_cli_help_and_bad_arguments(capsys, tmp_path):
    assert _rc(["--help"]) == 0
    assert "--with-weight" in capsys.readouterr().out
    for argv, msg in ((["--containers", "0"], "--containers"),
                      (["--containers", "99"], "at most"),
                      (["--names", "bogus"], "unknown"),
                      (["--trials", "1"], "trials"),
                      (["--names", "odwalla_half,water_half"], "one container with liquid"),
                      (["--report-only", str(tmp_path / "none.jsonl")], "no results file"),
                      (["--report-only", "x.jsonl", "--html-out", str(tmp_path / "y.html")],
                       "--report-only simulates nothing"),
                      (["--plot", str(tmp_path / "no" / "x.png")], "does not exist")):
        assert _rc(argv) == 2, argv
        err = capsys.readouterr().err
        assert msg in err, (argv, err)


@pytest.fixture(scope="module")
def short_run(tmp_path_factory):
    d = tmp_path_factory.mktemp("liquid")
    res = d / "r.jsonl"
    rc = app.main(["--names", "odwalla_half,odwalla_empty", "--trials", "2", "--no-dummy",
                   "--roll-cycles", "0.5", "--seed", "5", "--jobs", "2", "--results", str(res),
                   "--plot", str(d / "fig.png"), "--feature", "whole", "--json"])
    return rc, d, res


@pytest.mark.slow
def test_short_run_full_differs_from_empty(short_run, capsys):
    rc, d, res = short_run
    assert rc == 0
    assert (d / "fig.png").stat().st_size > 0
    lines = [json.loads(ln) for ln in res.read_text().splitlines()]
    assert len(lines) == 4 and not any(ln["error"] for ln in lines)
    feats = {True: [], False: []}
    for ln in lines:
        r = roll_record(ln["record"])
        from mmlearn.models.tactile.liquid import liquid_feature

        feats[r.liquid].append(liquid_feature(r.taxels, rate_hz=r.rate_hz))
        # the lifted container's weight from the wrist sensor is its mass times g
        m = ln["record"]["instance"]["mass"]
        assert r.weight == pytest.approx(9.81 * m, abs=0.3)
    # a single reversal does not separate the tactile feature of a half-full bottle from an
    # empty one (0.00083 vs 0.00089 at this seed: the liquid's ringing needs the full roll);
    # the features are the high-passed taxels' spread, positive and small
    assert all(0 < f < 0.05 for v in feats.values() for f in v)
    weights = {liq: [roll_record(ln["record"]).weight for ln in lines
                     if ln["record"]["liquid"] == liq] for liq in (True, False)}
    assert min(weights[True]) > 2 * max(weights[False])
    # --report-only recomputes the same report from the results file
    capsys.readouterr()
    assert app.main(["--report-only", str(res), "--names", "odwalla_half,odwalla_empty",
                     "--trials", "2", "--no-dummy", "--feature", "whole", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["n_trials"] == 4 and 0.0 <= out["rate"] <= 1.0
    assert {r["container"] for r in out["table"]} == {"odwalla_half", "odwalla_empty"}
    assert out["sweep"]["report_only"] is True
    # the records keep the roll command (where its rate changed); half a cycle leaves no
    # coast phase long enough for the detrended coast feature (the default): a clear error
    assert out["feature"] == "whole" and "coast_detrended" not in out["features"]
    assert out["rate_tactile"] == out["features"]["whole"]["rate_tactile"]
    assert all(len(ln["record"]["roll_changes"]) == 3 for ln in lines)  # start, 1 reversal, stop
    assert app.main(["--report-only", str(res), "--names", "odwalla_half,odwalla_empty",
                     "--trials", "2", "--no-dummy", "--json"]) == 2
    assert "not available" in capsys.readouterr().err


def test_coast_mask_and_feature_bad_inputs():
    from mmlearn.models.tactile.liquid import (RollRecord, coast_mask, liquid_feature,
                                               liquid_features)

    t = np.arange(0.0, 2.0, 1 / 24)
    m = coast_mask(t, [[0.5, 0.7], [1.2, 1.2]], start=0.2, end=1.8, delay=0.1)
    # inside [0.2, 1.8], outside [0.5, 0.8] and [1.2, 1.3]
    want = (t >= 0.2) & (t <= 1.8) & ~((t >= 0.5) & (t <= 0.8)) & ~((t >= 1.2) & (t <= 1.3))
    np.testing.assert_array_equal(m, want)
    with pytest.raises(TactileDataError, match="delay"):
        coast_mask(t, [[0.5, 0.7]], start=0.2, end=1.8, delay=-0.1)
    with pytest.raises(TactileDataError, match="start <= end"):
        coast_mask(t, [[0.7, 0.5]], start=0.2, end=1.8)
    x = np.random.default_rng(0).normal(size=(len(t), 4))
    with pytest.raises(TactileDataError, match="mask"):
        liquid_feature(x, mask=m[:-1])
    with pytest.raises(TactileDataError, match="coast"):
        RollRecord(x, coast=np.zeros(len(t), bool))
    # the coast feature is the spread over the masked samples of the same filtered norm
    from mmlearn.models.tactile.liquid import filtered_norm

    assert liquid_feature(x, mask=m) == pytest.approx(np.std(filtered_norm(x)[m], ddof=1))
    with pytest.raises(TactileDataError, match="coast mask"):
        liquid_features([RollRecord(x)], feature="coast")
    # the detrended coast feature: a quadratic in each coast phase is removed exactly, a
    # ringing is not
    from mmlearn.models.tactile.liquid import coast_feature

    tt = np.arange(200) / 24.0
    phases = ((tt % 1.0) > 0.2) & ((tt % 1.0) < 0.8)  # 0.6 s coast phases
    slow = np.outer(1 + 0.5 * tt + 0.05 * tt**2, np.ones(4))
    ring = slow + 0.01 * np.outer(np.sin(2 * np.pi * 3.5 * tt), [1, -1, 1, -1])
    assert coast_feature(slow, phases) < 0.02 * coast_feature(ring, phases)
    with pytest.raises(TactileDataError, match="no coast phase"):
        coast_feature(ring, (tt % 1.0) < 0.1)
    with pytest.raises(ValueError, match="feature"):
        liquid_features([RollRecord(x)], feature="bogus")


def test_config_rejects_coast_feature_without_coast():
    c = app.LiquidDetectionConfig(roll_profile="sine")
    with pytest.raises(ValueError, match="constant-rate"):
        app._check(c)
    app._check(app.LiquidDetectionConfig(roll_profile="sine", feature="whole"))
    with pytest.raises(ValueError, match="coast_delay"):
        app._check(app.LiquidDetectionConfig(coast_delay=float("nan")))
    assert _rc(["--coast-delay", "0.5", "--report-only", "x.jsonl"]) == 2
