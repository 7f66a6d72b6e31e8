"""The Sphinx documentation: it builds without a warning and documents every system."""

import importlib.util
import inspect
import re
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"


def _ext():
    spec = importlib.util.spec_from_file_location("mmlearn_docs", DOCS / "_ext" / "mmlearn_docs.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _system_blocks():
    """(class name, YAML text) of every ``.. pydrake_system::`` block in systems/."""
    import mmlearn.systems as systems
    out = []
    for name in systems.__all__:
        obj = getattr(systems, name)
        doc = inspect.getdoc(obj) or "" if inspect.isclass(obj) else ""
        m = re.search(r"\.\. pydrake_system::\n\n((?:[ \t]+.*\n?|\n)+)", doc)
        if m:
            out.append((name, inspect.cleandoc(m.group(1))))
    return out


def test_every_leaf_system_documents_its_ports():
    from pydrake.systems.framework import LeafSystem
    import mmlearn.systems as systems
    leaf = {n for n in systems.__all__
            if inspect.isclass(getattr(systems, n)) and issubclass(getattr(systems, n), LeafSystem)}
    blocks = dict(_system_blocks())
    assert leaf and leaf <= set(blocks), sorted(leaf - set(blocks))
    ext = _ext()
    for name, text in blocks.items():
        spec = yaml.safe_load(text)
        assert spec["name"] == name
        drawing = ext.port_diagram(spec["name"], spec.get("input_ports") or [],
                                   spec.get("output_ports") or [])
        for port in (spec.get("input_ports") or []) + (spec.get("output_ports") or []):
            assert str(port) in drawing


def test_port_blocks_name_each_ports_accessor():
    from mmlearn.systems import CameraMarkerSensor, MarkerSensor, WristForceSensor
    ext = _ext()
    assert ext._system_class("MarkerSensor", None) is MarkerSensor
    assert ext.port_getters(MarkerSensor, ["body_poses", "query_object (optional)"],
                            ["observations", "no_such_port"]) == (
        ["get_body_poses_input_port", "get_query_object_input_port",
         "get_observations_output_port"], ['GetOutputPort("no_such_port")'])
    # a frame suffix and an index are not in the accessor's name
    assert ext.port_getters(WristForceSensor, [], ["force_W"])[0] == ["get_force_output_port"]
    assert ext.port_getters(CameraMarkerSensor, ["color_image_0", "...", "color_image_{k-1}"],
                            [])[0] == ["get_color_image_input_port"]
    assert ext.port_getters(None, ["a"], ["b"]) == ([], ['GetInputPort("a")', 'GetOutputPort("b")'])


def test_port_diagram_puts_inputs_left_and_outputs_right():
    drawing = _ext().port_diagram("Sensor", ["a", "bb"], ["out"]).splitlines()
    assert drawing[1].index("a ->") < drawing[1].index("Sensor") < drawing[1].index("-> out")
    assert drawing[2].strip().startswith("bb ->") and "->" not in drawing[2].split("|")[-1]


@pytest.mark.slow
def test_docs_build_without_warnings_and_list_every_system(tmp_path):
    pytest.importorskip("sphinx")
    pytest.importorskip("myst_parser")
    out = tmp_path / "html"
    r = subprocess.run([sys.executable, "-m", "sphinx", "-W", "-q", "-b", "html", str(DOCS),
                        str(out)], capture_output=True, text=True, timeout=900, cwd=ROOT)
    assert r.returncode == 0, r.stderr[-3000:]
    import mmlearn.systems as systems
    html = (out / "api" / "systems.html").read_text()
    documented = set(re.findall(r'id="mmlearn\.systems\.\w+\.(\w+)"', html))
    classes = [n for n in systems.__all__ if inspect.isclass(getattr(systems, n))]
    assert classes and not [n for n in classes if n not in documented]
    assert html.count("pydrake-system") >= 20
    for page in ("getting_started", "conventions", "sweeps", "data_formats", "articulation",
                 "body_schema", "perception", "tactile", "imitation"):
        assert (out / f"{page}.html").is_file(), page


def test_results_tables_are_generated_from_the_results_files():
    """The committed tables are exactly what docs/make_tables.py makes of docs/results/."""
    spec = importlib.util.spec_from_file_location("make_tables", DOCS / "make_tables.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    assert mod.main(["--check"]) == 0, "run: python docs/make_tables.py"
    for page in mod.PAGES:
        text = (DOCS / f"{page}.md").read_text()
        assert f"results/tables/{page}.md" in text, page



def _make_tables_in(tmp_path, monkeypatch):
    """docs/make_tables.py working on a copy of docs/results/ and README.md in tmp_path."""
    import shutil
    spec = importlib.util.spec_from_file_location("make_tables", DOCS / "make_tables.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    results = tmp_path / "docs" / "results"
    shutil.copytree(DOCS / "results", results)
    shutil.copy(ROOT / "README.md", tmp_path / "README.md")
    monkeypatch.setattr(mod, "ROOT", tmp_path)
    monkeypatch.setattr(mod, "RESULTS", results)
    monkeypatch.setattr(mod, "TABLES", results / "tables")
    return mod, results


def test_a_changed_results_file_makes_the_tables_stale(tmp_path, monkeypatch, capsys):
    import json
    mod, results = _make_tables_in(tmp_path, monkeypatch)
    assert mod.main(["--check"]) == 0
    lasa = json.loads((results / "lasa.json").read_text())
    lasa["shapes"][0]["rmse_mm"] += 1.0
    (results / "lasa.json").write_text(json.dumps(lasa))
    assert mod.main(["--check"]) == 1
    assert "tables/imitation.md" in capsys.readouterr().err
    assert mod.main([]) == 0 and mod.main(["--check"]) == 0


def test_the_readme_figures_are_generated_and_checked(tmp_path, monkeypatch, capsys):
    """The README's capability and beyond-the-thesis tables come from the results files:
    a changed file makes --check fail naming README.md; regenerating writes the new figure."""
    import json
    mod, results = _make_tables_in(tmp_path, monkeypatch)
    readme = (tmp_path / "README.md").read_text()
    for name in mod.README_BLOCKS:
        assert f"<!-- generated:{name} -->" in readme and f"<!-- /generated:{name} -->" in readme
    for page, blocks in mod.PAGE_BLOCKS.items():
        text = (ROOT / page).read_text()
        assert all(f"<!-- generated:{name} -->" in text for name in blocks), page
    d = json.loads((results / "structure_prior.json").read_text())
    right = sum(r["right_with_prior"] for r in d["rows"])
    d["rows"][0]["right_with_prior"] -= 1
    (results / "structure_prior.json").write_text(json.dumps(d))
    assert mod.main(["--check"]) == 1
    assert "README.md" in capsys.readouterr().err
    assert mod.main([]) == 0 and mod.main(["--check"]) == 0
    assert f"right structure {right - 1}/" in (tmp_path / "README.md").read_text()
    (tmp_path / "README.md").write_text(readme + "<!-- generated:nosuch -->\n<!-- /generated:nosuch -->\n")
    assert mod.main(["--check"]) == 2
    assert mod.resolve(["operate_trials", "teaching.json"]) == ["operate_trials.json", "teaching.json"]
    with pytest.raises(ValueError, match="nosuch"):
        mod.resolve(["nosuch"])


def test_a_changed_results_file_changes_a_page_block(tmp_path, monkeypatch, capsys):
    """docs/operating_accuracy.md's split table comes from radius_error_causes.json: a changed
    file makes --check fail naming the page; regenerating writes the new figure into it."""
    import json
    import shutil
    mod, results = _make_tables_in(tmp_path, monkeypatch)
    page = tmp_path / "docs" / "operating_accuracy.md"
    shutil.copy(DOCS / "operating_accuracy.md", page)
    assert mod.main(["--check"]) == 0
    d = json.loads((results / "radius_error_causes.json").read_text())
    row = next(r for r in d["rows"] if "error_m" in r)
    assert "+0.432" not in page.read_text()
    row["error_m"], row["radius_m"] = 0.4321, row["true_radius_m"] + 0.4321
    (results / "radius_error_causes.json").write_text(json.dumps(d))
    assert mod.main(["--check"]) == 1
    assert "docs/operating_accuracy.md" in capsys.readouterr().err
    assert mod.main([]) == 0 and mod.main(["--check"]) == 0
    assert "+0.432" in page.read_text()
    (results / "radius_error_causes.json").unlink()
    assert mod.main([]) == 0
    assert "no `docs/results/radius_error_causes.json`" in page.read_text()


def test_teaching_per_seed_comparison_counts_from_the_runs():
    """Batch's fewest successful demonstrations per seed against interactive teaching's."""
    spec = importlib.util.spec_from_file_location("make_tables", DOCS / "make_tables.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)

    def batch(seed, n, ok, prior=None):
        params = {"demos": n} if prior is None else {"demos": n, "isotropic_prior": prior}
        return {"fn": "imitation.reproduce@1", "params": params, "seed": seed, "success": ok}

    def teach(seed, used, ok=True):
        return {"fn": "imitation.teach@2", "params": {}, "seed": seed, "success": ok,
                "demos_used": used}
    runs = [batch(1, 1, False), batch(1, 2, True), batch(1, 3, True), teach(1, 2),
            batch(2, 1, False), batch(2, 2, False), batch(2, 3, True), teach(2, 4),
            batch(3, 2, False), batch(3, 2, True, prior=1.0), teach(3, 3),
            batch(4, 4, True), teach(4, 2, ok=False)]
    c = mod.teaching_per_seed(runs)
    assert c["batch_fewest"] == {1: 2, 2: 3, 3: None, 4: 4}
    assert c["no_more"] == 1 and c["batch_never"] == [3]
    assert c["mean_batch_fewest"] == pytest.approx(3.0)


def test_the_peer_table_says_when_the_peer_was_absent():
    """The ripl-articulation comparison still shows mmlearn's side without the peer."""
    spec = importlib.util.spec_from_file_location("make_tables", DOCS / "make_tables.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    side = {"tracks": 10, "right": 9, "axis_err_mean_deg": 1.25, "axis_err_max_deg": 3.5,
            "cpu_ms_median": 17.0}
    doc = {"mmlearn": {"door": side}, "ripl": None, "ripl_skipped": "no --peer-python given"}
    text = mod.ENGINEERING.peer_ripl(lambda name: doc, lambda name: "CMD")
    assert "| door | 9/10 | 1.2 / 3.5 | 17.0 | - | - | - |" in text
    assert "no --peer-python given" in text
    assert "peer_ripl" in mod.ENGINEERING.peer_ripl(lambda name: None, lambda name: "CMD")


def test_articulation_page_model_snippet_runs(capsys):
    """The articulation page's model example (no diagram) runs and finds the door revolute."""
    text = (DOCS / "articulation.md").read_text()
    code = re.search(r"## Model API.*?```python\n(.*?)```", text, re.S).group(1)
    ns: dict = {}
    exec(compile(code, "articulation.md", "exec"), ns)
    assert ns["sel"].selected == "revolute"
    assert abs(ns["sel"].best.summary()["params"]["radius_m"] - 0.4) < 0.03
    assert ns["obj"].summary()["edges"][0]["model"] == "revolute"


@pytest.mark.slow
def test_articulation_page_system_snippet_learns_the_door(tmp_path):
    """The articulation page's MarkerSensor + ArticulationEstimator program, as a user runs it."""
    text = (DOCS / "articulation.md").read_text()
    code = re.search(r"## Systems.*?```python\n(.*?)```", text, re.S).group(1)
    script = tmp_path / "door.py"
    script.write_text(code.replace("print(model.summary())", "print(repr(model.summary()))"))
    r = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True,
                       text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    summary = eval(r.stdout.strip().splitlines()[-1], {"inf": float("inf")})
    edge = summary["edges"][0]
    assert edge["model"] == "revolute"
    assert abs(edge["params"]["radius_m"] - 0.34) < 0.05


#: a measured figure typed into a page: a number with a unit, a ratio, "n of m", "n/m"
_TYPED_FIGURE = re.compile(r"(?<![\w.])\d+(?:\.\d+)?(?:e-?\d+)?\s?"
                           r"(?:ms|us|s|%|x|deg|mm|cm|m|N|Hz)(?![\w])"
                           r"|\b\d+ of \d+\b|(?<![\w.])\d+/\d+(?![\w./])")
#: the lists of alternatives measured and not taken: they are not in the code any more, so
#: their figures could not be re-run; they state their reasons without figures
_NOT_TAKEN = re.compile(r"^(Measured and \*?not\*? taken|Looked at and left)\b")


def _not_taken_lines(text: str) -> list[tuple[int, str]]:
    """(line number, line) of every "Measured and not taken" / "Looked at and left" paragraph
    and the list that follows it (up to the next paragraph that is not a list item), outside
    generated blocks."""
    text = re.sub(r"<!-- generated:(\w+) -->.*?<!-- /generated:\1 -->",
                  lambda m: "\n" * m.group(0).count("\n"), text, flags=re.S)
    lines = text.splitlines()
    out, i = [], 0
    while i < len(lines):
        if not _NOT_TAKEN.match(lines[i]):
            i += 1
            continue
        j = i
        while j < len(lines) and lines[j].strip():  # the paragraph itself
            out.append((j + 1, lines[j]))
            j += 1
        while j < len(lines):  # the list after it, blank lines between its items
            line = lines[j]
            if line.strip() and not (line.startswith("- ") or line.startswith("  ")):
                break
            out.append((j + 1, line))
            j += 1
        i = j
    return out


def test_the_not_taken_lists_carry_no_typed_figures():
    """What was measured and not taken is said with its reason, not with one-off figures
    (those alternatives are not in the code, so nothing re-runs them); figures a user can
    re-run come from results files (generated blocks)."""
    pages = [ROOT / "README.md", *sorted(DOCS.glob("*.md"))]
    found = {p.name: _not_taken_lines(p.read_text()) for p in pages}
    assert sum(map(len, found.values())) >= 20, "the not-taken lists were not found"
    typed = [f"{name}:{n}: {line.strip()}" for name, lines in found.items()
             for n, line in lines if _TYPED_FIGURE.search(line)]
    assert not typed, "typed figures in a measured-and-not-taken list:\n" + "\n".join(typed)


def test_the_typed_figure_rule_catches_figures():
    text = ("Intro.\n\nMeasured and not taken:\n\n- a pass (0.56 vs 0.51 ms per call);\n"
            "- another: 2.3x slower,\n  found in 3 of 5 frames.\n\nAfter the list: 12 ms.\n")
    lines = _not_taken_lines(text)
    assert [n for n, line in lines if _TYPED_FIGURE.search(line)] == [5, 6, 7]
    assert all("After the list" not in line for _, line in lines)
    for ok in ("every 10th sample", "seed 1", "`front_max_tilt_deg: 90`", "Eq. 5.3", "x4"):
        assert not _TYPED_FIGURE.search(ok), ok
    for bad in ("9/10", "1.4 s", "5 %", "1e-13 m", "0.445 m", "7-8 cm"):
        assert _TYPED_FIGURE.search(bad), bad


def test_the_detector_ablation_table_comes_from_its_results_file(tmp_path, monkeypatch, capsys):
    """docs/perception.md's deviation table and vertical-plane line come from
    detector_ablations.json: a changed file makes --check fail naming the page."""
    import json
    import shutil
    mod, results = _make_tables_in(tmp_path, monkeypatch)
    page = tmp_path / "docs" / "perception.md"
    shutil.copy(DOCS / "perception.md", page)
    assert mod.main(["--check"]) == 0
    d = json.loads((results / "detector_ablations.json").read_text())
    v = d["variants"]["no_reveals"]
    v["closed_found"] = v["closed_frames"] - 1
    (results / "detector_ablations.json").write_text(json.dumps(d))
    assert mod.main(["--check"]) == 1
    assert "docs/perception.md" in capsys.readouterr().err
    assert mod.main([]) == 0
    assert f"| {v['closed_frames'] - 1}/{v['closed_frames']} |" in page.read_text()
    assert "detector_ablations.json" in mod.COMMANDS and "detector_ablations" in mod.VOLATILE


def test_every_results_file_is_registered_with_its_command():
    """Each results file under docs/results/ has the command that makes it (COMMANDS), and
    every registered file is committed: a figure cannot come from a file nobody can re-make."""
    spec = importlib.util.spec_from_file_location("make_tables", DOCS / "make_tables.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    files = {p.name for p in (DOCS / "results").glob("*.json")}
    assert not files - set(mod.COMMANDS), "results files without a command"
    assert not set(mod.COMMANDS) - files, "registered results files not committed"
    for name, cmd in mod.COMMANDS.items():
        argv = cmd.split()
        assert argv[0] == "python" and len(argv) > 1, name
        if "--json" in argv and argv.index("--json") + 1 < len(argv) and \
                argv[argv.index("--json") + 1].endswith(".json"):
            assert argv[argv.index("--json") + 1] == f"docs/results/{name}", name


@pytest.mark.slow
def test_the_ablation_benchmark_runs_on_recorded_frames():
    """benchmarks/bench_detector_ablations.py on the two recorded kitchen frames with two
    configurations: one JSON document, both fronts found by default."""
    import json
    script = ROOT / "benchmarks" / "bench_detector_ablations.py"
    out = subprocess.run([sys.executable, str(script), "--frames-dir",
                          str(ROOT / "tests" / "data" / "front_frames"), "--variants",
                          "default,no_layers", "--json"], capture_output=True, text=True,
                         timeout=300, check=True).stdout
    v = json.loads(out)["variants"]
    assert set(v) == {"default", "no_layers"}
    assert v["default"]["frames"] == 2 and v["default"]["found"] == 2
    assert v["default"]["same_as_default"] == 2 and v["default"]["lost"] == []
    assert v["no_layers"]["fields"] == {"layer_planes": 0}
    bad = subprocess.run([sys.executable, str(script), "--variants", "nosuch"],
                         capture_output=True, text=True, timeout=120)
    assert bad.returncode == 2 and "nosuch" in bad.stderr


@pytest.mark.slow
def test_the_camera_marker_benchmark_writes_the_arm_errors(tmp_path):
    """bench_camera_marker_sensor.py --arm writes its per-part errors to --json FILE (the
    body-schema page's camera line is made from them); --json without a file is refused."""
    import json
    script = ROOT / "benchmarks" / "bench_camera_marker_sensor.py"
    out = tmp_path / "arm.json"
    subprocess.run([sys.executable, str(script), "--arm", "2dof", "--poses", "2", "--width",
                    "640", "--json", str(out)], capture_output=True, text=True, timeout=300,
                   check=True)
    d = json.loads(out.read_text())
    assert d["arm"] == "2dof" and d["poses"] == 2 and (d["width"], d["height"]) == (640, 480)
    assert len(d["parts"]) == 4 and all(0 <= p["visible"] <= 1 for p in d["parts"])
    bad = subprocess.run([sys.executable, str(script), "--arm", "2dof", "--json"],
                         capture_output=True, text=True, timeout=120)
    assert bad.returncode == 2 and "--json" in bad.stderr
