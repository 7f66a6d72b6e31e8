"""Trial functions of the experiments, referenced as callables with a stable, versioned name.

A trial is a pure function of its keyword parameters and a seed that returns a JSON-able
record. Register it with :func:`register_trial`; the experiment runner
(:mod:`mmlearn.apps.common.sweep`) keys each result by the trial's name and version, its
parameters and its seed, so a renamed or moved function keeps its results, and a trial whose
record changes meaning gets a new version (a results file of the older version is refused)::

    @register_trial("articulation.operate", version=1)
    def operate_trial(*, seed: int, kind: str) -> dict: ...
"""

from __future__ import annotations

import re
from typing import Callable

__all__ = ["register_trial", "trial_id", "registered_trials"]

_NAME = re.compile(r"^[a-z][a-z0-9_]*(\.[a-z][a-z0-9_]*)+$")
_REGISTRY: dict[str, Callable] = {}


def register_trial(name: str, *, version: int = 1):
    """Decorator: register ``fn`` as the trial ``name`` (dotted, ``capability.trial``) at
    ``version`` (a positive integer; raise it when the record's meaning changes)."""
    if not isinstance(name, str) or not _NAME.match(name):
        raise ValueError(f"trial name must be dotted lower-case words like 'articulation.operate', "
                         f"got {name!r}")
    if isinstance(version, bool) or not isinstance(version, int) or version < 1:
        raise ValueError(f"trial version must be a positive integer, got {version!r}")

    def deco(fn: Callable) -> Callable:
        known = _REGISTRY.get(name)
        if known is not None and (known.__module__, known.__qualname__) != (fn.__module__,
                                                                            fn.__qualname__):
            raise ValueError(f"trial name {name!r} is taken by {known.__module__}."
                             f"{known.__qualname__}")
        fn.trial_name = name
        fn.trial_version = version
        _REGISTRY[name] = fn
        return fn

    return deco


def trial_id(fn: Callable) -> str:
    """``"name@version"`` of a registered trial function (its identity in results files)."""
    name = getattr(fn, "trial_name", None)
    if not callable(fn) or name is None:
        raise ValueError(f"{getattr(fn, '__qualname__', fn)!r} is not a registered trial "
                         "function (decorate it with register_trial)")
    return f"{name}@{fn.trial_version}"


def registered_trials() -> dict[str, Callable]:
    """The trials registered so far (those whose modules have been imported), by name."""
    return dict(_REGISTRY)
