"""Configuration fields declared with their units and ranges (mmlearn.models.common.config)."""

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
