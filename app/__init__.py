"""The application shell: the ``robocal`` command line, its commands, the Textual TUI and the demo.

It composes the other packages (acquisition, calibration core, offline reduction, simulation) and holds
no physics of its own.
"""
