"""The bench set-up JSON (``robocal session --setup``, ``robocal import --setup``, and the copy every session database
keeps): one JSON Schema for the whole file, every sub-object included, checked once at the edge -- when a file is
read or a stored session is opened -- before anything uses it; the defaults stand in that schema and are filled in
at that moment (:func:`with_defaults`), so no reader supplies its own.

Old files: a compliance load as a lever (``lever_mm``, ``theta_i_deg``, ``loads_n``) and the link's gauges as
distances along it (``gauges_x_mm``, ``load_x_mm``) are still valid; they are mapped once onto the step vocabulary
(masses at points on links, gauges as points with an axis) by :func:`acq.session.setup.session_setup`, which needs
the robot's geometry to do it.  Keys starting with ``_`` are comments.  NaN and Infinity are refused by the parser.
"""
from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

from calib.jsonfile import FINITE, check_schema, parse_json, read_json

from .plan_doc import PLAN_SCHEMA

_VEC3 = {"type": "array", "items": FINITE, "minItems": 3, "maxItems": 3}
_VEC3_OR_NULL = {"anyOf": [_VEC3, {"type": "null"}]}
_NUMBERS = {"type": "array", "items": FINITE}
_POSITIVE = {"type": "number", "exclusiveMinimum": 0, "maximum": 1e9}
_ANGLE = {"type": "number", "minimum": -360, "maximum": 360}
_JOINT = {"type": "integer", "minimum": 0, "maximum": 64}
_LOADS = {"type": "array", "items": {"type": "number", "minimum": 0, "maximum": 1e6}}


def _obj(properties: dict, required=(), **kw) -> dict:
    """An object with exactly these keys (comments ``_...`` aside)."""
    return {"type": "object", "properties": properties, "required": list(required),
            "patternProperties": {"^_": {}}, "additionalProperties": False, **kw}


_COMPLIANCE_ENTRY = _obj({
    "link": _JOINT, "point_mm": _VEC3, "lever_mm": _POSITIVE, "theta_i_deg": _ANGLE, "loads_n": _LOADS,
    "masses_kg": _LOADS, "pose_deg": _NUMBERS})
_GAUGE = _obj({"name": {"type": "string"}, "link": _JOINT, "point_mm": _VEC3, "axis": _VEC3},
              required=("name", "link", "point_mm", "axis"))
_LINK = _obj({
    "joint": _JOINT, "link": _JOINT, "gauges_x_mm": _NUMBERS, "load_x_mm": FINITE, "loads_n": _LOADS,
    "masses_kg": _LOADS, "second_moment_mm4": {"anyOf": [_POSITIVE, {"type": "null"}]}, "pose_deg": _NUMBERS,
    "gauge_sigma_mm": _POSITIVE, "load_point_mm": _VEC3_OR_NULL, "gauges": {"type": "array", "items": _GAUGE}},
    required=("joint",))
_PREFLIGHT = _obj({
    "joint_margin_deg": {"type": "number", "minimum": 0, "maximum": 90},
    "max_elevation_deg": {"type": "number", "exclusiveMinimum": 0, "maximum": 90},
    "min_focus_mm": {"type": "number", "minimum": 0, "maximum": 1e6}, "max_range_mm": _POSITIVE,
    "intersection_deg": {**_NUMBERS, "minItems": 2, "maxItems": 2},
    "sweep_radius_mm": {**_NUMBERS, "minItems": 2, "maxItems": 2},
    "load_lever_fraction": {"type": "number", "minimum": 0, "maximum": 1}, "reach_margin": _POSITIVE,
    "link_radius_mm": {"anyOf": [{"type": "number", "minimum": 0, "maximum": 1e4}, {"type": "null"}]}})

SETUP_SCHEMA: dict[str, Any] = _obj({
    "robot": {"type": "string", "default": ""},       # a description file; empty: the shipped Puma
    "base_link": {"type": "string"},                  # a URDF robot's chain cut (empty: the root / the moving leaf)
    "tip_link": {"type": "string"},
    "scenario": {"type": "string", "default": ""},    # the twin scenario (emulated sessions only)
    "base_xyz_mm": _VEC3,
    "base_rpy_deg": {**_VEC3, "items": _ANGLE, "default": [0.0, 0.0, 0.0]},
    "stations": _obj({"names": {"type": "array", "items": {"type": "string", "minLength": 1}, "minItems": 2,
                                "maxItems": 2, "default": ["A", "B"]},
                      "L_mm": _POSITIVE,
                      "gamma1_deg": {"type": "number", "minimum": -180, "maximum": 180},
                      "gamma2_deg": {"type": "number", "minimum": -180, "maximum": 180},
                      "sigma_arcsec": {**_POSITIVE, "default": 3.0}},
                     required=("L_mm", "gamma1_deg", "gamma2_deg")),
    "min_focus_mm": {"type": "number", "minimum": 0, "maximum": 1e6},
    "floor_z_mm": FINITE,
    "preflight": _PREFLIGHT,
    "tool_target_mm": _VEC3,
    "sweep_radius_mm": {"anyOf": [_POSITIVE, {"type": "object", "additionalProperties": _POSITIVE}]},
    "sweep_targets": {"type": "object", "additionalProperties": _obj(
        {"link": {"anyOf": [_JOINT, {"type": "null"}]}, "point_mm": _VEC3, "radius_mm": _POSITIVE},
        required=("point_mm",))},
    "reference_pose_deg": _NUMBERS,
    "point_p": {"anyOf": [_obj({"link": _JOINT, "L_p_mm": FINITE}, required=("L_p_mm",)), {"type": "null"}]},
    "extended_tool": _obj({"A1_mm": _VEC3, "A2_mm": _VEC3}, required=("A1_mm", "A2_mm")),
    "far_target_mm": _VEC3_OR_NULL,
    "ruler": _obj({
        "marks_mm": {"type": "array", "items": FINITE, "minItems": 2},
        "placements": {"type": "array", "minItems": 1, "items": _obj(
            {"where": {"type": "string"}, "C_mm": _VEC3_OR_NULL, "dir": _VEC3,
             "marks": {"type": "array", "items": {"type": "string"}}}, required=("C_mm", "dir"))}},
        required=("marks_mm", "placements")),
    "compliance": {"type": "object", "propertyNames": {"pattern": "^[0-9]+$"},
                   "additionalProperties": _COMPLIANCE_ENTRY},
    "link": _LINK,
    "running_errors": {"type": "array", "items": {"type": "string"}},
    # ISO 9283 pose accuracy and repeatability (acq.session.iso_cube): cycles per pose (the standard's 30; at least
    # two for a repeatability), the cube's side and centre when the cell dictates them, the approach move
    "iso9283": _obj({"cycles": {"type": "integer", "minimum": 2, "maximum": 10000}, "side_mm": _POSITIVE,
                     "centre_mm": _VEC3, "approach_deg": {"type": "number", "exclusiveMinimum": 0, "maximum": 30}}),
    "plan": PLAN_SCHEMA,                              # a plan carried in the set-up: the session plan's schema
    "design": {"type": "object", "additionalProperties": _obj(   # robocal plan setup's record (informative)
        {"variables": {"type": "object", "additionalProperties": FINITE},
         "errors": {"type": "object", "additionalProperties": FINITE}, "note": {"type": "string"}})},
}, required=("stations", "base_xyz_mm", "tool_target_mm", "ruler"))


def with_defaults(doc: Any, schema: dict = SETUP_SCHEMA) -> Any:
    """A copy of ``doc`` with every absent key that has a ``default`` in the schema filled in (objects nested under
    ``properties``): the one place the set-up's defaults are applied."""
    if not isinstance(doc, dict) or schema.get("type") != "object":
        return doc
    out = copy.deepcopy(doc)
    for key, sub in schema.get("properties", {}).items():
        if key not in out and "default" in sub:
            out[key] = copy.deepcopy(sub["default"])
        elif key in out:
            out[key] = with_defaults(out[key], sub)
    return out


def default_of(*path: str) -> Any:
    """The schema's default of a set-up key (``default_of("stations", "sigma_arcsec")``), for a reader given a set-up
    that did not come through :func:`check_setup` (one built in code)."""
    sub = SETUP_SCHEMA
    for key in path:
        sub = sub["properties"][key]
    return copy.deepcopy(sub["default"])


#: the radius of a swept target about its joint when the set-up gives none (the thesis's suggestion, section 5.3:
#: about 600 mm; limits 100-1200 mm)
SETUP_SCHEMA["properties"]["sweep_radius_mm"]["default"] = 600.0


def check_setup(doc: Any, where: str) -> dict:
    """``doc`` with its defaults if it is a valid set-up; one line naming ``where`` and the key otherwise."""
    return with_defaults(check_schema(doc, SETUP_SCHEMA, where))


def read_setup(path: str | Path) -> dict:
    """Read and check a set-up JSON file (defaults filled in)."""
    return with_defaults(read_json(path, schema=SETUP_SCHEMA))


def read_partial_setup(path: str | Path, required: tuple[str, ...]) -> dict:
    """A set-up file that a command completes with its own values (``robocal demo --setup`` keeps the emulated
    cell's stations and base, ``robocal plan setup --setup`` writes its design into it): every key it has is checked
    as in a full set-up, but only ``required`` must be present.  A bad file is one line naming it and the key."""
    return with_defaults(read_json(path, schema={**SETUP_SCHEMA, "required": list(required)}))


def setup_from_text(text: str, where: str) -> dict:
    """A set-up stored as text (the session database's ``setup_json``), checked, defaults filled in."""
    return check_setup(parse_json(text, where), where)
