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
        camera: CameraConfig = param(CameraConfig(), factory=True, nested=CameraConfig)

        def validate(self) -> "SensorConfig":
            return validate_fields(self)

The kind of the default sets the kind of value a field accepts: a ``bool`` default takes only
``True`` / ``False``, a string default only strings, a number default only (finite) numbers.
Numbers must be finite unless ``finite=False``; ``None`` passes only with ``optional=True``.
Checks that relate two fields stay in the config's own ``validate`` after the field checks.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import numbers
import typing
from typing import Any

import numpy as np

__all__ = ["param", "validate_fields", "field_spec", "validate_tree"]

_KEY = "mmlearn"
_NUMBER = (numbers.Real, np.integer, np.floating)


def param(default: Any = dataclasses.MISSING, *, unit: str = "", gt=None, ge=None, lt=None,
          le=None, choices=None, integer: bool = False, optional: bool = False,
          finite: bool = True, length: int | tuple | None = None, elements: bool = False,
          nested=None, factory: bool = False, doc: str = "", **field_kw):
    """A dataclass field with its allowed values in the metadata.

    Args:
        default: the default value (with ``factory=True``, deep-copied per instance: use it
            for lists, nested configs and other mutable defaults).
        unit: the unit, named in messages (``"m"``, ``"rad"``, ``"N"``, ``"Hz"``).
        gt, ge, lt, le: bounds (greater than, at least, less than, at most).
        choices: the allowed values of a choice field.
        integer: the value must be an integer (``bool`` is not).
        optional: ``None`` is allowed.
        finite: numbers must be finite (default).
        length: a sequence of this many entries, or ``(least, most)`` (either may be None).
        elements: apply the number checks to each entry of a sequence.
        nested: the value is a nested config (or, for a list or tuple, each entry is): the
            class it must be an instance of, or True for any dataclass. It is checked by its
            own ``validate()`` when it has one, else by :func:`validate_fields`.
        doc: a short description (shown by tools that list a config's fields).
        field_kw: passed to ``dataclasses.field`` (e.g. ``default_factory``).
    """
    meta = dict(field_kw.pop("metadata", {}) or {})
    kind = None
    if isinstance(default, (bool, np.bool_)):
        kind = "bool"
    elif isinstance(default, str):
        kind = "str"
    elif isinstance(default, _NUMBER):
        kind = "number"
    meta[_KEY] = dict(unit=unit, gt=gt, ge=ge, lt=lt, le=le, choices=None if choices is None
                      else tuple(choices), integer=integer, optional=optional, finite=finite,
                      length=length, elements=elements, nested=nested, kind=kind, doc=doc)
    if factory:
        value = default
        field_kw["default_factory"] = lambda: copy.deepcopy(value)
    elif default is not dataclasses.MISSING:
        field_kw["default"] = default
    f = dataclasses.field(metadata=meta, **field_kw)
    return _Field(f.default, f.default_factory, f.init, f.repr, f.hash, f.compare, f.metadata,
                  f.kw_only)


class _Field(dataclasses.Field):
    """A dataclass field whose ``type`` is the resolved annotation even in a module with
    ``from __future__ import annotations`` (where the annotation is a string): Drake's
    ``yaml_load_typed`` reads ``field.type`` and needs the type itself."""

    __slots__ = ("_owner", "_annotation")

    def __set_name__(self, owner, name):
        self._owner = owner
        super().__set_name__(owner, name)

    @property
    def type(self):
        t = self._annotation
        if isinstance(t, str) and getattr(self, "_owner", None) is not None:
            try:
                t = self._annotation = typing.get_type_hints(self._owner)[self.name]
            except Exception:  # noqa: BLE001 - a name not defined yet: keep the string
                pass
        return t

    @type.setter
    def type(self, value):
        self._annotation = value


def field_spec(cls_or_obj, name: str) -> dict:
    """The declared checks of one field (empty for a field declared without :func:`param`)."""
    for f in dataclasses.fields(cls_or_obj):
        if f.name == name:
            return dict(f.metadata.get(_KEY, {}))
    raise KeyError(name)


def _num(x) -> str:
    text = f"{x:g}"
    return text if float(text) == float(x) else repr(x)


def _allowed(spec: dict) -> str:
    """What a number field accepts: "> 0 (Hz)", "in [0, 1)", "an integer >= 1"."""
    lo = next(((k, spec[k]) for k in ("ge", "gt") if spec.get(k) is not None), None)
    hi = next(((k, spec[k]) for k in ("le", "lt") if spec.get(k) is not None), None)
    ops = {"ge": ">=", "gt": ">", "le": "<=", "lt": "<"}
    if lo and hi:
        text = (f"in {'[' if lo[0] == 'ge' else '('}{_num(lo[1])}, {_num(hi[1])}"
                f"{']' if hi[0] == 'le' else ')'}")
    else:
        text = " ".join(f"{ops[b[0]]} {_num(b[1])}" for b in (lo, hi) if b)
    if spec.get("integer"):
        text = f"an integer {text}".rstrip()
    elif not text:
        text = "a finite number" if spec.get("finite", True) else "a number"
    if spec.get("unit"):
        text += f" ({spec['unit']})"
    return text


def _check_number(where: str, value, spec: dict) -> None:
    checked = _has_number_checks(spec)
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, _NUMBER):
        raise ValueError(f"{where} must be a number" + (f" ({_allowed(spec)})" if checked else "")
                         + f", got {value!r}")
    if spec.get("integer") and not (isinstance(value, (numbers.Integral, np.integer))):
        raise ValueError(f"{where} must be {_allowed(spec)}, got {value!r}")
    v = float(value)
    if spec.get("finite", True) and not math.isfinite(v):
        raise ValueError(f"{where} must be finite" + (f" and {_allowed(spec)}" if checked else "")
                         + f", got {value!r}")
    ok = ((spec.get("gt") is None or v > spec["gt"]) and (spec.get("ge") is None or v >= spec["ge"])
          and (spec.get("lt") is None or v < spec["lt"]) and (spec.get("le") is None
                                                              or v <= spec["le"]))
    if not ok:
        raise ValueError(f"{where} must be {_allowed(spec)}, got {value!r}")


def _has_number_checks(spec: dict) -> bool:
    return any(spec.get(k) is not None for k in ("gt", "ge", "lt", "le")) or spec.get("integer")


def _check_length(where: str, value, length) -> None:
    if isinstance(value, (str, bytes, dict)) or not hasattr(value, "__len__"):
        raise ValueError(f"{where} must be a sequence, got {value!r}")
    if length is None:
        return
    least, most = (length, length) if isinstance(length, int) else length
    n = len(value)
    if least == most and n != least:
        raise ValueError(f"{where} must have {least} entries, got {n}: {value!r}")
    if least is not None and n < least:
        raise ValueError(f"{where} must have at least {least} "
                         f"entr{'y' if least == 1 else 'ies'}, got {n}: {value!r}")
    if most is not None and n > most:
        raise ValueError(f"{where} must have at most {most} entries, got {n}: {value!r}")


def _check_nested(where: str, value, nested) -> None:
    cls = nested if isinstance(nested, type) else None
    if (cls is not None and not isinstance(value, cls)) or not dataclasses.is_dataclass(value) \
            or isinstance(value, type):
        name = cls.__name__ if cls is not None else "configuration (dataclass)"
        raise ValueError(f"{where} must be a {name}, got {value!r}")
    try:
        if callable(getattr(value, "validate", None)):
            value.validate()
        else:
            validate_fields(value)
    except ValueError as e:
        raise ValueError(f"{where}: {e}") from None


def _check_field(where: str, value, spec: dict) -> None:
    if spec["choices"] is not None:
        if value not in spec["choices"]:
            raise ValueError(f"{where} must be one of {', '.join(map(str, spec['choices']))}"
                             f", got {value!r}")
        return
    if spec.get("nested"):
        if spec["length"] is not None:
            _check_length(where, value, spec["length"])
        if isinstance(value, (list, tuple)):
            for i, x in enumerate(value):
                _check_nested(f"{where}[{i}]", x, spec["nested"])
        else:
            _check_nested(where, value, spec["nested"])
        return
    kind = spec.get("kind")
    if kind == "bool":
        if not isinstance(value, (bool, np.bool_)):
            raise ValueError(f"{where} must be true or false, got {value!r}")
        return
    if kind == "str":
        if not isinstance(value, str):
            raise ValueError(f"{where} must be a string, got {value!r}")
        return
    if spec["length"] is not None or spec["elements"]:
        _check_length(where, value, spec["length"])
        if spec["elements"] or _has_number_checks(spec):
            for i, x in enumerate(np.asarray(value, dtype=object).ravel()):
                _check_number(f"{where}[{i}]", x, spec)
        return
    if kind is None and isinstance(value, (bool, np.bool_)) and not _has_number_checks(spec):
        return
    if kind == "number" or isinstance(value, _NUMBER) or _has_number_checks(spec):
        _check_number(where, value, spec)


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
        _check_field(where, value, spec)
    return obj


def validate_tree(obj, where: str = ""):
    """Check a loaded configuration and every configuration nested in it: each dataclass's
    own ``validate()`` when it has one, else :func:`validate_fields`; then any number left
    NaN or infinite in a field not declared ``finite=False`` (a field without :func:`param`
    too). Raises ``ValueError`` naming the dotted path of the field; returns ``obj``."""
    if not dataclasses.is_dataclass(obj) or isinstance(obj, type):
        return obj
    try:
        if callable(getattr(obj, "validate", None)):
            obj.validate()
        else:
            validate_fields(obj)
    except ValueError as e:
        raise ValueError(f"{where}{e}" if not where else f"{where.rstrip('.')}: {e}") from None
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        key = f"{where}{f.name}"
        spec = f.metadata.get(_KEY, {})
        if dataclasses.is_dataclass(value) and not isinstance(value, type):
            validate_tree(value, key + ".")
            continue
        if isinstance(value, (list, tuple)):
            for i, x in enumerate(value):
                if dataclasses.is_dataclass(x) and not isinstance(x, type):
                    validate_tree(x, f"{key}[{i}].")
        if spec.get("finite", True) is False:
            continue
        bad = _first_non_finite(value)
        if bad is not None:
            raise ValueError(f"{key}{bad} must be finite, got {_at(value, bad)!r}")
    return obj


def _first_non_finite(value, path: str = ""):
    if isinstance(value, (bool, np.bool_, str)) or value is None:
        return None
    if isinstance(value, _NUMBER):
        return None if math.isfinite(float(value)) else path
    if isinstance(value, (list, tuple, np.ndarray)):
        for i, x in enumerate(value):
            r = _first_non_finite(x, f"{path}[{i}]")
            if r is not None:
                return r
    return None


def _at(value, path: str):
    for part in path.strip("[]").split("]["):
        if part:
            value = value[int(part)]
    return value
