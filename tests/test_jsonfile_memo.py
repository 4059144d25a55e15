"""The schema check remembers documents it found valid (the demo checks its set-up several times per run), and the
memory never lets an invalid document through: another value, another schema or a tuple where the schema wants an
array is checked again."""
from __future__ import annotations

import pytest

import calib.jsonfile as jf
from calib.errors import RobocalError

SCHEMA = {"type": "object", "properties": {"xs": {"type": "array", "items": {"type": "number", "finite": True}}},
          "required": ["xs"]}


@pytest.fixture
def checks(monkeypatch):
    monkeypatch.setattr(jf, "_VALID", {})
    seen = []
    real = jf._validator_class

    def counting():
        seen.append(1)
        return real()
    monkeypatch.setattr(jf, "_validator_class", counting)
    return seen


def test_a_valid_document_is_checked_once(checks):
    doc = {"xs": [1.0, 2.0]}
    assert jf.check_schema(doc, SCHEMA, "d") is doc
    assert jf.check_schema({"xs": [1.0, 2.0]}, SCHEMA, "d") == doc
    assert len(checks) == 1


def test_another_value_or_schema_is_checked_again(checks):
    jf.check_schema({"xs": [1.0]}, SCHEMA, "d")
    with pytest.raises(RobocalError, match=r"d: xs\[0\]"):
        jf.check_schema({"xs": ["1.0"]}, SCHEMA, "d")
    jf.check_schema({"xs": [1.0]}, dict(SCHEMA), "d")
    assert len(checks) == 3


def test_a_tuple_is_not_taken_for_the_array_it_prints_as(checks):
    jf.check_schema({"xs": [1.0]}, SCHEMA, "d")
    with pytest.raises(RobocalError, match="d: xs"):
        jf.check_schema({"xs": (1.0,)}, SCHEMA, "d")


def test_nan_is_refused_every_time(checks):
    for _ in range(2):
        with pytest.raises(RobocalError, match="not a finite number"):
            jf.check_schema({"xs": [float("nan")]}, SCHEMA, "d")
