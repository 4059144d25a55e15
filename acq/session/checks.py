"""Acceptance checks run on a step's readings before the operator decides (accept / repeat / skip / pause).

Each check says what it measured, its limit and, when it fails, what the operator should do (the operator's guide,
docs/operator-guide.md, has the long form).  Limits are defaults for 3" instruments at 2-4 m; the session plan may
override them (``limits``).

Two checks depend on how well the session knows its geometry, so their limits follow it instead of being constants:

* **miss distance** (the sight lines of A and B should meet at the target).  With the stations the technician wrote
  down (tape and mutual sighting: a few mm) only gross mistakes can be told from station error, so the limit is the
  coarse ``miss_distance_mm``.  Once the ruler steps are saved the runner refits the stations (:mod:`.stations`) and
  the limit becomes ``miss_distance_sigmas`` times the miss the reading noise explains (station sigma x distance to
  the target, averaged over the readings), but not below ``miss_distance_floor_mm``: a vertical sighting error of
  a few tens of arc seconds then fails.
* **plausibility** (the sighted point against the robot description).  An uncalibrated description is wrong by
  tens of mm (a Puma's a3 can be 10 mm off, the base is placed with a tape), so the predictor gives each point the
  spread its tolerances imply and the limit is ``plausibility_sigmas`` times that, at least ``plausibility_mm``: it
  catches the wrong target, the wrong pose or a gross blunder, not calibration-sized differences.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from calib.angles import circular_mean, wrap_angle, wrap_float
from calib.errors import RobocalError
from calib.theodolite import PLAIN_MEAN_BELOW, Station, face_mean, intersect  # noqa: F401 (face_mean: re-exported)
from calib.units import ARCSEC, DEG

from .rig import mean_rows

DEFAULT_LIMITS = {
    "face_agreement_arcsec": 40.0,     # |2c| and |2k| from face I / face II
    "repeat_spread_arcsec": 15.0,      # std of repeat sightings
    "miss_distance_mm": 5.0,           # shortest distance between the two stations' sight lines (setup stations)
    "miss_distance_sigmas": 6.0,       # ... with ruler-fitted stations: this many noise sigmas of the miss
    "miss_distance_floor_mm": 0.1,     # ... but never tighter than this
    "encoder_ptp_counts": 2.0,         # encoder counts moving while holding
    "encoder_pose_deg": 0.05,          # encoder reading vs commanded pose
    "plausibility_mm": 30.0,           # sighted point vs the nominal model: at least this
    "plausibility_sigmas": 3.0,        # ... or this many sigmas of the description's tolerances at that point
    "level_arcsec": 10.0,              # residual tilt of a levelled theodolite (a 20"/2 mm plate level: half a mark)
    "collimation_arcsec": 20.0,        # collimation c and index i of an instrument in adjustment (instrument check)
}


@dataclass
class Check:
    name: str
    passed: bool
    value: float | None
    limit: float | None
    unit: str
    message: str

    def as_row(self, attempt: int) -> dict:
        return {"attempt": attempt, "name": self.name, "passed": self.passed, "value": self.value,
                "limit_value": self.limit, "unit": self.unit, "message": self.message}




def _mean(xs: list[float]) -> float:
    """np.mean's float of a list: one or two readings (a face's, in a step) in plain floats -- a sum of two halved is
    numpy's mean of two -- more through numpy (its pairwise sum)."""
    return float(np.mean(xs)) if len(xs) > 2 else sum(xs[1:], xs[0]) / len(xs)


def sample_std(xs: list[float]) -> float:
    """``np.std(xs, ddof=1)`` as a float; fewer than :data:`calib.theodolite.PLAIN_MEAN_BELOW` values (a step's
    repeats) in plain floats, numpy's operations in numpy's order -- the mean, the squared deviations, their sum over
    n - 1, the root -- so the same float (a test holds them equal) without numpy's per-call cost."""
    n = len(xs)
    if n >= PLAIN_MEAN_BELOW or n < 2:
        return float(np.std(np.asarray(xs, float), ddof=1))
    m = sum(xs[1:], xs[0]) / n
    sq = [(x - m) * (x - m) for x in xs]
    return math.sqrt(sum(sq[1:], sq[0]) / (n - 1))


def _grouped(readings: list[dict], *fields: str) -> dict[tuple, list[dict]]:
    """Readings by the values of ``fields``, each group in the readings' order: one pass over a step's readings
    instead of one per group (the checks run at every step, on a dozen readings)."""
    out: dict[tuple, list[dict]] = {}
    for r in readings:
        key = tuple([r[f] for f in fields])
        got = out.get(key)
        if got is None:
            out[key] = [r]
        else:
            got.append(r)
    return out


def vector_norm(x: np.ndarray) -> float:
    """``float(np.linalg.norm(x))`` of a 1-D float array: numpy's own steps for a vector (the square root of its
    dot with itself; a correctly rounded root either way) without the wrapper's checks -- a step's checks ask for
    a few distances, where the wrapper cost more than the arithmetic (a test holds them equal)."""
    if x.ndim != 1 or x.dtype != np.float64:
        return float(np.linalg.norm(x))
    return math.sqrt(x.dot(x))


def face_agreement(readings: list[dict], limit_arcsec: float) -> list[Check]:
    out = []
    groups = _grouped(readings, "station", "target")
    for (st, tg) in sorted(groups):
        rs = groups[(st, tg)]
        f1 = [r for r in rs if r["face"] == 1]
        f2 = [r for r in rs if r["face"] == 2]
        if not f1 or not f2:
            continue
        hz1, v1 = _mean([r["hz_rad"] for r in f1]), _mean([r["v_rad"] for r in f1])
        hz2, v2 = _mean([r["hz_rad"] for r in f2]), _mean([r["v_rad"] for r in f2])
        two_c = abs(wrap_float(hz1 - (hz2 - np.pi))) / ARCSEC
        two_k = abs(float(v1 + v2 - 2 * np.pi)) / ARCSEC
        worst = max(two_c, two_k)
        ok = worst <= limit_arcsec
        out.append(Check(f"face I/II {st} {tg}", ok, worst, limit_arcsec, "arcsec",
                         "faces agree" if ok else f"face I and II of {st} on {tg} differ by {worst:.0f}\": re-sight "
                         f"both faces on the target centre; if it persists, check the instrument's collimation"))
    return out


def repeat_spread(readings: list[dict], limit_arcsec: float) -> list[Check]:
    out = []
    groups = _grouped(readings, "station", "target", "face")
    for key in sorted(groups):
        rs = groups[key]
        if len(rs) < 2:
            continue
        h0 = rs[0]["hz_rad"]
        s = max(sample_std([wrap_float(r["hz_rad"] - h0) for r in rs]), sample_std([r["v_rad"] for r in rs])) / ARCSEC
        ok = s <= limit_arcsec
        out.append(Check(f"repeat spread {key[0]} {key[1]} face {key[2]}", ok, s, limit_arcsec, "arcsec",
                         "repeats agree" if ok else "repeat sightings scatter: the target or instrument moved; "
                         "check the tripod and the robot brakes, then repeat"))
    return out


#: the checks' intersections stop once every point's Gauss-Newton step is below this (mm), instead of the
#: reduction's 1e-10 (rounding).  Why it is safe: the points only meet millimetre limits (the tightest, the miss
#: floor, is 0.1 mm; the figures are shown to 0.01 mm), and from the closest point of two sight lines Gauss-Newton
#: converges quadratically (next step ~ 3e-3/mm x step^2: the demo's first steps 1e-5..1e-3 mm, the second
#: 1e-13..1e-8 mm, the third rounding), so after a step below 1e-6 mm the step not taken is rounding, far below
#: 1e-9 mm.  It saves the third iteration, which only confirmed convergence.
CHECK_STEP_TOL_MM = 1e-6


def intersect_targets(readings: list[dict], stations: dict[str, Station]) -> dict[str, tuple]:
    """Target name -> (point_mm, cov_mm2, miss_mm) from face-averaged readings of the two stations (named as in
    ``stations``: the set-up names them).  All targets in one intersection (it is vectorised over points), to
    :data:`CHECK_STEP_TOL_MM`."""
    names = list(stations)[:2]
    seen: dict[str, list] = {}
    groups = _grouped(readings, "station", "target")
    for tg in sorted({r["target"] for r in readings}):
        pair = []
        for st in names:
            rs = groups.get((st, tg))
            if not rs:
                break
            # lists, not arrays: face_mean takes a few readings in plain floats (a sequence is all it needs)
            pair.append(face_mean([r["hz_rad"] for r in rs], [r["v_rad"] for r in rs], [r["face"] for r in rs]))
        if len(pair) == 2:
            seen[tg] = pair
    if not seen:
        return {}
    hv = np.array(list(seen.values()))                              # (targets, station, (hz, v))
    x = intersect([stations[n] for n in names], [(hv[:, k, 0], hv[:, k, 1]) for k in range(2)],
                  step_tol_mm=CHECK_STEP_TOL_MM)
    return {tg: (x.point_mm[i], x.cov_mm2[i], float(x.miss_mm[i])) for i, tg in enumerate(seen)}


def miss_sigma_mm(readings: list[dict], stations: dict[str, Station], point_mm: np.ndarray, target: str) -> float:
    """1-sigma miss distance the reading noise explains at ``point_mm``: each station's vertical sigma times its
    distance to the point, over the square root of the readings averaged (faces and repeats)."""
    var = 0.0
    for name in list(stations)[:2]:
        st = stations[name]
        n = max(1, sum(1 for r in readings if r["station"] == name and r["target"] == target))
        d = vector_norm(np.asarray(point_mm) - st.position)
        var += (st.sigma_v_rad * d) ** 2 / n
    return float(np.sqrt(var))


def miss_and_plausibility(readings: list[dict], stations: dict[str, Station], predicted: dict, limits: dict,
                          fitted: bool = False) -> list[Check]:
    """Miss distance of the sight lines per target and, where ``predicted`` has the target, its distance from the
    model's point.  ``predicted`` maps target -> point (mm) or (point, sigma_mm); ``fitted``: the stations come from
    the ruler fit, so the miss limit follows the reading noise (module docstring)."""
    out = []
    try:
        pts = intersect_targets(readings, stations)
    except RobocalError as exc:
        return [Check("intersection", False, None, None, "", f"sight lines do not intersect ({exc}); check that "
                                                              f"both theodolites are on the same target")]
    for tg, (p, _, miss) in pts.items():
        if fitted:
            lim = max(limits["miss_distance_floor_mm"],
                      limits["miss_distance_sigmas"] * miss_sigma_mm(readings, stations, p, tg))
        else:
            lim = limits["miss_distance_mm"]
        ok = miss <= lim
        out.append(Check(f"miss distance {tg}", ok, miss, lim, "mm",
                         "sight lines meet" if ok else f"the sight lines of {' and '.join(list(stations)[:2])} pass "
                         f"{miss:.2f} mm apart: one "
                         f"instrument is not on the centre of {tg} (most often a vertical pointing error); re-sight "
                         f"both"))
        if tg in predicted:
            pr = predicted[tg]
            point, sig = (pr if isinstance(pr, tuple) else (pr, 0.0))
            d = vector_norm(p - np.asarray(point))
            lim = max(limits["plausibility_mm"], limits["plausibility_sigmas"] * float(sig))
            ok = d <= lim
            out.append(Check(f"plausible {tg}", ok, d, lim, "mm",
                             "where the model expects it" if ok else f"{tg} is {d:.0f} mm from where the robot "
                             f"model puts it: wrong target, wrong pose or a gross sighting error"))
    return out


def encoders_settled(cap, pose_deg, limits: dict) -> list[Check]:
    if cap is None:
        return []
    if cap.n < 3:
        return [Check("encoders", False, float(cap.n), 3.0, "samples",
                      "too few encoder samples: check the tap connection")]
    counts = np.asarray(cap.counts)
    ptp = float((counts.max(0) - counts.min(0)).max())                  # np.ptp's numbers, without its wrappers
    out = [Check("encoders settled", ptp <= limits["encoder_ptp_counts"], ptp, limits["encoder_ptp_counts"], "counts",
                 "robot holding still" if ptp <= limits["encoder_ptp_counts"] else
                 "encoder counts still moving: wait for the robot to settle (brakes, servo), then repeat")]
    joint_rad = np.asarray(cap.joint_rad)
    if pose_deg is not None and np.isfinite(joint_rad).all():
        dev = float(np.abs(mean_rows(joint_rad) / DEG - np.asarray(pose_deg)).max())
        ok = dev <= limits["encoder_pose_deg"]
        out.append(Check("pose reached", ok, dev, limits["encoder_pose_deg"], "deg",
                         "encoders read the requested pose" if ok else
                         f"encoders read {dev:.3f} deg away from the requested pose: move the robot there"))
    return out


def levelled(step, readings: list[dict], values: dict, limits: dict) -> list[Check]:
    """Levelling step: the residual tilt the operator read, across and along, against ``level_arcsec``."""
    tilt = [abs(float(values[k])) for k in ("tilt_cross_arcsec", "tilt_length_arcsec") if k in values]
    if not tilt:
        return [Check("level", False, None, limits["level_arcsec"], "arcsec",
                      "no tilt entered: read the instrument's level and enter both tilts")]
    worst = max(tilt)
    ok = worst <= limits["level_arcsec"]
    st = step.setup.get("station", "")
    return [Check(f"level {st}", ok, worst, limits["level_arcsec"], "arcsec",
                  "levelled" if ok else f"theodolite {st} tilts {worst:.0f}\": level it again (plate level at 90 "
                  f"deg steps, then the electronic level) -- the analysis needs parallel vertical axes")]


def instrument_errors(step, readings: list[dict], values: dict, limits: dict) -> list[Check]:
    """Instrument check: collimation c = 2c/2 and index i = 2k/2 of each station from its two faces on the far
    target, each against ``collimation_arcsec``."""
    out = []
    lim = limits["collimation_arcsec"]
    for (st, tg) in sorted({(r["station"], r["target"]) for r in readings}):
        f1 = [r for r in readings if (r["station"], r["target"], r["face"]) == (st, tg, 1)]
        f2 = [r for r in readings if (r["station"], r["target"], r["face"]) == (st, tg, 2)]
        if not f1 or not f2:
            out.append(Check(f"instrument {st}", False, None, lim, "arcsec", f"{st} did not read both faces on "
                             f"{tg}: change face and sight it again"))
            continue
        hz1, v1 = circular_mean([r["hz_rad"] for r in f1]), np.mean([r["v_rad"] for r in f1])
        hz2, v2 = circular_mean([r["hz_rad"] for r in f2]), np.mean([r["v_rad"] for r in f2])
        c = float(wrap_angle(hz1 - (hz2 - np.pi))) / 2 / ARCSEC
        i = float(v1 + v2 - 2 * np.pi) / 2 / ARCSEC
        worst = max(abs(c), abs(i))
        ok = worst <= lim
        out.append(Check(f"instrument {st}", ok, worst, lim, "arcsec",
                         f"collimation {c:+.1f}\", index {i:+.1f}\"" + ("" if ok else
                         f": beyond {lim:g}\" -- two-face means still cancel them, but have {st} adjusted")))
    return out


def missing_inputs(step, values: dict) -> list[Check]:
    """One failed check per value the step needs and the operator did not enter (a load, a gauge, a tilt): the
    plan's value is never taken in its place, so the step cannot be acquired until it is entered."""
    out = []
    for spec in step.inputs:
        v = values.get(spec.name)
        if v is None or not np.isfinite(float(v)):
            hint = "" if spec.suggested is None else f" (the plan asks for {spec.suggested:g} {spec.unit})"
            out.append(Check(f"entered {spec.name}", False, None, None, spec.unit,
                             f"{spec.prompt} ({spec.unit}) was not entered{hint}: enter the value you measured, "
                             f"then repeat (r)"))
    return out


def inputs_as_planned(step, readings: list[dict], values: dict, limits: dict) -> list[Check]:
    """Each entered value against the plan's, where the step gives a tolerance: a mass far from the planned one is
    another mass hung (or a typing slip), which the operator must see before accepting -- the entered value is the
    one the reduction uses."""
    out = []
    for spec in step.inputs:
        if spec.tolerance is None or spec.suggested is None or values.get(spec.name) is None:
            continue
        v = float(values[spec.name])
        dev = abs(v - spec.suggested)
        ok = dev <= spec.tolerance
        both = f"entered {v:g} {spec.unit}, the plan {spec.suggested:g} {spec.unit}"
        out.append(Check(f"as planned {spec.name}", ok, dev, spec.tolerance, spec.unit,
                         f"{spec.prompt}: {both}" if ok else
                         f"{spec.prompt}: {both}, {dev:.3g} {spec.unit} apart — hang what the plan asks and "
                         f"repeat (r), or accept (a) if {v:g} {spec.unit} is really what is there: the entered value "
                         f"is the one used"))
    return out
