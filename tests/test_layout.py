"""The package layout: one subpackage per capability, imports in one direction, short modules."""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
CAPABILITIES = ("common", "articulation", "body_schema", "perception", "tactile", "imitation")
TOPS = ("models", "systems", "diagrams", "apps", "sdf")
# who may import whom: apps -> diagrams -> systems -> models; diagrams, systems -> sdf -> models
ALLOWED = {
    "models": {"models"},
    "systems": {"systems", "models", "sdf"},
    "sdf": {"sdf", "models"},
    "diagrams": {"diagrams", "systems", "models", "sdf"},
    "apps": {"apps", "diagrams", "systems", "models", "sdf"},
}
MAX_LINES = 900


def _modules(top: str):
    return sorted(p for p in (REPO / top).rglob("*.py"))


def _imports(path: Path):
    """(line, imported dotted module) of every import of an mmlearn module in ``path``."""
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            yield node.lineno, node.module
            if node.module in ("mmlearn", *(f"mmlearn.{t}" for t in TOPS)):
                for alias in node.names:
                    yield node.lineno, f"{node.module}.{alias.name}"
        elif isinstance(node, ast.Import):
            for alias in node.names:
                yield node.lineno, alias.name


def test_imports_point_one_way():
    bad = []
    for top in TOPS:
        for path in _modules(top):
            for line, mod in _imports(path):
                parts = mod.split(".")
                if parts[0] == "pydrake" and top == "models" and mod.startswith("pydrake.systems"):
                    bad.append(f"{path.relative_to(REPO)}:{line} imports {mod}")
                if parts[0] != "mmlearn" or len(parts) < 2 or parts[1] not in TOPS:
                    continue
                if parts[1] not in ALLOWED[top]:
                    bad.append(f"{path.relative_to(REPO)}:{line} imports {mod}")
    assert not bad, "imports against the layers:\n" + "\n".join(bad)


def test_no_app_imports_another_app():
    bad = []
    for path in (REPO / "apps").glob("*.py"):
        for line, mod in _imports(path):
            parts = mod.split(".")
            if parts[:2] == ["mmlearn", "apps"] and len(parts) > 2 and parts[2] not in (
                    "common", "examples"):
                bad.append(f"{path.relative_to(REPO)}:{line} imports {mod}")
    assert not bad, "\n".join(bad)


def test_capability_subpackages_and_short_modules():
    models_top = [p.name for p in (REPO / "models").glob("*.py") if p.name != "__init__.py"]
    assert len(models_top) <= 8, models_top
    for top in ("models", "systems", "diagrams"):
        subs = [c for c in CAPABILITIES if (REPO / top / c / "__init__.py").is_file()]
        assert len(subs) >= (4 if top == "models" else 3), (top, subs)
    long = [f"{p.relative_to(REPO)}: {n}" for top in TOPS for p in _modules(top)
            if (n := len(p.read_text().splitlines())) > MAX_LINES]
    assert not long, "modules over %d lines: %s" % (MAX_LINES, long)


def test_trials_are_never_named_by_strings():
    import re

    pattern = re.compile(r"""["']mmlearn\.[\w.]+:\w+["']""")
    hits = [f"{p.relative_to(REPO)}:{i}" for top in (*TOPS, "benchmarks")
            for p in (REPO / top).rglob("*.py")
            for i, line in enumerate(p.read_text().splitlines(), 1) if pattern.search(line)]
    assert not hits, hits


@pytest.mark.parametrize("top", ["models", "systems", "diagrams"])
def test_every_public_name_resolves_from_the_top_and_its_capability(top):
    pkg = importlib.import_module(f"mmlearn.{top}")
    assert len(pkg.__all__) == len(set(pkg.__all__))
    for cap in CAPABILITIES:
        if not (REPO / top / cap / "__init__.py").is_file():
            continue
        sub = importlib.import_module(f"mmlearn.{top}.{cap}")
        for name in sub.__all__:
            assert getattr(sub, name) is not None, (cap, name)
    for name in pkg.__all__:
        value = getattr(pkg, name)
        assert value is not None, name
    with pytest.raises(AttributeError, match="no attribute 'NoSuchName'"):
        getattr(pkg, "NoSuchName")


def test_systems_named_in_the_design_are_importable_from_the_top():
    from mmlearn.systems import ArticulationEstimator, MarkerSensor  # noqa: F401
    from mmlearn.models import RevoluteModel, select_link_model  # noqa: F401
