"""The emulated instruments' world driven by the twin: what the theodolites, encoder tap and dial gauges observe.

Why a separate World: the emulated instruments must show the *twin* (:mod:`sim.twin`: true geometry, transmission
errors, compliance, coupling, the scenario's stations and noise), so a session recorded from emulated instruments has
a known truth to check estimates against.

State (all set by the session's "physical" layer, i.e. what a technician does with the robot and the targets):

* the robot's commanded joint readings ``q`` (the encoder tap turns them into counts with the description's gears and
  coupling -- exactly :meth:`sim.twin.Twin.encoder`);
* the loads: masses hung at points fixed on links (:class:`HungMass`), the loading direction per joint, the last-motion
  directions.  A load is a force (mass x the model's gravity) at its point: the twin's one model turns it into joint
  torques, joint deflections and link bending (the scenario's compliance effects with their values).  Nothing here
  knows which procedure hung it;
* the current target: a point fixed on a link (frame j, mm; by default the flange frame: the tool target P, the
  extended tool's A1/A2) or a fixed point in the measurement frame (ruler marks C, D, E).

``sight(station, face)`` returns that station's reading of the current target with the scenario's reading noise and
gross errors, drawn from one seeded generator under a lock: the two theodolites and the tap run in different threads.
:meth:`gauge_mm` is a dial gauge touching a point on a link: the displacement of that point along the gauge's axis,
loaded minus unloaded at the same pose, both through the twin's model.

Fault hook: :meth:`inject_sighting_error` adds a given error to a station's next readings -- the operator sighting
the wrong spot -- so tests can show which acceptance check catches it.
"""
from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np

from calib.effects import PoseContext
from calib.errors import RobocalError
from calib.loads import HungMass, point_force_context
from calib.profile import profile_of
from sim.twin import TWO_PI, Twin

@dataclass(frozen=True)
class Target:
    """What the theodolites aim at: a point fixed in frame ``link`` (``tool_mm``; default the flange frame n) or a
    fixed point in the measurement frame (``point_mm``)."""

    name: str
    tool_mm: tuple[float, float, float] | None = None
    point_mm: tuple[float, float, float] | None = None
    link: int | None = None


class TwinWorld:
    """World protocol implementation on a :class:`sim.twin.Twin` (thread-safe)."""

    def __init__(self, twin: Twin, q0_deg=None, *, seed: int | None = None, gauge_sigma_mm: float = 0.001):
        self.twin = twin
        self.robot = twin.robot
        self.stations = {s.name: s for s in twin.stations}
        self.gauge_sigma_mm = gauge_sigma_mm
        self._g = twin.model.gravity_n_per_kg(twin.theta)          # N per kg, measurement frame
        self._rng = np.random.default_rng(twin.scenario.seed if seed is None else seed)
        self._lock = threading.RLock()
        n = self.robot.n
        q0 = profile_of(self.robot).ready_deg if q0_deg is None else q0_deg       # default: the reference pose
        self._q = np.asarray(q0, float) * self.robot.edge_scale          # where the joints are
        self._q_cmd = self._q.copy()                          # where they were last commanded to
        self._direction = np.zeros(n)
        self._torque = np.zeros(n)
        self._load_dir = np.zeros(n)
        self._payload = 0.0
        self._masses: tuple[HungMass, ...] = ()
        tool = twin.true_parameters()
        self._default_tool = tuple(float(tool[f"tool.{k}_mm"]) for k in "xyz")
        self._target = Target("P", tool_mm=self._default_tool)
        self._cache: np.ndarray | None = None
        self._ahead: dict[Target, np.ndarray] = {}  # targets evaluated together at the present state (prefetch)
        self._faults: dict[str, list] = {}          # station -> [hz_rad, v_rad, readings left]
        self._exact: dict[tuple, list] = {}         # (station, face, target point) -> readings before noise
        # what the twin's model is evaluated with at the present state: the encoder's readings, the pose context
        # (loaded or not); forgotten with the targets' cache when the joints move or the loads change
        self._at: dict = {}

    # -- what the session's physical layer sets -------------------------------------------------------------------
    def command(self, q_rad) -> None:
        """Move the robot to joint readings ``q_rad``; remembers the direction of each joint's last motion.  A joint
        that moves stops where its servo puts it: the command plus the scenario's positioning scatter
        (``repeatability_deg``), which the encoders read like any other position."""
        q = np.asarray(q_rad, float)
        if q.shape != (self.robot.n,) or not np.all(np.isfinite(q)):
            raise RobocalError(f"twin world: expected {self.robot.n} finite joint angles, got {q!r}")
        with self._lock:
            moved = np.abs(q - self._q_cmd) > 1e-12
            self._direction = np.where(moved, np.sign(q - self._q_cmd), self._direction)
            self._q_cmd = q.copy()
            rep = self.twin.scenario.repeatability_rad
            scatter = rep * self._rng.standard_normal(q.size) * moved if rep > 0 else 0.0
            self._q = np.where(moved, q + scatter, self._q)
            if moved.any():                 # a command to where the joints are changes nothing the target depends on
                self._cache = None
                self._ahead.clear()
                self._at.clear()

    def set_load(self, joint_torque_nm=None, load_direction=None, payload_kg: float = 0.0) -> None:
        """Torques applied directly to the joints (N m; kept for old callers -- the bench hangs masses instead),
        +1 loading / -1 unloading per joint, payload at the tool (kg)."""
        n = self.robot.n
        with self._lock:
            self._torque = np.zeros(n) if joint_torque_nm is None else np.asarray(joint_torque_nm, float).copy()
            self._load_dir = np.zeros(n) if load_direction is None else np.asarray(load_direction, float).copy()
            self._payload = float(payload_kg)
            self._cache = None
            self._ahead.clear()
            self._at.clear()

    def hang(self, masses=(), load_direction=None) -> None:
        """Replace the hung masses (:class:`HungMass`) and the loading direction per joint (+1 / -1 / 0)."""
        n = self.robot.n
        masses = tuple(masses)
        for m in masses:
            if not 0 <= m.link <= n or not np.all(np.isfinite(m.point_mm)) or not np.isfinite(m.mass_kg) \
                    or m.mass_kg < 0:
                raise RobocalError(f"twin world: a load needs a link 0..{n}, a finite point and a mass >= 0 kg, "
                                   f"got {m!r}")
        load_dir = np.zeros(n) if load_direction is None else np.asarray(load_direction, float).copy()
        with self._lock:
            if masses == self._masses and np.array_equal(load_dir, self._load_dir):
                return                      # the same loads again: the target stays where it is
            self._masses = masses
            self._load_dir = load_dir
            self._cache = None
            self._ahead.clear()
            self._at.clear()

    def aim(self, target: Target) -> None:
        """Make ``target`` the one the theodolites read."""
        with self._lock:
            if target != self._target:
                self._target = target
                self._cache = None

    @property
    def default_tool_mm(self) -> tuple[float, float, float]:
        return self._default_tool

    # -- World protocol -------------------------------------------------------------------------------------------
    def joint_angles_rad(self) -> np.ndarray:
        """The commanded joint readings: the tap makes counts from them exactly as :meth:`Twin.encoder` does."""
        with self._lock:
            return self._q.copy()

    def context(self, loaded: bool = True) -> PoseContext:
        """The pose context now; ``loaded=False``: the same without the hung masses (what a zeroed gauge saw)."""
        with self._lock:
            ms = self._masses if loaded else ()
            return PoseContext(1, self.robot.n, direction=self._direction[None], load_direction=self._load_dir[None],
                               payload_kg=np.array([self._payload]), joint_torque_nm=self._torque[None],
                               **point_force_context(ms, self._g))

    def _point(self, link: int | None, point_mm, loaded: bool = True) -> np.ndarray:
        """True position (3,) of a point fixed in frame ``link`` (None: the flange tool point ``point_mm``) at the
        encoder's joint readings, through the twin's one model."""
        ev = self.twin.model.evaluate(self._reading(), self._context_now(loaded), self.twin.theta,
                                      tool_mm=np.asarray(point_mm, float), link=link)
        return ev.point_mm[0]

    def _reading(self) -> np.ndarray:
        """(1, n) the joint readings the controller derives from the encoder counts at the present state (kept
        until the joints move: a step evaluates its targets and gauge points at one state)."""
        q = self._at.get("q")
        if q is None:
            q = self._at["q"] = self.twin.encoder(self._q[None])[1]
        return q

    def _context_now(self, loaded: bool) -> PoseContext:
        """:meth:`context` kept until the state changes (the model reads it, never writes it)."""
        ctx = self._at.get(loaded)
        if ctx is None:
            ctx = self._at[loaded] = self.context(loaded)
        return ctx

    def prefetch(self, targets) -> None:
        """The true positions of ``targets`` (:class:`Target`) on the flange at the robot's present state, in one
        evaluation of the twin's model for them all (a step sights its targets in turn at one state: the extended
        tool's A1 and A2); kept until the state changes or the target is aimed at.  The same model at the same state:
        the points are those :meth:`target_mm` would compute one by one."""
        todo = [t for t in targets if t.point_mm is None and t.tool_mm is not None and t.link is None]
        with self._lock:
            todo = [t for t in dict.fromkeys(todo) if t not in self._ahead]
            if len(todo) < 2:
                return
            rows = np.zeros(len(todo), int)
            ev = self.twin.model.evaluate(self._reading()[rows], self._context_now(True).subset(rows), self.twin.theta,
                                          tool_mm=np.array([t.tool_mm for t in todo], float))
            self._ahead.update(zip(todo, ev.point_mm))

    def target_mm(self) -> np.ndarray:
        """The current target's true position in the measurement frame (mm)."""
        with self._lock:
            if self._cache is not None:
                return self._cache.copy()
            t = self._target
            p = self._ahead.get(t)
            if p is None:
                p = np.asarray(t.point_mm, float) if t.point_mm is not None else self._point(t.link, t.tool_mm)
            self._cache = p
            return p.copy()

    def true_sight(self, station_name: str, face: int) -> tuple[float, float]:
        st = self._station(station_name)
        hz, v = st.observe(self.target_mm()[None], face)
        return float(hz[0]), float(v[0])

    def sight(self, station_name: str, face: int) -> tuple[float, float]:
        """The station's reading of the current target: :meth:`sim.twin.Twin.observe` (the one place reading noise
        and gross errors are drawn) with this world's generator, plus an injected sighting fault if any."""
        st = self._station(station_name)
        p = self.target_mm()
        with self._lock:
            key = (station_name, face, p.tobytes())
            exact = self._exact.get(key)
            if exact is None:           # the target's readings without noise: once per target, station and face
                if len(self._exact) >= 64:
                    self._exact.clear()
                exact = self._exact[key] = self.twin.exact_one(p, st, face)
            (hz, v), _ = self.twin.noisy_one(exact, [st], self._rng)
            f = self._faults.get(station_name)
            if f is not None and f[2] > 0:
                # a pointing error: face II reads the zenith angle as 360 deg - V, so it flips the sign there
                hz, v = hz + f[0], v + (f[1] if face == 1 else -f[1])
                f[2] -= 1
        return hz % TWO_PI, v                   # numpy's mod of floats is Python's %: the same float

    def inject_sighting_error(self, station_name: str, hz_rad: float = 0.0, v_rad: float = 0.0,
                              readings: int = 1) -> None:
        """Fault hook: the next ``readings`` readings of ``station_name`` point (hz_rad, v_rad) off the target (right,
        down): a mis-sighting that face I and face II share, so the face mean keeps it (unlike an index error)."""
        self._station(station_name)
        if readings < 0 or not np.isfinite(hz_rad) or not np.isfinite(v_rad):
            raise RobocalError(f"twin world: sighting error needs finite angles and readings >= 0, got "
                               f"{hz_rad!r}, {v_rad!r}, {readings!r}")
        with self._lock:
            self._faults[station_name] = [float(hz_rad), float(v_rad), int(readings)]

    def slope_distance_m(self, station_name: str) -> float:
        st = self._station(station_name)
        return float(np.linalg.norm(self.target_mm() - st.position) / 1000.0)

    # -- dial gauges ----------------------------------------------------------------------------------------------
    def gauge_mm(self, link: int, point_mm, axis) -> float:
        """A dial gauge touching the point ``point_mm`` fixed in frame ``link``, reading its displacement along the
        measurement-frame ``axis`` (mm): loaded minus unloaded at the same pose, both through the twin's model
        (joint deflections and link bending with the scenario's values), plus the gauge's reading noise."""
        u = np.asarray(axis, float)
        norm = np.linalg.norm(u)
        if u.shape != (3,) or not np.isfinite(norm) or norm == 0:
            raise RobocalError(f"twin world: a gauge axis must be a non-zero 3-vector, got {axis!r}")
        with self._lock:
            d = self._point(link, point_mm, True) - self._point(link, point_mm, False)
            y = float(d @ u / norm) + self._rng.normal(0.0, self.gauge_sigma_mm)
        return round(y, 4)          # gauges read to 0.1 um at best

    def _station(self, name: str):
        try:
            return self.stations[name]
        except KeyError:
            raise RobocalError(f"twin world: no station {name!r} (stations: {', '.join(self.stations)})") from None
