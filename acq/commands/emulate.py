"""``robocal emulate geocom|gsi|tap``: run an emulated instrument until interrupted.

The first line of output is where to connect: a device path (``--pty``, ``--slcan-pty``, ``--serial-pty``) or a
``socket://`` URL (``--tcp``), or ``<interface>:<channel>`` (``--can``); everything after it is informational.
"""
from __future__ import annotations

import threading

import numpy as np

from calib.errors import RobocalError
from calib.units import DEG
from acq.argtypes import any_int, float_range, positive_float, seed_int

NAME = "emulate"
HELP = "run an emulated theodolite (GeoCOM, GSI) or encoder tap; prints where to connect, serves until Ctrl-C"


def add_arguments(p):
    p.add_argument("device", choices=("geocom", "gsi", "tap"), help="what to emulate")
    how = p.add_mutually_exclusive_group()
    how.add_argument("--pty", action="store_true", help="theodolite on a pseudo-terminal (default for geocom/gsi)")
    how.add_argument("--tcp", type=any_int, metavar="PORT", help="serve on TCP PORT (0 = any); connect with socket://")
    how.add_argument("--slcan-pty", action="store_true",
                     help="tap as an SLCAN adapter on a pty, for python-can's slcan interface (default for tap)")
    how.add_argument("--serial-pty", action="store_true", help="tap as COBS+CRC frames on a pty")
    how.add_argument("--can", metavar="IFACE:CHANNEL", help="tap as a node on a python-can bus, e.g. socketcan:vcan0")
    p.add_argument("--seed", type=seed_int, default=0, help="world noise seed (default 0)")
    p.add_argument("--no-noise", action="store_true", help="no reading noise")
    p.add_argument("--station", help="station name in the world (default A for geocom, B for gsi)")
    p.add_argument("--q-deg", type=float_range(-360, 360), nargs=6, metavar="Q", help="robot joint angles (deg) the world holds")
    p.add_argument("--gsi8", action="store_true", help="gsi: GSI-8 words (default GSI-16)")
    p.add_argument("--unit", choices=("gon", "deg", "dms"), default="gon", help="gsi: angle unit (default gon)")
    p.add_argument("--stream-hz", type=float_range(0, 1000), default=0.0, help="gsi: also stream a block at this rate")
    p.add_argument("--rate-hz", type=float_range(0, 10000, low_open=True), default=200.0, help="tap: samples per second (default 200)")
    p.add_argument("--duration", type=positive_float, metavar="S", help="stop after S seconds (default: until Ctrl-C)")


def _world(args):
    from acq.emulate.world import DEMO_Q_DEG, KinematicWorld, demo_stations
    from calib.robot import load_robot
    q = np.array(args.q_deg if args.q_deg else DEMO_Q_DEG) * DEG
    return KinematicWorld(load_robot(), demo_stations(), q, seed=args.seed, noise=not args.no_noise)


def run(args) -> int:
    if args.tcp is not None and not 0 <= args.tcp <= 65535:
        raise RobocalError(f"emulate {args.device}: --tcp {args.tcp}: a TCP port is 0..65535")
    world = _world(args)
    hosts = []
    try:
        where, info = _start(args, world, hosts)
        print(where, flush=True)
        print(info, flush=True)
        stop = threading.Event()
        try:
            stop.wait(args.duration if args.duration is not None else None)
        except KeyboardInterrupt:
            pass
        return 0
    except OSError as exc:
        raise RobocalError(f"emulate {args.device}: cannot start: {exc}") from None
    finally:
        for h in hosts:
            h.close()


def _start(args, world, hosts) -> tuple[str, str]:
    from acq.emulate.pty_host import PtyHost
    from acq.emulate.tcp_host import TcpHost
    robot = world.robot
    if args.device in ("geocom", "gsi"):
        if args.slcan_pty or args.serial_pty or args.can:
            raise RobocalError(f"emulate {args.device}: --slcan-pty/--serial-pty/--can are for the tap")
        if args.device == "geocom":
            from acq.emulate.geocom_device import GeoComDevice
            dev = GeoComDevice(world, args.station or "A", seed=args.seed)
            what = f"GeoCOM theodolite (station {dev.station}, {dev.instrument_name})"
        else:
            from acq.emulate.gsi_device import GsiDevice
            dev = GsiDevice(world, args.station or "B", gsi16=not args.gsi8, angle_unit=args.unit,
                            stream_hz=args.stream_hz)
            what = f"GSI theodolite (station {dev.station}, GSI-{16 if dev.gsi16 else 8}, {args.unit})"
        if args.tcp is not None:
            host = TcpHost(dev, port=args.tcp)
            hosts.append(host)
            return host.url, f"{what} on {host.url}; Ctrl-C stops"
        host = PtyHost(dev)
        hosts.append(host)
        return host.path, f"{what} on pty {host.path}; Ctrl-C stops"
    # tap
    if args.pty or args.tcp is not None:
        raise RobocalError("emulate tap: use --slcan-pty, --serial-pty or --can")
    if args.serial_pty:
        from acq.emulate.tap_device import SerialTapDevice
        host = PtyHost(SerialTapDevice(world, robot, rate_hz=args.rate_hz))
        hosts.append(host)
        return host.path, f"encoder tap, COBS+CRC-16 frames at {args.rate_hz:g} Hz on {host.path}; Ctrl-C stops"
    if args.can:
        import can

        from acq.emulate.can_node import CanTapNode
        from acq.emulate.tap_device import TapModel
        iface, _, channel = args.can.partition(":")
        if not channel:
            raise RobocalError(f"emulate tap: --can wants INTERFACE:CHANNEL, got {args.can!r}")
        try:
            bus = can.Bus(interface=iface, channel=channel)
        except (can.CanError, OSError, ValueError, ImportError) as exc:
            raise RobocalError(f"emulate tap: cannot open CAN bus {args.can}: {exc}") from None
        node = CanTapNode(bus, TapModel(world, robot, rate_hz=args.rate_hz), own_bus=True).start()
        hosts.append(_Closer(node.stop))
        return args.can, f"encoder tap node on {args.can} at {args.rate_hz:g} samples/s; Ctrl-C stops"
    from acq.emulate.slcan_device import SlcanTapDevice
    host = PtyHost(SlcanTapDevice(world, robot, rate_hz=args.rate_hz))
    hosts.append(host)
    return host.path, (f"encoder tap behind an SLCAN adapter on {host.path} "
                       f"(python-can: interface='slcan', channel='{host.path}'); Ctrl-C stops")


class _Closer:
    def __init__(self, fn):
        self.close = fn
