"""``scenario_runner._series``: the result's ``Series`` built from the passage's arrays without
pydantic's per-value pass when numpy finds them valid, and by the model's own validation when
not. The two paths must give the same model, and the same refusals."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
from pydantic import ValidationError

from schemas import result as res
from service.physics import scenario_runner as runner


def _passage(n: int = 50, cribs: int = 3) -> Any:  # a PassageOutput's arrays
    rng = np.random.default_rng(7)
    out = SimpleNamespace(**{name: rng.normal(size=n) for name in runner.SERIES_FLOATS})
    out.in_contact = rng.uniform(size=n) > 0.3
    out.channels = {f"c{i}": rng.normal(size=n) * 1e4 for i in range(cribs)}
    return out


def _validated(p: Any, channels: bool = True) -> res.Series:
    return res.Series.model_validate(
        {
            **{name: getattr(p, name).tolist() for name in runner.SERIES_FLOATS},
            "in_contact": p.in_contact.tolist(),
            "channels": {k: v.tolist() for k, v in p.channels.items()} if channels else None,
        }
    )


@pytest.mark.parametrize("with_channels", [True, False])
def test_the_fast_path_builds_the_validated_model(with_channels: bool) -> None:
    p = _passage()
    got = runner._series(p, p.channels if with_channels else None)
    want = _validated(p, with_channels)
    assert got == want
    assert got.model_fields_set == want.model_fields_set
    assert got.model_dump_json() == want.model_dump_json()
    assert all(type(v) is float for v in got.force) and all(type(v) is bool for v in got.in_contact)


@pytest.mark.parametrize(("field", "value"), [("force", np.nan), ("t", np.inf), ("v_m", -np.inf)])
def test_a_value_that_is_not_finite_is_refused_by_the_model(field: str, value: float) -> None:
    p = _passage()
    getattr(p, field)[7] = value
    with pytest.raises(ValidationError, match=field):
        runner._series(p, p.channels)


def test_a_channel_that_is_not_finite_is_refused_by_the_model() -> None:
    p = _passage()
    p.channels["c1"][3] = np.nan
    with pytest.raises(ValidationError, match="channels"):
        runner._series(p, p.channels)


@pytest.mark.parametrize("field", ["x", "in_contact", "channels.c2"])
def test_a_series_of_another_length_is_refused_by_the_model(field: str) -> None:
    p = _passage()
    if field == "in_contact":
        p.in_contact = p.in_contact[:-1]
    elif field.startswith("channels"):
        p.channels["c2"] = p.channels["c2"][:-2]
    else:
        setattr(p, field, getattr(p, field)[:-1])
    with pytest.raises(ValidationError, match=field):
        runner._series(p, p.channels)


def test_the_fast_path_checks_every_rule_the_model_has() -> None:
    """A new field, constraint or validator on ``Series`` must be checked by ``_series`` too:
    this test fails until it is (the fast path builds the model without pydantic's
    validation, checking finiteness and lengths only)."""
    assert set(res.Series.model_fields) == {*runner.SERIES_FLOATS, "in_contact", "channels"}
    decorators = res.Series.__pydantic_decorators__
    assert set(decorators.model_validators) == {"_same_length"}
    assert not decorators.field_validators and not decorators.validators

    def shape(name: str) -> dict[str, object]:
        prop = res.Series.model_json_schema()["properties"][name]
        return {k: v for k, v in prop.items() if k not in ("description", "title", "default")}

    floats = {"items": {"type": "number"}, "type": "array"}
    for name in runner.SERIES_FLOATS:
        assert shape(name) in (floats, {"anyOf": [floats, {"type": "null"}]}), name
        # and each refuses a value that is not finite
        with pytest.raises(ValidationError):
            res.Series.model_validate(
                {**_validated(_passage()).model_dump(), name: [float("nan")] * 50}
            )
    assert shape("in_contact") == {"items": {"type": "boolean"}, "type": "array"}
    assert shape("channels") == {
        "anyOf": [{"additionalProperties": floats, "type": "object"}, {"type": "null"}]
    }
