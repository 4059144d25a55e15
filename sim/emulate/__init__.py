"""Emulated instruments, shipped for the demo and the tests, observing one world: the twin
(:class:`~sim.emulate.twin_world.TwinWorld`, made by :func:`~sim.emulate.factories.make_world` from a scenario).

Devices (byte state machines, no I/O; each parses with its own code, never the drivers' codecs):
:class:`~sim.emulate.geocom_device.GeoComDevice`, :class:`~sim.emulate.gsi_device.GsiDevice`,
:class:`~sim.emulate.tap_device.SerialTapDevice`, :class:`~sim.emulate.slcan_device.SlcanTapDevice`, and the CAN node
:class:`~sim.emulate.can_node.CanTapNode` (python-can bus).

Harnesses: ``robocal://<kind>?seed=3`` for :func:`serial.serial_for_url` (registered by :mod:`acq.link`;
``robocal://instance/<name>`` for a device published with :func:`sim.emulate.registry.publish`),
:class:`~sim.emulate.pty_host.PtyHost` (a real pty path), :class:`~sim.emulate.tcp_host.TcpHost` (``socket://``),
and ``robocal emulate geocom|gsi|tap`` on the command line.
"""
