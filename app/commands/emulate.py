"""``robocal emulate geocom|gsi|tap``: run an emulated instrument until interrupted.

The first line of output is where to connect: a device path (``--pty``, ``--slcan-pty``, ``--serial-pty``) or a
``socket://`` URL (``--tcp``), or ``<interface>:<channel>`` (``--can``); everything after it is informational.

The instrument observes the twin (``--scenario FILE``, the default scenario by default), the same world as the demo
and every ``robocal://`` URL.  Every option is checked before anything starts (a rate of 0, NaN or 1e308, an unknown
station, a pose outside the joint limits is one line and exit 2).  A server thread that fails stops the process
with one line and a non-zero exit instead of leaving a process that no longer answers.
"""
from __future__ import annotations

import signal
import threading

from acq import argtypes as at
from calib.errors import RobocalError

NAME = "emulate"
HELP = "run an emulated theodolite (GeoCOM, GSI) or encoder tap; prints where to connect, serves until Ctrl-C"
EXAMPLES = """\
robocal emulate geocom --pty                    # prints the pty path a GeoCOM client connects to
robocal emulate tap --slcan-pty                 # python-can's slcan interface opens the printed path
robocal emulate geocom --tcp 0 --scenario my_twin.toml
"""


class ServerFailed(RuntimeError):
    """An emulator's server thread died: a bug, reported by the last-resort handler (exit 3)."""


def add_arguments(p):
    from sim.emulate.gsi_device import MAX_STREAM_HZ
    from sim.emulate.tap_device import MAX_RATE_HZ
    p.add_argument("device", choices=("geocom", "gsi", "tap"), help="what to emulate")
    how = p.add_mutually_exclusive_group()
    how.add_argument("--pty", action="store_true", help="theodolite on a pseudo-terminal (default for geocom/gsi)")
    how.add_argument("--tcp", type=at.any_int, metavar="PORT",
                     help="serve on TCP PORT (0 = any); connect with socket://")
    how.add_argument("--slcan-pty", action="store_true",
                     help="tap as an SLCAN adapter on a pty, for python-can's slcan interface (default for tap)")
    how.add_argument("--serial-pty", action="store_true", help="tap as COBS+CRC frames on a pty")
    how.add_argument("--can", metavar="IFACE:CHANNEL", help="tap as a node on a python-can bus, e.g. socketcan:vcan0")
    p.add_argument("--scenario", type=at.existing_file, metavar="FILE",
                   help="twin scenario TOML the instruments observe (default: the shipped default scenario)")
    p.add_argument("--seed", type=at.seed_int, default=0, help="world noise seed (default 0)")
    p.add_argument("--no-noise", action="store_true", help="no reading noise")
    p.add_argument("--station", help="station name in the scenario (default A for geocom, B for gsi)")
    p.add_argument("--q-deg", type=at.finite_float, nargs="+", metavar="Q",
                   help="robot joint angles (deg) the world holds (default: READY)")
    p.add_argument("--gsi8", action="store_true", help="gsi: GSI-8 words (default GSI-16)")
    p.add_argument("--unit", choices=("gon", "deg", "dms"), default="gon", help="gsi: angle unit (default gon)")
    p.add_argument("--stream-hz", type=at.float_range(0.0, MAX_STREAM_HZ), default=0.0,
                   help=f"gsi: also stream a block at this rate (0 = off, at most {MAX_STREAM_HZ:g})")
    p.add_argument("--rate-hz", type=at.float_range(0.0, MAX_RATE_HZ, low_open=True), default=200.0,
                   help=f"tap: samples per second (default 200, at most {MAX_RATE_HZ:g})")
    p.add_argument("--duration", type=at.positive_float, metavar="S", help="stop after S seconds (default: until Ctrl-C)")


def _world(args):
    """The twin's world, with the pose and station checked against the scenario's robot and stations."""
    import numpy as np

    from sim.emulate.factories import make_world
    from calib.units import DEG
    world = make_world(args.scenario, seed=args.seed, noise=not args.no_noise)
    where = f"emulate {args.device}"
    if args.q_deg is not None:
        robot = world.robot
        q = np.asarray(args.q_deg, float)
        if q.shape != (robot.n,):
            raise RobocalError(f"{where}: --q-deg needs {robot.n} joint angles for {robot.name}, got {len(q)}")
        lim = np.asarray(robot.limits_rad) / DEG
        for j, (x, (lo, hi)) in enumerate(zip(q, lim), 1):
            if not lo <= x <= hi:
                raise RobocalError(f"{where}: --q-deg: joint {j} = {x:g} deg is outside its limits "
                                   f"{lo:g}..{hi:g} deg")
        world.command(q * DEG)
    if args.device != "tap" and args.station is not None and args.station not in world.stations:
        raise RobocalError(f"{where}: --station {args.station!r}: the scenario has stations "
                           f"{', '.join(world.stations)}")
    return world


def run(args) -> int:
    if args.tcp is not None and not 0 <= args.tcp <= 65535:
        raise RobocalError(f"emulate {args.device}: --tcp {args.tcp}: a TCP port is 0..65535")
    world = _world(args)
    hosts: list = []
    stop = threading.Event()
    failures: list[tuple[object, BaseException]] = []

    def failed(host, exc: BaseException) -> None:
        failures.append((host, exc))
        stop.set()

    # Ctrl-C (SIGINT) or SIGTERM is the normal way to stop an emulator: it sets the stop event instead of raising
    # KeyboardInterrupt wherever the main thread happens to be (in a host's close, say), so the exit is always clean
    previous = ({sig: signal.signal(sig, lambda *_: stop.set()) for sig in (signal.SIGINT, signal.SIGTERM)}
                if threading.current_thread() is threading.main_thread() else {})
    try:
        where, info = _start(args, world, hosts, failed)
        print(where, flush=True)
        print(f"{info} [twin scenario: {world.twin.scenario.name}]", flush=True)
        stop.wait(args.duration if args.duration is not None else None)
    except OSError as exc:
        raise RobocalError(f"emulate {args.device}: cannot start: {exc}") from None
    finally:
        for h in hosts:
            h.close()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    if failures:
        host, exc = failures[0]
        raise ServerFailed(f"{host.describe()} stopped: {type(exc).__name__}: {exc}")
    return 0


def _start(args, world, hosts, failed) -> tuple[str, str]:
    from sim.emulate.pty_host import PtyHost
    from sim.emulate.tcp_host import TcpHost
    robot = world.robot
    if args.device in ("geocom", "gsi"):
        if args.slcan_pty or args.serial_pty or args.can:
            raise RobocalError(f"emulate {args.device}: --slcan-pty/--serial-pty/--can are for the tap")
        if args.device == "geocom":
            if args.stream_hz or args.gsi8:
                raise RobocalError("emulate geocom: --stream-hz and --gsi8 are options of the GSI emulator "
                                   "(robocal emulate gsi)")
            from sim.emulate.geocom_device import GeoComDevice
            dev = GeoComDevice(world, args.station or "A", seed=args.seed)
            what = f"GeoCOM theodolite (station {dev.station}, {dev.instrument_name})"
        else:
            from sim.emulate.gsi_device import GsiDevice
            dev = GsiDevice(world, args.station or "B", gsi16=not args.gsi8, angle_unit=args.unit,
                            stream_hz=args.stream_hz)
            what = f"GSI theodolite (station {dev.station}, GSI-{16 if dev.gsi16 else 8}, {args.unit})"
        if args.tcp is not None:
            host = TcpHost(dev, port=args.tcp, on_failure=failed)
            hosts.append(host)
            return host.url, f"{what} on {host.url}; Ctrl-C stops"
        host = PtyHost(dev, on_failure=failed)
        hosts.append(host)
        return host.path, f"{what} on pty {host.path}; Ctrl-C stops"
    # tap
    if args.pty or args.tcp is not None:
        raise RobocalError("emulate tap: use --slcan-pty, --serial-pty or --can")
    if args.serial_pty:
        from sim.emulate.tap_device import SerialTapDevice
        host = PtyHost(SerialTapDevice(world, robot, rate_hz=args.rate_hz), on_failure=failed)
        hosts.append(host)
        return host.path, f"encoder tap, COBS+CRC-16 frames at {args.rate_hz:g} Hz on {host.path}; Ctrl-C stops"
    if args.can:
        import can

        from sim.emulate.can_node import CanTapNode
        from sim.emulate.tap_device import TapModel
        iface, _, channel = args.can.partition(":")
        if not channel:
            raise RobocalError(f"emulate tap: --can wants INTERFACE:CHANNEL, got {args.can!r}")
        try:
            bus = can.Bus(interface=iface, channel=channel)
        except (can.CanError, OSError, ValueError, ImportError) as exc:
            raise RobocalError(f"emulate tap: cannot open CAN bus {args.can}: {exc}") from None
        node = CanTapNode(bus, TapModel(world, robot, rate_hz=args.rate_hz), own_bus=True, on_failure=failed)
        hosts.append(node)
        node.start()
        return args.can, f"encoder tap node on {args.can} at {args.rate_hz:g} samples/s; Ctrl-C stops"
    from sim.emulate.slcan_device import SlcanTapDevice
    host = PtyHost(SlcanTapDevice(world, robot, rate_hz=args.rate_hz), on_failure=failed)
    hosts.append(host)
    return host.path, (f"encoder tap behind an SLCAN adapter on {host.path} "
                       f"(python-can: interface='slcan', channel='{host.path}'); Ctrl-C stops")
