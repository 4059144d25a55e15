"""pyserial protocol handler package: ``serial.protocol_handler_packages.append("sim.emulate.urlhandler")``."""
