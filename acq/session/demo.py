"""The demo session: every procedure recorded from emulated instruments driven by the twin, scripted operator.

Wiring (the same a real cell uses, only the devices are emulated):

* the twin (:mod:`calib.twin`, default scenario) behind a :class:`~acq.emulate.twin_world.TwinWorld`;
* two GeoCOM theodolite emulators published in the registry and opened with the **real** driver
  (``open_theodolite("geocom", "robocal://instance/...")``), so the stored frames are protocol bytes;
* the encoder tap emulator as a node on a python-can ``virtual`` channel, read by the **real** CAN tap reader;
* :class:`~acq.session.rig.EmulatedBench` plays the technician's hands (robot motion, loads, aiming), and
  :class:`~acq.session.headless.ScriptedOperator` the technician's answers (dial gauges read from the world).

Time: the emulated devices and the rig run on a :class:`~acq.clock.SimClock` (an encoder window is an advance of
simulated time, not a sleep), except where a human watches (the TUI's ``--emulate`` passes a real clock).  Session
parameters are chosen so ``robocal demo`` stays quick on 2 cores (``benchmarks/bench_demo.py``): fewer positions and
repeats than a real session, but every procedure is present.
"""
from __future__ import annotations

import json
import uuid
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from acq.clock import Clock, SimClock
from acq.errors import DeviceTimeout
from calib.model import MeasurementModel
from calib.twin import Twin, load_scenario
from calib.units import ARCSEC, DEG

from .headless import ScriptedOperator
from .preflight import Preflight
from .setup import predictor, session_setup, setup_stations, standard_setup
from .procedures import all_steps, tool_target
from .rig import EmulatedBench, Rig
from .runner import Runner
from .steps import Step
from .store import SessionStore

DEMO_TITLE = "robocal demo: emulated Puma 560 (twin) and two GeoCOM theodolites"
#: poses in the demo's Chapter 6 set: enough to identify the geometry with the running errors (about 30 free
#: parameters) at a few sigma of the truth, still a quick recording
DEMO_POSES = 48
#: wait after each move before recording encoders (the tap's frames in flight carry the previous pose); real time only
DEMO_SETTLE_S = 0.02
#: transmission-error runs: joint 4 inside its -110..170 deg limits (with the pre-flight's 2 deg margin), joint 6 over
#: most of its +-266 deg
TE_RANGE_DEG = {"4": [-105.0, 165.0], "6": [-150.0, 150.0],
                #: joints 2 and 3 (options, ``--te-joints``): +-90 deg about READY, the upper arm from horizontal
                #: to horizontal and the forearm from along it to folded back level, inside their limits with the
                #: pre-flight's margin and in both stations' sight (checked by the pre-flight like every step)
                "2": [-90.0, 90.0], "3": [-90.0, 90.0]}
#: the joints whose transmission error the default plans measure (the thesis's: the wrist's)
DEFAULT_TE_JOINTS = (4, 6)


def transmission_plan(joints=None, points: int = 25, repeats: int = 2) -> dict:
    """The plan's ``transmission`` entry for ``joints`` (default :data:`DEFAULT_TE_JOINTS`), each over its range in
    :data:`TE_RANGE_DEG`; what ``--te-joints`` of ``robocal session`` and ``robocal demo`` maps to."""
    js = [int(j) for j in (joints or DEFAULT_TE_JOINTS)]
    return {"joints": js, "points": points, "repeats": repeats, "range_deg": {str(j): TE_RANGE_DEG[str(j)] for j in js}}
#: the encoder-resolution run (Fig 5.14): joint 6 over 150 deg in 6 steps -- few steps keep the demo quick, the wide
#: arc fixes the run's own axis well enough that the slope's error is a few 1e-4 of the resolution
RESOLUTION_RUN = {"joints": [6], "points": 6, "span_deg": 150.0, "repeats": 1}


def demo_setup(twin: Twin, base: dict | None = None) -> dict:
    """The bench geometry a technician would write down for the emulated cell: ``base`` (a set-up file from
    ``robocal plan setup``; default :func:`acq.session.setup.standard_setup`) with the stations and the robot's base
    as measured on the twin's cell (rounded like a tape and mutual sighting give them: not the twin's truth)."""
    tp = twin.true_parameters()
    a, b = twin.stations
    setup = json.loads(json.dumps(base)) if base is not None else standard_setup()
    setup.update({
        "robot": setup.get("robot", ""), "scenario": setup.get("scenario", ""),
        "base_xyz_mm": [round(tp[f"base.{k}_mm"], 0) for k in "xyz"], "base_rpy_deg": [0.0, 0.0, 0.0],
    })
    # L from a tape, gammas from mutual sighting of the instruments (to about 0.01 deg)
    setup["stations"] = {**setup.get("stations", {}),
                         "L_mm": round(b.x_mm - a.x_mm, -1), "gamma1_deg": round(-a.yaw_rad / DEG, 2),
                         "gamma2_deg": round((b.yaw_rad - np.pi) / DEG, 2), "sigma_arcsec": a.sigma_hz_rad / ARCSEC}
    return setup


def demo_plan(twin: Twin, seed: int, n_poses: int = DEMO_POSES, quick: bool = True, te_joints=None) -> dict:
    """Which procedures with which parameters; the pose set is chosen now so a resume replays the same poses."""
    from calib.plan import select_poses
    model = MeasurementModel(twin.robot)
    lim = twin.robot.limits_rad
    try:
        plan = select_poses(model, n_poses, seed=seed, pool=300 if quick else 2000, test=100,
                            accept=lambda q: _visible(twin, q), compare=False)
        q = np.asarray(plan.q_rad) / DEG
    except Exception:           # planning is an aid; fall back to seeded random poses within the limits
        rng = np.random.default_rng(seed)
        q = (lim[:, 0] + 0.2 * np.ptp(lim, 1) + 0.6 * np.ptp(lim, 1) * rng.random((n_poses, twin.robot.n))) / DEG
    return {
        "procedures": ["levelling", "instrument_check", "ruler", "sweeps", "poses", "transmission", "compliance",
                       "link_compliance", "coupling", "encoder_resolution"],
        "ruler": {"repeats": 2},
        "sweeps": {"points": 5, "span_deg": 60.0, "joints": [1, 2, 3, 4, 5, 6]},
        "poses": {"q_deg": np.round(q, 3).tolist()},
        "transmission": transmission_plan(te_joints),
        "compliance": {"joints": [3, 4], "repeats": 3},
        "coupling": {"angle_deg": 10.0, "pairs": [[5, 6], [4, 6], [4, 5]], "repeats": 4},
        "encoder_resolution": RESOLUTION_RUN,
        "seed": seed,
    }


def _visible(twin: Twin, q_rad: np.ndarray) -> np.ndarray:
    """Poses whose tool target is in front of both stations, above the floor, not too close, and that pass the
    pre-flight (sight lines clear of the arm, inside the limits) with the demo's set-up."""
    pts = MeasurementModel(twin.robot).points(q_rad, theta=_nominal_theta(twin))
    ok = (pts[:, 1] > 1200) & (pts[:, 2] > -400)
    setup = session_setup(demo_setup(twin), twin.robot)
    pf = Preflight(twin.robot, setup)
    target = tool_target(setup)
    cand = np.flatnonzero(ok)
    steps = [Step(f"pose/{i}", "poses", "", "", pose_deg=tuple(np.asarray(q_rad[i]) / DEG), targets=(target,))
             for i in cand]
    failed = {f.key for f in pf.check(steps)}
    ok[cand] = [s.key not in failed for s in steps]
    return ok


def _nominal_theta(twin: Twin, tool_mm=(50.0, 0.0, 100.0)) -> np.ndarray:
    m = MeasurementModel(twin.robot)
    th = m.nominal.copy()
    tp = twin.true_parameters()
    for k in ("x_mm", "y_mm", "z_mm"):
        th[m.index[f"base.{k}"]] = tp[f"base.{k}"]
    th[: m.n_geometric] = m.kin.params_with_tool(np.asarray(tool_mm, float), th[: m.n_geometric])
    return th




@dataclass
class DemoRig:
    runner: Runner
    world: object
    twin: Twin
    store: SessionStore
    names: list

    def close(self) -> None:
        from acq.emulate import registry
        self.runner.rig.close()
        for n in self.names:
            registry.withdraw(n)
        for node in getattr(self, "_nodes", []):
            node.stop()
        self.store.close()


def build_demo(db: str | Path, seed: int = 0, resume: bool = False, script: dict | None = None,
               plan: dict | None = None, steps_filter=None, operator=None, setup: dict | None = None,
               scenario: str | None = None, te_joints=None, clock: Clock | None = None) -> DemoRig:
    """Open (or create) the demo session in ``db`` and wire emulated devices, bench, operator and runner.

    ``setup``: a set-up file's content (``robocal plan setup --out``) for a new session; its stations and base are
    replaced by the emulated cell's (:func:`demo_setup`).  ``scenario``: a twin scenario TOML (default: the default
    scenario); a resumed session keeps its own.  ``te_joints``: the transmission-error joints of the default plan
    (``--te-joints``; default :data:`DEFAULT_TE_JOINTS`).  ``clock``: the emulated devices' and the rig's time; by
    default a :class:`~acq.clock.SimClock` (the encoder windows take no wall time), a
    :class:`~acq.clock.RealClock` where a human watches the session (the TUI's ``--emulate``)."""

    from acq.drivers import open_theodolite
    from acq.emulate import registry
    from acq.emulate.can_node import CanTapNode, SenderVirtualBus
    from acq.emulate.geocom_device import GeoComDevice
    from acq.emulate.tap_device import TapModel
    from acq.emulate.twin_world import TwinWorld
    from acq.encoders import open_tap

    db = str(db)
    clock = SimClock() if clock is None else clock
    if resume:
        store = SessionStore.open(db, durable=not clock.simulated)
        meta = store.session_row()
        from .setup_file import setup_from_text
        from .store import json_column
        plan_d = json_column(meta["plan_json"], f"{db}: session plan_json")
        setup = setup_from_text(meta["setup_json"], f"{db}: session setup_json")
        seed = plan_d.get("seed", seed)
        # a resumed emulated session continues with a fresh noise stream (the twin's truth is the same)
        seed_offset = 1 + len(store.done_keys())
        meta_d = json_column(meta.get("metadata_json") or "{}", f"{db}: session metadata_json")
        scenario = meta_d.get("scenario_path")
    else:
        plan_d = None
        seed_offset = 0
    twin = Twin(load_scenario(scenario or None), seed=seed)
    if not resume:
        setup = session_setup(demo_setup(twin, setup), twin.robot)
        plan_d = plan or demo_plan(twin, seed, te_joints=te_joints)
        store = SessionStore.create(db, DEMO_TITLE, plan_d, setup, operator="scripted demo operator",
                                    metadata={"emulated": True, "scenario": "default" if not scenario else "file",
                                              "scenario_path": str(Path(scenario).resolve()) if scenario else None,
                                              "seed": seed},
                                    durable=not clock.simulated)       # a simulated session can be recorded again
    world = TwinWorld(twin, seed=seed * 1000 + seed_offset)
    tag = uuid.uuid4().hex[:8]
    names = []
    drivers = {}
    for st, serial in (("A", 1001), ("B", 1002)):
        name = f"demo-{tag}-{st}"
        url = registry.publish(name, GeoComDevice(world, st, serial_no=serial, seed=seed, clock=clock))
        names.append(name)
        drivers[st] = open_theodolite("geocom", url, name=f"theodolite {st}")
    channel = f"robocal-demo-{tag}"
    node = CanTapNode(SenderVirtualBus(channel=channel),
                      TapModel(world, twin.robot, rate_hz=500.0, clock=clock), own_bus=True)
    tap = open_tap("can", interface="virtual", channel=channel, robot=twin.robot)
    rig = Rig(drivers, tap, clock=clock)
    rig.start()                                 # the reader listens before the node sends its first sample
    node.start()
    if clock.simulated:
        clock.add_drain(_tap_drain(rig, node))
    known = _device_ids(store)               # a crash may have left some devices recorded and others not
    for role, driver, url, ident in rig.identities():
        if role in known:
            rig.device_ids[role] = known[role]
        else:
            rig.device_ids[role] = store.add_device(role, driver, url, ident,
                                                    {"emulated": True, "channel": channel} if role == "encoder tap"
                                                    else {"emulated": True})
    bench = EmulatedBench(world)
    setup = session_setup(setup, twin.robot)           # a resumed session's set-up may use the old keys
    steps = all_steps(plan_d, setup)
    if steps_filter is not None:
        steps = [s for s in steps if steps_filter(s)]

    def inputs(step: Step) -> dict:
        """What the scripted operator reads off the bench: the load it hung, dial gauges, the instrument's
        electronic level."""
        out = bench.read_inputs(step)
        drv = drivers.get(step.setup.get("station"))
        if drv is not None and any(i.name == "tilt_cross_arcsec" for i in step.inputs):
            r = drv.angles_with_inclination()
            out.update(tilt_cross_arcsec=r.incline_cross_rad / ARCSEC, tilt_length_arcsec=r.incline_length_rad / ARCSEC)
        return out

    op = operator or ScriptedOperator(script, inputs=inputs)
    from .stations import stations_from_store
    # settle_s: frames already on the bus when the robot "moves" carry the old counts; real cells wait for the servo.
    # On the simulated clock nothing is in flight at a move (each advance ends when the reader has every frame sent)
    # and the twin's robot stops at once: no settle, and half the frames to emulate
    runner = Runner(store, rig, steps, op, bench=bench, stations=setup_stations(setup),
                    predict=predictor(twin.robot, setup), settle_s=0.0 if clock.simulated else DEMO_SETTLE_S,
                    refit_stations=lambda st: stations_from_store(st, setup),
                    preflight=Preflight(twin.robot, setup))
    d = DemoRig(runner, world, twin, store, names)
    d._nodes = [node]
    return d


def _tap_drain(rig: Rig, node, timeout_s: float = 10.0):
    """A :class:`~acq.clock.SimClock` drain: wait until the tap reader has delivered every sample the node sent, so a
    simulated wait returns with its window's samples in the rig.

    The virtual bus loses nothing, it can only be late (a busy machine): a sample is never written off, since a late
    one would then land in the next window, stamped before its move, and bias that reading silently.  A reader
    still behind after ``timeout_s`` of real time fails the attempt as a device timeout (the runner repeats it);
    the next wait, at the start of the repeated capture, waits for the stragglers again before its window opens."""

    def drain() -> None:
        sent = node.samples_sent
        if not rig.wait_received(sent, timeout_s):
            raise DeviceTimeout("encoder tap", "read", f"the reader has {rig.received} of the {sent} samples the "
                                f"emulated tap sent after {timeout_s:g} s")
    return drain


def _has_devices(store: SessionStore) -> bool:
    return store.conn.execute("SELECT count(*) FROM device").fetchone()[0] > 0


def _device_ids(store: SessionStore) -> dict:
    return {role: did for did, role in store.conn.execute("SELECT device_id, role FROM device ORDER BY device_id")}
