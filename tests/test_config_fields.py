"""Configuration fields declared with their units and ranges (mmlearn.models.common.config)."""

import dataclasses
import sys
import types
from dataclasses import dataclass, replace

import pytest

from mmlearn.models.common.config import param, validate_fields


@dataclass
class C:
    rate_hz: float = param(30.0, unit="Hz", gt=0)
    mode: str = param("fast", choices=("fast", "exact"))
    seed: int = param(0, integer=True, ge=0)
    size: tuple = param((3, 3), length=2, ge=1, integer=True)
    opt: float | None = param(None, optional=True, ge=0)
    lst: list = param([1.0], factory=True, elements=True, ge=0)


def test_each_declared_check_names_class_field_value_and_what_is_allowed():
    c = validate_fields(C())
    for kw, msg in [(dict(rate_hz=0), "C: rate_hz must be > 0 \\(Hz\\), got 0"), (dict(rate_hz=float("nan")), "finite"),
                    (dict(mode="slow"), "one of fast, exact"), (dict(seed=-1), "seed must be an integer >= 0"),
                    (dict(seed=1.5), "integer"), (dict(size=(1,)), "2 entries"), (dict(size=(1, 0)), "size\\[1\\]"),
                    (dict(rate_hz="x"), "number"), (dict(lst=[1, -1]), "lst\\[1\\]"), (dict(seed=True), "number")]:
        with pytest.raises(ValueError, match=msg):
            validate_fields(replace(c, **kw))
    assert C().lst is not C().lst


@dataclass
class Inner:
    gain: float = param(1.0, gt=0, le=1)

    def validate(self):
        validate_fields(self)
        if self.gain == 0.5:
            raise ValueError("Inner: gain 0.5 is refused by its own validate")


@dataclass
class Outer:
    flag: bool = param(True)
    name: str = param("a")
    scale: float = param(2.0)
    inner: Inner = param(Inner(), factory=True, nested=Inner)
    extra: Inner | None = param(None, optional=True, nested=Inner)
    many: list = param([Inner()], factory=True, nested=Inner, length=(1, None))
    big: int = param(5, integer=True, ge=0, lt=2147483)


def test_kinds_ranges_and_nested_configs():
    o = validate_fields(Outer())
    for kw, msg in [(dict(flag=1), "flag must be true or false, got 1"),
                    (dict(name=3), "name must be a string"),
                    (dict(scale="x"), "scale must be a number, got 'x'"),
                    (dict(scale=float("inf")), "scale must be finite"),
                    (dict(inner=Inner(gain=2.0)),
                     "Outer: inner: Inner: gain must be in \\(0, 1\\], got 2.0"),
                    (dict(inner=Inner(gain=0.5)), "Outer: inner: Inner: gain 0.5 is refused"),
                    (dict(inner=3), "inner must be a Inner, got 3"),
                    (dict(extra=Inner(gain=-1.0)), "extra: Inner: gain"),
                    (dict(many=[Inner(), Inner(gain=0.0)]), "many\\[1\\]: Inner: gain"),
                    (dict(many=[]), "many must have at least 1 entry, got 0"),
                    (dict(big=2147483), "big must be an integer in \\[0, 2147483\\), got 2147483")]:
        with pytest.raises(ValueError, match=msg):
            validate_fields(replace(o, **kw))
    validate_fields(replace(o, extra=Inner(gain=0.2), flag=False))
    a, b = Outer(), Outer()
    assert a.inner is not b.inner and a.many[0] is not b.many[0]


_FUTURE_SOURCE = '''
from __future__ import annotations
from dataclasses import dataclass
from mmlearn.models.common.config import param

@dataclass
class Inner:
    gain: float = param(1.0, gt=0)

@dataclass
class Outer:
    flag: bool = param(True)
    rate_hz: float = param(30.0, gt=0)
    inner: Inner = param(Inner(), factory=True, nested=Inner)
    extra: Inner | None = param(None, optional=True, nested=Inner)
'''


def test_yaml_loads_a_config_declared_with_string_annotations():
    from pydrake.common.yaml import yaml_load_typed

    mod = types.ModuleType("future_config")
    sys.modules["future_config"] = mod
    try:
        exec(compile(_FUTURE_SOURCE, "future_config", "exec"), mod.__dict__)
        Outer, Inner = mod.Outer, mod.Inner
        assert [f.type for f in dataclasses.fields(Outer)][:2] == [bool, float]
        o = yaml_load_typed(schema=Outer, data="flag: false\nrate_hz: 10\ninner: {gain: 2.0}\n"
                                               "extra: {gain: 3.0}\n")
        assert o == Outer(flag=False, rate_hz=10.0, inner=Inner(2.0), extra=Inner(3.0))
        with pytest.raises(RuntimeError, match="rate_hzz"):
            yaml_load_typed(schema=Outer, data="rate_hzz: 10\n")
    finally:
        del sys.modules["future_config"]
