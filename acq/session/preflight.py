"""Pre-flight of a session plan: every step checked against the robot description and the set-up before the robot
moves, so the operator is never asked for something a real cell cannot do.

Why: the emulated bench will happily drive a joint past its stop, hang a weight that produces no torque or sight a
target through the robot's own arm; a real cell cannot.  Each check below computes what the step would physically do
from the one forward model (:class:`calib.model.MeasurementModel`, nominal parameters with the set-up's base) and the
set-up's stations, and compares it with a limit.  The operator's guide (docs/operator-guide.md, "Pre-flight") says
what each check means and what to change when it fails.

Checks (registered in :data:`CHECKS`, each a function ``(Preflight, StepGeometry) -> list[Finding]``):

* ``joint limit``: every joint of ``pose_deg`` inside the description's limits less ``joint_margin_deg``;
* ``reach``: a target on the robot no farther from the base than the arm and its tool can reach, above the floor
  (``floor_z_mm`` of the set-up, when given);
* ``sight``: for each station and target, the sight line's elevation within +-``max_elevation_deg``, the range between
  the instruments' focus distance (``min_focus_mm``) and ``max_range_mm``, and -- when the set-up gives the links'
  thickness (``link_radius_mm``; the description has no link geometry) -- no link of the robot across the line;
* ``intersection``: the angle between the two stations' sight lines at the target within ``intersection_deg``;
* ``sweep radius``: a swept target's distance from the swept joint's axis within ``sweep_radius_mm`` (thesis: 100 to
  1200 mm, about 600 suggested);
* ``load torque``: a hung mass's torque about the tested joint at that pose, from the point, gravity and the joint
  axis through the model's loads, at least ``load_lever_fraction`` of mass x g x its distance from the axis (a weight
  hung where the axis is vertical turns nothing).

Limits: :data:`PREFLIGHT_LIMITS`, overridden by the set-up's ``preflight`` table.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from calib.model import MeasurementModel
from calib.names import joint_label
from calib.units import DEG

from .setup import nominal_theta, setup_stations
from .setup_types import BenchSetup, setup_of
from .steps import Step, TargetSpec

PREFLIGHT_LIMITS = {
    "joint_margin_deg": 2.0,              # stay this far inside every joint limit
    "max_elevation_deg": 45.0,            # theodolite sight lines steeper than this are not readable
    "min_focus_mm": 900.0,                # closest distance the telescopes focus (the set-up's min_focus_mm wins)
    "max_range_mm": 12000.0,              # farthest a 30x telescope resolves a target
    "intersection_deg": [20.0, 160.0],    # angle of the two sight lines at the target
    "sweep_radius_mm": [100.0, 1200.0],   # radius of a swept target about its joint (thesis section 5.3)
    "load_lever_fraction": 0.5,           # torque at least this fraction of m g r (lever within 60 deg of level)
    "reach_margin": 1.1,                  # targets no farther from the base than this x the arm's reach
    "link_radius_mm": None,               # thickness of the links for the line of sight (None: not checked)
}


@dataclass(frozen=True)
class Finding:
    """One failed check of one step: what, where, the value against its limit."""

    check: str
    key: str
    value: float
    limit: float
    unit: str
    detail: str

    def line(self) -> str:
        return f"{self.key}: {self.check}: {self.detail}"


@dataclass
class StepGeometry:
    """What the nominal model says a step does physically: the chain at its pose and where its targets are."""

    step: Step
    fp: object | None                        # calib.kinematics.ChainPass at the pose (one pose), or None
    points: dict[str, np.ndarray]            # target name -> point in the measurement frame (mm)


CHECKS: dict[str, Callable[["Preflight", StepGeometry], list[Finding]]] = {}
#: the checks that read the stations (the runner's ruler refit changes them); the others' findings are kept per step
USES_STATIONS: set[str] = set()


def preflight_check(name: str, uses_stations: bool = False):
    """Register a check under ``name`` (runs on every step; a check that does not apply returns []);
    ``uses_stations``: its findings depend on ``Preflight.stations`` (computed again at each check of a step)."""
    def deco(fn):
        CHECKS[name] = fn
        if uses_stations:
            USES_STATIONS.add(name)
        return fn
    return deco


class Preflight:
    """Checks steps against ``robot`` and ``setup``; ``stations`` default to the set-up's (name -> Station)."""

    def __init__(self, robot, setup: BenchSetup | dict, stations: dict | None = None, limits: dict | None = None):
        setup = setup_of(setup)
        self.robot = robot
        self.setup = setup
        self.model = MeasurementModel(robot)
        self.theta = nominal_theta(self.model, setup)
        self.stations = stations if stations is not None else setup_stations(setup)
        lim = {**PREFLIGHT_LIMITS, **({} if setup.min_focus_mm is None else {"min_focus_mm": setup.min_focus_mm})}
        self.limits = {**lim, **setup.preflight, **(limits or {})}
        self.g_n_per_kg = self.model.gravity_n_per_kg(self.theta)
        self._chains: dict[tuple, object] = {}     # pose -> one-pose chain pass (nominal model: stations do not matter)
        self._links: dict[int, tuple] = {}         # id(chain pass) -> (pass, links, segments) for the line of sight
        self._fixed: dict[int, tuple] = {}         # id(step) -> (step, geometry, findings of the station-free checks)
        self._unloaded: dict[int, tuple] = {}      # id(chain pass) -> (pass, joint torques without hung masses)
        # each joint's limits in its edge unit (deg or mm), as plain floats: the same numbers as
        # ``limits_rad / scale`` (one IEEE division), without numpy per scalar at every step
        self._joint_bounds = [(float(lo), float(hi), pr)
                              for (lo, hi), pr in ((robot.limits_rad[j] / (1.0 if robot.prismatic[j] else DEG),
                                                    bool(robot.prismatic[j])) for j in range(robot.n))]
        self.reach_mm = arm_reach_mm(robot)

    # -- geometry ------------------------------------------------------------------------------------------------
    def geometry(self, step: Step) -> StepGeometry:
        fp = self.chain(step)
        return StepGeometry(step, fp, self._points(step, fp))

    def chain(self, step: Step):
        """The nominal chain at the step's pose (one pose), or None; kept per pose: the runner checks every step
        once before the session and again, with the refitted stations, before it runs (the chain does not depend on
        the stations)."""
        if not self._posed(step):
            return None
        key = tuple(step.pose_deg)
        fp = self._chains.get(key)
        if fp is None:
            fp = self.model.kin.forward(np.asarray(key, float)[None] * DEG, self.theta[: self.model.n_geometric])
            self._keep(key, fp)
        return fp

    def _posed(self, step: Step) -> bool:
        return step.pose_deg is not None and len(step.pose_deg) == self.robot.n

    def _points(self, step: Step, fp) -> dict[str, np.ndarray]:
        pts = {}
        for t in step.targets:
            p = self.target_point(fp, t)
            if p is not None:
                pts[t.name] = p
        return pts

    def target_point(self, fp, t: TargetSpec) -> np.ndarray | None:
        """A target's point in the measurement frame: fixed (``point_mm``) or carried by link ``t.link``."""
        if t.point_mm is not None:
            return np.asarray(t.point_mm, float)
        if t.tool_mm is None or fp is None:
            return None
        j = self.robot.n if t.link is None else int(t.link)
        return self.model.kin.point_on(fp, [j], np.asarray(t.tool_mm, float)[None])[0, 0]

    # -- running -------------------------------------------------------------------------------------------------
    def check_step(self, step: Step) -> list[Finding]:
        """The step's findings in the registry's order.  Its geometry and the findings of the checks that do not
        read the stations are kept per step: the runner checks every step before the session and again, with the
        refitted stations, before it runs it."""
        got = self._fixed.get(id(step))
        if got is None or got[0] is not step:
            geo = self.geometry(step)
            got = (step, geo, {name: fn(self, geo) for name, fn in CHECKS.items() if name not in USES_STATIONS})
            if len(self._fixed) < 10_000:
                self._fixed[id(step)] = got
        _, geo, fixed = got
        out: list[Finding] = []
        for name, fn in CHECKS.items():
            out += fixed[name] if name in fixed else fn(self, geo)
        return out

    def check(self, steps: list[Step]) -> list[Finding]:
        """Every step's findings, in step order; the chain runs once for all the steps' poses not seen yet."""
        new = {tuple(s.pose_deg) for s in steps if self._posed(s)} - self._chains.keys()
        if new:
            poses = sorted(new)
            fp = self.model.kin.forward(np.array(poses, float) * DEG, self.theta[: self.model.n_geometric])
            for k, pose in enumerate(poses):
                self._keep(pose, fp.pose(k))
        out: list[Finding] = []
        for s in steps:
            out += self.check_step(s)
        return out

    def _keep(self, pose: tuple, fp) -> None:
        if len(self._chains) < 10_000:
            self._chains[pose] = fp


def failing_lines(findings: list[Finding]) -> list[str]:
    """One line per failing step (its failed checks joined), in step order."""
    by_key: dict[str, list[Finding]] = {}
    for f in findings:
        by_key.setdefault(f.key, []).append(f)
    return [f"{k}: " + "; ".join(f"{f.check}: {f.detail}" for f in fs) for k, fs in by_key.items()]


# -- the checks --------------------------------------------------------------------------------------------------
@preflight_check("joint limit")
def _joint_limits(pf: Preflight, geo: StepGeometry) -> list[Finding]:
    q = geo.step.pose_deg
    if q is None:
        return []
    r = pf.robot
    margin = pf.limits["joint_margin_deg"]
    out = []
    for j, (lo, hi, prismatic) in enumerate(pf._joint_bounds[:min(len(q), r.n)]):
        m, unit = (0.0, "mm") if prismatic else (margin, "deg")
        for bound, beyond in ((lo + m, q[j] < lo + m), (hi - m, q[j] > hi - m)):
            if beyond:
                out.append(Finding("joint limit", geo.step.key, float(q[j]), float(bound), unit,
                                   f"{joint_label(r, j + 1)} at {q[j]:.1f} {unit}, limit {bound:.1f} {unit} "
                                   f"({lo if bound == lo + m else hi:.1f} with a {m:g} {unit} margin)"))
    return out


def arm_reach_mm(robot) -> float:
    """Farthest a point on the arm can be from the base origin: the links' lengths in a row."""
    return float(np.sum(np.hypot(robot.a_mm, robot.d_mm)))


def _on_robot(geo: StepGeometry):
    for t in geo.step.targets:
        if t.point_mm is None and t.name in geo.points:
            yield t, geo.points[t.name]


@preflight_check("reach")
def _reach(pf: Preflight, geo: StepGeometry) -> list[Finding]:
    if geo.fp is None:
        return []
    out = []
    base = geo.fp.frame_t[0, 0]
    for t, p in _on_robot(geo):
        j = pf.robot.n if t.link is None else t.link
        reach = pf.limits["reach_margin"] * (pf.reach_mm + float(np.linalg.norm(t.tool_mm)))
        d = float(np.linalg.norm(p - base))
        if d > reach:
            out.append(Finding("reach", geo.step.key, d, reach, "mm", f"target {t.name} (link {j}) {d:.0f} mm "
                               f"from the base, the arm with that target reaches {reach:.0f} mm"))
    floor = pf.setup.floor_z_mm
    if floor is not None:
        lowest = min([float(np.min(geo.fp.frame_t[0, :, 2]))] + [float(p[2]) for _, p in _on_robot(geo)])
        if lowest < floor:
            out.append(Finding("reach", geo.step.key, lowest, float(floor), "mm",
                               f"the arm goes down to z {lowest:.0f} mm, below the floor at {floor:.0f} mm"))
    return out


#: samples along each link for the line-of-sight test (fractions 0..1 of the link)
_LINK_SAMPLES = np.linspace(0.0, 1.0, 40)[None, :, None]


def _link_points(b0, b1, n: int = 40) -> np.ndarray:
    """``n`` points along each segment b0[k]-b1[k] (K, n, 3), ends included."""
    s = _LINK_SAMPLES if n == _LINK_SAMPLES.shape[1] else np.linspace(0.0, 1.0, n)[None, :, None]
    return b0[:, None] + s * (b1 - b0)[:, None]


def _distances_to(a0, a1, pts) -> np.ndarray:
    """Shortest distances between the segments a0-a1 ((3,) or (S, 3): one per station) and the point sets ``pts``
    (K, n, 3): (K,) or (S, K), exact along a."""
    a0, a1 = np.asarray(a0, float), np.asarray(a1, float)
    one = a0.ndim == 1
    a0, u = np.atleast_2d(a0), np.atleast_2d(a1 - a0)                        # (S, 3)
    uu = np.einsum("sc,sc->s", u, u)
    diff = pts[None] - a0[:, None, None, :]                                   # (S, K, n, 3)
    t = np.clip(np.matmul(diff, (u / np.where(uu > 0, uu, 1.0)[:, None])[:, None, :, None])[..., 0], 0.0, 1.0)
    d = np.sqrt(np.min(np.sum((diff - t[..., None] * u[:, None, None, :]) ** 2, axis=-1), axis=-1))   # (S, K)
    return d[0] if one else d


@preflight_check("sight", uses_stations=True)
def _sight(pf: Preflight, geo: StepGeometry) -> list[Finding]:
    lim = pf.limits
    out = []
    names = list(pf.stations)
    # the stations' centres as plain floats (Station.position's numbers): numpy per scalar costs 10x more
    centres = [[float(st.x_mm), float(st.y_mm), float(st.z_mm)] for st in pf.stations.values()]
    for name, p in geo.points.items():
        rngs = []
        pl = p.tolist()
        for sname, c in zip(names, centres):
            dx, dy, dz = pl[0] - c[0], pl[1] - c[1], pl[2] - c[2]
            rng = math.sqrt(dx * dx + dy * dy + dz * dz)
            rngs.append(rng)
            el = math.degrees(math.atan2(dz, math.hypot(dx, dy)))
            if abs(el) > lim["max_elevation_deg"]:
                out.append(Finding("sight", geo.step.key, el, lim["max_elevation_deg"], "deg",
                                   f"station {sname} sees {name} at {el:+.1f} deg elevation, limit "
                                   f"+-{lim['max_elevation_deg']:g} deg"))
            if rng < lim["min_focus_mm"]:
                out.append(Finding("sight", geo.step.key, rng, lim["min_focus_mm"], "mm",
                                   f"{name} is {rng:.0f} mm from station {sname}, closer than its focus distance "
                                   f"{lim['min_focus_mm']:.0f} mm"))
            elif rng > lim["max_range_mm"]:
                out.append(Finding("sight", geo.step.key, rng, lim["max_range_mm"], "mm",
                                   f"{name} is {rng:.0f} mm from station {sname}, beyond {lim['max_range_mm']:.0f} mm"))
        for sname, blocked in zip(names, _blocking_links(pf, geo, centres, pl, rngs)):
            if blocked is not None:
                j, dist = blocked
                out.append(Finding("sight", geo.step.key, dist, float(pf.limits["link_radius_mm"]), "mm",
                                   f"link {j} passes {dist:.0f} mm from the line of sight of station {sname} to "
                                   f"{name} (link radius {pf.limits['link_radius_mm']:g} mm): the robot hides it"))
    return out


def _blocking_links(pf: Preflight, geo: StepGeometry, stations_mm, p, lengths_mm=None) -> list:
    """Per station (S, 3): (link, distance) of the first link crossing its sight line to ``p`` (frame origin to frame
    origin, thickened by the set-up's ``link_radius_mm``), or None; the last ``2 r`` before the target are left out
    (the target's own mount).  All stations at once; ``lengths_mm``: the lines' lengths when the caller has them.
    The sight lines' ends in plain floats for the screen (:func:`_clear_of`), numpy's operations on the same floats;
    the sampled test, when the screen cannot clear a line, through numpy."""
    r = pf.limits.get("link_radius_mm")
    if not r or geo.fp is None:
        return [None] * len(stations_mm)
    r = float(r)
    stations = np.asarray(stations_mm, float).reshape(-1, 3).tolist()
    p = np.asarray(p, float).tolist()
    d = [[p[0] - c[0], p[1] - c[1], p[2] - c[2]] for c in stations]                      # (S, 3)
    L = [math.sqrt(x * x + y * y + z * z) for x, y, z in d] if lengths_mm is None else \
        [float(x) for x in lengths_mm]
    if not all(x > 0.0 and math.isfinite(x) for x in L):          # a target at a station: numpy's inf and nan
        Lv = np.asarray(L, float)
        end = np.asarray(stations) + np.asarray(d) * np.maximum(0.0, 1.0 - 2.0 * r / Lv)[:, None]
        end = end.tolist()
    else:
        end = []
        for c, dd, length in zip(stations, d, L):
            f = max(0.0, 1.0 - 2.0 * r / length)                     # np.maximum's float for a finite one
            end.append([c[0] + dd[0] * f, c[1] + dd[1] * f, c[2] + dd[2] * f])
    links, segments = _link_samples(pf, geo.fp)
    if all(_clear_of(a, b, segments, r) for a, b in zip(stations, end)):
        return [None] * len(stations)
    out = []
    pts = _link_sample_points(geo.fp, links)
    for dist in _distances_to(np.asarray(stations, float), np.asarray(end, float), pts):
        hit = np.flatnonzero(dist < r)
        out.append((int(links[hit[0]]), float(dist[hit[0]])) if hit.size else None)
    return out


def _link_samples(pf: Preflight, fp) -> tuple[np.ndarray, list]:
    """The links of a one-pose chain pass (frame origin to frame origin, zero-length ones left out) and the links as
    plain floats [(b0, b1, middle, half length), ...]; kept per pass: every station and target of a step, and the
    step's second check with refitted stations, test the same links."""
    got = pf._links.get(id(fp))
    if got is not None and got[0] is fp:
        return got[1], got[2]
    org = fp.frame_t[0].tolist()
    kept, segments = [], []
    for j in range(1, len(org)):
        b0, b1 = org[j - 1], org[j]
        dx, dy, dz = b1[0] - b0[0], b1[1] - b0[1], b1[2] - b0[2]
        if math.sqrt(dx * dx + dy * dy + dz * dz) >= 1e-6:          # np.linalg.norm's sum of three, in order
            kept.append(j)
            segments.append((b0, b1, [(x + y) / 2 for x, y in zip(b0, b1)], math.dist(b0, b1) / 2))
    links = np.array(kept, dtype=np.intp)
    if len(pf._links) < 10_000:
        pf._links[id(fp)] = (fp, links, segments)
    return links, segments


def _link_sample_points(fp, links: np.ndarray) -> np.ndarray:
    """The points sampled along the links (K, n, 3) for the sampled line-of-sight test: only for the few sight
    lines the exact screen (:func:`_clear_of`) cannot clear, so made when asked."""
    org = fp.frame_t[0]
    return _link_points(org[links - 1], org[links])


#: a link is certainly clear of a sight line when the segments' exact distance exceeds the radius by this much (mm):
#: far above the rounding of either computation, far below anything a technician could place
_CLEAR_MARGIN_MM = 1e-6


def _clear_of(a0: list, a1: list, segments: list, r: float) -> bool:
    """True when no link segment comes within ``r`` (+ :data:`_CLEAR_MARGIN_MM`) of the segment a0-a1: the exact
    segment-to-segment distance, a lower bound of the sampled distances :func:`_distances_to` measures (its samples
    lie on the links), so a True here means the sampled test finds no link either.  Plain floats: a dozen segment
    pairs per sight line, where numpy's per-call cost is most of the sampled test."""
    lim = r + _CLEAR_MARGIN_MM
    u = [a1[0] - a0[0], a1[1] - a0[1], a1[2] - a0[2]]
    uu = u[0] * u[0] + u[1] * u[1] + u[2] * u[2]
    for b0, b1, m, half in segments:
        # first the link's enclosing sphere: every point of the link is within ``half`` of its middle, so the
        # middle's distance from the sight line less ``half`` is a lower bound (a third of the exact test's work)
        w = [m[0] - a0[0], m[1] - a0[1], m[2] - a0[2]]
        t = min(max((w[0] * u[0] + w[1] * u[1] + w[2] * u[2]) / uu, 0.0), 1.0) if uu > 0.0 else 0.0
        dx, dy, dz = w[0] - t * u[0], w[1] - t * u[1], w[2] - t * u[2]
        if math.sqrt(dx * dx + dy * dy + dz * dz) - half > lim:
            continue
        if _segment_distance(a0, a1, b0, b1) <= lim:
            return False
    return True


def _segment_distance(p1: list, q1: list, p2: list, q2: list) -> float:
    """Shortest distance between the segments p1-q1 and p2-q2 (3-D points as lists): the closest points' parameters
    clamped to both segments (Ericson, Real-Time Collision Detection, 5.1.9)."""
    d1 = [q1[0] - p1[0], q1[1] - p1[1], q1[2] - p1[2]]
    d2 = [q2[0] - p2[0], q2[1] - p2[1], q2[2] - p2[2]]
    w = [p1[0] - p2[0], p1[1] - p2[1], p1[2] - p2[2]]
    a = d1[0] * d1[0] + d1[1] * d1[1] + d1[2] * d1[2]
    e = d2[0] * d2[0] + d2[1] * d2[1] + d2[2] * d2[2]
    f = d2[0] * w[0] + d2[1] * w[1] + d2[2] * w[2]
    if a <= 1e-12 and e <= 1e-12:
        s = t = 0.0
    elif a <= 1e-12:
        s, t = 0.0, min(max(f / e, 0.0), 1.0)
    else:
        c = d1[0] * w[0] + d1[1] * w[1] + d1[2] * w[2]
        if e <= 1e-12:
            s, t = min(max(-c / a, 0.0), 1.0), 0.0
        else:
            b = d1[0] * d2[0] + d1[1] * d2[1] + d1[2] * d2[2]
            den = a * e - b * b
            s = min(max((b * f - c * e) / den, 0.0), 1.0) if den > 0.0 else 0.0
            t = (b * s + f) / e
            if t < 0.0:
                s, t = min(max(-c / a, 0.0), 1.0), 0.0
            elif t > 1.0:
                s, t = min(max((b - c) / a, 0.0), 1.0), 1.0
    dx = w[0] + d1[0] * s - d2[0] * t
    dy = w[1] + d1[1] * s - d2[1] * t
    dz = w[2] + d1[2] * s - d2[2] * t
    return math.sqrt(dx * dx + dy * dy + dz * dz)


@preflight_check("intersection", uses_stations=True)
def _intersection(pf: Preflight, geo: StepGeometry) -> list[Finding]:
    lo, hi = pf.limits["intersection_deg"]
    sts = list(pf.stations.values())
    if len(sts) < 2:
        return []
    out = []
    c0, c1 = ([float(st.x_mm), float(st.y_mm), float(st.z_mm)] for st in sts[:2])     # Station.position's floats
    for name, p in geo.points.items():
        if lo + _CLEAR_ANGLE_DEG < _angle_deg(p.tolist(), c0, c1) < hi - _CLEAR_ANGLE_DEG:
            continue                # certainly inside the limits (the numpy figure below is for the message)
        u, v = p - sts[0].position, p - sts[1].position
        ang = float(np.degrees(np.arccos(np.clip(u @ v / (np.linalg.norm(u) * np.linalg.norm(v)), -1, 1))))
        if not lo <= ang <= hi:
            bound = lo if ang < lo else hi
            out.append(Finding("intersection", geo.step.key, ang, bound, "deg",
                               f"sight lines meet at {ang:.1f} deg on {name}, limits {lo:g}-{hi:g} deg"))
    return out


#: an intersection angle this far inside its limits (deg) passes whatever the rounding of its computation
_CLEAR_ANGLE_DEG = 1e-6


def _angle_deg(p: list, c0: list, c1: list) -> float:
    """The angle (deg) at ``p`` between the sight lines from ``c0`` and ``c1``, in plain floats (the check's
    screen: a figure near a limit is computed again the check's own way)."""
    u = [p[0] - c0[0], p[1] - c0[1], p[2] - c0[2]]
    v = [p[0] - c1[0], p[1] - c1[1], p[2] - c1[2]]
    nn = math.sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]) * math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    if not nn > 0.0:
        return math.nan
    return math.degrees(math.acos(min(max((u[0] * v[0] + u[1] * v[1] + u[2] * v[2]) / nn, -1.0), 1.0)))


def _axis_distance(fp, joint: int, p: np.ndarray) -> float:
    """Distance (mm) of point p from joint ``joint``'s axis (1-based) at the pose."""
    z, o = fp.joint_axis[0, joint - 1], fp.joint_origin[0, joint - 1]
    r = p - o
    return float(np.linalg.norm(r - (r @ z) * z))


@preflight_check("sweep radius")
def _sweep_radius(pf: Preflight, geo: StepGeometry) -> list[Finding]:
    j = geo.step.meta.get("swept_joint")
    if j is None or geo.fp is None:
        return []
    lo, hi = pf.limits["sweep_radius_mm"]
    out = []
    for t, p in _on_robot(geo):
        r = _axis_distance(geo.fp, j, p)
        if not lo <= r <= hi:
            out.append(Finding("sweep radius", geo.step.key, r, lo if r < lo else hi, "mm",
                               f"target {t.name} turns on a {r:.0f} mm radius about joint {j}, limits "
                               f"{lo:g}-{hi:g} mm"))
    return out


def load_points(pf: Preflight, fp, loads: list[dict]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(links (K,), points in the measurement frame (K, 3) mm, forces (K, 3) N) of hung masses: each pulls its mass
    times the model's gravity (:meth:`calib.model.MeasurementModel.gravity_n_per_kg`) at its point."""
    links = np.array([int(ld["link"]) for ld in loads], int)
    pts = pf.model.kin.point_on(fp, links, np.array([[ld["point_mm"] for ld in loads]], float))[0]
    F = np.array([float(ld["mass_kg"]) * pf.g_n_per_kg for ld in loads])
    return links, pts, F


def load_torques_nm(pf: Preflight, fp, q_rad: np.ndarray, loads: list[dict], points: tuple | None = None) -> np.ndarray:
    """Torque (N m) about every joint from the hung masses alone: ``MeasurementModel.loads`` with the masses as point
    forces (contract C2) less the same without them (the arm's own weight cancels).  ``points``: the masses'
    :func:`load_points` when the caller has them."""
    m = pf.model
    links, _, F = load_points(pf, fp, loads) if points is None else points
    ctx = m.context(1, point_force_link=links, point_force_mm=np.array([[ld["point_mm"] for ld in loads]], float),
                    point_force_n=F[None])
    return m.loads(fp, ctx).joint_torque_nm[0] - _unloaded_torques_nm(pf, fp)


def _unloaded_torques_nm(pf: Preflight, fp) -> np.ndarray:
    """The joint torques of the arm alone at a one-pose chain pass (the model's loads without hung masses), kept
    per pass: a loading series hangs several masses at one pose, and every step is checked twice."""
    got = pf._unloaded.get(id(fp))
    if got is None or got[0] is not fp:
        got = (fp, pf.model.loads(fp, pf.model.context(1)).joint_torque_nm[0])
        if len(pf._unloaded) < 10_000:
            pf._unloaded[id(fp)] = got
    return got[1]


@preflight_check("load torque")
def _load_torque(pf: Preflight, geo: StepGeometry) -> list[Finding]:
    s = geo.step.setup
    loads = [ld for ld in s.get("loads", []) if float(ld.get("mass_kg", 0.0)) > 0]
    j = s.get("tested_joint", s.get("joint"))
    if not loads or j is None or geo.fp is None:
        return []
    q = np.asarray(geo.step.pose_deg, float) * DEG
    hung = load_points(pf, geo.fp, loads)
    tau = load_torques_nm(pf, geo.fp, q, loads, hung)[j - 1]
    _, pts, F = hung
    full = float(sum(np.linalg.norm(f) * _axis_distance(geo.fp, j, p) * 1e-3 for p, f in zip(pts, F)))
    frac = abs(tau) / full if full > 0 else 0.0
    need = pf.limits["load_lever_fraction"]
    if frac >= need:
        return []
    mass = sum(float(ld["mass_kg"]) for ld in loads)
    return [Finding("load torque", geo.step.key, float(abs(tau)), need * full, "N m",
                    f"{mass:.2f} kg hung there gives {abs(tau):.2f} N m about joint {j}, "
                    f"{100 * frac:.0f}% of m g r = {full:.2f} N m (limit {100 * need:.0f}%): "
                    f"load joint {j} where its axis is horizontal and the lever level")]
