"""``robocal evaluate``: how well a calibrated model predicts measured poses it was not fitted to."""
from __future__ import annotations

import json

from acq.argtypes import add_force_argument
from app.commands._csvargs import add_unit_arguments, model_and_table

NAME = "evaluate"
HELP = "predict the test rows of a pose CSV with a calibrated model: RMS, max, 95th percentile, per station/group"
EXAMPLES = """\
robocal evaluate model.json test.csv            # RMS, max and 95th percentile of the test rows
robocal evaluate model.json test.csv --locate --json
"""


def add_arguments(p):
    p.add_argument("model", metavar="MODEL.json", help="model written by robocal identify --out")
    p.add_argument("data", metavar="DATA.csv", help="pose CSV with measured x, y, z (test rows, or all rows)")
    p.add_argument("--locate", action="store_true",
                   help="re-station first: fit each station's transform (its fit rows if it has 3 or more, else "
                        "its rows) with the model held fixed")
    p.add_argument("--json", action="store_true", help="print the evaluation as JSON")
    add_unit_arguments(p)
    add_force_argument(p)


def _fmt(v) -> str:
    return "-" if v is None else f"{v:.3f}"


def run(args) -> int:
    from calib.evaluation import evaluate_table

    im, table = model_and_table(args, NAME)
    doc = evaluate_table(im.model, im.theta, table, with_locate=args.locate, im=im)
    if args.json:
        print(json.dumps(doc, indent=1))
        return 0
    if "before" in doc:
        from calib.accuracy import before_after_line
        print(f"robocal evaluate {args.data}: " + before_after_line(doc))
        u = doc["uncertainty"]
        if u["median_abs_z"] is not None:
            print(f"  predicted sigma: median |error|/sigma {u['median_abs_z']:.2f} (0.67 when honest), "
                  f"{100 * u['within_2sigma']:.0f} % within 2 sigma (95 % when honest)")
    print(f"{'  ' if 'before' in doc else f'robocal evaluate {args.data}: '}{doc['n']} {doc['rows']} rows: "
          f"RMS {_fmt(doc['rms_mm'])} mm, max {_fmt(doc['max_mm'])} mm, 95th percentile {_fmt(doc['p95_mm'])} mm")
    if "orientation" in doc:
        o = doc["orientation"]
        print(f"  orientation ({o['convention']}): geodesic error mean {o['mean_deg']:.4f} deg, RMS "
              f"{o['rms_deg']:.4f} deg, max {o['max_deg']:.4f} deg")
    for st in doc.get("stations", []):
        print(f"  station {st['station']} located from {st['n_rows']} rows (RMS there {st['rms_mm']:.3f} mm): "
              f"xyz_mm {', '.join(f'{v:.2f}' for v in st['xyz_mm'])}, "
              f"rpy_deg {', '.join(f'{v:.4f}' for v in st['rpy_deg'])}")
    for col, groups in doc["by"].items():
        for g, s in groups.items():
            print(f"  {col} {g}: {s['n']} rows, RMS {_fmt(s['rms_mm'])} mm, max {_fmt(s['max_mm'])} mm, "
                  f"p95 {_fmt(s['p95_mm'])} mm")
    return 0
