"""The typed set-up (acq/session/setup_types.py): taken once from the checked JSON, every key of the file unchanged,
read-only, defaults from the schema alone; and the import circles it broke stay broken."""
from __future__ import annotations

import ast
import dataclasses
import json
from pathlib import Path

import pytest

from acq.session.setup import session_setup, standard_setup
from acq.session.setup_file import SETUP_SCHEMA
from acq.session.setup_types import BenchSetup, mark_index, mark_names, setup_of
from calib.errors import RobocalError
from calib.loading import load_robot

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def doc():
    return session_setup(standard_setup(), load_robot(None))


def test_the_typed_setup_reads_what_the_file_says(doc):
    s = setup_of(doc)
    assert s.stations.L_mm == doc["stations"]["L_mm"] and s.stations.names == tuple(doc["stations"]["names"])
    assert s.base_xyz_mm == tuple(doc["base_xyz_mm"]) and s.tool_target_mm == tuple(doc["tool_target_mm"])
    assert s.ruler.marks_mm == tuple(doc["ruler"]["marks_mm"])
    assert [p.marks for p in s.ruler.placements] == [tuple(p["marks"]) for p in doc["ruler"]["placements"]]
    for key, entry in doc["compliance"].items():
        c = s.compliance[int(key)]
        assert (c.link, c.point_mm, c.loads_n) == (entry["link"], tuple(entry["point_mm"]), tuple(entry["loads_n"]))
    assert s.link.joint == doc["link"]["joint"]
    assert [g.to_doc() for g in s.link.gauges] == doc["link"]["gauges"]
    assert s.point_p.L_p_mm == doc["point_p"]["L_p_mm"] and s.point_p.link == doc["point_p"]["link"]
    assert {j: t.point_mm for j, t in s.sweep_targets.items()} == \
        {int(k): tuple(v["point_mm"]) for k, v in doc["sweep_targets"].items()}
    # the stored form is the file's, every key as written
    assert json.dumps(dict(s.doc), sort_keys=True) == json.dumps(doc, sort_keys=True)
    assert setup_of(s) is s                                   # typed once: a typed set-up passes through


def test_the_typed_setup_is_read_only(doc):
    s = setup_of(doc)
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.base_xyz_mm = (0.0, 0.0, 0.0)
    with pytest.raises(TypeError):
        s.compliance[3] = None


def test_defaults_come_from_the_schema(doc):
    bare = json.loads(json.dumps(doc))
    for key in ("names", "sigma_arcsec"):
        bare["stations"].pop(key)
    bare.pop("base_rpy_deg")
    s = BenchSetup.of(bare)
    st = SETUP_SCHEMA["properties"]["stations"]["properties"]
    assert s.stations.names == tuple(st["names"]["default"])
    assert s.stations.sigma_arcsec == st["sigma_arcsec"]["default"]
    assert s.base_rpy_deg == tuple(SETUP_SCHEMA["properties"]["base_rpy_deg"]["default"])


def test_a_bad_setup_is_one_line_naming_the_key(doc):
    bad = json.loads(json.dumps(doc))
    bad["stations"]["L_mm"] = -5
    with pytest.raises(RobocalError, match=r"bench.json: stations.L_mm"):
        setup_of(bad, "bench.json")


def test_mark_vocabulary():
    assert mark_names(3) == ("C", "D", "E") and mark_names(5) == ("C", "D", "E1", "E2", "E3")
    assert [mark_index(n) for n in mark_names(5)] == [0, 1, 2, 3, 4]
    with pytest.raises(ValueError):
        mark_index("F")


def _imports(path: Path) -> set[str]:
    """Every module a file imports, relative ones resolved against its package."""
    pkg = ".".join(path.relative_to(ROOT).with_suffix("").parts[:-1])
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = pkg.rsplit(".", node.level - 1)[0] if node.level else ""
            mod = ".".join(p for p in (base, node.module or "") if p)
            out |= {mod} | {f"{mod}.{a.name}" for a in node.names}
    return out


@pytest.mark.parametrize("path, forbidden", [
    ("acq/session/setup.py", "acq.session.procedures"),
    ("acq/session/setup_types.py", "acq.session.procedures"),
    ("sim/emulate/world.py", "sim.emulate."),
])
def test_the_broken_import_circles_stay_broken(path, forbidden):
    """setup <-> procedures (the mark vocabulary now lives with the ruler in setup_types) and world <-> factories
    (world.py, the protocol every device imports, imports nothing of its package)."""
    assert not [m for m in _imports(ROOT / path) if m.startswith(forbidden)]


def test_the_whole_file_has_one_schema(doc):
    """A plan carried in the set-up and the design record are checked with the file, not when first used."""
    with_plan = {**doc, "plan": {"procedures": ["sweeps"], "sweeps": {"points": 1}}}
    with pytest.raises(RobocalError, match=r"bench.json: plan.sweeps.points"):
        setup_of(with_plan, "bench.json")
    good = setup_of({**doc, "plan": {"procedures": ["sweeps"], "sweeps": {"points": 3}}})
    assert good.plan.sweeps.points == 3 and good.plan.procedures == ("sweeps",)
    with pytest.raises(RobocalError, match=r"bench.json: design.ruler"):
        setup_of({**doc, "design": {"ruler": {"variables": {"L_mm": "far"}}}}, "bench.json")
