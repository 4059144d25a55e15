"""Subcommands of ``robocal``: each module here is one command (see :mod:`app.cli`)."""
