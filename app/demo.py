"""The demo session: every procedure recorded from emulated instruments driven by the twin, scripted operator.

Wiring (the same a real cell uses, only the devices are emulated):

* the twin (:mod:`sim.twin`, default scenario) behind a :class:`~sim.emulate.twin_world.TwinWorld`;
* two GeoCOM theodolite emulators published in the registry and opened with the **real** driver
  (``open_theodolite("geocom", "robocal://instance/...")``), so the stored frames are protocol bytes;
* the encoder tap emulator as a node on a python-can ``virtual`` channel, read by the **real** CAN tap reader;
* :class:`~sim.emulate.bench.EmulatedBench` plays the technician's hands (robot motion, loads, aiming), and
  :class:`~acq.session.headless.ScriptedOperator` the technician's answers (dial gauges read from the world).

Time: the emulated devices and the rig run on a :class:`~acq.clock.SimClock` (an encoder window is an advance of
simulated time, not a sleep), except where a human watches (the TUI's ``--emulate`` passes a real clock).  Session
parameters are chosen so ``robocal demo`` stays quick on 2 cores (``benchmarks/bench_demo.py``): fewer positions and
repeats than a real session, but every procedure is present.
"""
from __future__ import annotations

import json
import pickle
import uuid
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from acq.cache import cached_array, cached_json
from acq.clock import Clock, SimClock
from sim.emulate.scenario import STATIONS, scenario_text
from acq.errors import DeviceTimeout
from calib.jsonfile import vouch
from calib.model import MeasurementModel
from calib.profile import profile_of
from calib.loading import RobotPath
from calib.loading import load_robot
from sim.twin import Twin, load_scenario, parse_scenario
from calib.units import ARCSEC, DEG

from acq.session.headless import ScriptedOperator
from offline.iso_commands import CompensatedCommands
from acq.session.plan_doc import PLAN_SCHEMA
from acq.session.plans import DEMO, session_plan, transmission_plan  # noqa: F401 (transmission_plan: for callers)
from acq.session.preflight import Preflight
from acq.session.bench import robot_setup
from acq.session.setup import GAUGE_SIGMA_MM, predictor, record_robot, session_setup, setup_stations, standard_setup
from acq.session.procedures import all_steps, tool_target
from acq.session.rig import Rig
from sim.emulate.bench import EmulatedBench
from acq.session.runner import Runner
from acq.session.setup_types import BenchSetup, setup_of
from acq.session.steps import Step
from acq.session.store import SessionStore

#: the demo's title on the thesis's Puma (another robot's demo names its description)
DEMO_TITLE = "robocal demo: emulated Puma 560 (twin) and two GeoCOM theodolites"
#: poses in the demo's Chapter 6 set: enough to identify the geometry with the running errors (about 30 free
#: parameters) at a few sigma of the truth, still a quick recording
DEMO_POSES = 48
#: wait after each move before recording encoders (the tap's frames in flight carry the previous pose); real time only
DEMO_SETTLE_S = 0.02


def demo_setup(twin: Twin, base: dict | None = None) -> dict:
    """The bench geometry a technician would write down for the emulated cell: ``base`` (a set-up file from
    ``robocal plan setup``; default the robot's bench, :func:`acq.session.bench.robot_setup`) with the stations and
    the robot's base
    as measured on the twin's cell (rounded like a tape and mutual sighting give them: not the twin's truth)."""
    tp = twin.true_parameters()
    a, b = twin.stations
    setup = json.loads(json.dumps(base)) if base is not None else robot_setup(twin.robot)
    setup.update({
        "robot": setup.get("robot", ""), "scenario": setup.get("scenario", ""),
        "base_xyz_mm": [round(tp[f"base.{k}_mm"], 0) for k in "xyz"], "base_rpy_deg": [0.0, 0.0, 0.0],
    })
    # L from a tape, gammas from mutual sighting of the instruments (to about 0.01 deg)
    setup["stations"] = {**setup.get("stations", {}),
                         "L_mm": round(b.x_mm - a.x_mm, -1), "gamma1_deg": round(-a.yaw_rad / DEG, 2),
                         "gamma2_deg": round((b.yaw_rad - np.pi) / DEG, 2), "sigma_arcsec": a.sigma_hz_rad / ARCSEC}
    return setup


def demo_plan(twin: Twin, seed: int, n_poses: int = DEMO_POSES, quick: bool = True, te_joints=None,
              setup: BenchSetup | dict | None = None) -> dict:
    """Which procedures with which parameters: :func:`acq.session.plans.session_plan` with the :data:`DEMO
    <acq.session.plans.DEMO>` preset and a pose set chosen now (so a resume replays the same poses).  A pure function
    of the robot, the set-up, the twin's base, the seed, the count and the transmission-error joints: kept in the
    on-disk cache (:mod:`acq.cache`) as the JSON document it is stored as (the runs narrowed to the cell's sight and
    the ISO 9283 cube, 0.1 s of CPU a run)."""
    setup = setup_of(session_setup(demo_setup(twin), twin.robot) if setup is None else setup)
    joints = None if te_joints is None else [int(j) for j in te_joints]
    return cached_json("demo-plan", _choice_inputs(twin, seed, n_poses, quick, setup) + pickle.dumps(joints),
                       lambda: session_plan(twin.robot, setup, DEMO, te_joints,
                                            np.round(demo_poses(twin, seed, n_poses, quick, setup), 3), seed))


def demo_poses(twin: Twin, seed: int, n_poses: int, quick: bool, setup: BenchSetup) -> np.ndarray:
    """The demo's pose set (joint readings, degrees or mm), chosen by :func:`calib.plan.select_poses` among
    candidates the pre-flight passes.  A pure function of the robot, the set-up, the twin's base, the seed and the
    count: kept in the on-disk cache (:mod:`acq.cache`; 0.3-0.4 s of CPU saved per run)."""
    return cached_array("demo-poses", _choice_inputs(twin, seed, n_poses, quick, setup),
                        lambda: _choose_poses(twin, seed, n_poses, quick, setup), shape=(n_poses, twin.robot.n))


def _choice_inputs(twin: Twin, seed: int, n_poses: int, quick: bool, setup: BenchSetup) -> bytes:
    """The inputs of the demo's choices, as the bytes that key them in the cache."""
    tp = twin.true_parameters()
    return pickle.dumps((twin.robot, json.dumps(dict(setup.doc), sort_keys=True, default=str),
                         [tp[f"base.{k}_mm"] for k in "xyz"], int(seed), int(n_poses), bool(quick)))


def _choose_poses(twin: Twin, seed: int, n_poses: int, quick: bool, setup: BenchSetup) -> np.ndarray:
    from calib.plan import select_poses
    model = MeasurementModel(twin.robot)
    lim = twin.robot.limits_rad
    try:
        plan = select_poses(model, n_poses, seed=seed, pool=300 if quick else 2000, test=100,
                            accept=lambda q: _visible(twin, q, setup), compare=False)
        return np.asarray(plan.q_rad) / twin.robot.edge_scale
    except Exception:           # planning is an aid; fall back to seeded random poses within the limits
        rng = np.random.default_rng(seed)
        return (lim[:, 0] + 0.2 * np.ptp(lim, 1) + 0.6 * np.ptp(lim, 1) * rng.random((n_poses, twin.robot.n))) \
            / twin.robot.edge_scale


#: the floor below the robot's frame 0 (mm): the thesis cell's is 400 mm below the instruments' horizon, the Puma's
#: frame 0 185 mm above it
FLOOR_BELOW_BASE_MM = 585.0


def _visible(twin: Twin, q_rad: np.ndarray, setup: BenchSetup) -> np.ndarray:
    """Poses whose tool target is in front of both stations, above the floor (:data:`FLOOR_BELOW_BASE_MM` below
    the robot's base), not too close, and that pass the pre-flight (sight lines clear of the arm, inside the limits)
    with the set-up."""
    m = MeasurementModel(twin.robot)
    th = m.nominal.copy()
    tp = twin.true_parameters()
    for k in ("x_mm", "y_mm", "z_mm"):
        th[m.index[f"base.{k}"]] = tp[f"base.{k}"]
    th[: m.n_geometric] = m.kin.params_with_tool(np.asarray(tool_target(setup).tool_mm, float), th[: m.n_geometric])
    pts = m.points(q_rad, theta=th)
    ok = (pts[:, 1] > 1200) & (pts[:, 2] > tp["base.z_mm"] - FLOOR_BELOW_BASE_MM)
    pf = Preflight(twin.robot, setup)
    target = tool_target(setup)
    cand = np.flatnonzero(ok)
    steps = [Step(f"pose/{i}", "poses", "", "", pose_deg=tuple(np.asarray(q_rad[i]) / twin.robot.edge_scale),
                  targets=(target,)) for i in cand]
    failed = {f.key for f in pf.check(steps)}
    ok[cand] = [s.key not in failed for s in steps]
    return ok


def robot_twin(robot_path, seed: int) -> tuple[Twin, str, dict]:
    """A twin of the robot at ``robot_path`` (a :class:`calib.loading.RobotPath` may carry a URDF's chain cut): its
    generated scenario (:func:`sim.emulate.scenario.scenario_text`) and the set-up its bench starts from
    (:func:`acq.session.bench.robot_setup`, the scenario's stations)."""
    path = RobotPath(str(Path(str(robot_path)).resolve()), getattr(robot_path, "base_link", None),
                     getattr(robot_path, "tip_link", None))
    robot = load_robot(path)
    base = record_robot(standard_setup(), path)
    base["stations"] = {**base["stations"], **{k: v for k, v in STATIONS.items() if k in base["stations"]}}
    setup = robot_setup(robot, base)
    text = scenario_text(robot, str(path), setup_of(setup), seed)
    return Twin(parse_scenario(text, f"scenario of {robot.name}"), seed=seed), text, setup


@dataclass
class DemoRig:
    """The demo's wired session: the runner, the emulated world and twin, the store, and the names published in
    the emulator registry (withdrawn at :meth:`close`)."""

    runner: Runner
    world: object
    twin: Twin
    store: SessionStore
    names: list

    def close(self) -> None:
        from sim.emulate import registry
        self.runner.rig.close()
        for n in self.names:
            registry.withdraw(n)
        for node in getattr(self, "_nodes", []):
            node.stop()
        self.store.close()


def build_demo(db: str | Path, seed: int = 0, resume: bool = False, script: dict | None = None,
               plan: dict | None = None, steps_filter=None, operator=None, setup: dict | None = None,
               scenario: str | None = None, te_joints=None, clock: Clock | None = None, robot=None) -> DemoRig:
    """Open (or create) the demo session in ``db`` and wire emulated devices, bench, operator and runner.

    ``setup``: a set-up file's content (``robocal plan setup --out``) for a new session; its stations and base are
    replaced by the emulated cell's (:func:`demo_setup`).  ``scenario``: a twin scenario TOML (default: the default
    scenario); a resumed session keeps its own.  ``te_joints``: the transmission-error joints of the default plan
    (``--te-joints``; default the robot profile's).  ``robot``: a robot description (``--robot``; a
    :class:`calib.loading.RobotPath` carries a URDF's chain cut) for a new session: its twin's scenario is generated
    (:func:`robot_twin`) and kept in the session.  ``clock``: the emulated devices' and the rig's time; by
    default a :class:`~acq.clock.SimClock` (the encoder windows take no wall time), a
    :class:`~acq.clock.RealClock` where a human watches the session (the TUI's ``--emulate``)."""

    from acq.drivers import open_theodolite
    from sim.emulate import registry
    from sim.emulate.can_node import CanTapNode, SenderVirtualBus
    from sim.emulate.geocom_device import GeoComDevice
    from sim.emulate.tap_device import TapModel
    from sim.emulate.twin_world import TwinWorld
    from acq.encoders import open_tap

    db = str(db)
    clock = SimClock() if clock is None else clock
    if resume:
        store = SessionStore.open(db, durable=not clock.simulated)
        meta = store.session_row()
        from acq.session.setup_file import setup_from_text
        from acq.session.store import json_column
        plan_d = json_column(meta["plan_json"], f"{db}: session plan_json")
        setup = setup_from_text(meta["setup_json"], f"{db}: session setup_json")
        seed = plan_d.get("seed", seed)
        # a resumed emulated session continues with a fresh noise stream (the twin's truth is the same)
        seed_offset = 1 + len(store.done_keys())
        meta_d = json_column(meta.get("metadata_json") or "{}", f"{db}: session metadata_json")
        scenario, text = meta_d.get("scenario_path"), meta_d.get("scenario_toml")
        twin = Twin(parse_scenario(text, f"{db}: scenario") if text else load_scenario(scenario or None), seed=seed)
    else:
        seed_offset = 0
        text = None
        if robot:
            twin, text, base = robot_twin(robot, seed)
            setup = base if setup is None else {**{k: v for k, v in setup.items() if k not in ("base_link", "tip_link")},
                                                 **{k: base[k] for k in ("robot", "base_link", "tip_link") if k in base}}
        else:
            twin = Twin(load_scenario(scenario or None), seed=seed)
        own = setup is None         # the bench robocal made itself (a user's --setup was checked as it was read)
        setup = session_setup(demo_setup(twin, setup), twin.robot, own=own)
        typed = setup_of(setup)
        # the plan robocal chose (a plan given by the caller is checked as the steps are made)
        plan_d = plan or vouch(demo_plan(twin, seed, te_joints=te_joints, setup=typed), PLAN_SCHEMA)
        title = DEMO_TITLE if profile_of(twin.robot).thesis else \
            f"robocal demo: emulated {twin.robot.name} (twin) and two GeoCOM theodolites"
        kind = "generated" if text else ("file" if scenario else "default")
        store = SessionStore.create(db, title, plan_d, setup, operator="scripted demo operator",
                                    metadata={"emulated": True, "scenario": kind, "scenario_toml": text,
                                              "scenario_path": str(Path(scenario).resolve()) if scenario else None,
                                              "seed": seed},
                                    durable=not clock.simulated)       # a simulated session can be recorded again
    # a resumed session's set-up may use the old keys (a new one's were mapped above: mapping is idempotent)
    setup = setup_of(session_setup(setup, twin.robot)) if resume else typed
    world = TwinWorld(twin, seed=seed * 1000 + seed_offset,       # the gauges read with the set-up's noise
                      gauge_sigma_mm=(setup.link and setup.link.gauge_sigma_mm) or GAUGE_SIGMA_MM)
    tag = uuid.uuid4().hex[:8]
    names = []
    drivers = {}
    for st, serial in (("A", 1001), ("B", 1002)):
        name = f"demo-{tag}-{st}"
        url = registry.publish(name, GeoComDevice(world, st, serial_no=serial, seed=seed, clock=clock))
        names.append(name)
        drivers[st] = open_theodolite("geocom", url, name=f"theodolite {st}")
    channel = f"robocal-demo-{tag}"
    node = tap = None
    if profile_of(twin.robot).tapped:           # the tap carries six joints' counts
        node = CanTapNode(SenderVirtualBus(channel=channel),
                          TapModel(world, twin.robot, rate_hz=500.0, clock=clock), own_bus=True)
        tap = open_tap("can", interface="virtual", channel=channel, robot=twin.robot)
    rig = Rig(drivers, tap, clock=clock)
    rig.start()                                 # the reader listens before the node sends its first sample
    if node is not None:
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
    from acq.session.stations import stations_from_store
    # settle_s: frames already on the bus when the robot "moves" carry the old counts; real cells wait for the servo.
    # On the simulated clock nothing is in flight at a move (each advance ends when the reader has every frame sent)
    # and the twin's robot stops at once: no settle, and half the frames to emulate
    runner = Runner(store, rig, steps, op, bench=bench, stations=setup_stations(setup),
                    predict=predictor(twin.robot, setup), settle_s=0.0 if clock.simulated else DEMO_SETTLE_S,
                    refit_stations=lambda st: stations_from_store(st, setup),
                    preflight=Preflight(twin.robot, setup),
                    command=CompensatedCommands(store, (plan_d.get("iso9283") or {}).get("model") or None))
    d = DemoRig(runner, world, twin, store, names)
    d._nodes = [node] if node is not None else []
    return d


def _tap_drain(rig: Rig, node, timeout_s: float = 10.0):
    """A :class:`~acq.clock.SimClock` drain: wait until the tap reader has delivered every sample the node sent, so a
    simulated wait returns with its window's samples in the rig.

    The virtual bus loses nothing, it can only be late (a busy machine): a sample is never written off, since a late
    one would then land in the next window, stamped before its move, and bias that reading silently.  A reader
    still behind after ``timeout_s`` of real time fails the attempt as a device timeout (the runner repeats it);
    the next wait, at the start of the repeated capture, waits for the stragglers again before its window opens.
    A reader the rig polls (:meth:`acq.session.rig.Rig.poll_tap`: on the simulated clock, no reader thread) is
    handed the frames now, in this thread; one still short then is short of frames the bus lost, and fails at once."""

    def drain() -> None:
        sent = node.samples_sent
        polled = getattr(getattr(rig, "tap", None), "polled", False)
        if polled:                  # a reader without its thread (the simulated clock's): handed what was sent
            rig.poll_tap()
        wait = 0.0 if polled else timeout_s           # polled, nothing more can come until the node sends again
        if not rig.wait_received(sent, wait):
            raise DeviceTimeout("encoder tap", "read", f"the reader has {rig.received} of the {sent} samples the "
                                f"emulated tap sent" + (f" after {wait:g} s" if wait else ""))
    return drain


def _has_devices(store: SessionStore) -> bool:
    return store.conn.execute("SELECT count(*) FROM device").fetchone()[0] > 0


def _device_ids(store: SessionStore) -> dict:
    return {role: did for did, role in store.conn.execute("SELECT device_id, role FROM device ORDER BY device_id")}
