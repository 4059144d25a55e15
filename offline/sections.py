"""What the results say, per procedure: the estimates in the units a metrologist reads, a verdict for each, the thesis's
own numbers beside them, and what to do when a stage failed.  The terminal summary and the HTML report are two views
of these sections (a registry: a new procedure adds one entry, no branch elsewhere).

Names, units and meanings at this edge come from one vocabulary, :mod:`calib.kinds` (lengths in mm; angles in
degrees, an encoder's resolution in arc seconds per count; joint stiffness in N m/rad with lb in/rad beside it, the
thesis's unit); numbers are rounded to their error by :mod:`offline.numbers`.

Verdicts (per estimate, then per section: the worst of its estimates):
* ``determined``: the stated 1-sigma error is small against the quantity (under 10 % of a magnitude such as a
  stiffness or a length; under 0.5 mm / 0.05 deg / 0.001 for a deviation or share that may be near zero);
* ``weakly determined``: under 50 % / 2 mm / 0.25 deg / 0.005;
* ``not determined``: anything larger, or a zero or non-finite error on an estimated quantity;
* ``held at design value``: a parameter the data cannot separate from another, kept at its design value.  It is
  shown as held, not as a failure, and does not weaken its section: the section is judged on what it estimated;
* ``negligible``: the procedure found the effect below what it can resolve and states a one-sided bound instead of an
  estimate (``bounds`` in the results: e.g. the link is at least this stiff); the section's ``bounded`` words say
  what that means (for the link, the thesis's own finding).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from calib.kinds import describe
from calib.units import DEG, NM_PER_LBIN

from offline.numbers import like_value, rounded, value_pm

DETERMINED, WEAK, UNDETERMINED = "determined", "weakly determined", "not determined"
NEGLIGIBLE = "negligible"
#: a parameter kept at its design value: not a failure, and no reason for its section's verdict
HELD = "held at design value (not determined by these poses)"
_RANK = {DETERMINED: 0, NEGLIGIBLE: 0, HELD: 0, WEAK: 1, UNDETERMINED: 2}
#: a difference from the thesis's printed number beyond this many σ is explained in words
THESIS_SIGMAS = 3.0


def needs_action(verdict: str) -> bool:
    """Whether a section's verdict calls for the operator's advice (a weak or missing result, not a bound)."""
    return _RANK[verdict] > 0


@dataclass
class Shown:
    """An estimate as shown: human name, value and error in display units, unit, truth, verdict, note, meaning."""

    name: str
    value: float
    error: float | None
    unit: str
    truth: float | None
    verdict: str
    note: str = ""
    extra: str = ""          # e.g. the lb in/rad equivalent
    meaning: str = ""

    @property
    def unit_text(self) -> str:
        """The unit as printed (``dimensionless`` for a pure number)."""
        return self.unit or "dimensionless"

    @property
    def value_text(self) -> str:
        """``value ± error unit`` rounded to the error, or what a held value is."""
        if self.error is None:
            return f"{self.value:.6g} {self.unit_text}, {HELD}"
        return f"{value_pm(self.value, self.error)} {self.unit_text}"

    def beside(self, x: float) -> str:
        """Another number in this estimate's unit (a truth, the thesis's), rounded as the value is."""
        return like_value(x, self.value, self.error)

    def sigmas(self, x: float) -> float | None:
        """(value - x) in units of the error."""
        return (self.value - x) / self.error if self.error else None


def verdict_of(e: dict) -> str:
    """The verdict of one estimate (see the module docstring)."""
    if e.get("held"):
        return HELD
    err, val = e.get("error"), e.get("value")
    if err is None or not math.isfinite(err) or err <= 0 or val is None or not math.isfinite(val):
        return UNDETERMINED
    unit = e.get("unit", "")
    if describe(e["name"]).magnitude:
        rel = err / abs(val) if val else math.inf
        return DETERMINED if rel < 0.10 else WEAK if rel < 0.5 else UNDETERMINED
    if unit == "mm":
        return DETERMINED if err < 0.5 else WEAK if err < 2.0 else UNDETERMINED
    if unit == "rad":               # against misalignments of up to about a degree (Fig 5.10)
        return DETERMINED if err < 0.05 * DEG else WEAK if err < 0.25 * DEG else UNDETERMINED
    if unit == "1":                 # a dimensionless share that may be near zero (coupling left, E_a slope)
        return DETERMINED if err < 1e-3 else WEAK if err < 5e-3 else UNDETERMINED
    return DETERMINED if err < 0.1 * max(abs(val), 1e-12) else WEAK if err < 0.5 * abs(val) else UNDETERMINED


def shown(e: dict, labels=None) -> Shown:
    """One estimate in display units, named and explained by :func:`calib.kinds.describe` (``labels``: the
    session's joint labels)."""
    d = describe(e["name"], labels)
    err = None if e.get("held") else e.get("error")
    extra = ""
    if e.get("unit") == "N m/rad":
        extra = f"{e['value'] / NM_PER_LBIN:.4g} lb in/rad"
    truth = e.get("truth")
    return Shown(d.name, e["value"] / d.scale, None if err is None else err / d.scale, d.unit,
                 None if truth is None else truth / d.scale, verdict_of(e), e.get("note", ""), extra, d.meaning)


@dataclass
class ThesisRow:
    """One of the thesis's numbers beside robocal's estimate: ``estimate`` names the estimate, ``thesis`` and
    ``thesis_error`` are in display units."""

    label: str
    estimate: str
    thesis: float
    unit: str
    thesis_error: float | None = None
    note: str = ""


@dataclass
class Section:
    key: str                         # procedure name in the session (steps' ``procedure``)
    title: str
    prefixes: tuple[str, ...]        # estimate names that belong here
    what: str                        # what was done, in words
    problem_prefixes: tuple[str, ...] = ()
    advice: str = ""                 # what the operator can do when the stage failed or is weak
    thesis: list[ThesisRow] = field(default_factory=list)
    figures: tuple[str, ...] = ()    # keys of the figure registry (offline.report)
    bounded: str = ""                # what a one-sided bound (no measurable effect) means here, for the verdict
    thesis_bounded: str = ""         # the thesis's own finding to put before it (a session of the thesis's Puma)
    only_with_results: bool = False  # shown only when it has estimates, bounds or problems (a stage that may not apply)


SECTIONS: list[Section] = []


def section(s: Section) -> Section:
    SECTIONS.append(s)
    return s


LB = 1.0 / NM_PER_LBIN
section(Section(
    "ruler", "Theodolite pre-calibration (ruler, §4.2)", ("ruler.",),
    "Marks C, D, E of a ruler sighted from both theodolites, both faces, at several placements; L, γ1, γ2 by least "
    "squares over every placement.", ("ruler",),
    "Repeat the ruler series with the ruler placed farther apart (vary R between 500 and 3000 mm, as the thesis does).",
    [ThesisRow("L (Fig 5.4)", "ruler.L_mm", 1609.9, "mm", 0.3),
     ThesisRow("γ1 (Fig 5.4)", "ruler.gamma1_rad", -1.489, "deg", 0.013),
     ThesisRow("γ2 (Fig 5.4)", "ruler.gamma2_rad", 1.358, "deg", 0.010)], ("ruler",)))
section(Section(
    "sweep", "Joint axes and DH parameters (circle point analysis, §4.3)", ("dh.", "misalign."),
    "Each joint swept alone while a target on its link is sighted; a circle and its axis fitted per joint; the DH "
    "parameters follow from successive axes, and each measured axis against its design direction (the misalignments).",
    ("sweeps", "sweep", "misalignment"),
    "Widen the sweep of a joint whose axis is weakly determined, or put its target farther from the axis "
    "(100-1200 mm, about 600 mm suggested).",
    [ThesisRow("a1 (Fig 5.10)", "dh.j2.a_mm", 431.0, "mm"),
     ThesisRow("a2 (Fig 5.10)", "dh.j3.a_mm", -29.7, "mm"),
     ThesisRow("d2 (Fig 5.10)", "dh.j4.d_mm", 432.2, "mm")], ("sweeps", "dh_lengths", "dh_angles")))
section(Section(
    "sweep", "The thesis's compensation scheme (eqs 4.3.12-15)", ("comp.",),
    "The thesis's own reduction of the sweeps, for a robot of its Puma's structure: the joint centres expressed in "
    "S_fj by the compensation scheme (eqs 4.3.12-13), then eq 4.3.15, with d3 from point P sighted on the tool's axis "
    "L_p beyond the flange (its a2 reads X along the robot base's x, the opposite sign of Fig 5.10's).",
    ("compensation scheme",),
    "Sight point P at READY with both stations, and sweep every joint.",
    [ThesisRow("a1, compensation scheme (eqs 4.3.12-15)", "comp.a1_mm", 431.0, "mm"),
     ThesisRow("d1, compensation scheme", "comp.d1_mm", 154.5, "mm"),
     ThesisRow("d2, compensation scheme", "comp.d2_mm", 432.2, "mm",
               note="eq 4.3.15's d2 is the elbow-wrist distance √(d2² + a2²); Fig 5.10 prints it corrected"),
     ThesisRow("d3 from P and L_p (eq 4.3.15)", "comp.d3_mm", 56.4, "mm")], only_with_results=True))
section(Section(
    "transmission", "Transmission error (§4.4)", ("te.",),
    "The joint angle from two targets on an extended tool, against the encoder, over the joint's range; a harmonic "
    "fit of the difference.", ("transmission",),
    "Repeat with more positions over a wider range of the joint (within its limits), moving one way only.",
    [ThesisRow("K_θ4 amplitude (§5.4.2)", "te.j4.amplitude1_rad", 0.050, "deg"),
     ThesisRow("K_θ4 order", "te.j4.omega", 0.9, "1"),
     ThesisRow("K_θ6 amplitude (§5.4.2)", "te.j6.amplitude1_rad", 0.047, "deg"),
     ThesisRow("K_θ6 order", "te.j6.omega", 1.8, "1")], ("transmission",)))
section(Section(
    "compliance", "Joint stiffness (§4.5)", ("compliance.",),
    "Weights hung at a known point of the link, loading then unloading; the deflection of the joint against the "
    "torque the weights produce about its axis.", ("compliance",),
    "Load the joint at a pose where its axis is horizontal, with more and larger weights; a load that produces no "
    "torque about the joint measures nothing.",
    [ThesisRow("K3 below 100 lb in (§5.5)", "compliance.j3.K1_Nm_per_rad", 1.156e5 * NM_PER_LBIN, "N m/rad"),
     ThesisRow("K3 above", "compliance.j3.K2_Nm_per_rad", 1.223e5 * NM_PER_LBIN, "N m/rad"),
     ThesisRow("K4 below 45 lb in", "compliance.j4.K1_Nm_per_rad", 2.275e5 * NM_PER_LBIN, "N m/rad"),
     ThesisRow("K4 above", "compliance.j4.K2_Nm_per_rad", 1.698e5 * NM_PER_LBIN, "N m/rad")], ("compliance",)))
section(Section(
    "link_compliance", "Link compliance (§4.6)", ("link.",),
    "Dial gauges along a link, loads at its end; the flexural rigidity from the gauge readings.",
    ("link", "link compliance"),
    "Repeat with larger loads or gauges farther from the joint.", [], ("link",),
    bounded="the gauges show no significant bending",
    thesis_bounded="thesis §5.7: link compliance negligible against joint compliance"))
section(Section(
    "coupling", "Wrist cross coupling (§4.7)", ("coupling.",),
    "A wrist joint moved alone, then with its neighbour; the tapped encoder counts give σ_jk.", ("coupling",),
    "Repeat the pair with a larger angle.",
    [ThesisRow("σ56 (§5.6)", "coupling.sigma56", 0.1802, "1", note="maker 0.1806"),
     ThesisRow("σ46", "coupling.sigma46", 0.0131, "1"),
     ThesisRow("σ45", "coupling.sigma45", 0.0139, "1",
               note="the thesis prints 0.0141; its own readings give 0.0139")], ("coupling",)))
section(Section(
    "encoder_resolution", "Encoder resolution (Fig 5.14)", ("resolution.",),
    "One joint turned through a wide arc while the targets are sighted and the encoder counted; the joint angle per "
    "count from the slope.", ("encoder_resolution", "encoder resolution"),
    "Turn the joint through a wider arc (within 180 deg of the first position) with more positions.", [],
    ("resolution",)))
section(Section(
    "poses", "Identification from the pose set (Chapter 6)", ("ident.",),
    "The tool target sighted at every pose of the designed set; the geometry and the running errors identified "
    "together, a quarter of the poses held out to measure the accuracy.", ("poses",),
    "Add poses where the weak parameters move (the identifiability note names the joint), or free fewer parameters.",
    [ThesisRow("a1 (Fig 5.10)", "ident.j2.a_mm", 431.0, "mm"),
     ThesisRow("a2 (Fig 5.10)", "ident.j3.a_mm", -29.7, "mm"),
     ThesisRow("d2 (Fig 5.10)", "ident.j4.d_mm", 432.2, "mm"),
     ThesisRow("d3 (Fig 5.10)", "ident.j6.d_mm", 56.4, "mm")], ("poses",)))


def in_session(sec: Section, res: dict) -> bool:
    """Whether the session recorded this procedure (unknown: assume it did).  A procedure the session never had gets
    no section: advice to repeat a ruler series means nothing to a session imported from a laser tracker."""
    procs = res.get("session", {}).get("procedures")
    if procs is None:
        return True
    return any(procs.get(k) for k in (sec.key, *sec.problem_prefixes))


def section_estimates(sec: Section, estimates: list[dict]) -> list[dict]:
    return [e for e in estimates if e["name"].startswith(sec.prefixes)]


def section_bounds(sec: Section, bounds: list[dict]) -> list[dict]:
    return [b for b in bounds if b["name"].startswith(sec.prefixes)]


def bound_text(b: dict, labels=None) -> str:
    """A bound as a metrologist states it: ``joint 2 link's flexural rigidity EI ≥ 3.1e+12 N mm² (95 %,
    one-sided)``."""
    d = describe(b["name"], labels)
    sign = "≥" if b.get("side", "lower") == "lower" else "≤"
    unit = d.unit or b.get("unit", "").replace("^2", "²")
    text = f"{d.name} {sign} {rounded(b['value'] / d.scale)} {unit} ({100 * b['confidence']:g} %, one-sided)"
    if b.get("detection_limit_Nmm2"):
        text += f"; these loads and gauges could not tell a link stiffer than {rounded(b['detection_limit_Nmm2'])} " \
                f"{unit} from a rigid one"
    return text


def section_problems(sec: Section, problems: list[str]) -> list[str]:
    keys = sec.problem_prefixes or (sec.key,)
    return [p for p in problems if p.split(":", 1)[0].strip().lower() in keys]


def beside_the_thesis(res: dict) -> bool:
    """Whether a results document's robot is the thesis's Puma (its profile says so; a document from before the
    profile: assumed), so its numbers may stand beside the thesis's."""
    return bool((res.get("profile") or {}).get("reference_robot", True))


def shows(sec: Section, res: dict) -> bool:
    """Whether a section appears for these results: its procedure was recorded, and, for a section of a stage that
    may not apply, it has something to say."""
    if not in_session(sec, res):
        return False
    return not sec.only_with_results or bool(section_estimates(sec, res.get("estimates", []))
                                             or section_bounds(sec, res.get("bounds", []))
                                             or section_problems(sec, res.get("problems", [])))


def section_verdict(sec: Section, estimates: list[dict], problems: list[str],
                    bounds: list[dict] = (), thesis: bool = True, labels=None) -> tuple[str, str]:
    """(verdict, reason) of a whole section: the worst of its estimates, negligible when it states a bound instead
    (the effect is below what the procedure resolves; with ``thesis``, the thesis's own finding put before it), or
    not determined when it failed.  Parameters held at their design values are no reason: the section is judged on
    what it estimated.  ``labels``: the session's joint labels, for the reason's words."""
    mine = section_estimates(sec, estimates)
    probs = section_problems(sec, problems)
    if not mine and section_bounds(sec, list(bounds)) and not probs:
        said = "; ".join(filter(None, [sec.thesis_bounded if thesis else "", sec.bounded]))
        return NEGLIGIBLE, said or "below what the procedure can resolve: a one-sided bound is stated"
    if not mine:
        return UNDETERMINED, (probs[0].split(":", 1)[1].strip() if probs else "no data for this procedure")
    estimated = [e for e in mine if not e.get("held")]
    if not estimated:
        return UNDETERMINED, "every parameter was held at its design value"
    worst = max(estimated, key=lambda e: _RANK[verdict_of(e)])
    v = verdict_of(worst)
    if v == DETERMINED:
        return v, "every estimate's error is small against its value"
    # the reason is the estimate's error against its value (a note on an estimate may be about its truth, which is
    # no reason for a verdict; the notes are shown beside the estimates)
    sw = shown(worst, labels)
    return v, f"{sw.name}: {sw.value_text}"


def thesis_rows(sec: Section, estimates: list[dict], thesis: bool = True, labels=None) -> list[dict]:
    """robocal's value beside the thesis's, and their difference in units of robocal's stated error (none unless
    ``thesis``: the robot is the thesis's Puma, :func:`beside_the_thesis`).  A difference beyond
    :data:`THESIS_SIGMAS` is explained (:func:`thesis_difference_words`)."""
    if not thesis:
        return []
    by_name = {e["name"]: e for e in estimates}
    out = []
    for row in sec.thesis:
        e = by_name.get(row.estimate)
        if e is None:
            continue
        s = shown(e, labels)
        diff = s.value - row.thesis
        z = s.sigmas(row.thesis)
        out.append({"label": row.label, "robocal": s.value, "error": s.error, "thesis": row.thesis,
                    "thesis_error": row.thesis_error, "unit": s.unit, "difference": diff, "sigmas": z,
                    "note": "; ".join(filter(None, [
                        row.note, "robocal: one slope over every load (the breakpoint is not determined)"
                        if e.get("single_slope") else "", thesis_difference_words(s, z),
                        f"{HELD}: nothing to compare" if e.get("held") else ""])),
                    "lbin": (s.value * LB, row.thesis * LB) if row.unit == "N m/rad" else None})
    return out


def thesis_difference_words(s: Shown, z: float | None) -> str:
    """Why an estimate lies more than :data:`THESIS_SIGMAS` from the thesis's printed number: the thesis measured
    its own Puma in 1986, and this robot (an emulated twin with its own truth, or another Puma) is not that one."""
    if z is None or abs(z) <= THESIS_SIGMAS:
        return ""
    if s.truth is not None:
        zt = s.sigmas(s.truth)
        return (f"more than {THESIS_SIGMAS:g}σ from the thesis's number because the twin's truth "
                f"({s.beside(s.truth)} {s.unit_text}) is not the thesis's robot; the estimate is {zt:+.1f}σ from "
                f"the twin's truth")
    return (f"more than {THESIS_SIGMAS:g}σ from the thesis's number: this robot is not the one the thesis measured, "
            f"so the difference compares two robots")
