"""The broadened validation (issue 14): harder cases from the independent generator, scored right / honest / wrong.

Families: ``single`` (one library effect, 3x the floor), ``two`` (two effects at once), ``near_floor`` (0.3-0.5x),
``outside`` (effects the library lacks -- judged right when left unexplained -- and ones its new entries match),
``heavy_tails`` (Student-t noise and 1 % gross errors, diagnosed with ``--outliers reject``), ``poses`` (50 and 100
poses), ``wrong_noise`` (``--noise-mm`` halved or doubled) and ``clean``.

Judging a case, with E the expected findings and the diagnosis's findings split into confident and doubtful:

* **wrong**: a confident finding outside E (a confidently named wrong effect);
* **wrong, flagged doubtful** (``wrong_doubtful``): no confident wrong finding, but a finding outside E marked
  doubtful -- still a wrong name, counted on its own (the doubtful flag softens it, it does not make it right);
* **right**: every expected finding named (doubtful or not) and nothing outside E (when E is empty: no finding);
* **honest miss**: some expected finding missing and nothing outside E: the diagnosis said less, not something false.

The issue's "no family has more than 5 % wrong" is about the confident wrong findings; both counts are printed.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from calib.diagnose.data import from_arrays
from calib.diagnose.engine import diagnose
from sim.independent import Spec, generate
from calib.diagnose.parallel import map_cases
from calib.loading import load_robot

FAMILIES = ("single", "two", "near_floor", "outside", "heavy_tails", "poses", "wrong_noise", "clean")
SIGMA_MM = 0.05


def _s(kind, level, **params) -> Spec:
    return Spec(kind, params, level)


#: (family, label, specs, expected findings, options)
_CASES = [
    ("single", "TE j4", [_s("transmission_error", 3, joint=4, order=1.8, phase=0.3)], {("transmission_error", 4)}, {}),
    ("single", "JC j3", [_s("joint_compliance", 3, joint=3)], {("joint_compliance", 3)}, {}),
    ("single", "BL j2", [_s("backlash", 3, joint=2)], {("backlash", 2)}, {}),
    ("single", "CC j5->j6", [_s("cross_coupling", 3, joint=6, source=5)], {("cross_coupling", 6, 5)}, {}),
    ("single", "scale j2", [_s("joint_scale", 3, joint=2)], {("joint_scale", 2)}, {}),
    ("single", "tool sag", [_s("tool_sag", 3)], {("tool_flex", None)}, {}),
    ("two", "JC j3 + TE j2", [_s("joint_compliance", 3, joint=3), _s("transmission_error", 3, joint=2, order=1.2,
                                                                         phase=1.0)],
     {("joint_compliance", 3), ("transmission_error", 2)}, {}),
    ("two", "TE j4 + CC j5->j6", [_s("transmission_error", 3, joint=4, order=0.9, phase=0.0),
                                  _s("cross_coupling", 3, joint=6, source=5)],
     {("transmission_error", 4), ("cross_coupling", 6, 5)}, {}),
    ("two", "BL j3 + scale j1", [_s("backlash", 3, joint=3), _s("joint_scale", 3, joint=1)],
     {("backlash", 3), ("joint_scale", 1)}, {}),
    ("near_floor", "TE j6 x0.4", [_s("transmission_error", 0.4, joint=6, order=2.0, phase=0.5)],
     {("transmission_error", 6)}, {}),
    ("near_floor", "JC j2 x0.5", [_s("joint_compliance", 0.5, joint=2)], {("joint_compliance", 2)}, {}),
    ("near_floor", "BL j3 x0.3", [_s("backlash", 0.3, joint=3)], {("backlash", 3)}, {}),
    ("outside", "base rocks with the waist", [_s("base_rock", 2.5, direction=[0.0, 1.0, 0.0])], set(), {}),
    ("outside", "twice-per-turn wobble j1", [_s("axis_wobble2", 2.5, joint=1, phase=0.4)], {("axis_tilt", 1)}, {}),
    ("outside", "quadratic error j2", [_s("joint_quadratic", 2.5, joint=2)], set(), {}),
    ("outside", "instrument moved", [_s("instrument_step", 3, at_s=3600.0, direction=[0.8, -0.6, 0.0])],
     {("instrument_drift", None)}, {}),
    ("outside", "axis wobble j4", [_s("axis_wobble", 3, joint=4, phase=0.7)], {("axis_tilt", 4)}, {}),
    ("heavy_tails", "JC j3, t3 + 1 %", [_s("joint_compliance", 3, joint=3)], {("joint_compliance", 3)},
     {"heavy_tails": True}),
    ("heavy_tails", "TE j4, t3 + 1 %", [_s("transmission_error", 3, joint=4, order=1.8, phase=0.3)],
     {("transmission_error", 4)}, {"heavy_tails": True}),
    ("heavy_tails", "clean, t3 + 1 %", [], set(), {"heavy_tails": True}),
    ("poses", "JC j3, 50 poses", [_s("joint_compliance", 3, joint=3)], {("joint_compliance", 3)}, {"n_poses": 50}),
    ("poses", "TE j4, 50 poses", [_s("transmission_error", 3, joint=4, order=1.8, phase=0.3)],
     {("transmission_error", 4)}, {"n_poses": 50}),
    ("poses", "BL j3, 100 poses", [_s("backlash", 3, joint=3)], {("backlash", 3)}, {"n_poses": 100}),
    ("poses", "clean, 50 poses", [], set(), {"n_poses": 50}),
    ("wrong_noise", "JC j3, noise given x0.5", [_s("joint_compliance", 3, joint=3)], {("joint_compliance", 3)},
     {"noise_factor": 0.5}),
    ("wrong_noise", "JC j3, noise given x2", [_s("joint_compliance", 3, joint=3)], {("joint_compliance", 3)},
     {"noise_factor": 2.0}),
    ("wrong_noise", "clean, noise given x0.5", [], set(), {"noise_factor": 0.5}),
    ("wrong_noise", "clean, noise given x2", [], set(), {"noise_factor": 2.0}),
    ("clean", "clean", [], set(), {}),
]


@dataclass(frozen=True)
class FamilyCase:
    family: str
    label: str
    seed: int
    index: int                   # into the case table

    @property
    def spec(self):
        return _CASES[self.index]


@dataclass
class FamilyResult:
    case: FamilyCase
    verdict: str                 # right / honest / wrong_doubtful / wrong
    named: list[str] = field(default_factory=list)
    seconds: float = 0.0


def family_cases(seeds: int = 1, families: tuple[str, ...] = FAMILIES, first_seed: int = 0,
                 labels: tuple[str, ...] | None = None) -> list[FamilyCase]:
    out = []
    for s in range(first_seed, first_seed + seeds):
        for i, (fam, lab, *_rest) in enumerate(_CASES):
            if fam in families and (labels is None or lab in labels):
                out.append(FamilyCase(fam, lab, s, i))
    return out


def _key(c) -> tuple:
    return (c.kind, c.joint, c.source) if c.kind == "cross_coupling" else (c.kind, c.joint)


def judge(expected: set, findings: list[tuple[tuple, bool]]) -> str:
    """right / honest / wrong_doubtful / wrong (see the module docstring); ``findings``: (key, doubtful)."""
    named = {k for k, _ in findings}
    if {k for k, doubtful in findings if not doubtful} - expected:
        return "wrong"
    if named - expected:
        return "wrong_doubtful"
    return "right" if expected <= named else "honest"


def run_family_case(case: FamilyCase) -> FamilyResult:
    t = time.perf_counter()
    _, _, specs, expected, opt = case.spec
    robot = load_robot()
    c, pts = generate(robot, specs, opt.get("n_poses", 120), 7919 * case.seed + case.index, SIGMA_MM,
                      opt.get("heavy_tails", False))
    data = from_arrays(robot, c.q, pts, noise_mm=SIGMA_MM * opt.get("noise_factor", 1.0), direction=c.direction,
                       payload_kg=c.payload_kg, temperature_c=c.temperature_c, time_s=c.time_s,
                       source=f"independent:{case.label}:seed{case.seed}")
    diag = diagnose(data, level="auto", outliers="reject", nested=False)
    found = [(_key(f.candidate), f.doubtful) for f in diag.selection.findings]
    named = [f.candidate.label + (" (doubtful)" if f.doubtful else "") for f in diag.selection.findings]
    return FamilyResult(case, judge(expected, found), named, time.perf_counter() - t)


@dataclass
class FamilyValidation:
    results: list[FamilyResult]
    seconds: float = 0.0

    def counts(self) -> dict[str, dict[str, int]]:
        out: dict[str, dict[str, int]] = {}
        for r in self.results:
            row = out.setdefault(r.case.family, {"right": 0, "honest": 0, "wrong_doubtful": 0, "wrong": 0})
            row[r.verdict] += 1
        return out

    def wrong_share(self, family: str, verdict: str = "wrong") -> float:
        """Share of ``family``'s cases with ``verdict`` (default: confidently wrong)."""
        c = self.counts().get(family)
        return c[verdict] / sum(c.values()) if c else 0.0

    def to_json(self) -> dict:
        return {"families": self.counts(), "seconds": self.seconds,
                "cases": [{"family": r.case.family, "case": r.case.label, "seed": r.case.seed, "verdict": r.verdict,
                           "named": r.named} for r in self.results]}

    def render(self) -> str:
        out = [f"Independent-generator validation: {len(self.results)} cases, {self.seconds:.0f} s",
               f"  {'family':<14}{'right':>7}{'honest':>8}{'wrong, flagged doubtful':>25}{'wrong':>7}"]
        tot = {"right": 0, "honest": 0, "wrong_doubtful": 0, "wrong": 0}
        for fam, c in self.counts().items():
            out.append(f"  {fam:<14}{c['right']:>7}{c['honest']:>8}{c['wrong_doubtful']:>25}{c['wrong']:>7}")
            tot = {k: tot[k] + c[k] for k in tot}
        out.append(f"  {'all':<14}{tot['right']:>7}{tot['honest']:>8}{tot['wrong_doubtful']:>25}{tot['wrong']:>7}")
        bad = [r for r in self.results if r.verdict != "right"]
        if bad:
            out.append("Not right:")
            out += [f"  [{r.verdict}] {r.case.family}: {r.case.label} seed {r.case.seed}: named "
                    f"{', '.join(r.named) or 'nothing'}" for r in bad]
        return "\n".join(out)


def run_families(case_list: list[FamilyCase], workers: int | None = None, progress=None) -> FamilyValidation:
    """Every case, in ``workers`` processes (default: the CPU count)."""
    t = time.perf_counter()
    results = map_cases(run_family_case, case_list, workers, progress)
    return FamilyValidation(results, time.perf_counter() - t)
