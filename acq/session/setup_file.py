"""The bench set-up JSON (``robocal session --setup``, ``robocal import --setup``, and the copy every session database
keeps): its structure checked whole, once, before a session starts or a stored session is reprocessed.

The schema names what the acquisition and the reprocessing read (stations, base, tool target, ruler) with types,
lengths and ranges; other keys (compliance levers, gauges, loads of newer procedures) may be present and are checked
by the procedures that read them.  NaN and Infinity are refused by the parser.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

from calib.jsonfile import FINITE, check_schema, parse_json, read_json

_VEC3 = {"type": "array", "items": FINITE, "minItems": 3, "maxItems": 3}
_POSITIVE = {"type": "number", "exclusiveMinimum": 0, "maximum": 1e9}

SETUP_SCHEMA: dict[str, Any] = {
    "type": "object",
    "required": ["stations", "base_xyz_mm", "tool_target_mm", "ruler"],
    "properties": {
        "robot": {"type": "string"},
        "base_link": {"type": "string"},         # a URDF robot's chain cut (empty: the root / the moving leaf)
        "tip_link": {"type": "string"},
        "scenario": {"type": "string"},
        "base_xyz_mm": _VEC3,
        "base_rpy_deg": {**_VEC3, "items": {"type": "number", "minimum": -360, "maximum": 360}},
        "stations": {"type": "object", "required": ["L_mm", "gamma1_deg", "gamma2_deg", "sigma_arcsec"],
                     "properties": {"L_mm": _POSITIVE,
                                    "gamma1_deg": {"type": "number", "minimum": -180, "maximum": 180},
                                    "gamma2_deg": {"type": "number", "minimum": -180, "maximum": 180},
                                    "sigma_arcsec": _POSITIVE}},
        "tool_target_mm": _VEC3,
        "extended_tool": {"type": "object", "additionalProperties": _VEC3},
        "ruler": {"type": "object", "required": ["marks_mm", "placements"], "properties": {
            "marks_mm": {"type": "array", "items": FINITE, "minItems": 2},
            "placements": {"type": "array", "minItems": 1, "items": {
                "type": "object", "required": ["C_mm", "dir"],
                "properties": {"where": {"type": "string"}, "C_mm": _VEC3, "dir": _VEC3}}}}},
        "compliance": {"type": "object", "additionalProperties": {"type": "object"}},
        "link": {"type": "object"},
    },
}


def check_setup(doc: Any, where: str) -> dict:
    """``doc`` if it is a valid set-up; one line naming ``where`` and the key otherwise."""
    return check_schema(doc, SETUP_SCHEMA, where)


def read_setup(path: str | Path) -> dict:
    """Read and check a set-up JSON file."""
    return read_json(path, schema=SETUP_SCHEMA)


def read_partial_setup(path: str | Path, required: tuple[str, ...]) -> dict:
    """A set-up file that a command completes with its own values (``robocal demo --setup`` keeps the emulated
    cell's stations and base, ``robocal plan setup --setup`` writes its design into it): every key it has is checked
    as in a full set-up, but only ``required`` must be present.  A bad file is one line naming it and the key."""
    return read_json(path, schema={**SETUP_SCHEMA, "required": list(required)})


def setup_from_text(text: str, where: str) -> dict:
    """A set-up stored as text (the session database's ``setup_json``), checked."""
    return check_setup(parse_json(text, where), where)
