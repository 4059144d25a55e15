"""Emulated instruments, shipped for the demo and the tests, observing one world: the twin
(:class:`~acq.emulate.twin_world.TwinWorld`, made by :func:`~acq.emulate.factories.make_world` from a scenario).

Devices (byte state machines, no I/O; each parses with its own code, never the drivers' codecs):
:class:`~acq.emulate.geocom_device.GeoComDevice`, :class:`~acq.emulate.gsi_device.GsiDevice`,
:class:`~acq.emulate.tap_device.SerialTapDevice`, :class:`~acq.emulate.slcan_device.SlcanTapDevice`, and the CAN node
:class:`~acq.emulate.can_node.CanTapNode` (python-can bus).

Harnesses: ``robocal://<kind>?seed=3`` for :func:`serial.serial_for_url` (registered by :mod:`acq.link`;
``robocal://instance/<name>`` for a device published with :func:`acq.emulate.registry.publish`),
:class:`~acq.emulate.pty_host.PtyHost` (a real pty path), :class:`~acq.emulate.tcp_host.TcpHost` (``socket://``),
and ``robocal emulate geocom|gsi|tap`` on the command line.
"""
