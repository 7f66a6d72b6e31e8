"""One way to declare and check the fields of a configuration dataclass.

A field states what it accepts in its metadata, through :func:`param`; :func:`validate_fields`
reads that metadata and raises one ``ValueError`` naming the class, the field, the value and
what is allowed. A config calls it from ``__post_init__`` (checked at construction) or from its
``validate()`` (checked where it is used, after a YAML load or a ``dataclasses.replace``)::

    @dataclass
    class SensorConfig:
        rate_hz: float = param(30.0, unit="Hz", gt=0)
        sigma: float = param(0.01, unit="m", ge=0)
        mode: str = param("fast", choices=("fast", "exact"))
        seed: int = param(0, integer=True, ge=0)
        size: tuple = param((3, 3), length=2, factory=True)

        def validate(self) -> "SensorConfig":
            return validate_fields(self)

Numbers must be finite unless ``finite=False``; ``None`` passes only with ``optional=True``.
Checks that relate two fields stay in the config's own ``validate`` after the field checks.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from typing import Any

import numpy as np

__all__ = ["param", "validate_fields", "field_spec"]

_KEY = "mmlearn"


def param(default: Any = dataclasses.MISSING, *, unit: str = "", gt=None, ge=None, lt=None,
          le=None, choices=None, integer: bool = False, optional: bool = False,
          finite: bool = True, length: int | None = None, elements: bool = False,
          factory: bool = False, doc: str = "", **field_kw):
    """A dataclass field with its allowed values in the metadata.

    Args:
        default: the default value (with ``factory=True``, copied per instance: use it for
            lists, tuples of arrays and other mutable defaults).
        unit: the unit, named in messages (``"m"``, ``"rad"``, ``"N"``, ``"Hz"``).
        gt, ge, lt, le: bounds (greater than, at least, less than, at most).
        choices: the allowed values of a choice field.
        integer: the value must be an integer (``bool`` is not).
        optional: ``None`` is allowed.
        finite: numbers must be finite (default).
        length: a sequence of this many entries.
        elements: apply the number checks to each entry of a sequence.
        doc: a short description (shown by tools that list a config's fields).
    """
    meta = dict(field_kw.pop("metadata", {}) or {})
    meta[_KEY] = dict(unit=unit, gt=gt, ge=ge, lt=lt, le=le, choices=None if choices is None
                      else tuple(choices), integer=integer, optional=optional, finite=finite,
                      length=length, elements=elements, doc=doc)
    if factory:
        value = default
        field_kw["default_factory"] = (lambda: type(value)(value)) if isinstance(
            value, (list, tuple, dict, set)) else (lambda: value)
    elif default is not dataclasses.MISSING:
        field_kw["default"] = default
    return dataclasses.field(metadata=meta, **field_kw)


def field_spec(cls_or_obj, name: str) -> dict:
    """The declared checks of one field (empty for a field declared without :func:`param`)."""
    for f in dataclasses.fields(cls_or_obj):
        if f.name == name:
            return dict(f.metadata.get(_KEY, {}))
    raise KeyError(name)


def _allowed(spec: dict) -> str:
    parts = []
    if spec.get("integer"):
        parts.append("an integer")
    for key, op in (("gt", ">"), ("ge", ">="), ("lt", "<"), ("le", "<=")):
        if spec.get(key) is not None:
            parts.append(f"{op} {spec[key]:g}")
    text = " ".join(parts) if parts else ("finite" if spec.get("finite", True) else "a number")
    if spec.get("unit"):
        text += f" ({spec['unit']})"
    return text


def _check_number(where: str, value, spec: dict) -> None:
    if isinstance(value, bool) or not isinstance(value, (numbers.Real, np.integer, np.floating)):
        raise ValueError(f"{where} must be a number, got {value!r}")
    if spec.get("integer") and not (isinstance(value, (numbers.Integral, np.integer))):
        raise ValueError(f"{where} must be an integer, got {value!r}")
    v = float(value)
    if spec.get("finite", True) and not math.isfinite(v):
        raise ValueError(f"{where} must be finite, got {value!r}")
    ok = ((spec.get("gt") is None or v > spec["gt"]) and (spec.get("ge") is None or v >= spec["ge"])
          and (spec.get("lt") is None or v < spec["lt"]) and (spec.get("le") is None
                                                              or v <= spec["le"]))
    if not ok:
        raise ValueError(f"{where} must be {_allowed(spec)}, got {value!r}")


def _has_number_checks(spec: dict) -> bool:
    return any(spec.get(k) is not None for k in ("gt", "ge", "lt", "le")) or spec.get("integer")


def validate_fields(obj):
    """Check every field of the dataclass instance ``obj`` declared with :func:`param`;
    return ``obj``. Raises ``ValueError("Class: field must be ..., got value")``."""
    cls = type(obj).__name__
    for f in dataclasses.fields(obj):
        spec = f.metadata.get(_KEY)
        if spec is None:
            continue
        value = getattr(obj, f.name)
        where = f"{cls}: {f.name}"
        if value is None:
            if spec["optional"]:
                continue
            raise ValueError(f"{where} must not be None")
        if spec["choices"] is not None:
            if value not in spec["choices"]:
                raise ValueError(f"{where} must be one of {', '.join(map(str, spec['choices']))}"
                                 f", got {value!r}")
            continue
        if spec["length"] is not None or spec["elements"]:
            if isinstance(value, (str, bytes)) or not hasattr(value, "__len__"):
                raise ValueError(f"{where} must be a sequence, got {value!r}")
            if spec["length"] is not None and len(value) != spec["length"]:
                raise ValueError(f"{where} must have {spec['length']} entries, got {len(value)}")
            if spec["elements"] or _has_number_checks(spec):
                for i, x in enumerate(np.asarray(value, dtype=object).ravel()):
                    _check_number(f"{where}[{i}]", x, spec)
            continue
        if isinstance(value, (numbers.Real, np.integer, np.floating)) or _has_number_checks(spec):
            _check_number(where, value, spec)
    return obj
