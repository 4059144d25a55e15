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


def test_a_vouched_document_is_not_checked_and_a_changed_one_is(checks):
    doc = {"xs": [1.0, 2.0]}
    assert jf.vouch(doc, SCHEMA) is doc
    assert jf.check_schema({"xs": [1.0, 2.0]}, SCHEMA, "d") and checks == []     # the same text: taken as valid
    with pytest.raises(RobocalError, match="finite"):
        jf.check_schema({"xs": [1.0, float("inf")]}, SCHEMA, "d")                   # another one is checked


def test_what_the_demo_vouches_for_follows_the_schemas(tmp_path, monkeypatch):
    """The demo's own bench, its plan, the transmission runs its plan narrowed and the model its reduction gives
    are vouched for (no check, no jsonschema import in a demo run): each one checked here for real."""
    import json
    from acq.session.plan_doc import PLAN_SCHEMA
    from acq.session.setup_file import SETUP_SCHEMA
    from app.demo import build_demo
    from calib.compensate import MODEL_SCHEMA
    d = build_demo(tmp_path / "s.db", seed=2)
    try:
        row = d.store.session_row()
        setup, plan = json.loads(row["setup_json"]), json.loads(row["plan_json"])
    finally:
        d.close()
    monkeypatch.setattr(jf, "_VALID", {})
    jf.check_schema(setup, SETUP_SCHEMA, "the demo's set-up")
    jf.check_schema(plan, PLAN_SCHEMA, "the demo's plan")
    jf.check_schema({"procedures": ["transmission"], "seed": plan["seed"], "transmission": plan["transmission"]},
                    PLAN_SCHEMA, "the transmission runs")
    import shutil
    from pathlib import Path
    from app.reprocess import reprocess
    db = tmp_path / "example.db"
    shutil.copy(Path(__file__).parents[1] / "examples" / "demo-session.db", db)
    robot = reprocess(str(db))["robot"]                  # the model document today's reduction makes
    monkeypatch.setattr(jf, "_VALID", {})
    jf.check_schema(robot, MODEL_SCHEMA, "a reduction's model")
