"""Truths of the pose set's identification, in the fit's gauge: parameters the pose set cannot determine are held at
their design values and the free ones absorb their true deviations.  The truth is the twin's own parameters moved
into that gauge by exact rules of the chain -- never the identification run on noise-free data, which would judge
identify by identify (issue 25 item 4):

* the first link's zero offset and d, held: the base takes them (``base Rz(dtheta) Tz(dd)``, exact, as joint 1
  turns about the base's z);
* the last link's parameters, held: the tool point takes them (``M_held^-1 M_twin t`` with ``M = Rz(off) Tz(d) Tx(a)
  Rx(alpha) Ry(beta)``, exact, as joint n's motion stands before M);
* a Hayati link's d, held (its parallel axes have no common normal): the shift ``Tz(dd)`` carried through ``Rx(alpha)
  Ry(beta)`` goes to the next link's d, its part across the axes to this link's a and, turning the common normal, to
  the two joints' zero offsets (to first order in the small angles: 5e-5 mm at the tool, tests/test_truth_gauge.py).

A held parameter the twin has elsewhere that no rule maps leaves the geometry without a truth in the fit's gauge
(said in each note): nothing is guessed.  The twin's own value is kept as ``truth_raw`` where they differ."""
from __future__ import annotations

import numpy as np

from calib.angles import rot_zyx, rpy_from_matrix
from calib.robot import Robot

from sim.emulate.truth import Scoring, truth_of

GAUGE_NOTE = ("truth in the gauge of the held parameters (what perfect data would give with them at their design "
              "values)")
BASE = ("base.x_mm", "base.y_mm", "base.z_mm", "base.yaw_rad", "base.pitch_rad", "base.roll_rad")
TOOL = ("tool.x_mm", "tool.y_mm", "tool.z_mm")


def link_matrix(v: dict[str, float], k: int) -> np.ndarray:
    """Link ``k``'s fixed part ``Rz(off) Tz(d) Tx(a) Rx(alpha) Ry(beta)`` (4, 4) from the values ``v`` (robocal's names;
    the joint's motion stands before it)."""
    off, d, a, al, be = (v[f"j{k}.{f}"] for f in ("theta_offset_rad", "d_mm", "a_mm", "alpha_rad", "beta_rad"))
    T = np.eye(4)
    T[:3, :3] = rot_zyx(off, 0.0, 0.0) @ rot_zyx(0.0, 0.0, al) @ rot_zyx(0.0, be, 0.0)
    T[:3, 3] = [a * np.cos(off), a * np.sin(off), d]
    return T


def base_takes_first_link(v: dict, held: dict, free: set) -> set[str]:
    """The base absorbs link 1's held zero offset and d; returns the held names mapped."""
    names = [n for n in ("j1.theta_offset_rad", "j1.d_mm") if n in held]
    if not names or not set(BASE) <= free:
        return set()
    R = rot_zyx(v["base.yaw_rad"], v["base.pitch_rad"], v["base.roll_rad"])
    t = np.array([v["base.x_mm"], v["base.y_mm"], v["base.z_mm"]])
    turn, lift = v["j1.theta_offset_rad"] - held.get("j1.theta_offset_rad", v["j1.theta_offset_rad"]), \
        v["j1.d_mm"] - held.get("j1.d_mm", v["j1.d_mm"])
    t = t + R[:, 2] * lift
    R = R @ rot_zyx(turn, 0.0, 0.0)
    roll, pitch, yaw = rpy_from_matrix(R)
    v.update(zip(BASE, (*t, yaw, pitch, roll)))
    v.update({n: held[n] for n in names})
    return set(names)


def tool_takes_last_link(v: dict, held: dict, free: set, n: int) -> set[str]:
    """The tool point absorbs link n's held parameters; returns the held names mapped."""
    names = [f"j{n}.{f}" for f in ("theta_offset_rad", "d_mm", "a_mm", "alpha_rad", "beta_rad") if f"j{n}.{f}" in held]
    if not names or not set(TOOL) <= free:
        return set()
    twin = link_matrix(v, n) @ np.r_[[v[t] for t in TOOL], 1.0]
    v.update({nm: held[nm] for nm in names})
    v.update(zip(TOOL, (np.linalg.inv(link_matrix(v, n)) @ twin)[:3]))
    return set(names)


def next_link_takes_hayati_d(v: dict, held: dict, robot: Robot) -> set[str]:
    """Each Hayati link's held d moved into the next link (first to last, so a run of parallel axes carries it on)."""
    mapped = set()
    for k in range(1, robot.n):
        d = f"j{k}.d_mm"
        if not robot.hayati[k - 1] or d not in held or robot.prismatic[k - 1] or robot.prismatic[k]:
            continue            # what it moves, if held too, is the later rules' (or left without a truth)
        dd = v[d] - held[d]
        al, be = v[f"j{k}.alpha_rad"], v[f"j{k}.beta_rad"]
        vx, vy = -dd * np.cos(al) * np.sin(be), dd * np.sin(al)       # Tz(dd) seen past Rx(alpha) Ry(beta)
        across = vy * np.cos(al) + vx * np.sin(be) * np.sin(al)       # ... back before them, across the normal
        v[f"j{k}.a_mm"] += vx * np.cos(be)
        turn = across / v[f"j{k}.a_mm"]
        v[f"j{k}.theta_offset_rad"] += turn
        v[f"j{k + 1}.theta_offset_rad"] -= turn * np.cos(al) * np.cos(be)
        v[f"j{k + 1}.d_mm"] += dd * np.cos(al) * np.cos(be)
        v[d] = held[d]
        mapped.add(d)
    return mapped


def gauge_truth(sc: Scoring, params: list[dict]) -> tuple[dict[str, float], list[str]]:
    """The twin's geometry in the identification's gauge (see the module docstring), and the held geometric
    parameters the twin has elsewhere that no rule maps (then the dict is empty)."""
    kin = sc.twin.model.kin
    truth = sc.truth
    v = {n: float(truth[n]) for n in kin.names if n in truth}
    held = {p["name"]: float(p["value"]) for p in params if not p["estimated"] and p["name"] in v}
    free = {p["name"] for p in params if p["estimated"] and p["name"] in v}
    mapped = next_link_takes_hayati_d(v, held, kin.robot)
    mapped |= base_takes_first_link(v, held, free)
    mapped |= tool_takes_last_link(v, held, free, kin.robot.n)
    left = [n for n, h in held.items() if n not in mapped and not np.isclose(v[n], h, rtol=0, atol=1e-12)]
    return ({} if left else {n: v[n] for n in free}), left


def held_away(sc: Scoring, params: list[dict]) -> dict[str, str]:
    """Estimated effect parameters whose effect has a parameter held away from the twin's value (a joint compliance
    fitted with one slope, its breakpoint held at infinity, where the twin has two slopes and a breakpoint): the free
    one absorbs the difference, so no truth in the fit's gauge is known for it -- name -> why, in words."""
    truth, geo = sc.truth, sc.twin.model.kin.index
    away: dict[str, list[str]] = {}
    for p in params:
        n = p["name"]
        if n not in geo and not p["estimated"] and n in truth and not np.isclose(truth[n], p["value"]):
            away.setdefault(n.rsplit(".", 1)[0], []).append(f"{n.rsplit('.', 1)[1]} held at {p['value']:.4g} "
                                                             f"(twin {truth[n]:.4g})")
    return {p["name"]: "no truth in the fit's gauge: its effect has " + ", ".join(away[p["name"].rsplit(".", 1)[0]])
            for p in params if p["estimated"] and p["name"] not in geo and p["name"].rsplit(".", 1)[0] in away}


@truth_of("poses")
def poses_truth(sc: Scoring, trace: dict) -> None:
    doc = sc.res.get("robot")
    if doc is None or "q_rad" not in trace:
        return
    params, truth = doc["parameters"], sc.truth
    gauge, left = gauge_truth(sc, params)
    unknown = held_away(sc, params)
    if left:
        why = "no truth in the fit's gauge: held " + ", ".join(left) + " differ from the twin's and no rule maps them"
        unknown.update({p["name"]: why for p in params if p["estimated"] and p["name"] in sc.twin.model.kin.index})
    for p in params:
        n, raw = p["name"], truth.get(p["name"])
        est = sc.estimate(f"ident.{n}")
        if not p["estimated"]:                      # held: its value is the design value by choice
            p["truth"], p["note"] = None, "held at its design value, not estimated: no truth to compare it with"
            if raw is not None:
                p["truth_raw"] = float(raw)
            if est is not None and raw is not None:
                sc.set(est["name"], raw)            # shown for information, never compared
            continue
        if n in unknown:
            p["truth"], p["note"] = None, unknown[n]
            if raw is not None:
                p["truth_raw"] = float(raw)
                sc.set(f"ident.{n}", None, raw=raw, note=unknown[n])
            continue
        tv = gauge.get(n, raw)
        p["truth"] = None if tv is None else float(tv)
        if tv is None:
            continue
        if raw is not None and est is not None and abs(tv - raw) > 0.1 * est["error"]:
            sc.set(est["name"], tv, raw=raw, note=GAUGE_NOTE)
        else:
            sc.set(f"ident.{n}", tv)
        if raw is not None and p["name"] in gauge and abs(tv - raw) > 0:
            p["truth_raw"], p["note"] = float(raw), GAUGE_NOTE
