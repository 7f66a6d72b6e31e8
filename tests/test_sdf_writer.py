"""The SDF writer (mmlearn.models.common.sdf_writer) and the models built with it.

Every generated model (robots, furniture, test objects, mechanisms, an exported articulation
model) is parsed by Drake and compared with what the string templates that the writer
replaced produced: ``tests/data/sdf_reference/summaries.json`` (made by
``tests/sdf_summary.py`` from those templates) holds, per model, the bodies (mass, inertia,
default pose, geometry: shape, size, pose, colour), joints (type, parent, child, frames,
axis, limits, damping), frames, actuators and force elements.
"""

import ast
import json
import math
import re
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from mmlearn.models.common.sdf_writer import (Box, Capsule, Cylinder, Mesh, SdfModel, Sphere,
                                              box_inertia, cylinder_inertia)

sys.path.insert(0, str(Path(__file__).resolve().parent))
import sdf_summary  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
REFERENCE = json.loads(sdf_summary.REFERENCE.read_text())
CASES = sdf_summary.cases()


def _diff(a, b, path=""):
    """Differences between two summaries (numbers to 1e-9 relative)."""
    if isinstance(a, dict) and isinstance(b, dict):
        if set(a) != set(b):
            return [f"{path}: keys differ: {sorted(set(a) ^ set(b))}"]
        return [d for k in a for d in _diff(a[k], b[k], f"{path}/{k}")]
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [f"{path}: {len(a)} vs {len(b)} entries"]
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in _diff(x, y, f"{path}[{i}]")]
    if isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
        if a == b or abs(a - b) <= 1e-9 * max(1.0, abs(a)):
            return []
    elif a == b:
        return []
    return [f"{path}: {a!r} vs {b!r}"]


def test_reference_covers_every_builder_object_and_mechanism():
    from mmlearn.sdf import builders, mechanisms, objects

    assert set(CASES) == set(REFERENCE)
    assert {f"shipped/{k}" for k in builders.DEFAULT_MODELS} <= set(CASES)
    assert {f"object/{k}" for k in objects.OBJECTS} <= set(CASES)
    kinds = {k.split("/")[1] for k in CASES if k.startswith("mechanism/")}
    assert set(mechanisms.KINDS) <= kinds
    assert any(k.startswith("articulation/") for k in CASES)


@pytest.mark.parametrize("name", sorted(CASES))
def test_generated_model_is_the_one_the_templates_made(name):
    text = CASES[name]()
    ET.fromstring(text.split("\n", 1)[1])  # well-formed XML
    new = json.loads(json.dumps(sdf_summary.summarize(text)))
    diffs = _diff(REFERENCE[name], new, name)
    assert not diffs, "\n".join(diffs[:20])


def test_reference_is_meaningful():
    """Spot checks that the summaries hold what the models are known to have."""
    arm = REFERENCE["shipped/arm_7dof.sdf"]
    assert arm["joints"]["q2"]["type"] == "revolute"
    assert arm["joints"]["q2"]["axis"] == [0.0, 1.0, 0.0]
    assert arm["joints"]["q2"]["lower"] == [-2.6] and arm["joints"]["q2"]["damping"] == [0.5]
    assert arm["actuators"]["q1"]["effort"] == 200.0
    assert arm["bodies"]["x4"]["mass"] == 2.0
    cab = REFERENCE["shipped/cabinet.sdf"]
    assert cab["joints"]["drawer_slide"]["type"] == "prismatic"
    assert cab["joints"]["left_hinge"]["upper"] == [pytest.approx(math.radians(110), 1e-5)]
    assert {g["role"] for g in cab["bodies"]["drawer"]["geometries"]} == {"visual",
                                                                           "collision"}
    dish = REFERENCE["mechanism/dishwasher/0"]["force_elements"]
    assert [f["type"] for f in dish] == ["RevoluteSpring"]
    car = REFERENCE["object/car_door"]["joints"]["window_guide"]
    assert car["X_CM"][:3] == [0.0, 1.9, 0.0]
    art = REFERENCE["articulation/cabinet"]["joints"]
    assert {k: v["type"] for k, v in art.items()} == {
        "cabinet_weld": "weld", "cabinet__drawer": "prismatic", "cabinet__door": "revolute",
        "door__door_knob": "weld", "cabinet__shutter": "weld", "loose": "quaternion_floating"}


def test_shipped_files_are_the_writer_output():
    from mmlearn.sdf import builders, model_path

    for fname, build in builders.DEFAULT_MODELS.items():
        assert model_path(fname).read_text() == build(), fname


_TAGS = re.compile(r"</?(sdf|model|link|joint|visual|collision|inertial|inertia|pose|frame|"
                   r"geometry|box|cylinder|material|axis|limit|dynamics)\b")


def _templates(src: str) -> list:
    """String constants (f-string parts included) with SDFormat tags; docstrings left out."""
    tree = ast.parse(src)
    docs = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
                docs.add(id(first.value))
    return [n.value for n in ast.walk(tree) if isinstance(n, ast.Constant)
            and isinstance(n.value, str) and id(n) not in docs and _TAGS.search(n.value)]


def test_no_sdf_string_templates_left():
    """The four places that wrote SDFormat as strings now all use the writer."""
    for rel in ("sdf/builders.py", "sdf/objects.py", "sdf/mechanisms.py",
                "models/articulation/io.py"):
        src = (REPO / rel).read_text()
        assert "sdf_writer import" in src, rel
        assert not _templates(src), (rel, _templates(src)[:3])
    # the check sees a template, but not a docstring
    assert _templates('def f(x):\n    "a <link>"\n    return f"<link name=\'{x}\'>"\n') == [
        "<link name='"]


def test_writer_imports_no_drake_so_models_may_use_it():
    code = ("import sys, mmlearn.models.common.sdf_writer, mmlearn.models.articulation.io; "
            "print(sorted(m for m in sys.modules if m.startswith('pydrake')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert "pydrake.systems" not in out
    assert "sdf_writer" not in out  # (a sanity check of the command)
    src = (REPO / "models" / "common" / "sdf_writer.py").read_text()
    assert "pydrake" not in src


# ------------------------------------------------------------------------- the writer
def _parse(text):
    from pydrake.multibody.parsing import Parser
    from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
    from pydrake.systems.framework import DiagramBuilder

    plant, sg = AddMultibodyPlantSceneGraph(DiagramBuilder(), 0.001)
    (mi,) = Parser(plant).AddModelsFromString(text, "sdf")
    plant.Finalize()
    return plant, sg, mi


def test_every_feature_parses_in_drake(tmp_path):
    (tmp_path / "tet.obj").write_text(
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n")
    m = SdfModel("all <parts> & \"quotes\"", pose=(1, 2, 0, 0, 0, 0.5))
    a = m.link("a")
    a.inertial(2.0, box_inertia(2.0, (0.1, 0.2, 0.3)), pose=(0, 0, 0.15))
    a.visual("a_capsule", Capsule(0.05, 0.2), pose=(0, 0, 0.1, 0.3, 0, 0), color=(1, 0, 0, 1))
    coll = a.collision("a_sphere", Sphere(0.1))
    props = m.element(coll, "drake:proximity_properties")
    m.element(props, "drake:compliant_hydroelastic")
    m.element(props, "drake:hydroelastic_modulus", 5e7)
    m.element(props, "drake:mesh_resolution_hint", 0.05)
    b = m.link("b", pose=(0, 0, 0.5))
    b.inertial(1.0, cylinder_inertia(1.0, 0.05, 0.3) + (0.0001, 0, 0))
    b.visual("b_mesh", Mesh((tmp_path / "tet.obj").as_uri(), scale=(0.1, 0.1, 0.1)))
    b.collision("b_cylinder", Cylinder(0.05, 0.3))
    c = m.link("c", pose=(0, 0, 0.2), relative_to="b")
    c.inertial(0.5, (0.01, 0.01, 0.01))
    c.visual("c_box", Box((0.1, 0.1, 0.1)))
    d = m.link("d", pose=(0, 0, 1.0))
    d.inertial(0.5, (0.01, 0.01, 0.01))
    m.joint("ball", "ball", "a", "b")
    m.joint("hinge", "revolute", "b", "c", pose=(0, 0, 0.05), axis=(0, 1, 0), lower=-1,
            upper=1.5, effort=5, velocity=2, damping=0.1, friction=0.7)
    m.joint("spin", "continuous", "c", "d", axis=(0, 0, 1))
    m.joint("weld", "fixed", "world", "a")
    m.frame("tip", attached_to="d", pose=(0.1, 0, 0, 0, 0, math.pi / 2))
    m.comment(a.element, "a comment -- with dashes")
    text = m.to_string()
    assert "&lt;parts&gt; &amp;" in text and 'xmlns:drake="http://drake.mit.edu"' in text
    plant, sg, mi = _parse(text)
    assert plant.GetModelInstanceName(mi) == 'all <parts> & "quotes"'
    types = {plant.get_joint(j).name(): plant.get_joint(j).type_name()
             for j in plant.GetJointIndices(mi)}
    assert types == {"ball": "ball_rpy", "hinge": "revolute", "spin": "revolute",
                     "weld": "weld"}
    hinge = plant.GetJointByName("hinge", mi)
    assert hinge.position_upper_limits()[0] == 1.5 and hinge.default_damping() == 0.1
    assert plant.GetJointByName("spin", mi).position_upper_limits()[0] == math.inf
    assert plant.get_joint_actuator(plant.GetJointActuatorIndices(mi)[0]).effort_limit() == 5
    assert plant.GetBodyByName("b", mi).default_mass() == 1.0
    ctx = plant.CreateDefaultContext()
    X_WC = plant.GetBodyByName("c", mi).EvalPoseInWorld(ctx)
    assert X_WC.translation() == pytest.approx([1, 2, 0.7])
    X_WT = plant.GetFrameByName("tip", mi).CalcPoseInWorld(ctx)
    assert X_WT.translation() == pytest.approx([1 + 0.1 * math.cos(0.5),
                                                2 + 0.1 * math.sin(0.5), 1.0])
    inspector = sg.model_inspector()
    shapes = sorted(type(inspector.GetShape(g)).__name__
                    for g in inspector.GetAllGeometryIds())
    assert shapes == ["Box", "Capsule", "Cylinder", "Mesh", "Sphere"]
    sphere = [g for g in inspector.GetAllGeometryIds()
              if type(inspector.GetShape(g)).__name__ == "Sphere"][0]
    props = inspector.GetProximityProperties(sphere)
    assert props.GetProperty("hydroelastic", "hydroelastic_modulus") == 5e7


def test_numbers_are_formatted_consistently():
    m = SdfModel("n", digits=4)
    assert m.num(1 / 3) == "0.3333" and m.num(-0.0) == "0" and m.num(2) == "2"
    assert m.num(1.23456e-7) == "1.235e-07"
    assert m.text((0.5, -1e-20, 3)) == "0.5 -1e-20 3"
    assert m.text(True) == "true" and m.text("abc") == "abc"
    assert SdfModel("n").num(math.pi) == "3.14159"
    assert SdfModel("n", digits=9).num(math.pi) == "3.14159265"
    for bad in (math.nan, math.inf):
        with pytest.raises(ValueError, match="finite"):
            m.num(bad)


def test_writer_rejects_malformed_input():
    m = SdfModel("x")
    with pytest.raises(ValueError, match="6 finite numbers"):
        SdfModel("x", pose=(0, 0, 0))
    with pytest.raises(ValueError, match="joint type"):
        m.joint("j", "planar", "world", "a")
    with pytest.raises(ValueError, match="needs an axis"):
        m.joint("j", "revolute", "world", "a", lower=0, upper=1)
    with pytest.raises(ValueError, match="fixed joint"):
        m.joint("j", "fixed", "world", "a", axis=(0, 0, 1))
    with pytest.raises(ValueError, match="ball joint"):
        m.joint("j", "ball", "world", "a", axis=(0, 0, 1))
    with pytest.raises(ValueError, match="pose"):
        m.link("a", pose=(0, 0))
    with pytest.raises(ValueError, match="3 or 6"):
        m.link("a").inertial(1.0, (1, 1))
    with pytest.raises(ValueError, match="r g b a"):
        m.link("b").visual("v", Box((1, 1, 1)), color=(1, 0, 0))


def test_output_order_and_text():
    m = SdfModel("o", static=True)
    m.frame("f", attached_to="a")
    m.joint("w", "fixed", "world", "a")
    m.link("a")
    text = m.to_string()
    assert text.startswith("<?xml version='1.0'?>\n<sdf version=\"1.9\">\n")
    assert text.endswith("</sdf>\n")
    assert text == m.to_string()  # writing twice gives the same text
    tags = [e.tag for e in ET.fromstring(text.split("\n", 1)[1]).find("model")]
    assert tags == ["static", "link", "joint", "frame"]


def test_module_example_parses():
    import mmlearn.models.common.sdf_writer as w

    doc = w.__doc__
    code = doc[doc.index("Example::") + len("Example::"):doc.index("Supported:")]
    ns = dict(vars(w))
    exec(compile("\n".join(line[4:] for line in code.splitlines()), "example", "exec"), ns)
    plant, _, mi = _parse(ns["text"])
    assert plant.GetJointByName("hinge", mi).position_upper_limits()[0] == 1.5
    assert plant.HasFrameNamed("lid_handle", mi)
