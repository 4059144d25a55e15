"""The instruments of a session (two theodolites and the encoder tap) and the "bench" (what happens physically).

:class:`Rig` owns the opened drivers: ``sight(station, face)`` returns an :class:`AngleReading` (raw reply frame
included), ``capture(seconds)`` the encoder samples received in a window after a settle time.  The tap runs in its own
thread and pushes samples into a bounded buffer; the runner thread does all theodolite I/O (drivers are thread-
confined), never the UI thread.

:class:`Bench` is what the technician does with the robot and the targets.  For a real cell it is
:class:`ManualBench` (nothing: the operator moves the robot and aims, the prompts say what).  The demo uses
:class:`EmulatedBench`, which moves the twin world's robot, hangs loads and points the theodolites -- the same
actions the scripted operator "performs".
"""
from __future__ import annotations

import collections
import threading
import time
from dataclasses import dataclass, field

import numpy as np

from acq.drivers.base import AngleReading

from .steps import Step, TargetSpec


@dataclass
class EncoderCapture:
    seq: np.ndarray
    t_device_us: np.ndarray
    t_mono_s: np.ndarray
    counts_wire: np.ndarray
    counts: np.ndarray
    joint_rad: np.ndarray

    @property
    def n(self) -> int:
        return len(self.seq)


@dataclass
class Rig:
    """Opened devices.  ``theodolites`` maps station name (A, B) to a driver; ``tap`` is optional."""

    theodolites: dict
    tap: object | None = None
    device_ids: dict = field(default_factory=dict)      # role -> store device_id
    _buf: collections.deque = field(default_factory=lambda: collections.deque(maxlen=200_000))
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def start(self) -> None:
        if self.tap is not None:
            self.tap.start(self._sink)

    def _sink(self, sample) -> None:
        with self._lock:
            self._buf.append(sample)

    def identities(self) -> list[tuple[str, str, str, dict]]:
        """(role, driver, url, identity) per device, for the session record."""
        out = []
        for st, drv in self.theodolites.items():
            info = drv.identify()
            out.append((f"theodolite {st}", info.driver, info.url, dict(info.__dict__)))
        if self.tap is not None:
            out.append(("encoder tap", type(self.tap).__name__, getattr(self.tap, "name", ""), {}))
        return out

    def face(self, station: str, face: int) -> None:
        """Bring the telescope to ``face`` (motorised instruments; a manual one is turned by the operator)."""
        drv = self.theodolites[station]
        if hasattr(drv, "face") and hasattr(drv, "change_face"):
            if drv.face() != face:
                drv.change_face()

    def sight(self, station: str) -> AngleReading:
        return self.theodolites[station].angles()

    def capture(self, seconds: float, settle_s: float = 0.0, min_samples: int = 5,
                timeout_s: float = 2.0) -> EncoderCapture | None:
        """Encoder samples that arrive after ``settle_s`` during ``seconds`` (at least ``min_samples``)."""
        if self.tap is None:
            return None
        t0 = time.monotonic() + settle_s
        deadline = t0 + max(seconds, 0.0)
        hard = t0 + timeout_s
        while True:
            now = time.monotonic()
            with self._lock:
                got = [s for s in self._buf if s.t_mono >= t0]
            if (now >= deadline and len(got) >= min_samples) or now >= hard:
                break
            time.sleep(0.002)
        with self._lock:
            self._buf.clear()
        if not got:
            return EncoderCapture(*(np.zeros((0,), np.int64),) * 2, np.zeros(0), np.zeros((0, 6), np.int64),
                                  np.zeros((0, 6), np.int64), np.zeros((0, 6)))
        return EncoderCapture(
            np.array([s.seq for s in got], np.int64), np.array([s.t_device_us for s in got], np.int64),
            np.array([s.t_mono for s in got]), np.array([s.counts_wire for s in got], np.int64),
            np.array([s.counts for s in got], np.int64),
            np.array([s.joint_rad if s.joint_rad is not None else np.full(len(s.counts), np.nan) for s in got]))

    def close(self) -> None:
        if self.tap is not None:
            try:
                self.tap.stop()
            except Exception:
                pass
        for drv in self.theodolites.values():
            try:
                drv.close()
            except Exception:
                pass


class Bench:
    """Physical actions of a step; a real cell has none (the operator acts on the prompts)."""

    def prepare(self, step: Step, inputs: dict) -> None:
        """Robot to the step's pose, loads hung (called after the operator confirmed the step's setup)."""

    def aim(self, target: TargetSpec) -> None:
        """Theodolites on ``target``."""


class ManualBench(Bench):
    pass


class EmulatedBench(Bench):
    """Acts on a :class:`acq.emulate.twin_world.TwinWorld`: the demo's robot, loads and targets."""

    def __init__(self, world):
        from acq.emulate.twin_world import Target
        self.world = world
        self._Target = Target

    def prepare(self, step: Step, inputs: dict) -> None:
        from calib.units import DEG
        w = self.world
        if step.pose_deg is not None:
            w.command(np.asarray(step.pose_deg, float) * DEG)
        n = w.robot.n
        torque = np.zeros(n)
        ld = np.zeros(n)
        s = step.setup
        if step.procedure == "compliance":
            j = s["joint"] - 1
            load = inputs.get("load_n", s["load_n"])
            lever = inputs.get("lever_mm", s["lever_mm"])
            th = inputs.get("theta_i_deg", s.get("theta_i_deg", 0.0)) * DEG
            torque[j] = load * lever * 1e-3 * np.cos(th)
            ld[j] = s["load_direction"]
        w.set_load(torque, ld)

    def aim(self, target: TargetSpec) -> None:
        self.world.aim(self._Target(target.name, tool_mm=target.tool_mm, point_mm=target.point_mm))

    def read_gauges(self, step: Step) -> dict:
        """What the dial gauges show at a link-compliance step (the scripted operator reads them)."""
        s = step.setup
        return {f"gauge{g + 1}_mm": self.world.dial_gauge_mm(x, s["load_x_mm"], s["load_n"])
                for g, x in enumerate(s["gauges_x_mm"])}
