"""Truths of the geometric stages: the ruler's stations, the swept DH parameters (in the frame the sweeps measure
them in), the misalignment table and the thesis's compensation scheme -- each the twin's geometry at the session's
reference pose."""
from __future__ import annotations

import numpy as np

from calib.angles import wrap_angle
from calib.estimators.misalignment import ROW           # the names the estimates carry: vocabulary, no formula
from calib.kinematics import Kinematics
from calib.units import DEG

from acq.session.procedures import sweep_target
from acq.session.setup import nominal_theta, point_p
from acq.session.setup_types import BenchSetup

from sim.emulate.truth import Scoring, truth_of
from sim.emulate.truth.scheme import misalignment_rows, puma_lengths


@truth_of("ruler")
def ruler_truth(sc: Scoring, trace: dict) -> None:
    A, B = sc.twin.stations
    for name, v in (("L_mm", B.x_mm - A.x_mm), ("gamma1_rad", -A.yaw_rad), ("gamma2_rad", B.yaw_rad - np.pi),
                    ("hB_mm", B.z_mm - A.z_mm)):
        sc.set(f"ruler.{name}", v)


def _frames(sc: Scoring, q0: np.ndarray):
    """Kinematics, the design parameters (the set-up's base), the design chain at the reference pose, the twin's
    true chain there and the joints' deflection from their readings (rad).  Why the deflection: the joints were swept
    with the arm under its own weight and the gears' transmission error, so the axes the sweeps measure are those of
    the twin's chain at its effective joint angles (the readings plus its running errors), not at the readings."""
    kin = Kinematics(sc.robot)
    p_design = nominal_theta(kin, sc.setup)
    truth = sc.truth
    p_true = np.array([truth.get(nm, v) for nm, v in zip(kin.names, p_design)])
    _, theta = sc.twin.true_points(q0[None])
    return kin, p_design, kin.forward(q0[None], p_design), kin.forward(theta, p_true), theta[0] - q0


def base_gauge_truth(truth: dict, setup: BenchSetup, R0: np.ndarray, tv: dict) -> dict:
    """The truth of the first link's d and zero offset in the frame the sweeps measure them in: frame 0 where the
    set-up puts the base (a tape gives it to the millimetre), not where the twin has it.  Why: the foot of joint 1's
    common normal is measured from the set-up's origin along z0, and its zero from the set-up's yaw, so a base 0.1
    mm lower than written reads as d1 0.1 mm larger -- a gauge, not an estimation error."""
    if "base.z_mm" not in truth:
        return {}
    out = {}
    o_true = np.array([truth[f"base.{k}_mm"] for k in "xyz"])
    o_set = np.asarray(setup.base_xyz_mm, float)
    if "j1.d_mm" in tv:
        out["j1.d_mm"] = tv["j1.d_mm"] + float((o_true - o_set) @ R0[:, 2])
    if "j1.theta_offset_rad" in tv and "base.yaw_rad" in truth:
        yaw_set = float(setup.base_rpy_deg[2]) * DEG
        out["j1.theta_offset_rad"] = tv["j1.theta_offset_rad"] + truth["base.yaw_rad"] - yaw_set
    return out


@truth_of("sweeps")
def dh_truth(sc: Scoring, trace: dict) -> None:
    """The twin's DH values; the first link's in the set-up's base frame; a Hayati link's d held at its design value
    moves into the next link's d (its axis is parallel)."""
    if "q0_rad" not in trace:
        return
    robot, truth = sc.robot, sc.truth
    names = [e["name"][3:] for e in sc.res["estimates"] if e["name"].startswith("dh.")]
    _, _, design, _, bent = _frames(sc, np.asarray(trace["q0_rad"], float))
    tv = {n: truth[n] for n in names if n in truth}
    for k in range(robot.n):                 # the sweeps see the joint where its running errors put it, as the
        name = f"j{k + 1}.theta_offset_rad"   # estimate wrapped to a half turn
        if name in tv:
            tv[name] = float(wrap_angle(tv[name] + bent[k]))
    tv.update(base_gauge_truth(truth, sc.setup, design.frame_R[0, 0], tv))
    for k in np.flatnonzero(robot.hayati[:-1]):
        held, nxt = f"j{k + 1}.d_mm", f"j{k + 2}.d_mm"
        if held in truth and nxt in tv:
            tv[nxt] = truth[nxt] + np.cos(robot.alpha_rad[k]) * (truth[held] - robot.d_mm[k])
    for n, v in tv.items():
        sc.set(f"dh.{n}", v)
    for row in sc.res["figures"].get("dh", []):
        row["truth"] = tv.get(row["name"])


@truth_of("misalignment")
def misalignment_truth(sc: Scoring, trace: dict) -> None:
    """The twin's own axes at the reference pose (its effective joint angles there) against the design's."""
    q0 = (sc.res.get("trace", {}).get("sweeps") or {}).get("q0_rad")
    if q0 is None:
        return
    n = sc.robot.n
    _, _, design, true, _ = _frames(sc, np.asarray(q0, float))
    zd = np.array([design.frame_R[0, j][:, 2] for j in range(n)])
    xf = np.array([design.frame_R[0, j + 1][:, 0] for j in range(n)])
    zt = np.array([true.frame_R[0, j][:, 2] for j in range(n)])
    full = [f"j{k + 1}.{r}" for k in range(n) for r in ROW]
    for k, v in zip(full, misalignment_rows(zt, zd, xf).ravel()):
        sc.set(f"misalign.{k}", v)


def twins_own_lengths(truth: dict) -> dict[str, float]:
    """Eq 4.3.15's lengths as the twin's own link values (the description's mapping: a1 = link 2's a, a2 = link 3's
    a read along the base's x -- the opposite sign of Fig 5.10's --, d1 the shoulder offset along the parallel axes 2
    and 3, d2 the elbow-wrist distance, d3 the flange offset); empty for a twin without them."""
    keys = ("j2.a_mm", "j3.a_mm", "j2.d_mm", "j3.d_mm", "j4.d_mm", "j6.d_mm", "j2.alpha_rad")
    if not all(k in truth for k in keys):
        return {}
    t = {k: float(truth[k]) for k in keys}
    shoulder = t["j2.d_mm"] + np.cos(t["j2.alpha_rad"]) * t["j3.d_mm"]       # along axis 2: axis 3 antiparallel
    return {"a1_mm": t["j2.a_mm"], "a2_mm": -t["j3.a_mm"], "d1_mm": float(shoulder),
            "d2_mm": float(np.hypot(t["j4.d_mm"], t["j3.a_mm"])), "d3_mm": t["j6.d_mm"]}


SCHEME_NOTE = ("truth: eq 4.3.15 on the twin's exact axes at the reference pose; the twin's own {name} is {raw:.2f} "
               "mm (truth_raw): the scheme reads it through the tilts and zero offsets it does not compensate")


@truth_of("compensation")
def compensation_truth(sc: Scoring, trace: dict) -> None:
    """The thesis route on the twin's exact geometry at the reference pose (:mod:`sim.emulate.truth.scheme`, not the
    estimator): each sweep target's foot on its true axis as the centre, the true axis directions, P where the twin
    puts it; d3 the twin's flange offset itself.  Where the scheme's reading of the exact axes is not the twin's own
    link value (the twists between the axes and link 2's beta move the wrist sideways, which d1 reads as shoulder
    offset: +3.6 mm on the demo twin), the latter is kept as ``truth_raw`` with a note."""
    q0 = (sc.res.get("trace", {}).get("sweeps") or {}).get("q0_rad")
    if q0 is None or not trace:
        return
    kin, _, design, fp, _ = _frames(sc, np.asarray(q0, float))
    n_links, truth = kin.robot.n, sc.truth
    zd = np.array([design.frame_R[0, j][:, 2] for j in range(6)])
    xf = np.array([design.frame_R[0, j + 1][:, 0] for j in range(6)])
    ax = []
    for j in range(6):
        z, o = fp.joint_axis[0, j], fp.joint_origin[0, j]
        tg = sweep_target(sc.setup, j + 1)
        x = kin.point_on(fp, [n_links if tg.link is None else tg.link], np.asarray(tg.tool_mm, float))[0, 0]
        ax.append(np.concatenate([o + ((x - o) @ z) * z, z]))
    pp = point_p(sc.setup)
    P = kin.point_on(fp, [pp[0]], np.asarray(pp[1]))[0, 0] if pp is not None else np.zeros(3)
    rows = sc.res["figures"].get("compensation", [])
    names = [r["name"] for r in rows]
    scheme = puma_lengths(np.array(ax), zd, xf, P, trace.get("L_p_mm") or 0.0, design.frame_R[0, 0])
    out = {nm: scheme[nm] for nm in names if nm in scheme}
    own = twins_own_lengths(truth)
    if "d3_mm" in out and "d3_mm" in own:
        out["d3_mm"] = own["d3_mm"]
    for nm, v in out.items():
        est, raw = sc.estimate(f"comp.{nm}"), own.get(nm)
        if raw is not None and est is not None and abs(v - raw) > 0.1 * est["error"]:
            sc.set(f"comp.{nm}", v, raw=raw, note=SCHEME_NOTE.format(name=nm.split("_")[0], raw=raw))
        else:
            sc.set(f"comp.{nm}", v)
    for row in rows:
        row["truth"] = out.get(row["name"])
