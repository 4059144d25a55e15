"""The Puma 560 twin: a seeded, reproducible "truth" made from the same forward model, with every effect switchable.

A scenario file (TOML; ``calib/data/twin_default.toml`` is the annotated default) says how the simulated robot differs
from its description — geometric deviations, the tool, non-geometric effects — where the theodolites stand and how
they err, and how the encoders read.  :class:`Twin` then answers what the instruments would show:

* :meth:`Twin.measure` — for joint readings commanded to the controller: the encoder counts (integers, so quantised),
  the joint readings the controller derives from them with the *nominal* description, the true joint angles, the true
  tool points and both theodolites' readings (noise, instrument errors, optional gross errors);
* :meth:`Twin.observe` — readings of arbitrary points (ruler marks, dial-gauge targets) from any stations: the one
  place reading noise and gross errors are drawn (:meth:`Twin.sight`, :meth:`Twin.measure` and the emulators call it).

Later work (estimators, identification, emulators, diagnosis) draws all synthetic truth from here.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np

from calib.effects import EFFECTS, Effect, PoseContext, effect_from_table
from calib.kinematics import Kinematics
from calib.model import MeasurementModel
from calib.robot import Robot
from calib.loading import load_robot
from calib.theodolite import Station, thesis_stations
from calib.tomlspec import Checker, Field
from calib.units import ARCSEC, DEG

TWO_PI = 2 * np.pi

# -- scenario file specs -----------------------------------------------------------------------------------------
TOP = {
    "twin": Field("table", default={}), "geometry": Field("table", default={}), "base": Field("table", default={}),
    "tool": Field("table", default={}), "stations": Field("table", default={}), "noise": Field("table", default={}),
    "effect": Field("tables", default=[]),
}
TWIN = {"seed": Field("int", default=0, min=0), "robot": Field("str", default=""),
        "name": Field("str", default="twin"),
        # a URDF robot's chain cut (empty: the root / the only moving leaf)
        "base_link": Field("str", default=""), "tip_link": Field("str", default="")}
GEOMETRY = {
    "set": Field("table", default={}),                       # parameter name -> true value (mm / deg)
    "random_alpha_deg": Field("number", default=0.0, min=0),  # 1-sigma seeded deviations
    "random_theta_offset_deg": Field("number", default=0.0, min=0),
    "random_length_mm": Field("number", default=0.0, min=0),
    "random_beta_deg": Field("number", default=0.0, min=0),
}
BASE = {"xyz_mm": Field("vector", default=[474.9, 2853.0, 184.9], length=3),
        "rpy_deg": Field("vector", default=[0.0, 0.0, 0.0], length=3, min=-360, max=360)}
TOOL = {"xyz_mm": Field("vector", default=[0.0, 0.0, 0.0], length=3)}
STATIONS = {
    "L_mm": Field("number", default=1609.9, min=100, max=20000),
    "gamma1_deg": Field("number", default=-1.489, min=-180, max=180),
    "gamma2_deg": Field("number", default=1.358, min=-180, max=180),
    "height_b_mm": Field("number", default=0.0),
    "sigma_arcsec": Field("number", default=3.0, positive=True),
    "collimation_arcsec": Field("vector", default=[0.0, 0.0], length=2),
    "trunnion_arcsec": Field("vector", default=[0.0, 0.0], length=2),
    "index_arcsec": Field("vector", default=[0.0, 0.0], length=2),
    "tilt_arcsec": Field("vector", default=[0.0, 0.0, 0.0, 0.0], length=4),   # A x, A y, B x, B y
}
NOISE = {
    "angles": Field("bool", default=True),
    "gross_rate": Field("number", default=0.0, min=0, max=1),
    "gross_arcsec": Field("number", default=60.0, positive=True),
    "encoder_quantisation": Field("bool", default=True),
    "repeatability_deg": Field("number", default=0.0, min=0),      # 1-sigma joint positioning scatter per move
}
#: each effect kind's ``[[effect]]`` keys (the registry's; kept for readers of this module)
EFFECT_SPECS: dict[str, dict[str, Field]] = {k: cls.scenario_fields for k, cls in EFFECTS.items()}


@dataclass
class Scenario:
    """A checked scenario: everything the twin needs, in internal units."""

    name: str
    seed: int
    robot: Robot                      # the nominal description (what the controller and the operator believe)
    true_params: np.ndarray           # geometric parameter vector of the truth (Kinematics order)
    effects: list[Effect]
    stations: list[Station]
    angle_noise: bool = True
    gross_rate: float = 0.0
    gross_rad: float = 60 * ARCSEC
    encoder_quantisation: bool = True
    repeatability_rad: float = 0.0    # where a commanded move really ends: servo scatter, 1-sigma per joint
    source: str = "<memory>"
    disabled: list[str] = field(default_factory=list)


def load_scenario(path: str | Path | None = None) -> Scenario:
    """Load a scenario file; ``None`` gives the default (the thesis's findings on its Puma 560)."""
    if path is None:
        ref = resources.files("calib") / "data" / "twin_default.toml"
        chk, data = Checker.parse(ref.read_text(encoding="utf-8"), "twin_default.toml (default)")
    else:
        chk, data = Checker.load(path)
    return _scenario(chk, data)


def parse_scenario(text: str, source: str = "<string>") -> Scenario:
    chk, data = Checker.parse(text, source)
    return _scenario(chk, data)


def _scenario(chk: Checker, data: dict) -> Scenario:
    """A checked scenario from the parsed file: robot, true geometry, stations, noise, effects (in that order)."""
    top = chk.table(data, TOP, "")
    tw = chk.table(top["twin"], TWIN, "twin")
    robot = load_robot(tw["robot"] or None, tw["base_link"] or None, tw["tip_link"] or None)
    truth = _true_geometry(chk, top, robot, np.random.default_rng(tw["seed"]))
    stations = _stations(chk.table(top["stations"], STATIONS, "stations"))
    noise = chk.table(top["noise"], NOISE, "noise")
    effects, disabled = _effects(chk, top["effect"], robot.n)
    return Scenario(name=tw["name"], seed=tw["seed"], robot=robot, true_params=truth, effects=effects,
                    stations=stations, angle_noise=noise["angles"], gross_rate=noise["gross_rate"],
                    gross_rad=noise["gross_arcsec"] * ARCSEC, encoder_quantisation=noise["encoder_quantisation"],
                    repeatability_rad=noise["repeatability_deg"] * DEG, source=chk.source, disabled=disabled)


def _true_geometry(chk: Checker, top: dict, robot: Robot, rng: np.random.Generator) -> np.ndarray:
    """The true geometric parameter vector: seeded random deviations first, explicit values override them, then the
    base and the tool."""
    kin = Kinematics(robot)
    truth = kin.nominal.copy()
    geo = chk.table(top["geometry"], GEOMETRY, "geometry")
    n = robot.n
    for key, scale, unit in (("random_alpha_deg", DEG, "alpha_rad"), ("random_theta_offset_deg", DEG,
                                                                       "theta_offset_rad"),
                             ("random_beta_deg", DEG, "beta_rad")):
        sig = geo[key] * scale
        for j in range(n):
            dev = rng.normal(0.0, sig) if sig > 0 else 0.0
            if unit == "beta_rad" and not robot.hayati[j]:
                continue
            truth[kin.index[f"j{j + 1}.{unit}"]] += dev
    if geo["random_length_mm"] > 0:
        for j in range(n):
            for unit in ("a_mm", "d_mm"):
                if unit == "d_mm" and robot.hayati[j]:
                    continue
                truth[kin.index[f"j{j + 1}.{unit}"]] += rng.normal(0.0, geo["random_length_mm"])
    if not isinstance(geo["set"], dict):
        chk.fail("geometry.set", "must be a table of parameter = value")
    for name, raw in geo["set"].items():
        key = f"geometry.set.{name}"
        internal = name.replace("_deg", "_rad")
        if internal not in kin.index or internal.startswith(("base.", "tool.")):
            chk.fail(key, "unknown parameter (use j<k>.a_mm, j<k>.d_mm, j<k>.alpha_deg, j<k>.theta_offset_deg, "
                          "j<k>.beta_deg)")
        v = chk.value(raw, Field("number"), key)
        truth[kin.index[internal]] = v * DEG if name.endswith("_deg") else v
    base = chk.table(top["base"], BASE, "base")
    truth[kin.index["base.x_mm"]:kin.index["base.z_mm"] + 1] = base["xyz_mm"]
    roll, pitch, yaw = (np.asarray(base["rpy_deg"]) * DEG)
    truth[kin.index["base.yaw_rad"]], truth[kin.index["base.pitch_rad"]], truth[kin.index["base.roll_rad"]] = \
        yaw, pitch, roll
    tool = chk.table(top["tool"], TOOL, "tool")
    truth[kin.index["tool.x_mm"]:kin.index["tool.z_mm"] + 1] = tool["xyz_mm"]
    return truth


def _stations(st: dict) -> list[Station]:
    """Theodolites A and B in the thesis's layout (L, gamma1, gamma2), with the scenario's instrument errors."""
    sig = st["sigma_arcsec"] * ARCSEC
    a, b = thesis_stations(st["L_mm"], st["gamma1_deg"] * DEG, st["gamma2_deg"] * DEG, sig, st["height_b_mm"])
    tilt = np.asarray(st["tilt_arcsec"]) * ARCSEC
    return [Station(s.name, s.x_mm, s.y_mm, s.z_mm, s.yaw_rad, tilt[2 * i], tilt[2 * i + 1],
                    st["collimation_arcsec"][i] * ARCSEC, st["trunnion_arcsec"][i] * ARCSEC,
                    st["index_arcsec"][i] * ARCSEC, sig, sig) for i, s in enumerate((a, b))]


def _effects(chk: Checker, tables, n_joints: int) -> tuple[list[Effect], list[str]]:
    """The enabled effects of the ``[[effect]]`` tables (through the registry) and the labels of the disabled ones."""
    if not isinstance(tables, list):
        chk.fail("effect", "must be an array of tables ([[effect]])")
    effects, disabled = [], []
    for i, raw in enumerate(tables, 1):
        eff, enabled = effect_from_table(raw, chk, f"effect[{i}]", n_joints)
        if enabled:
            effects.append(eff)
        else:
            disabled.append(eff.label)
    return effects, disabled


@dataclass
class TwinMeasurement:
    """What the instruments show for N poses (and the truth behind it, for tests and reports)."""

    q_command_rad: np.ndarray     # (N, n) what was commanded
    counts: np.ndarray            # (N, n) int64 encoder counts (motor side)
    q_read_rad: np.ndarray        # (N, n) joint readings from the counts with the nominal description
    theta_true_rad: np.ndarray    # (N, n) true joint angles
    point_true_mm: np.ndarray     # (N, 3) true tool point in the measurement frame
    readings_rad: np.ndarray      # (N, 2k) Hz, V per station
    gross: np.ndarray             # (N, 2k) bool: a gross error was added to this reading
    faces: list[int]


class Twin:
    """The simulated robot and instruments of a :class:`Scenario`; seeded, so runs are reproducible."""

    def __init__(self, scenario: Scenario | None = None, seed: int | None = None):
        self.scenario = scenario or load_scenario()
        self.robot = self.scenario.robot
        self.model = MeasurementModel(self.robot, self.scenario.effects)
        self.theta = np.concatenate([self.scenario.true_params] + [e.values for e in self.scenario.effects])
        self.stations = self.scenario.stations
        self.rng = np.random.default_rng(self.scenario.seed if seed is None else seed)

    @property
    def nominal_model(self) -> MeasurementModel:
        """The model the operator starts from: the description, no effects."""
        return MeasurementModel(self.robot)

    def context(self, n_poses: int, **kw) -> PoseContext:
        return self.model.context(n_poses, **kw)

    def encoder(self, q_rad: np.ndarray):
        """Counts for joint readings and the readings the controller derives back from them (quantised)."""
        counts_f = self.robot.counts_from_joint(q_rad)
        counts = np.rint(counts_f).astype(np.int64) if self.scenario.encoder_quantisation else counts_f
        return counts, self.robot.joint_from_counts(counts)

    def true_points(self, q_read_rad, ctx: PoseContext | None = None, tool_mm=None):
        ev = self.model.evaluate(q_read_rad, ctx, self.theta, tool_mm=tool_mm)
        return ev.point_mm, ev.theta_rad

    def observe(self, points_mm: np.ndarray, stations: list[Station] | None = None, faces: list[int] | None = None,
                rng: np.random.Generator | None = None):
        """What the theodolites read for points (N, 3): readings (N, 2k) ordered (Hz_1, V_1, Hz_2, V_2, ...) and the
        gross-error mask (N, 2k).

        The one place reading noise and gross sighting errors are drawn (every simulated instrument calls it): each
        station's observation with its instrument errors (:meth:`calib.theodolite.Station.observe`), then Gaussian
        noise of the station's sigma (when the scenario has angle noise), then gross errors of +-``gross_rad`` at the
        scenario's rate, then Hz wrapped to [0, 2 pi).  ``stations`` default to the scenario's, ``faces`` to face I,
        ``rng`` to the twin's own generator (an emulator passes its own so that its stream is its own).
        """
        stations = self.stations if stations is None else stations
        return self.noisy(self.exact_readings(points_mm, stations, faces), stations, rng)

    def exact_readings(self, points_mm: np.ndarray, stations: list[Station] | None = None,
                       faces: list[int] | None = None) -> np.ndarray:
        """The readings (N, 2k) of :meth:`observe` before noise: each station's observation with its instrument
        errors.  A caller that reads one point many times (an emulated theodolite) may keep them and pass them to
        :meth:`noisy` for each reading."""
        stations = self.stations if stations is None else stations
        faces = faces or [1] * len(stations)
        pts = np.atleast_2d(np.asarray(points_mm, float))
        cols = []
        for s, f in zip(stations, faces):
            cols += list(s.observe(pts, f))
        return np.stack(cols, -1)

    def exact_one(self, point_mm: np.ndarray, station: Station, face: int) -> list[float]:
        """:meth:`exact_readings` of one point (3,) from one station, as floats [Hz, V]: the station's own
        observation of the point (an emulated theodolite keeps these per target and face, then draws
        :meth:`noisy_one` for each reading), without stacking one-element arrays."""
        hz, v = station.observe(np.asarray(point_mm, float)[None], face)
        return [float(hz[0]), float(v[0])]

    def noisy(self, exact: np.ndarray, stations: list[Station] | None = None,
              rng: np.random.Generator | None = None):
        """Readings and gross-error mask from :meth:`exact_readings` (not modified): the noise and gross errors of
        :meth:`observe`, then Hz wrapped."""
        stations = self.stations if stations is None else stations
        rng = self.rng if rng is None else rng
        exact = np.asarray(exact, float)
        if exact.shape[0] == 1:             # an emulated theodolite asks for one reading at a time
            out, gross = self.noisy_one(exact[0].tolist(), stations, rng)
            return np.array([out]), np.array([gross])
        if self.scenario.angle_noise:
            sig = np.array([v for s in stations for v in (s.sigma_hz_rad, s.sigma_v_rad)])
            out = exact + rng.normal(size=exact.shape) * sig
        else:
            out = exact.copy()
        gross = rng.random(out.shape) < self.scenario.gross_rate
        if gross.any():
            out = out + gross * rng.choice([-1.0, 1.0], out.shape) * self.scenario.gross_rad
        out[:, 0::2] = np.mod(out[:, 0::2], 2 * np.pi)        # Hz wrapped
        return out, gross

    def noisy_one(self, exact: list[float], stations: list[Station], rng: np.random.Generator) -> tuple[list, list]:
        """:meth:`noisy` of one point's readings (a list: Hz, V per station) in plain floats: the same draws from
        ``rng`` in the same order (``normal`` of shape (1, 2k) is ``standard_normal`` of 2k, then ``random``), the
        same operations on the same floats (``%`` is numpy's ``mod`` for floats), so the very readings of the array
        code -- without its dozen numpy calls per reading, the emulated theodolites' main cost."""
        k = len(exact)
        if self.scenario.angle_noise:
            sig = [v for s in stations for v in (s.sigma_hz_rad, s.sigma_v_rad)]
            out = [x + z * g for x, z, g in zip(exact, rng.standard_normal(k).tolist(), sig)]
        else:
            out = list(exact)
        gross = [u < self.scenario.gross_rate for u in rng.random(k).tolist()]
        if any(gross):                      # rare: the array code's own expression
            out = (np.array([out]) + np.array([gross]) * rng.choice([-1.0, 1.0], (1, k))
                   * self.scenario.gross_rad)[0].tolist()
        out[0::2] = [x % TWO_PI for x in out[0::2]]        # Hz wrapped
        return out, gross

    def sight(self, points_mm: np.ndarray, faces: list[int] | None = None):
        """Noisy readings (N, 2k) of points from every station, and the gross-error mask (see :meth:`observe`)."""
        return self.observe(points_mm, None, faces)

    def measure(self, q_command_rad, ctx: PoseContext | None = None, faces: list[int] | None = None,
                tool_mm=None) -> TwinMeasurement:
        q = np.atleast_2d(np.asarray(q_command_rad, float))
        counts, q_read = self.encoder(q)
        pts, th = self.true_points(q_read, ctx, tool_mm)
        rd, gross = self.observe(pts, None, faces)
        return TwinMeasurement(q, counts, q_read, th, pts, rd, gross, faces or [1] * len(self.stations))

    def true_parameters(self) -> dict[str, float]:
        return dict(zip(self.model.names, self.theta))

    def random_poses(self, count: int, margin_rad: float = 10 * DEG) -> np.ndarray:
        """Uniform joint readings inside the limits less a margin (the twin's rng, so reproducible)."""
        lim = self.robot.limits_rad
        margin = np.where(self.robot.prismatic, 0.05 * np.ptp(lim, axis=1), margin_rad)   # mm for prismatic joints
        lo, hi = lim[:, 0] + margin, lim[:, 1] - margin
        return lo + (hi - lo) * self.rng.random((count, self.robot.n))
