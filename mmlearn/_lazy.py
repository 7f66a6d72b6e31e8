"""Lazy re-exports for the package ``__init__`` modules.

``from mmlearn.systems import ArticulationEstimator`` imports only the module that defines the
name, so importing one capability does not import (and pay for) all the others.
"""

from __future__ import annotations

import importlib


def lazy_exports(package: str, exports: dict[str, list[str]]):
    """Return ``(__getattr__, __dir__)`` for a package whose public names live in submodules.

    Args:
        package: the package's ``__name__``.
        exports: submodule (relative to the package) -> the public names it defines.
    """
    where = {name: module for module, names in exports.items() for name in names}

    def __getattr__(name: str):
        module = where.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(f"{package}.{module}"), name)
        globals_ = importlib.import_module(package).__dict__
        globals_[name] = value
        return value

    def __dir__():
        return sorted(set(where) | set(importlib.import_module(package).__dict__))

    return __getattr__, __dir__


def capability_exports(package: str, capabilities: tuple[str, ...]) -> dict[str, list[str]]:
    """``{capability: names}`` for a top package that re-exports its capability subpackages'
    ``__all__``. A name two capabilities define differently is left to its subpackages (say
    ``mmlearn.models.articulation.StructureResult``); one they share (a re-export of a common
    name) is taken from the first capability that lists it."""
    subs = {c: importlib.import_module(f"{package}.{c}") for c in capabilities}
    owners: dict[str, list] = {}
    for c, sub in subs.items():
        for name in sub.__all__:
            owners.setdefault(name, []).append((c, sub))
    out: dict[str, list[str]] = {c: [] for c in capabilities}
    for name, where in owners.items():
        first = getattr(where[0][1], name)
        if all(getattr(s, name) is first for _, s in where[1:]):
            out[where[0][0]].append(name)
    return out
