"""The bench set-up as the acquisition sees it: approximate stations from the set-up file (until the ruler steps
refit them) and where the nominal model expects each tool target, with the tolerance of an uncalibrated description.
Used by every session, real or emulated (not only the demo)."""
from __future__ import annotations

import json
from contextlib import contextmanager
from functools import lru_cache
from dataclasses import replace

import numpy as np

from calib.errors import RobocalError
from calib.jsonfile import vouch
from calib.model import MeasurementModel
from calib.profile import THESIS_READY_DEG, profile_of
from calib.loading import load_robot
from calib.setup_plan import sweep_targets
from calib.theodolite import thesis_stations
from calib.units import ARCSEC, DEG

from .setup_file import SETUP_SCHEMA, default_of
from .setup_types import BenchSetup, PointP, mark_index, mark_names, setup_of
from .steps import Step


def standard_setup() -> dict:
    """The thesis's cell as a technician writes it down (the template ``robocal session --write-setup`` and
    ``robocal plan setup --out`` start from): two theodolites 1.6 m apart, the Puma 2.9 m in front of them, a ruler of
    marks C, D, E placed twice, the tool and extended-tool targets, the loads and gauges.  Every load is a mass at a
    point where it turns its joint: joint 4 with the forearm level, link 2 with the upper arm level."""
    return {
        "robot": "",                                     # the shipped description
        "scenario": "",                                  # the twin scenario (emulated sessions only)
        "base_xyz_mm": [475.0, 2853.0, 185.0], "base_rpy_deg": [0.0, 0.0, 0.0],
        # L from a tape, gammas from mutual sighting of the instruments (to about 0.01 deg); the ruler refines them
        "stations": {"names": ["A", "B"], "L_mm": 1610.0, "gamma1_deg": -1.49, "gamma2_deg": 1.36,
                     "sigma_arcsec": 3.0},
        "min_focus_mm": 900.0,
        # the arm's links as 50 mm-radius bars along the chain, for the pre-flight's line of sight (the description
        # has no link shapes; a Puma's forearm is about 100 mm across)
        "preflight": {"link_radius_mm": 50.0},
        "tool_target_mm": [50.0, 0.0, 100.0],
        "sweep_radius_mm": 600.0,
        # point P of eq 4.3.15's d3: a mark on the tool's axis L_p beyond the flange (frame 6), sighted once at READY
        "point_p": {"link": 6, "L_p_mm": 150.0},
        "extended_tool": {"A1_mm": [0.0, 0.0, 100.0], "A2_mm": [500.0, 0.0, 600.0]},      # 707 mm apart
        "far_target_mm": [-1000.0, 3000.0, 300.0],        # a mark on the wall left of the robot, 3-4 m away
        # the series varies R as the thesis does (Fig 5.4: R 1792-1860 mm): mark E at three distances, one sighted
        # per placement with C, D and the last; each placement steps back and turns
        "ruler": {"marks_mm": [0.0, 930.0, 1800.0, 1830.0, 1860.0],
                  "placements": [{"where": "1.2 m in front, left", "C_mm": [-300.0, 1200.0, 0.0], "dir": [1, 0, 0],
                                  "marks": ["C", "D", "E1", "E3"]},
                                 {"where": "1.5 m in front, turned a little", "C_mm": [-250.0, 1500.0, 0.0],
                                  "dir": [1, 0.075, 0], "marks": ["C", "D", "E2", "E3"]},
                                 {"where": "1.8 m in front, turned", "C_mm": [-200.0, 1800.0, 0.0],
                                  "dir": [1, 0.15, 0], "marks": ["C", "D", "E3"]}]},
        "compliance": {"3": {"lever_mm": 500.0, "loads_n": [0, 10, 20, 30, 45, 60, 75], "theta_i_deg": 0.0,
                             "pose_deg": list(THESIS_READY_DEG)},
                       # joint 4 loaded with the forearm level (its axis horizontal): a lever clamped on the wrist
                       # housing (link 4), level, 500 mm out along joint 5's axis; joint 1 at -90 deg points the
                       # forearm at the theodolites, so the joint turns A1 -> A2 across their sight lines (across
                       # the baseline it would move A2 in depth, the direction they measure worst).  Small steps up
                       # to 5 N m: the thesis's stiffness changes at 45 lb in (5.1 N m), and a slope needs three
                       # loads or more on each side of the breakpoint to be told apart
                       "4": {"link": 4, "point_mm": [0.0, 0.0, -500.0],
                             "loads_n": [0, 2, 4, 6, 8, 10, 15, 20, 25, 35, 45],
                             "pose_deg": [-90.0, -90.0, 0.0, 0.0, 0.0, 0.0]}},
        # the upper arm level (at READY it stands vertical and a weight only compresses it)
        "link": {"joint": 2, "gauges_x_mm": [150.0, 280.0, 400.0], "load_x_mm": 430.0, "loads_n": [0, 50, 100, 150],
                 "second_moment_mm4": None, "pose_deg": [0.0, 0.0, 90.0, 0.0, 0.0, 0.0]},
    }


def record_robot(setup: dict, robot_path) -> dict:
    """The set-up naming the robot a session is recorded with: ``robot_path`` (``--robot``: a path, or a
    :class:`calib.loading.RobotPath` carrying ``--base-link`` / ``--tip-link``) as ``robot``, its chain cut as
    ``base_link`` / ``tip_link``; the set-up itself when no ``--robot`` was given.  Why: the session keeps its
    set-up, and reprocessing loads the robot from it (:func:`setup_robot`), so the cut must travel with the name."""
    if not robot_path:
        return setup
    out = {**setup, "robot": str(robot_path)}
    for key in ("base_link", "tip_link"):
        out.pop(key, None)
        if getattr(robot_path, key, None):
            out[key] = str(getattr(robot_path, key))
    return out


def setup_robot(setup: BenchSetup | dict):
    """The robot a session's set-up names: ``robot`` (a description file; empty: the shipped Puma) cut at
    ``base_link`` / ``tip_link`` when the set-up records a URDF chain cut, so a reprocess loads the same chain the
    session was recorded with."""
    s = setup_of(setup)
    return load_robot(s.robot or None, s.base_link or None, s.tip_link or None)


def setup_profile(setup: BenchSetup):
    """The profile (:func:`calib.profile.profile_of`) of the robot the set-up names: what the plan's defaults
    come from (which joints, which pairs)."""
    return _profile(setup.robot, setup.base_link, setup.tip_link)


@lru_cache(maxsize=16)
def _profile(robot: str, base_link: str, tip_link: str):
    """Cached: a plan's generators ask for it once per procedure."""
    return profile_of(load_robot(robot or None, base_link or None, tip_link or None))


def reference_pose_deg(setup: BenchSetup) -> tuple[float, ...]:
    """The pose the joints are swept about and the runs start from (deg): the set-up's ``reference_pose_deg``,
    which :func:`session_setup` fills from the robot's profile; the thesis's READY for a set-up written before."""
    return tuple(float(v) for v in (setup.reference_pose_deg or THESIS_READY_DEG))


def station_names(setup: BenchSetup) -> tuple[str, str]:
    """The two stations' names as the set-up gives them (``stations.names``; default A and B)."""
    return setup.stations.names


def point_p(setup: BenchSetup, n_links: int | None = None):
    """The set-up's point P (eq 4.3.15's d3): ``(link, point in that frame (mm), L_p_mm)`` -- a mark on the tool's
    axis ``L_p_mm`` beyond the flange -- or None when the set-up has none (older set-ups: no P step).  ``n_links``:
    the robot's joint count, to check the link (default link 6, the Puma's flange)."""
    pp: PointP | None = setup.point_p
    if pp is None:
        return None
    with _section("point_p"):
        if not np.isfinite(pp.L_p_mm) or pp.L_p_mm <= 0:
            raise ValueError(f"L_p_mm must be a positive length, got {pp.L_p_mm:g}")
        if n_links is not None and not 1 <= pp.link <= n_links:
            raise ValueError(f"link must be one of the robot's links 1..{n_links}, got {pp.link}")
        return pp.link, (0.0, 0.0, pp.L_p_mm), pp.L_p_mm


def setup_stations(setup: BenchSetup | dict) -> dict:
    """Approximate stations from the setup (for the acquisition checks; reprocessing uses the ruler's)."""
    s = setup_of(setup).stations
    a, b = thesis_stations(s.L_mm, s.gamma1_deg * DEG, s.gamma2_deg * DEG, s.sigma_arcsec * ARCSEC)
    na, nb = s.names
    return {na: replace(a, name=na), nb: replace(b, name=nb)}


def nominal_theta(model: MeasurementModel, setup: BenchSetup | dict) -> np.ndarray:
    """The model's nominal parameters with the robot base where the set-up puts it (position and roll-pitch-yaw)."""
    s = setup_of(setup)
    return theta_with_base(model, s.base_xyz_mm, s.base_rpy_deg)


def theta_with_base(model: MeasurementModel, base_xyz_mm, base_rpy_deg=(0.0, 0.0, 0.0)) -> np.ndarray:
    """The model's nominal parameters with the robot base at ``base_xyz_mm``, turned by ``base_rpy_deg``."""
    th = model.nominal.copy()
    for k, v in zip(("x_mm", "y_mm", "z_mm"), base_xyz_mm):
        th[model.index[f"base.{k}"]] = v
    roll, pitch, yaw = np.asarray(base_rpy_deg, float) * DEG
    for k, v in (("yaw_rad", yaw), ("pitch_rad", pitch), ("roll_rad", roll)):
        th[model.index[f"base.{k}"]] = v
    return th


#: 1-sigma gap between a robot description and the real robot, before calibration: link lengths (a Puma's a3 can be
#: 10 mm off its drawing), twists and zero offsets (the thesis found misalignments up to 1.2 deg), the base placed
#: with a tape and a level, the tool target from its drawing.
DESCRIPTION_TOLERANCES = {"length_mm": 5.0, "angle_deg": 0.3, "base_mm": 10.0, "base_angle_deg": 0.3,
                          "tool_mm": 2.0, "load_mass_kg": 0.01}


#: a dial gauge's reading noise (mm, 1-sigma) when the set-up's ``link.gauge_sigma_mm`` does not say: a 1 um gauge
GAUGE_SIGMA_MM = 0.001


def _prior_sigmas(names: list[str], tol: dict) -> np.ndarray:
    out = []
    for n in names:
        if n.startswith("base."):
            out.append(tol["base_mm"] if n.endswith("_mm") else tol["base_angle_deg"] * DEG)
        elif n.startswith("tool."):
            out.append(tol["tool_mm"])
        else:
            out.append(tol["length_mm"] if n.endswith("_mm") else tol["angle_deg"] * DEG)
    return np.asarray(out)


def predictor(robot, setup: BenchSetup | dict, tolerances: dict | None = None):
    """Where the nominal model with the setup's base puts each tool target of a step, and how far off an
    uncalibrated description can be there: target -> (point_mm, sigma_mm) for the plausibility check.

    sigma is the root of the trace of J S J^T, J the point's Jacobian in the geometric parameters and S the
    description's tolerances (:data:`DESCRIPTION_TOLERANCES`): a point far from the base gets a wider limit."""
    m = MeasurementModel(robot)
    th = nominal_theta(m, setup)
    sd = _prior_sigmas(list(m.kin.names), {**DESCRIPTION_TOLERANCES, **(tolerances or {})})
    known: dict[tuple, tuple] = {}          # (pose, tool, link) -> (point, sigma), from prime()

    def _evaluate(poses: list[tuple], tool, link) -> list[tuple]:
        ev = m.evaluate(np.asarray(poses, float) * DEG, theta=th, jacobian=True, tool_mm=np.asarray(tool, float),
                        link=link)
        J = ev.jacobian[:, :, : m.n_geometric] * sd[None, None, :]
        return list(zip(ev.point_mm, np.sqrt(np.sum(J * J, axis=(1, 2)))))

    def _wanted(step: Step):
        if step.pose_deg is not None:
            for t in step.targets:
                if t.tool_mm is not None:
                    yield t.name, (tuple(step.pose_deg), tuple(t.tool_mm), t.link)

    def prime(steps: list[Step]) -> None:
        """Predict every step's targets now, one vectorised evaluation per target (a session's plan is known
        before it runs; one pose at a time costs the runner a model evaluation per step)."""
        groups: dict[tuple, list[tuple]] = {}
        for s in steps:
            for _, key in _wanted(s):
                if key not in known:
                    groups.setdefault(key[1:], []).append(key[0])
        for (tool, link), poses in groups.items():
            poses = list(dict.fromkeys(poses))
            for pose, (p, sig) in zip(poses, _evaluate(poses, tool, link)):
                if len(known) < 100_000:
                    known[(pose, tool, link)] = (p, float(sig))

    def predict(step: Step) -> dict:
        """The step's targets (copies: the kept points stay as computed); a pose not primed -- a command computed
        when the step is reached, repeated in every cycle of ISO 9283's compensated run -- is kept like a primed
        one, by pose, tool and link."""
        out = {}
        for name, key in _wanted(step):
            got = known.get(key)
            if got is None:
                p, sig = _evaluate([key[0]], key[1], key[2])[0]
                got = (p, float(sig))
                if len(known) < 100_000:
                    known[key] = got
            out[name] = (got[0].copy(), got[1])
        return out

    predict.prime = prime
    return predict


# -- the session set-up: old keys onto new ones ----------------------------------------------------------------------
def frame_point(fp, link: int, p_world: np.ndarray) -> list[float]:
    """A measurement-frame point in frame ``link`` coordinates at the pose of ``fp`` (one pose)."""
    return [round(float(v), 3) for v in fp.frame_R[0, link].T @ (p_world - fp.frame_t[0, link])]


def up_direction(fp, robot) -> np.ndarray:
    """Unit vector against the description's gravity, in the measurement frame (the base carries gravity along)."""
    g = fp.gravity()[0]
    return -g / np.linalg.norm(g)


def lever_of(fp, joint: int, p_world: np.ndarray, up: np.ndarray) -> tuple[float, float]:
    """(distance from joint ``joint``'s axis in mm, angle of that lever above the horizontal in deg) of a point."""
    z, o = fp.joint_axis[0, joint - 1], fp.joint_origin[0, joint - 1]
    r = p_world - o
    r = r - (r @ z) * z
    L = float(np.linalg.norm(r))
    return L, float(np.degrees(np.arcsin(np.clip(r @ up / L, -1, 1)))) if L > 0 else 0.0


def lever_point(fp, joint: int, lever_mm: float, theta_deg: float, up: np.ndarray) -> np.ndarray:
    """The point ``lever_mm`` from joint ``joint``'s axis, level across it, raised ``theta_deg`` (old set-ups)."""
    z, o = fp.joint_axis[0, joint - 1], fp.joint_origin[0, joint - 1]
    h = np.cross(z, up)
    if np.linalg.norm(h) < 1e-9:                      # axis vertical: any horizontal direction (and no torque)
        h = np.cross(z, [1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.cross(z, [0.0, 1.0, 0.0])
    h = h / np.linalg.norm(h)
    t = np.radians(theta_deg)
    return o + lever_mm * (np.cos(t) * h + np.sin(t) * up)


def design_sweep_targets(model: MeasurementModel, setup: BenchSetup, robot,
                         radius_mm: float | dict | None = None) -> dict:
    """Per-joint sweep targets at ``radius_mm`` (default the set-up's ``sweep_radius_mm`` or 600 mm) about each
    joint's axis at the reference pose (the set-up's ``reference_pose_deg``, else the robot profile's), on the side
    facing the theodolites (see :func:`calib.setup_plan.sweep_targets`)."""
    r = radius_mm if radius_mm is not None else setup.sweep_radius_mm
    radii = {int(k): float(v) for k, v in r.items()} if isinstance(r, dict) else \
        {j: float(r) for j in range(1, robot.n + 1)}
    mid = np.mean([st.position for st in setup_stations(setup).values()], axis=0)
    q = np.asarray(setup.reference_pose_deg or profile_of(robot).ready_deg, float) * robot.edge_scale
    return sweep_targets(model, nominal_theta(model, setup), q, radii, mid)


@contextmanager
def _section(where: str):
    """Turn a malformed set-up entry into one line naming it (``set-up: compliance.4: missing point_mm``)."""
    try:
        yield
    except KeyError as exc:
        raise RobocalError(f"set-up: {where}: missing {exc.args[0]}") from None
    except (TypeError, ValueError, IndexError) as exc:
        raise RobocalError(f"set-up: {where}: {exc}") from None


def _ruler_marks(placement: dict, marks_mm) -> None:
    """Every mark a placement sights must be one the ruler has (C, D, E -- or E1, E2 ... when E is marked at
    several distances)."""
    names = mark_names(len(marks_mm))
    for name in placement.get("marks", names):
        if name not in names:
            raise ValueError(f"unknown mark {name!r}: this ruler's marks are {', '.join(names)}")
        mark_index(name)


def _check_entry(where: str, robot, joint: int, pose, link: int, masses) -> None:
    n = robot.n
    if not 1 <= joint <= n:
        raise RobocalError(f"set-up: {where}: joint {joint} is not one of 1..{n}")
    if not 0 <= link <= n:
        raise RobocalError(f"set-up: {where}: link {link} is not one of 0..{n}")
    if len(pose) != n or not np.all(np.isfinite(np.asarray(pose, float))):
        raise RobocalError(f"set-up: {where}: pose_deg needs {n} finite joint readings, got {list(pose)}")
    if any(not np.isfinite(v) or v < 0 for v in masses):
        raise RobocalError(f"set-up: {where}: loads must be finite and not negative, got {list(masses)}")


def _compliance_entry(key: str, cfg: dict, robot, chain, g: float, ready) -> None:
    """One joint-compliance entry: a lever (old keys) or a point on link j (new), both filled in."""
    j = int(key)
    cfg.setdefault("link", j)
    pose = cfg.setdefault("pose_deg", list(ready))
    if "masses_kg" not in cfg:
        cfg["masses_kg"] = [round(float(v) / g, 4) for v in cfg["loads_n"]]
    cfg.setdefault("loads_n", [round(float(v) * g, 3) for v in cfg["masses_kg"]])
    _check_entry(f"compliance.{key}", robot, j, pose, int(cfg["link"]), cfg["masses_kg"])
    fp = chain(pose)
    up = up_direction(fp, robot)
    if "point_mm" not in cfg:
        p = lever_point(fp, j, float(cfg["lever_mm"]), float(cfg.get("theta_i_deg", 0.0)), up)
        cfg["point_mm"] = frame_point(fp, int(cfg["link"]), p)
    p = fp.frame_R[0, cfg["link"]] @ np.asarray(cfg["point_mm"], float) + fp.frame_t[0, cfg["link"]]
    lever, theta = lever_of(fp, j, p, up)
    cfg.setdefault("lever_mm", round(lever, 3))
    cfg.setdefault("theta_i_deg", round(theta, 3))


def _link_entry(link: dict, robot, chain, g: float, ready) -> None:
    """The link-compliance entry: gauges and the load along link j (old keys) or as points on it (new)."""
    j = int(link.setdefault("link", link["joint"]))
    link.setdefault("joint", j)
    pose = link.setdefault("pose_deg", list(ready))
    if "masses_kg" not in link:
        link["masses_kg"] = [round(float(v) / g, 4) for v in link["loads_n"]]
    link.setdefault("loads_n", [round(float(v) * g, 3) for v in link["masses_kg"]])
    _check_entry("link", robot, j, pose, j, link["masses_kg"])
    a = float(robot.a_mm[j - 1])
    down = -up_direction(chain(pose), robot)
    if "load_point_mm" not in link:
        link["load_point_mm"] = [float(link["load_x_mm"]) - a, 0.0, 0.0]
    link.setdefault("load_x_mm", link["load_point_mm"][0] + a)
    if "gauges" not in link:
        link["gauges"] = [{"name": f"gauge{i + 1}", "link": j, "point_mm": [float(x) - a, 0.0, 0.0],
                           "axis": [round(float(v), 6) for v in down]}
                          for i, x in enumerate(link["gauges_x_mm"])]
    link.setdefault("gauges_x_mm", [gg["point_mm"][0] + a for gg in link["gauges"]])


def session_setup(setup: dict, robot, own: bool = False) -> dict:
    """The set-up with every old key mapped onto the step vocabulary's (contract C3), old keys kept.

    Old set-up files describe a compliance load as ``lever_mm`` from the joint's centre at ``theta_i_deg`` above the
    horizontal with ``loads_n``; the link-compliance gauges as ``gauges_x_mm`` and the load as ``load_x_mm`` along
    link ``joint``.  The steps speak of masses at points on links (``link``, ``point_mm`` in frame j, ``masses_kg``)
    and gauges as points with an axis; this adds those (and the old keys for set-ups that give only the new ones),
    and designs the per-joint sweep targets when the set-up has none.  A malformed entry is one line naming it.
    ``own``: robocal made ``setup`` itself (the demo's bench), so the typed set-up is vouched for
    (:func:`calib.jsonfile.vouch`) instead of checked against the schema again.
    """
    out = json.loads(json.dumps(setup))
    m = MeasurementModel(robot)
    with _section("base_xyz_mm / base_rpy_deg"):
        th = theta_with_base(m, out["base_xyz_mm"], out.get("base_rpy_deg", default_of("base_rpy_deg")))
        th = th[: m.n_geometric]
    g = float(np.linalg.norm(robot.gravity_m_s2))
    with _section("reference_pose_deg"):
        ready = out.setdefault("reference_pose_deg", list(profile_of(robot).ready_deg))
        if len(ready) != robot.n or not np.all(np.isfinite(np.asarray(ready, float))):
            raise ValueError(f"needs {robot.n} finite joint readings, got {list(ready)}")

    def chain(q_deg):
        return m.kin.forward(np.asarray(q_deg, float)[None] * robot.edge_scale, th)

    for key, cfg in out.get("compliance", {}).items():
        with _section(f"compliance.{key}"):
            _compliance_entry(key, cfg, robot, chain, g, ready)
    if out.get("link"):
        with _section("link"):
            _link_entry(out["link"], robot, chain, g, ready)
    typed = setup_of(vouch(out, SETUP_SCHEMA) if own else out)
    point_p(typed, robot.n)                                  # a bad point P is one line here, not a crash later
    for k, pl in enumerate(out.get("ruler", {}).get("placements", [])):
        with _section(f"ruler.placements[{k}].marks"):
            _ruler_marks(pl, out["ruler"].get("marks_mm", []))
    if "sweep_targets" not in out:
        with _section("sweep_radius_mm"):
            out["sweep_targets"] = design_sweep_targets(m, typed, robot)
    return vouch(out, SETUP_SCHEMA) if own else out
