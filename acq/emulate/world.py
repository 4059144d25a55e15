"""Where the emulated instruments get their truth: an injected :class:`World`.

Why an interface: the digital twin (``calib/twin.py``, a Puma with every effect) will provide the world later; until
then :class:`KinematicWorld` builds one from :mod:`calib.kinematics` and :mod:`calib.theodolite`.  The emulators ask
only two questions, both "now":

* ``joint_angles_rad()`` -> the six true joint angles (the encoder tap turns them into counts with
  ``robot.counts_from_joint``);
* ``sight(station_name, face)`` -> what that theodolite reads on the current target: ``(hz_rad, v_rad)``, instrument
  errors and reading noise included.  ``face`` is 1 (face I) or 2 (face II), as in :mod:`calib.theodolite`.

Implementations must be thread-safe: the tap and two theodolites run in different threads.
"""
from __future__ import annotations

import threading
from typing import Mapping, Protocol, Sequence, runtime_checkable

import numpy as np

from calib.errors import RobocalError
from calib.kinematics import Kinematics
from calib.robot import Robot, load_robot
from calib.theodolite import Station
from calib.units import DEG


@runtime_checkable
class World(Protocol):
    """What an emulated instrument may ask about the world."""

    def joint_angles_rad(self) -> np.ndarray: ...

    def sight(self, station_name: str, face: int) -> tuple[float, float]: ...


class KinematicWorld:
    """Nominal kinematics, perfect joints, stations with their modelled errors, Gaussian reading noise.

    ``target_q_rad`` is the pose the robot holds; :meth:`set_joint_angles` moves it (a test or the demo drives the
    robot).  Noise comes from one seeded :class:`numpy.random.Generator`, so a seed reproduces a session.
    """

    def __init__(self, robot: Robot, stations: Sequence[Station] | Mapping[str, Station],
                 target_q_rad: Sequence[float] | None = None, *, seed: int | None = 0, noise: bool = True,
                 tool_point: str | None = None):
        self.robot = robot
        self.kin = Kinematics(robot)
        if tool_point is not None:
            self._params = self.kin.params_with_tool(robot.tool_point(tool_point))
        else:
            self._params = None
        self.stations: dict[str, Station] = dict(stations) if isinstance(stations, Mapping) else {
            s.name: s for s in stations}
        self.noise = noise
        self._rng = np.random.default_rng(seed)
        self._lock = threading.Lock()
        q = np.zeros(robot.n) if target_q_rad is None else np.asarray(target_q_rad, float)
        self._q = self._check_q(q)

    def _check_q(self, q: np.ndarray) -> np.ndarray:
        if q.shape != (self.robot.n,) or not np.all(np.isfinite(q)):
            raise RobocalError(f"world: expected {self.robot.n} finite joint angles, got {q!r}")
        return q.copy()

    def set_joint_angles(self, q_rad: Sequence[float]) -> None:
        q = self._check_q(np.asarray(q_rad, float))
        with self._lock:
            self._q = q

    def joint_angles_rad(self) -> np.ndarray:
        with self._lock:
            return self._q.copy()

    def target_mm(self) -> np.ndarray:
        """The current target point in the measurement frame (mm)."""
        return self.kin.points(self.joint_angles_rad()[None, :], self._params)[0]

    def true_sight(self, station_name: str, face: int) -> tuple[float, float]:
        """Noise-free reading (instrument errors included), for tests that compare against the emulator."""
        st = self._station(station_name)
        hz, v = st.observe(self.target_mm()[None, :], face)
        return float(hz[0]), float(v[0])

    def slope_distance_m(self, station_name: str) -> float:
        """Optional World extra: distance from the station centre to the target (EDM), metres."""
        st = self._station(station_name)
        return float(np.linalg.norm(self.target_mm() - st.position) / 1000.0)

    def sight(self, station_name: str, face: int) -> tuple[float, float]:
        st = self._station(station_name)
        hz, v = self.true_sight(station_name, face)
        if self.noise:
            with self._lock:
                dh, dv = self._rng.normal(0.0, 1.0, 2)
            hz = float(np.mod(hz + dh * st.sigma_hz_rad, 2 * np.pi))
            v = float(v + dv * st.sigma_v_rad)
        return hz, v

    def _station(self, name: str) -> Station:
        try:
            return self.stations[name]
        except KeyError:
            raise RobocalError(f"world: no station {name!r} (stations: {', '.join(self.stations)})") from None


#: READY-like pose used by the demo world (deg): the tool point is well in front of both stations
DEMO_Q_DEG = (10.0, -60.0, 120.0, 5.0, 30.0, 0.0)


def demo_stations(sigma_rad: float = 1.0 * DEG / 3600) -> tuple[Station, Station]:
    """Two stations 2.5 m in front of the Puma, 3 m apart, with small instrument errors (for the demo and tests)."""
    a = Station("A", -1500.0, -2500.0, 300.0, yaw_rad=1.0, collimation_rad=4e-5, trunnion_rad=2e-5,
                index_rad=3e-5, sigma_hz_rad=sigma_rad, sigma_v_rad=sigma_rad)
    b = Station("B", 1500.0, -2500.0, 250.0, yaw_rad=2.0, collimation_rad=-3e-5, trunnion_rad=1e-5,
                index_rad=-2e-5, sigma_hz_rad=sigma_rad, sigma_v_rad=sigma_rad)
    return a, b


def demo_world(seed: int | None = 0, noise: bool = True) -> KinematicWorld:
    """The default world of ``robocal://`` URLs and ``robocal emulate``: shipped Puma, two demo stations."""
    return KinematicWorld(load_robot(), demo_stations(), np.array(DEMO_Q_DEG) * DEG, seed=seed, noise=noise)
