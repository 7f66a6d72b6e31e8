"""The bad-input harness (tests/bad_inputs.py) over all 20 apps: every case ends in exit
status 2 with one error line; no traceback, no bad input accepted."""

import pytest

import bad_inputs


@pytest.fixture(scope="module")
def cases(tmp_path_factory):
    files = bad_inputs.make_files(tmp_path_factory.mktemp("bad_inputs"))
    return bad_inputs.build_cases(files)


def _check(outcomes):
    bad = [o for o in outcomes if o.kind != "clean"]
    assert not bad, "\n".join(f"{o.kind} {o.case.app} {o.case.what}: status {o.status}, "
                              f"{o.detail} {o.stderr.strip()[-300:]}" for o in bad[:20])


def test_bad_flag_values_of_every_app(cases):
    quick = [c for c in cases if not c.what.startswith(("meaningless", "input"))
             and "--config" not in c.argv and "--priors" not in c.argv]
    outcomes = [bad_inputs.run_case(c) for c in quick]
    s = bad_inputs.summary(outcomes)
    assert s["apps"] == 20 and s["cases"] >= 300, s
    _check(outcomes)


@pytest.mark.slow
def test_bad_files_and_meaningless_inputs(cases):
    rest = [c for c in cases if c.what.startswith(("meaningless", "input"))
            or "--config" in c.argv or "--priors" in c.argv]
    outcomes = [bad_inputs.run_case(c, limit_s=60.0) for c in rest]
    assert len(outcomes) >= 100
    _check(outcomes)


def test_the_harness_sees_a_traceback_and_an_accepted_input(monkeypatch):
    import mmlearn.apps.fit_articulation as app

    def crash(argv):
        raise KeyError("record")

    monkeypatch.setattr(app, "main", crash)
    o = bad_inputs.run_case(bad_inputs.Case("fit_articulation", [], "crash"))
    assert o.kind == "traceback" and "KeyError" in o.detail
    monkeypatch.setattr(app, "main", lambda argv: 0)
    assert bad_inputs.run_case(bad_inputs.Case("fit_articulation", [], "ok")).kind == "accepted"
    monkeypatch.setattr(app, "main", lambda argv: print("a: error: x\nb: error: y",
                                                        file=__import__("sys").stderr) or 2)
    assert bad_inputs.run_case(bad_inputs.Case("fit_articulation", [], "2")).kind == "multiline"
