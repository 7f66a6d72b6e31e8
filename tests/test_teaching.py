"""Interactive teaching (diagrams/imitation/teaching.py): the loop's logic with a scripted
robot and teacher, the command line's checks, and one real round in Drake (slow)."""

import json

import pytest

import mmlearn.diagrams.imitation.teaching as teaching
import mmlearn.diagrams.imitation.trials as trials
from mmlearn.apps import imitate


def _script(monkeypatch, outcomes):
    """The robot's rounds follow ``outcomes`` ("success", "failed", "unsure"); returns the
    calls seen."""
    seen = {"reproduce": [], "demo": []}
    it = iter(outcomes)

    def reproduce(**kw):
        o = next(it)
        seen["reproduce"].append((kw["seed"], len(kw["demonstrations"]), kw["stop_when_unsure"]))
        seen.setdefault("prior", []).append(kw["isotropic_prior"])
        return {"success": o == "success", "place_error_m": 0.01,
                "confidence": {"unsure": o == "unsure"}, "stopped_unsure": o == "unsure",
                "objects_start": {}}

    def demo(task, seed, index, situation, swap, scale):
        seen["demo"].append((index, situation, swap))
        return f"demo {index}"

    monkeypatch.setattr(trials, "reproduce_task", reproduce)
    monkeypatch.setattr(teaching, "_first_demo", lambda *a: "demo 0")
    monkeypatch.setattr(teaching, "_demo_in_situation", demo)
    return seen


def test_teacher_demonstrates_only_where_the_robot_failed_or_asked(monkeypatch):
    seen = _script(monkeypatch, ["unsure", "failed", "success", "success"])
    rec = teaching.teach_interactively(task="pick_place", seed=7, max_demos=6, swap_tables=True)
    assert rec["success"] is True and rec["demos_used"] == 3
    assert [r["outcome"] for r in rec["rounds"]] == ["unsure", "failed", "success"]
    assert rec["asked_before_failing"] == 1
    assert rec["failed_unflagged"] == 1
    # each round learns from all demonstrations so far, in a new situation; then the
    # taught robot is tested, without stopping, in batch learning's situation (seed 7)
    assert seen["reproduce"] == [(701, 1, True), (702, 2, True), (703, 3, True), (7, 3, False)]
    assert rec["test_success"] is True and rec["test"]["situation_seed"] == 7
    assert set(seen["prior"]) == {teaching.TEACHING_PRIOR} and teaching.TEACHING_PRIOR > 0
    # the teacher shows the task in the situations that went wrong
    assert seen["demo"] == [(1, 701, True), (2, 702, True)]
    json.dumps(rec)


def test_teaching_stops_at_max_demos(monkeypatch):
    seen = _script(monkeypatch, ["failed"] * 10)
    rec = teaching.teach_interactively(task="pick_place", seed=1, max_demos=2)
    assert rec["success"] is False and rec["demos_used"] == 2 and len(rec["rounds"]) == 2
    assert len(seen["demo"]) == 1


def test_first_success_needs_one_demo(monkeypatch):
    # teaching ended with a success, the final test in batch's situation failed: both told
    seen = _script(monkeypatch, ["success", "failed"])
    rec = teaching.teach_interactively(task="whiteboard", seed=2, max_demos=3,
                                       isotropic_prior=0.0)
    assert rec["success"] and rec["demos_used"] == 1 and rec["rounds"][0]["demos"] == 1
    assert rec["test_success"] is False and seen["prior"] == [0.0, 0.0]


def test_without_final_test(monkeypatch):
    seen = _script(monkeypatch, ["unsure", "success"])
    rec = teaching.teach_interactively(seed=3, final_test=False)
    assert rec["test"] is None and rec["test_success"] is None and len(seen["reproduce"]) == 2


@pytest.mark.parametrize("kw, msg", [({"task": "juggle"}, "task"), ({"max_demos": 0}, "max_demos"),
                                     ({"seed": -1}, "seed"),
                                     ({"isotropic_prior": -1.0}, "isotropic_prior")])
def test_bad_arguments(kw, msg):
    with pytest.raises(ValueError, match=msg):
        teaching.teach_interactively(**kw)


@pytest.mark.parametrize("extra", [["--demos-file", "demos.json"], ["--html-out", "x.html"]])
def test_cli_rejects_bad_combinations(extra, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "demos.json").write_text("{}")
    assert imitate.main(["--interactive", *extra]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--interactive" in err[0]


def test_cli_rejects_zero_max_demos(capsys):
    with pytest.raises(SystemExit) as e:
        imitate.main(["--interactive", "--max-demos", "0"])
    assert e.value.code == 2
    assert "--max-demos" in capsys.readouterr().err


@pytest.mark.slow
def test_one_real_round(capsys):
    """The real loop with one demonstration: it runs, and the record says what happened."""
    code = imitate.main(["--task", "obstacle", "--interactive", "--max-demos", "1",
                         "--seed", "3", "--json"])
    assert code == 0
    rec = json.loads(capsys.readouterr().out)
    assert rec["demos_used"] == 1 and len(rec["rounds"]) == 1
    r = rec["rounds"][0]
    assert r["outcome"] in teaching.OUTCOMES
    assert rec["success"] == (r["outcome"] == "success")
    c = r["confidence"]
    assert c["threshold"] > c["reference_surprise"] > 0
    # the final test ran in the situation a batch reproduction of seed 3 is tested in
    assert rec["test"]["situation_seed"] == 3 and rec["test_success"] in (True, False)
    assert rec["test"]["reach_error_m"] is not None


def test_experiment_conditions_and_report():
    from mmlearn.apps.imitation_experiments import conditions, format_table, report

    conds = conditions(["teaching"])
    assert [c[1].get("demos") for c in conds[:4]] == [1, 2, 3, 4]
    assert conds[-1][2] is teaching.teaching_trial and conds[-1][1]["swap_tables"]
    # batch from 2 demonstrations with the interactive learner, side by side
    assert conds[4][1] == {"task": "pick_place", "demos": 2, "swap_tables": True,
                           "isotropic_prior": teaching.TEACHING_PRIOR}
    lines = [{"key": f"k{i}", "spec": {"fn": "imitation.teach@2", "seed": i, "params": {},
                                       "label": f"pick_place interactive, swapped tables seed {i}"},
              "record": {"success": ok, "demos": n, "demos_used": n, "asked_before_failing": a,
                         "failed_unflagged": f, "test_success": t, "place_error_m": 0.01},
              "error": None, "wall_s": 1.0}
             for i, (ok, n, a, f, t) in enumerate([(True, 2, 1, 0, True), (True, 3, 2, 1, False),
                                                   (False, 6, 0, 5, False)])]
    res = report(lines)
    row = res["conditions"][0]
    assert row["successes"] == 2 and row["mean_demos"] == pytest.approx(11 / 3)
    assert row["asked_before_failing"] == 3 and row["failed_unflagged"] == 6
    assert row["test_successes"] == 1 and row["demos_counts"] == {"2": 1, "3": 1, "6": 1}
    assert "3.7" in format_table(res)
