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
import itertools
import sys
import threading
from dataclasses import dataclass, field

import numpy as np

from acq.clock import Clock, RealClock
from acq.drivers.base import AngleReading
from calib.units import DEG

from .steps import Step, TargetSpec


#: no wait_received is pending (the sink notifies only when a waiter's count is reached)
_NOBODY = sys.maxsize


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


def mean_rows(a: np.ndarray) -> np.ndarray:
    """``np.mean(a, 0)`` of a 2-D float64 array: the very ufunc call np.mean makes (``np.add.reduce`` over the rows,
    then divided by their count), so the same floats, without its wrapper -- every encoder window's mean joint
    readings are taken twice (the runner's event, the pose check) at about 10 us of wrapper each (a test holds them
    equal).  Anything else goes to np.mean."""
    if type(a) is np.ndarray and a.ndim == 2 and a.dtype == np.float64 and len(a):
        return np.add.reduce(a, 0) / len(a)
    return np.mean(a, 0)


@dataclass
class Rig:
    """Opened devices.  ``theodolites`` maps station name (A, B) to a driver; ``tap`` is optional.  ``clock``
    (:mod:`acq.clock`) times the encoder windows: real time for a real cell (the default), the emulated bench's
    :class:`~acq.clock.SimClock` for the demo.

    The tap's samples go into a bounded buffer with a running count, so a capture polls one integer and copies only
    its own window, whatever the buffer holds."""

    theodolites: dict
    tap: object | None = None
    device_ids: dict = field(default_factory=dict)      # role -> store device_id
    clock: Clock = field(default_factory=RealClock)
    _buf: collections.deque = field(default_factory=lambda: collections.deque(maxlen=200_000))
    _lock: threading.Lock = field(default_factory=threading.Lock)
    _arrived: threading.Condition = field(init=False)
    received: int = field(default=0, init=False)        # samples delivered by the tap since start
    _awaited: int = field(default=_NOBODY, init=False)  # the count a wait_received is waiting for
    _faces: dict = field(default_factory=dict, init=False)  # station -> face its telescope was last seen in

    def __post_init__(self) -> None:
        self._arrived = threading.Condition(self._lock)

    def start(self) -> None:
        """Start the tap's reader: in its own thread, or -- on a simulated clock, with a reader that can be polled --
        fed from the clock's thread by :meth:`poll_tap` (the emulated node sends in that thread too)."""
        if self.tap is not None:
            self.tap.start(self._sink, thread=not (self.clock.simulated and getattr(self.tap, "pollable", False)))

    def poll_tap(self) -> None:
        """Hand a reader started without its thread what arrived on its bus (nothing to do for a threaded one)."""
        if self.tap is not None and getattr(self.tap, "polled", False):
            self.tap.poll()

    def _sink(self, sample) -> None:
        with self._lock:
            self._buf.append(sample)
            self.received += 1
            if self.received >= self._awaited:          # wake the waiter once, not at every sample
                self._arrived.notify_all()

    def wait_received(self, n: int, timeout_s: float) -> bool:
        """Block (real time) until ``n`` samples have arrived since start; False on timeout."""
        with self._lock:
            self._awaited = n
            try:
                return self._arrived.wait_for(lambda: self.received >= n, timeout_s)
            finally:
                self._awaited = _NOBODY                 # nobody waits: the sink stops notifying

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
        """Bring the telescope to ``face`` (motorised instruments; a manual one is turned by the operator).

        The face the rig last saw is kept, so a sighting in the face the telescope is already in costs no question
        to the instrument (half the round trips of a session); :meth:`sight` checks every reading's face against
        it, so a telescope turned by hand in between is noticed and brought back before the reading is used.  For
        the same reason a telescope known to be in the other face is turned without asking first (the face is
        asked only when the rig does not know it: at the start and after a fault)."""
        drv = self.theodolites[station]
        known = self._faces.get(station)
        if not (hasattr(drv, "face") and hasattr(drv, "change_face")) or known == face:
            return
        self._faces.pop(station, None)
        if (drv.face() if known is None else known) != face:
            drv.change_face()
        self._faces[station] = face

    def sight(self, station: str) -> AngleReading:
        """One reading of ``station``; a motorised telescope found in another face than the rig left it in is
        turned back (:meth:`face`) and read again."""
        want = self._faces.get(station)
        try:
            r = self.theodolites[station].angles()
            if want is not None and r.face is not None and r.face != want:
                self._faces.pop(station, None)
                self.face(station, want)
                r = self.theodolites[station].angles()
        except Exception:
            self._faces.pop(station, None)           # a device fault may leave the telescope anywhere
            raise
        return r

    def capture(self, seconds: float, settle_s: float = 0.0, min_samples: int = 5,
                timeout_s: float = 2.0) -> EncoderCapture | None:
        """Encoder samples that arrive after ``settle_s`` during ``seconds`` (at least ``min_samples``; waiting at
        most ``timeout_s`` after the settle time)."""
        if self.tap is None:
            return None
        clock = self.clock
        clock.sleep(settle_s)
        t0 = clock.now()
        with self._lock:
            first = self.received                       # the window's first sample, counted since start
        deadline, hard = t0 + max(seconds, 0.0), t0 + timeout_s
        while True:
            now = clock.now()
            with self._lock:
                n = self.received - first
            if (now >= deadline and n >= min_samples) or now >= hard:
                break
            clock.sleep(max(deadline - now, 0.002))
        with self._lock:
            n = min(self.received - first, len(self._buf))
            got = list(itertools.islice(self._buf, len(self._buf) - n, None))
            self._buf.clear()
        return _capture(got)

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


def _capture(got: list) -> EncoderCapture:
    if not got:
        return EncoderCapture(*(np.zeros((0,), np.int64),) * 2, np.zeros(0), np.zeros((0, 6), np.int64),
                              np.zeros((0, 6), np.int64), np.zeros((0, 6)))
    return EncoderCapture(
        np.array([s.seq for s in got], np.int64), np.array([s.t_device_us for s in got], np.int64),
        np.array([s.t_mono for s in got]), np.array([s.counts_wire for s in got], np.int64),
        np.array([s.counts for s in got], np.int64),
        np.array([s.joint_rad if s.joint_rad is not None else np.full(len(s.counts), np.nan) for s in got]))


class Bench:
    """Physical actions of a step; a real cell has none (the operator acts on the prompts)."""

    def prepare(self, step: Step, inputs: dict) -> None:
        """Robot to the step's pose, loads hung (called after the operator confirmed the step's setup)."""

    def aim(self, target: TargetSpec) -> None:
        """Theodolites on ``target``."""


class ManualBench(Bench):
    pass


def c3_setup(setup: dict, pose_deg, inputs: dict, kin) -> dict:
    """A step's physical set-up in the vocabulary of contract C3 (loads and gauges at points on links), with the
    operator's ``load_kg`` (when entered) as the mass of the first load.

    Steps written before C3 are translated, by geometry only: a load ``load_n`` on a lever ``lever_mm`` of joint j
    is a mass ``load_n / g`` at ``lever_mm`` along frame j's x axis (a point on link j); a load or a gauge at ``x``
    mm along link j is a point on the segment from joint j's centre (frame j-1) to frame j at the step's pose, gauges
    reading along gravity.  Whether the load turns a joint is then the geometry's business, not the step's.
    """
    s = dict(setup)
    if "loads" not in s and "joint" in s:
        j = int(s["joint"])
        gravity = kin.robot.gravity_m_s2
        g = float(np.linalg.norm(gravity))
        load_n = float(inputs.get("load_n", s.get("load_n", 0.0)))
        if "lever_mm" in s:                                                  # joint compliance
            lever = float(inputs.get("lever_mm", s["lever_mm"]))
            s["loads"] = [{"link": j, "point_mm": [lever, 0.0, 0.0], "mass_kg": load_n / g}]
        elif "load_x_mm" in s:                                               # link compliance
            along = _along_link(kin, pose_deg, j)
            s["loads"] = [{"link": j, "point_mm": along(s["load_x_mm"]), "mass_kg": load_n / g}]
            down = (np.asarray(gravity, float) / g).tolist()
            s["gauges"] = [{"name": f"gauge{i + 1}", "link": j, "point_mm": along(x), "axis": down}
                           for i, x in enumerate(s.get("gauges_x_mm", []))]
    loads = [dict(ld) for ld in s.get("loads", [])]
    if loads and inputs.get("load_kg") is not None:
        loads[0]["mass_kg"] = float(inputs["load_kg"])
    s["loads"] = loads
    return s


def load_directions(setup: dict, n: int) -> np.ndarray:
    """(n,) +1 loading / -1 unloading / 0 per joint from ``setup["load_direction"]`` ({"3": 1})."""
    d = np.zeros(n)
    ld = setup.get("load_direction") or {}
    if not isinstance(ld, dict):                      # older steps: one number for the step's joint
        j = setup.get("tested_joint", setup.get("joint"))
        ld = {str(j): ld} if j is not None else {}
    for j, v in ld.items():
        d[int(j) - 1] = float(v)
    return d


def _along_link(kin, pose_deg, j: int):
    """x mm -> the point (frame j coordinates) at x from joint j's axis along link j's body (the beam that bends)."""
    q = np.zeros(kin.n) if pose_deg is None else np.asarray(pose_deg, float) * DEG
    fp = kin.forward(q[None])
    (start,), (end,) = fp.link_beam(j)
    R = fp.frame_R[0, j]
    L = np.linalg.norm(end - start)

    def at(x_mm: float) -> list[float]:
        p = start + (end - start) * float(x_mm) / L
        return (R.T @ (p - end)).tolist()
    return at
