"""The quick tier (``pytest -m "not slow"``) reaches every module of the package.

Static: each test file is parsed; a module counts as reached when a test that is not marked
``slow`` (or a module-level import, fixture or helper of a file that has such a test) imports
it, imports a public name it defines (``from mmlearn.systems import MarkerSensor`` counts for
the module that defines ``MarkerSensor``) or names it in a string (``python -m
mmlearn.apps.<name>``). Every module of models/, systems/, diagrams/, apps/ and sdf/ must be
reached.
"""

from __future__ import annotations

import ast
import importlib
import pkgutil
import re
from pathlib import Path

TESTS = Path(__file__).resolve().parent
PACKAGES = ("mmlearn.models", "mmlearn.systems", "mmlearn.diagrams", "mmlearn.apps",
            "mmlearn.sdf")
_NAME = re.compile(r"\bmmlearn(?:\.\w+)+")


def package_modules() -> set[str]:
    """Every module (not package) under PACKAGES."""
    out = set()
    for pkg in PACKAGES:
        mod = importlib.import_module(pkg)
        for info in pkgutil.walk_packages(mod.__path__, prefix=f"{pkg}."):
            if not info.ispkg:
                out.add(info.name)
    return out


def _is_slow_mark(node: ast.expr) -> bool:
    """``pytest.mark.slow`` (also inside a list, or called)."""
    if isinstance(node, (ast.List, ast.Tuple)):
        return any(_is_slow_mark(e) for e in node.elts)
    if isinstance(node, ast.Call):
        node = node.func
    return isinstance(node, ast.Attribute) and node.attr == "slow"


def _file_is_slow(tree: ast.Module) -> bool:
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(
                isinstance(t, ast.Name) and t.id == "pytestmark" for t in node.targets):
            return _is_slow_mark(node.value)
    return False


def _quick_parts(tree: ast.Module):
    """The top-level statements and functions whose references count: everything except
    the tests marked slow (and everything is slow in a file marked slow). Returns None
    when the file has no quick test."""
    if _file_is_slow(tree):
        return None
    parts, quick_tests = [], 0
    for node in tree.body:
        defs = [node]
        if isinstance(node, ast.ClassDef) and node.name.startswith("Test"):
            if any(_is_slow_mark(d) for d in node.decorator_list):
                continue
            defs = node.body
        for d in defs:
            if isinstance(d, (ast.FunctionDef, ast.AsyncFunctionDef)) and \
                    d.name.startswith("test"):
                if any(_is_slow_mark(m) for m in d.decorator_list):
                    continue
                quick_tests += 1
            parts.append(d)
    return parts if quick_tests else None


def _resolve(module: str, name: str) -> str | None:
    """The module that defines ``name`` imported from package or module ``module``."""
    try:
        mod = importlib.import_module(module)
    except ImportError:
        return None
    try:
        return importlib.import_module(f"{module}.{name}").__name__
    except ImportError:
        pass
    for sub, names in getattr(mod, "_EXPORTS", {}).items():
        if name in names:
            return _resolve(f"{module}.{sub}", name) or f"{module}.{sub}"
    defined_in = getattr(getattr(mod, name, None), "__module__", None) or ""
    return defined_in if defined_in.startswith("mmlearn.") else module


def referenced_modules(path: Path) -> set[str]:
    """The mmlearn modules the quick tests of test file ``path`` reach (see the docstring)."""
    tree = ast.parse(path.read_text(), str(path))
    parts = _quick_parts(tree) if path.name.startswith("test_") else tree.body
    out = set()
    for part in parts or ():
        for node in ast.walk(part):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("mmlearn"):
                out.add(node.module)
                out.update(filter(None, (_resolve(node.module, a.name) for a in node.names)))
            elif isinstance(node, ast.Import):
                out.update(a.name for a in node.names if a.name.startswith("mmlearn"))
            elif isinstance(node, ast.Constant) and isinstance(node.value, str):
                out.update(_NAME.findall(node.value))
    return out


def quick_reach() -> set[str]:
    out = set()
    for path in sorted(TESTS.glob("*.py")):
        out |= referenced_modules(path)
    return out


def test_every_module_is_reached_by_a_quick_test():
    missing = sorted(package_modules() - quick_reach())
    assert not missing, ("modules no quick test imports (add a quick test, or move a test "
                         "out of the slow tier): " + ", ".join(missing))


def test_the_check_sees_slow_marks(tmp_path):
    f = tmp_path / "test_x.py"
    f.write_text("import pytest\nfrom mmlearn.models.common import se3\n\n"
                 "@pytest.mark.slow\ndef test_a():\n    from mmlearn.sdf import builders\n\n"
                 "def test_b():\n    'python -m mmlearn.apps.open_cabinet'\n")
    assert referenced_modules(f) == {"mmlearn.models.common", "mmlearn.models.common.se3",
                                     "mmlearn.apps.open_cabinet"}
    f.write_text("import pytest\npytestmark = pytest.mark.slow\n"
                 "from mmlearn.models.common import se3\n\ndef test_a():\n    pass\n")
    assert referenced_modules(f) == set()
