"""``robocal twin``: run the Puma 560 twin and print a calibration-relevant summary."""
from __future__ import annotations

import json

from acq.argtypes import int_range, output_file, seed_int
from sim.twin import Twin, load_scenario
from sim.twin_report import render, summarise

NAME = "twin"
HELP = "run the simulated Puma 560 (the twin) and summarise its sim-to-real gap"
EXAMPLES = """\
robocal twin --poses 500                         # the sim-to-real gap, effect by effect
robocal twin --scenario my_scenario.toml --json --export poses.csv
"""


def add_arguments(p):
    p.add_argument("--scenario", metavar="FILE", help="twin scenario TOML (default: the thesis's findings)")
    p.add_argument("--poses", type=int_range(10, 1000000), default=200, metavar="N", help="number of random poses (default 200)")
    p.add_argument("--seed", type=seed_int, default=None, help="override the scenario's seed for the poses and noise")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.add_argument("--export", type=output_file, metavar="FILE.csv",
                   help="also write the poses as a pose-measurement CSV (joint readings, intersected points)")


def run(args) -> int:
    from calib.errors import RobocalError
    if args.poses < 10:
        raise RobocalError(f"twin: --poses must be at least 10, got {args.poses}")
    twin = Twin(load_scenario(args.scenario), seed=args.seed)
    summary = summarise(twin, args.poses, export=args.export)
    print(json.dumps(summary, indent=2) if args.json else render(summary))
    return 0
