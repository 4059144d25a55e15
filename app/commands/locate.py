"""``robocal locate``: re-station an instrument: the transform from the calibrated robot to each station set-up."""
from __future__ import annotations

import json

from acq.argtypes import add_force_argument
from app.commands._csvargs import add_unit_arguments, model_and_table

NAME = "locate"
HELP = "fit only the instrument-to-robot transform (per station) with the calibrated model held fixed"
EXAMPLES = """\
robocal locate model.json day2.csv               # re-station the instruments, model held fixed
"""


def add_arguments(p):
    p.add_argument("model", metavar="MODEL.json", help="model written by robocal identify --out")
    p.add_argument("data", metavar="DATA.csv", help="pose CSV with measured x, y, z (and a station column)")
    p.add_argument("--json", action="store_true", help="print the stations as JSON")
    add_unit_arguments(p)
    add_force_argument(p)


def run(args) -> int:
    from calib.evaluation import locate
    from calib.rows import predict_rows

    im, table = model_and_table(args, NAME)
    locs = locate(predict_rows(im.model, im.theta, table, new_stations=True), table)
    doc = {"source": table.source, "stations": [loc.as_dict() for loc in locs.values()]}
    if args.json:
        print(json.dumps(doc, indent=1))
        return 0
    print(f"robocal locate {args.data}: measured = R predicted + t, per station")
    for st in doc["stations"]:
        print(f"  station {st['station']}: {st['n_rows']} rows, RMS {st['rms_mm']:.3f} mm, "
              f"t = ({', '.join(f'{v:.3f}' for v in st['xyz_mm'])}) mm, "
              f"roll/pitch/yaw = ({', '.join(f'{v:.5f}' for v in st['rpy_deg'])}) deg")
    return 0
