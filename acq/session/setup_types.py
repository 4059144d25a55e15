"""The bench set-up as typed data: what the procedures, plans, pre-flight, reduction and emulator read, by attribute.

The file's JSON form (:mod:`acq.session.setup_file`: one schema, defaults filled in where the file is read) stays the
stored and written form -- every key unchanged, others depend on them -- and :func:`setup_of` turns it into these
frozen dataclasses once, at the edge (a file read, a stored session opened, a command line's set-up built).  Old keys
(a load as a lever, gauges as distances) are migrated once by :func:`acq.session.setup.session_setup` before this
view is taken; a field the old or new vocabulary may leave out is ``None`` here, and nothing downstream supplies a
default of its own: the defaults stand in the schema, and the few derived ones in the properties below.

A default the schema gives (station names, reading noise, base orientation, sweep radius) is read from it
(:func:`acq.session.setup_file.default_of`), never repeated here; the dataclass defaults below are those the schema
has none for (a placement's direction, point P's link, a level lever).

The ruler's mark vocabulary (C, D, E or E1, E2 ...) lives here with the ruler it names: the set-up checks a
placement's marks with it, the procedures and the exchange import read it.

Units: lengths in mm, angles in degrees (the file's), loads in N and kg.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any, Mapping

from .plan_doc import SessionPlan, plan_of
from .setup_file import check_setup, default_of

MARKS = ("C", "D", "E")

Vec3 = tuple[float, float, float]


def mark_names(n_marks: int) -> tuple[str, ...]:
    """Names of a ruler's marks: C, D, E for three (the thesis's); C, D, E1, E2 ... when E is marked at several
    distances (the series that varies R)."""
    return MARKS if n_marks == 3 else ("C", "D", *[f"E{i}" for i in range(1, n_marks - 1)])


def mark_index(name: str) -> int:
    """Index of a mark in ``marks_mm`` from its name (C 0, D 1, E or E1 2, E2 3 ...)."""
    if name in ("C", "D", "E"):
        return "CDE".index(name)
    if name.startswith("E") and name[1:].isdigit() and int(name[1:]) >= 1:
        return int(name[1:]) + 1
    raise ValueError(f"unknown ruler mark {name!r} (C, D, E or E1, E2 ...)")


def _vec(v) -> tuple[float, ...] | None:
    return None if v is None else tuple(float(x) for x in v)


def _opt(v, kind=float):
    return None if v is None else kind(v)


@dataclass(frozen=True)
class Stations:
    """The two theodolites as the set-up gives them: baseline ``L_mm`` from a tape, the gammas from mutual
    sighting; the ruler refines them."""

    L_mm: float
    gamma1_deg: float
    gamma2_deg: float
    names: tuple[str, str]                          # default: the schema's (A, B)
    sigma_arcsec: float                             # default: the schema's

    @classmethod
    def of(cls, d: Mapping) -> Stations:
        names = d.get("names") or default_of("stations", "names")
        return cls(float(d["L_mm"]), float(d["gamma1_deg"]), float(d["gamma2_deg"]), (str(names[0]), str(names[1])),
                   float(d.get("sigma_arcsec", default_of("stations", "sigma_arcsec"))))


@dataclass(frozen=True)
class Placement:
    """One placement of the ruler: mark C where (``C_mm``, None when not surveyed) and the ruler's direction;
    ``marks``: the marks it sights (None: all of them)."""

    C_mm: Vec3 | None
    dir: Vec3 = (1.0, 0.0, 0.0)
    where: str | None = None
    marks: tuple[str, ...] | None = None

    @classmethod
    def of(cls, d: Mapping) -> Placement:
        return cls(_vec(d.get("C_mm")), _vec(d.get("dir", (1.0, 0.0, 0.0))), d.get("where"),
                   None if d.get("marks") is None else tuple(str(m) for m in d["marks"]))


@dataclass(frozen=True)
class Ruler:
    """The ruler: its marks' distances from mark C along it (mm) and where it is placed."""

    marks_mm: tuple[float, ...]
    placements: tuple[Placement, ...]

    @property
    def mark_names(self) -> tuple[str, ...]:
        return mark_names(len(self.marks_mm))

    def sighted(self, placement: Placement) -> tuple[str, ...]:
        """The marks a placement sights: those it lists, else every mark."""
        return self.mark_names if placement.marks is None else placement.marks

    @classmethod
    def of(cls, d: Mapping) -> Ruler:
        return cls(tuple(float(v) for v in d["marks_mm"]), tuple(Placement.of(p) for p in d["placements"]))


@dataclass(frozen=True)
class PointP:
    """Point P of eq 4.3.15's d3: a mark on the tool's axis ``L_p_mm`` beyond the flange, on frame ``link``."""

    L_p_mm: float
    link: int = 6

    @classmethod
    def of(cls, d: Mapping | None) -> PointP | None:
        return None if not d else cls(float(d["L_p_mm"]), int(d.get("link", 6)))


@dataclass(frozen=True)
class ExtendedTool:
    """The extended tool's two targets A1 and A2 in the flange frame (mm)."""

    A1_mm: Vec3
    A2_mm: Vec3


@dataclass(frozen=True)
class SweepTarget:
    """Target P_j of one joint's sweep, in frame ``link`` (None: the flange)."""

    point_mm: Vec3
    link: int | None = None
    radius_mm: float | None = None


@dataclass(frozen=True)
class ComplianceLoad:
    """One joint's compliance load: masses at ``point_mm`` on ``link`` (the step vocabulary), and the lever the
    operator measures (``lever_mm`` from the joint's axis, ``theta_i_deg`` above level); old set-ups give only the
    lever and forces, until :func:`acq.session.setup.session_setup` maps them."""

    loads_n: tuple[float, ...]
    link: int | None = None
    point_mm: Vec3 | None = None
    masses_kg: tuple[float, ...] | None = None
    lever_mm: float | None = None
    theta_i_deg: float = 0.0
    pose_deg: tuple[float, ...] | None = None

    @classmethod
    def of(cls, d: Mapping) -> ComplianceLoad:
        return cls(tuple(float(v) for v in d.get("loads_n", ())), _opt(d.get("link"), int), _vec(d.get("point_mm")),
                   _vec(d.get("masses_kg")), _opt(d.get("lever_mm")), float(d.get("theta_i_deg", 0.0)),
                   _vec(d.get("pose_deg")) or None)


@dataclass(frozen=True)
class Gauge:
    """A dial gauge: a point on a link and the axis it reads along."""

    name: str
    link: int
    point_mm: Vec3
    axis: Vec3

    def to_doc(self) -> dict:
        """The file's form (a step records its gauges so)."""
        return {"name": self.name, "link": self.link, "point_mm": list(self.point_mm), "axis": list(self.axis)}


@dataclass(frozen=True)
class LinkLoad:
    """The link-compliance test: gauges along link ``link`` (``joint``'s), masses hung at its end."""

    joint: int
    loads_n: tuple[float, ...] = ()
    link: int | None = None
    gauges_x_mm: tuple[float, ...] = ()
    load_x_mm: float | None = None
    masses_kg: tuple[float, ...] | None = None
    second_moment_mm4: float | None = None
    pose_deg: tuple[float, ...] | None = None
    gauge_sigma_mm: float | None = None
    load_point_mm: Vec3 | None = None
    gauges: tuple[Gauge, ...] | None = None

    @classmethod
    def of(cls, d: Mapping | None) -> LinkLoad | None:
        if not d:
            return None
        gauges = None if d.get("gauges") is None else tuple(
            Gauge(str(g["name"]), int(g["link"]), _vec(g["point_mm"]), _vec(g["axis"])) for g in d["gauges"])
        return cls(int(d["joint"]), tuple(float(v) for v in d.get("loads_n", ())), _opt(d.get("link"), int),
                   tuple(float(v) for v in d.get("gauges_x_mm", ())), _opt(d.get("load_x_mm")),
                   _vec(d.get("masses_kg")), _opt(d.get("second_moment_mm4")), _vec(d.get("pose_deg")) or None,
                   _opt(d.get("gauge_sigma_mm")), _vec(d.get("load_point_mm")), gauges)


@dataclass(frozen=True)
class IsoSetup:
    """``iso9283``: ISO 9283's test as the cell dictates it (:mod:`acq.session.iso_cube`); a field left out is the
    plan's default (the standard's 30 cycles, the cube the search finds, a 2 deg approach)."""
    cycles: int | None = None
    side_mm: float | None = None
    centre_mm: Vec3 | None = None
    approach_deg: float | None = None

    @classmethod
    def of(cls, d: Mapping | None) -> IsoSetup | None:
        if d is None:
            return None
        return cls(_opt(d.get("cycles"), int), _opt(d.get("side_mm")), _vec(d.get("centre_mm")),
                   _opt(d.get("approach_deg")))


@dataclass(frozen=True)
class BenchSetup:
    """The whole set-up file, typed.  ``doc`` is the JSON form it was read from (what a session stores; a writer
    edits a copy of it); it takes no part in equality.  The mappings are read-only views."""

    stations: Stations
    base_xyz_mm: Vec3
    ruler: Ruler
    base_rpy_deg: Vec3                               # default: the schema's
    sweep_radius_mm: float | Mapping[str, float]     # default: the schema's
    tool_target_mm: Vec3 | None = None              # required in a full set-up; a partial one may leave it out
    robot: str = ""                                  # "": the shipped description
    base_link: str = ""                              # "": no chain cut
    tip_link: str = ""
    scenario: str = ""
    min_focus_mm: float | None = None
    floor_z_mm: float | None = None
    preflight: Mapping[str, Any] = field(default_factory=dict)
    sweep_targets: Mapping[int, SweepTarget] | None = None
    reference_pose_deg: tuple[float, ...] | None = None
    point_p: PointP | None = None
    extended_tool: ExtendedTool | None = None
    far_target_mm: Vec3 | None = None
    compliance: Mapping[int, ComplianceLoad] = field(default_factory=dict)
    link: LinkLoad | None = None
    running_errors: tuple[str, ...] | None = None
    plan: SessionPlan | None = None                 # a plan carried in the set-up
    iso9283: IsoSetup | None = None
    doc: Mapping[str, Any] = field(default_factory=dict, compare=False, repr=False)

    @classmethod
    def of(cls, d: Mapping) -> BenchSetup:
        """From a checked document (defaults filled in by :func:`acq.session.setup_file.check_setup`)."""
        et = d.get("extended_tool")
        return cls(
            stations=Stations.of(d["stations"]), base_xyz_mm=_vec(d["base_xyz_mm"]),
            tool_target_mm=_vec(d.get("tool_target_mm")), ruler=Ruler.of(d["ruler"]), robot=d.get("robot") or "",
            base_link=d.get("base_link") or "", tip_link=d.get("tip_link") or "", scenario=d.get("scenario") or "",
            base_rpy_deg=_vec(d.get("base_rpy_deg", default_of("base_rpy_deg"))),
            min_focus_mm=_opt(d.get("min_focus_mm")), floor_z_mm=_opt(d.get("floor_z_mm")),
            preflight=MappingProxyType(dict(d.get("preflight") or {})),
            sweep_radius_mm=d.get("sweep_radius_mm", default_of("sweep_radius_mm")),
            sweep_targets=None if d.get("sweep_targets") is None else MappingProxyType({
                int(k): SweepTarget(_vec(v["point_mm"]), _opt(v.get("link"), int), _opt(v.get("radius_mm")))
                for k, v in d["sweep_targets"].items()}),
            reference_pose_deg=_vec(d.get("reference_pose_deg")) or None, point_p=PointP.of(d.get("point_p")),
            extended_tool=None if et is None else ExtendedTool(_vec(et["A1_mm"]), _vec(et["A2_mm"])),
            far_target_mm=_vec(d.get("far_target_mm")),
            compliance=MappingProxyType({int(k): ComplianceLoad.of(v) for k, v in (d.get("compliance") or {}).items()}),
            link=LinkLoad.of(d.get("link")),
            running_errors=None if d.get("running_errors") is None else tuple(str(t) for t in d["running_errors"]),
            plan=None if d.get("plan") is None else plan_of(d["plan"], "set-up: plan"),
            iso9283=IsoSetup.of(d.get("iso9283")),
            doc=MappingProxyType(d))


def setup_of(setup: BenchSetup | Mapping, where: str = "set-up") -> BenchSetup:
    """The typed set-up: itself when it is one; a JSON document checked against the schema (one line naming
    ``where`` and the key when it is not valid) and typed.  Entry points call it once; what they call takes the
    result."""
    if isinstance(setup, BenchSetup):
        return setup
    return BenchSetup.of(check_setup(dict(setup), where))
