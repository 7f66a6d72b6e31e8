"""Trial functions of the experiments, referenced as callables with a stable, versioned name.

A trial is a pure function of its keyword parameters and a seed that returns a JSON-able
record. Register it with :func:`register_trial`; the experiment runner
(:mod:`mmlearn.apps.common.sweep`) keys each result by the trial's name and version, its
parameters and its seed, so a renamed or moved function keeps its results, and a trial whose
record changes meaning gets a new version (a results file of the older version is refused)::

    @register_trial("articulation.operate", version=1,
                    record={"opened": (float, None), "success": bool})
    def operate_trial(*, seed: int, kind: str) -> dict: ...

``record`` is the schema of the trial's record (checked by :func:`check_record` when a
results file is read): the keys every record has and their types (``float`` accepts any
number, ``None`` in a tuple allows null), or a function of the trial's parameters giving
that mapping (a trial whose record depends on what it was asked). The trial's version is
the version of that schema: every results-file line names it (``"fn": "name@version"``).
"""

from __future__ import annotations

import re
from typing import Callable

__all__ = ["register_trial", "trial_id", "registered_trials", "check_record"]

_NAME = re.compile(r"^[a-z][a-z0-9_]*(\.[a-z][a-z0-9_]*)+$")
_REGISTRY: dict[str, Callable] = {}


def register_trial(name: str, *, version: int = 1, record=None):
    """Decorator: register ``fn`` as the trial ``name`` (dotted, ``capability.trial``) at
    ``version`` (a positive integer; raise it when the record's meaning changes), with the
    schema ``record`` of its records (see the module text; None: any dict)."""
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
        fn.trial_record = record
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


def _type_ok(v, t) -> bool:
    if t is None:
        return v is None
    if t is float:
        return isinstance(v, (int, float)) and not isinstance(v, bool)
    if t is int:
        return isinstance(v, int) and not isinstance(v, bool)
    return isinstance(v, t)


def _type_name(t) -> str:
    return "null" if t is None else {float: "a number", int: "an integer", bool: "true/false",
                                     str: "a string", list: "a list",
                                     dict: "a mapping"}.get(t, t.__name__)


def check_record(fn: Callable | str, record, params: dict | None = None) -> str | None:
    """Why ``record`` is not a valid record of the trial ``fn`` (a registered function or
    its ``"name@version"``), or None when it is: a mapping with every key of the trial's
    schema, each of its type. A trial not registered here (or without a schema) accepts any
    mapping."""
    if not isinstance(record, dict):
        return f"the record is {type(record).__name__}, expected a mapping"
    if isinstance(fn, str):
        fn = _REGISTRY.get(fn.split("@", 1)[0])
    schema = getattr(fn, "trial_record", None)
    if callable(schema):
        try:
            schema = schema(params or {})
        except (KeyError, TypeError, ValueError) as e:
            return f"its parameters do not name a known record ({type(e).__name__}: {e})"
    for key, types in (schema or {}).items():
        if key not in record:
            return f"the record lacks {key!r}"
        types = types if isinstance(types, tuple) else (types,)
        if not any(_type_ok(record[key], t) for t in types):
            return (f"the record's {key!r} is {_short(record[key])}, expected "
                    + " or ".join(_type_name(t) for t in types))
    return None


def _short(v) -> str:
    """A short text of a JSON value for a message."""
    text = repr(v)
    return text if len(text) <= 40 else text[:37] + "..."
