"""``robocal demo``: the main job on the embedded default.

Until the emulated calibration session exists, the demo is a twin run (the thesis's Puma 560 with its measured
effects) and its calibration-relevant summary.
"""
from __future__ import annotations

from . import twin as _twin

NAME = "demo"
HELP = "run the main job on the embedded default (the emulated Puma 560 and theodolites)"


def add_arguments(p):
    _twin.add_arguments(p)


def run(args) -> int:
    return _twin.run(args)
