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


def capability_namespace(package: str, capabilities: tuple[str, ...]):
    """Return ``(__getattr__, __dir__)`` for a top package (``mmlearn.models``, ...) that
    re-exports its capability subpackages' ``__all__``.

    Nothing of a capability beyond its ``__init__`` is imported until one of its names is
    used. A name two capabilities define differently is left to its subpackages (say
    ``mmlearn.models.articulation.StructureResult``); one they share (a re-export of a common
    name) is taken from the first capability that lists it. The package's ``__all__`` and
    ``_EXPORTS`` (``{capability: names}``) are computed on first use; deciding which shared
    names are the same object imports their modules then.
    """
    subs = {c: importlib.import_module(f"{package}.{c}") for c in capabilities}
    owners: dict[str, list[str]] = {}
    for c, sub in subs.items():
        for name in sub.__all__:
            owners.setdefault(name, []).append(c)

    def same_everywhere(name: str) -> bool:
        first, *rest = owners[name]
        value = getattr(subs[first], name)
        return all(getattr(subs[c], name) is value for c in rest)

    def exports() -> dict[str, list[str]]:
        out: dict[str, list[str]] = {c: [] for c in capabilities}
        for name, where in owners.items():
            if len(where) == 1 or same_everywhere(name):
                out[where[0]].append(name)
        return out

    def __getattr__(name: str):
        if name == "_EXPORTS":
            value = exports()
        elif name == "__all__":
            value = [n for names in __getattr__("_EXPORTS").values() for n in names]
        else:
            where = owners.get(name)
            if where is None or (len(where) > 1 and not same_everywhere(name)):
                raise AttributeError(f"module {package!r} has no attribute {name!r}")
            value = getattr(subs[where[0]], name)
        importlib.import_module(package).__dict__[name] = value
        return value

    def __dir__():
        return sorted(set(owners) | set(importlib.import_module(package).__dict__))

    return __getattr__, __dir__
