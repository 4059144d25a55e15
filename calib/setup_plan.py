"""Design of the measurement set-up for the Chapter 4 procedures (thesis sections 5.2-5.4): where to put the
ruler, the robot and the targets so that the estimation errors are small.

Each procedure has an error function of its set-up geometry built from the same estimators and instrument model the
calibration uses (no second copy of the math):

* ruler pre-calibration: the first-order errors of L, gamma1, gamma2 (:mod:`calib.estimators.ruler`), and what they
  cost at the robot — the position error they cause at the joint centre (X_c1, Y_c1);
* joint sweep: a target at radius R_j swept about an axis at (X_c, Y_c, Z_c); the circle fit's first-order
  covariance (:mod:`calib.estimators.axes`) from the intersection covariance of every target position gives the
  errors of the axis position and direction, and the link-parameter error they imply over a link of length l:
  sqrt(sigma_centre^2 + (l sigma_direction)^2);
* transmission error: two targets A1, A2 a distance R_dj apart on the extended tool; the joint angle's first-order
  error (:mod:`calib.estimators.transmission`, eq 4.4.1).

A search (scipy's differential evolution, seeded) minimises each under the physical constraints: the room, the
instruments' minimum focus distance, 500 < R, L < 3000 mm, 100 < R_j < 1200 mm.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from .errors import GeometryError, RobocalError
from .estimators import axes, ruler, transmission
from .theodolite import intersect, thesis_point, thesis_readings, thesis_stations
from .units import ARCSEC, DEG


@dataclass
class Constraints:
    """Physical limits of the set-up (mm)."""

    room_x_mm: tuple[float, float] = (-1500.0, 3500.0)    # along the baseline, from theodolite A
    room_y_mm: float = 4000.0                             # depth in front of the baseline
    min_focus_mm: float = 900.0                           # closest sighting distance of the instruments
    L_mm: tuple[float, float] = (500.0, 3000.0)
    R_mm: tuple[float, float] = (500.0, 3000.0)
    Rj_mm: tuple[float, float] = (100.0, 1200.0)
    Rd_mm: tuple[float, float] = (50.0, 1000.0)
    sigma_arcsec: float = 3.0
    sigma_ruler_mm: float = 0.05


# -- ruler -----------------------------------------------------------------------------------------------------
def ruler_errors(L_mm: float, R_mm: float, r1_mm: float, X1_mm: float, Y1_mm: float, c: Constraints,
                 gamma1_rad: float = -1.489 * DEG, gamma2_rad: float = 1.358 * DEG,
                 robot_xy_mm: tuple[float, float] = (474.9, 2853.0)) -> dict[str, float]:
    """1-sigma errors of L, gamma1, gamma2 (first order) for a ruler with marks C, D, E at (X1 + [0, r1, R], Y1),
    and the position error they cause at the robot (mm)."""
    s = ruler.simulate_sightings(L_mm, gamma1_rad, gamma2_rad, [((X1_mm, Y1_mm, 0.0), 0.0, 0.0)],
                                 [0.0, r1_mm, R_mm])
    x = np.concatenate([ruler.closed_form_readings(s), [R_mm, r1_mm]])
    J = ruler.closed_form_first_order(x)
    sig = np.r_[[c.sigma_arcsec * ARCSEC] * 6, c.sigma_ruler_mm, c.sigma_ruler_mm]
    cov = (J * sig ** 2) @ J.T
    # what it costs at the robot: d(point)/d(L, g1, g2) of eq 4.3.1 at the joint centre
    a, b = thesis_stations(L_mm, gamma1_rad, gamma2_rad)
    p = np.array([[robot_xy_mm[0], robot_xy_mm[1], 0.0]])
    al, be, ph = thesis_readings(a, b, p)
    base = np.array([L_mm, gamma1_rad, gamma2_rad])
    Jp = np.empty((3, 3))
    for k, h in enumerate((1e-3, 1e-7, 1e-7)):
        d = np.zeros(3)
        d[k] = h
        Jp[:, k] = (thesis_point(al, be, ph, *(base + d)) - thesis_point(al, be, ph, *(base - d)))[0] / (2 * h)
    cp = Jp @ cov @ Jp.T
    e = np.sqrt(np.diag(cov))
    return {"L_mm": float(e[0]), "gamma1_deg": float(e[1] / DEG), "gamma2_deg": float(e[2] / DEG),
            "robot_point_mm": float(np.sqrt(np.trace(cp)))}


# -- joint sweep -----------------------------------------------------------------------------------------------
def sweep_errors(Rj_mm: float, centre_mm, c: Constraints, L_mm: float = 1609.9, axis=(0.0, 0.0, 1.0),
                 span_deg: float = 90.0, n_points: int = 8, link_mm: float = 432.0) -> dict[str, float]:
    """Errors of a joint axis from ``n_points`` target positions at radius ``Rj_mm`` over ``span_deg``."""
    n = np.asarray(axis, float)
    n = n / np.linalg.norm(n)
    e1 = np.cross(n, [1.0, 0, 0] if abs(n[0]) < 0.9 else [0, 1.0, 0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    t = np.radians(np.linspace(-span_deg / 2, span_deg / 2, n_points))
    P = np.asarray(centre_mm, float) + Rj_mm * (np.cos(t)[:, None] * e1 + np.sin(t)[:, None] * e2)
    st = list(thesis_stations(L_mm, 0.0, 0.0, c.sigma_arcsec * ARCSEC))
    rd = [s.observe(P) for s in st]
    inter = intersect(st, rd)
    U = np.zeros((3 * n_points, 3 * n_points))
    for i in range(n_points):
        U[3 * i:3 * i + 3, 3 * i:3 * i + 3] = inter.cov_mm2[i]
    theta = axes.fit_circle(P)
    C = axes.circle_first_order(P, theta, U)
    Cc, Cn = C[:3, :3], C[3:6, 3:6]
    proj = np.eye(3) - np.outer(n, n)                   # the centre's position across the axis is what matters
    sc = float(np.sqrt(np.trace(proj @ Cc @ proj)))
    sn = float(np.sqrt(np.trace(Cn)))
    return {"centre_mm": sc, "direction_deg": sn / DEG, "link_mm": float(np.hypot(sc, link_mm * sn)),
            "point_mm": float(np.sqrt(np.mean(np.trace(inter.cov_mm2, axis1=1, axis2=2))))}


# -- transmission error ------------------------------------------------------------------------------------------
def te_errors(Rd_mm: float, centre_mm, c: Constraints, L_mm: float = 1609.9, axis=(0.0, 0.0, 1.0),
              turn_deg: float = 10.0) -> dict[str, float]:
    """First-order error of the joint angle measured from targets A1, A2 spaced ``Rd_mm`` on a tool across the
    axis at ``centre_mm`` (eq 4.4.1), between a reference pose and one turned by ``turn_deg``."""
    n = np.asarray(axis, float)
    n = n / np.linalg.norm(n)
    e1 = np.cross(n, [1.0, 0, 0] if abs(n[0]) < 0.9 else [0, 1.0, 0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    c0 = np.asarray(centre_mm, float)

    def targets(a):
        u = np.cos(a) * e1 + np.sin(a) * e2
        return c0 + 0.5 * Rd_mm * u, c0 - 0.5 * Rd_mm * u

    A1r, A2r = targets(0.0)
    A1, A2 = targets(np.radians(turn_deg))
    pts = np.array([A1r, A2r, A1, A2])
    st = list(thesis_stations(L_mm, 0.0, 0.0, c.sigma_arcsec * ARCSEC))
    inter = intersect(st, [s.observe(pts) for s in st])
    U = np.zeros((12, 12))
    for i in range(4):
        U[3 * i:3 * i + 3, 3 * i:3 * i + 3] = inter.cov_mm2[i]
    x = pts.ravel()
    J = transmission.joint_angle_first_order(x, n)
    return {"angle_deg": float(np.sqrt(J @ U @ J.T)[0, 0] / DEG)}


# -- search --------------------------------------------------------------------------------------------------------
@dataclass
class SetupPlan:
    procedure: str
    variables: dict[str, float]
    errors: dict[str, float]
    objective: str
    trend: list[dict] = field(default_factory=list)
    note: str = ""                   # what the design took as given (e.g. the set-up's robot base)


def _search(fun: Callable[[np.ndarray], float], bounds, seed: int, progress=None, maxiter: int = 40):
    from scipy import optimize      # 0.3-0.5 s to import: only the set-up search needs it
    state = {"k": 0}

    def cb(xk, convergence=0.0):
        state["k"] += 1
        if progress:
            progress("searching", min(1.0, state["k"] / maxiter))

    res = optimize.differential_evolution(fun, bounds, seed=seed, maxiter=maxiter, popsize=12, tol=1e-6,
                                          polish=True, callback=cb)
    return res.x


def _safe(f):
    def g(x):
        try:
            v = f(x)
        except (GeometryError, RobocalError, np.linalg.LinAlgError, FloatingPointError):
            return 1e9
        return v if np.isfinite(v) else 1e9
    return g


def plan_ruler(c: Constraints, seed: int = 0, progress=None) -> SetupPlan:
    """Ruler placement and baseline minimising the position error the theodolite parameters cause at the robot."""
    def unpack(x):
        L, R, frac, X1, Y1 = x
        return L, R, frac * R, X1, Y1

    def feasible(L, R, r1, X1, Y1):
        marks = np.array([X1, X1 + r1, X1 + R])
        dA = np.hypot(marks, Y1)
        dB = np.hypot(marks - L, Y1)
        return (np.all(np.minimum(dA, dB) >= c.min_focus_mm) and X1 >= c.room_x_mm[0]
                and X1 + R <= c.room_x_mm[1] and Y1 <= c.room_y_mm)

    def f(x):
        L, R, r1, X1, Y1 = unpack(x)
        if not feasible(L, R, r1, X1, Y1):
            return 1e9
        return ruler_errors(L, R, r1, X1, Y1, c)["robot_point_mm"]

    bounds = [c.L_mm, c.R_mm, (0.2, 0.8), (c.room_x_mm[0], c.room_x_mm[1] - c.R_mm[0]), (c.min_focus_mm, c.room_y_mm)]
    x = _search(_safe(f), bounds, seed, progress)
    L, R, r1, X1, Y1 = unpack(x)
    trend = [{"L_mm": Lv, **ruler_errors(Lv, R, r1, X1, Y1, c)} for Lv in np.linspace(*c.L_mm, 11)]
    return SetupPlan("ruler", {"L_mm": L, "R_mm": R, "r1_mm": r1, "X1_mm": X1, "Y1_mm": Y1},
                     ruler_errors(L, R, r1, X1, Y1, c), "position error at the robot from L, gamma1, gamma2 (mm)",
                     trend)


def plan_sweep(c: Constraints, seed: int = 0, progress=None, link_mm: float = 432.0,
               axis=(0.0, 1.0, 0.0), centre_mm=None) -> SetupPlan:
    """Robot placement (joint centre X_c, Y_c, Z_c) and radius of rotation R_j minimising the link-parameter error
    for a joint whose axis points along ``axis`` (default: towards the theodolites, the circle facing them).

    ``centre_mm``: the joint centre where a set-up already puts the robot (its ``base_xyz_mm``): only R_j is then
    designed, so the predicted errors describe the set-up the design is written into (a set-up file keeps its robot
    where it stands; a centre chosen here would not move it)."""
    def f(x):
        Rj, Xc, Yc, Zc = x
        if Yc - Rj < c.min_focus_mm or Yc + Rj > c.room_y_mm:
            return 1e9
        return sweep_errors(Rj, (Xc, Yc, Zc), c, link_mm=link_mm, axis=axis)["link_mm"]

    note = ""
    if centre_mm is None:
        bounds = [c.Rj_mm, c.room_x_mm, (c.min_focus_mm, c.room_y_mm), (-1000.0, 1000.0)]
        Rj, Xc, Yc, Zc = _search(_safe(f), bounds, seed, progress)
    else:
        Xc, Yc, Zc = (float(v) for v in centre_mm)
        Rj = float(_search(_safe(lambda x: f([x[0], Xc, Yc, Zc])), [c.Rj_mm], seed, progress)[0])
        note = (f"joint centre fixed where the set-up puts the robot's base (X {Xc:.0f}, Y {Yc:.0f}, Z {Zc:.0f} mm): "
                f"only R_j designed")
    trend = [{"Rj_mm": r, **sweep_errors(r, (Xc, Yc, Zc), c, link_mm=link_mm, axis=axis)}
             for r in np.linspace(*c.Rj_mm, 12)]
    return SetupPlan("sweep", {"Rj_mm": Rj, "Xc_mm": Xc, "Yc_mm": Yc, "Zc_mm": Zc},
                     sweep_errors(Rj, (Xc, Yc, Zc), c, link_mm=link_mm, axis=axis), "link-parameter error (mm)",
                     trend, note)


def plan_te(c: Constraints, seed: int = 0, progress=None) -> SetupPlan:
    """Target spacing R_dj and joint placement minimising the joint-angle error of the transmission-error run."""
    def f(x):
        Rd, Xc, Yc, Zc = x
        if Yc - Rd / 2 < c.min_focus_mm or Yc + Rd / 2 > c.room_y_mm:
            return 1e9
        return te_errors(Rd, (Xc, Yc, Zc), c)["angle_deg"]

    bounds = [c.Rd_mm, c.room_x_mm, (c.min_focus_mm, c.room_y_mm), (-1000.0, 1000.0)]
    Rd, Xc, Yc, Zc = _search(_safe(f), bounds, seed, progress)
    trend = [{"Rd_mm": r, **te_errors(r, (Xc, Yc, Zc), c)} for r in np.linspace(*c.Rd_mm, 12)]
    return SetupPlan("te", {"Rd_mm": Rd, "Xc_mm": Xc, "Yc_mm": Yc, "Zc_mm": Zc}, te_errors(Rd, (Xc, Yc, Zc), c),
                     "joint-angle error (deg)", trend)


PROCEDURES: dict[str, Callable[..., SetupPlan]] = {"ruler": plan_ruler, "sweep": plan_sweep, "te": plan_te}
#: the keyword through which a procedure's design takes the set-up's robot base (``base_xyz_mm``) as given, when the
#: design is written into a set-up (``robocal plan setup --out``)
FIXED_BY_SETUP: dict[str, str] = {"sweep": "centre_mm"}


# -- per-link sweep targets ------------------------------------------------------------------------------------------
def sweep_targets(model, theta: np.ndarray, q_rad: np.ndarray, radius_mm: dict[int, float],
                  toward_mm=(0.0, -1e4, 0.0)) -> dict[str, dict]:
    """A target P_j for each joint's sweep at ``radius_mm[j]`` from joint j's axis (thesis section 4.3: "a reference
    point P_j is chosen on the link j"), fixed on link j.  Where the axis is not vertical the target stands out
    level across it (its circle is then seen edge-on by neither station and the arm, which hangs below or stands
    above the axis, is not between them); on a vertical axis it stands out on the flange's side.  Of the two sides,
    the one facing ``toward_mm`` (the theodolites).  Returns ``{"j": {"link": j, "point_mm": [x, y, z] in frame j,
    "radius_mm": R}}``."""
    n = model.robot.n
    fp = model.kin.forward(np.asarray(q_rad, float)[None], theta[: model.n_geometric])
    R6, t6 = fp.frame_R[0, n], fp.frame_t[0, n]
    g = fp.gravity()[0]
    up = -g / np.linalg.norm(g)
    toward = np.asarray(toward_mm, float)
    out = {}
    for j, R in sorted(radius_mm.items()):
        z, o = fp.joint_axis[0, j - 1], fp.joint_origin[0, j - 1]
        r = t6 - o
        foot = o + (r @ z) * z
        u = np.cross(z, up)                         # level, across the axis
        if np.linalg.norm(u) < 0.1:                 # the axis (nearly) vertical: towards the flange
            u = t6 - foot
            if np.linalg.norm(u) < 1.0:             # the flange on the axis too: along the flange's x
                u = R6[:, 0] - (R6[:, 0] @ z) * z
        u /= np.linalg.norm(u)
        if u @ (toward - foot) < 0:                 # the side of the axis facing the theodolites
            u = -u
        p = foot + float(R) * u
        Rj, tj = fp.frame_R[0, j], fp.frame_t[0, j]
        out[str(j)] = {"link": j, "point_mm": [round(float(v), 2) for v in Rj.T @ (p - tj)], "radius_mm": float(R)}
    return out


# -- the session set-up file ---------------------------------------------------------------------------------------
def _ruler_into(v: dict, setup: dict, placements: int = 3, step_mm: float = 30.0) -> None:
    """The designed ruler (R, r1 at X1, Y1) and baseline L, as a series that varies R as the thesis does (Fig 5.4:
    R from 1792 to 1860 mm): mark E at ``placements`` distances ``step_mm`` apart ending at the designed R, one of them
    sighted per placement with C, D and the last; each placement steps back and turns."""
    setup.setdefault("stations", {})["L_mm"] = round(v["L_mm"], 0)
    X1, Y1, R = v["X1_mm"], v["Y1_mm"], v["R_mm"]
    es = [round(R - step_mm * (placements - 1 - i), 1) for i in range(placements)]
    last = f"E{placements}"
    setup["ruler"] = {"marks_mm": [0.0, round(v["r1_mm"], 1), *es], "placements": [
        {"where": f"designed placement {k + 1}: C at X {X1:.0f}, Y {Y1 + 300.0 * k:.0f} mm, R {es[k]:.0f} mm",
         "C_mm": [round(X1, 1), round(Y1 + 300.0 * k, 1), 0.0], "dir": [1.0, round(0.1 * k, 3), 0.0],
         "marks": list(dict.fromkeys(["C", "D", f"E{k + 1}", last]))}
        for k in range(placements)]}


def _sweep_into(v: dict, setup: dict) -> None:
    setup["sweep_radius_mm"] = round(v["Rj_mm"], 0)
    setup.pop("sweep_targets", None)          # designed again at the new radius when the session starts


def _te_into(v: dict, setup: dict) -> None:
    et = setup.setdefault("extended_tool", {"A1_mm": [0.0, 0.0, 100.0]})
    a1 = np.asarray(et.get("A1_mm", [0.0, 0.0, 100.0]), float)
    et["A2_mm"] = [round(float(x), 1) for x in a1 + v["Rd_mm"] * np.array([1.0, 0.0, 1.0]) / np.sqrt(2.0)]


#: how each procedure's design enters the session set-up file (``robocal plan setup ... --out``)
INTO_SETUP: dict[str, Callable[[dict, dict], None]] = {"ruler": _ruler_into, "sweep": _sweep_into, "te": _te_into}


def into_setup(plans: list[SetupPlan], setup: dict) -> dict:
    """A copy of the session ``setup`` with the designed variables of ``plans`` written in."""
    out = json.loads(json.dumps(setup))
    for p in plans:
        INTO_SETUP[p.procedure](p.variables, out)
    out["design"] = {**out.get("design", {}), **{p.procedure: {"variables": p.variables, "errors": p.errors,
                                                                **({"note": p.note} if p.note else {})}
                                                  for p in plans}}
    return out
