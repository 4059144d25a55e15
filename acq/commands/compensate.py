"""``robocal compensate``: use an identified model — corrected joint commands or readings, predicted tool points."""
from __future__ import annotations

import json

import numpy as np

from calib.errors import RobocalError

NAME = "compensate"
HELP = "correct joint commands or readings with an identified model and predict the tool point"
EXAMPLES = """\
robocal compensate model.json 10 -40 70 30 -20 50            # corrected command, predicted point with sigma
robocal compensate model.json 10 -40 70 30 -20 50 --reading  # true joint angles for encoder readings
"""


def add_arguments(p):
    p.add_argument("model", metavar="MODEL.json", help="model file written by robocal identify --out")
    p.add_argument("q", nargs="+", metavar="Q", help="joint angles in degrees")
    p.add_argument("--reading", action="store_true",
                   help="the angles are encoder readings: print the true joint angles (eq 6.1 generalised)")
    p.add_argument("--json", action="store_true", help="print the result as one JSON object")


def run(args) -> int:
    from calib.compensate import compensate_command, corrected_readings, load_model, nominal_in_same_frame, predict

    im = load_model(args.model)
    n = im.model.robot.n
    if len(args.q) != n:
        raise RobocalError(f"compensate: expected {n} joint angles, got {len(args.q)}")
    try:
        q = np.array([[float(v) for v in args.q]])
    except ValueError:
        raise RobocalError("compensate: joint angles must be numbers (degrees)") from None
    if not np.isfinite(q).all():
        raise RobocalError("compensate: joint angles must be finite")
    im.model.robot.check_readings(q, "compensate")
    scale = im.model.robot.edge_scale             # rad per degree; 1 for a prismatic joint (mm)
    q = q * scale
    if args.reading:
        true = corrected_readings(im, q)[0]
        p, s = predict(im, q)
        out = {"joint_deg": (true / scale).tolist(), "x_mm": p[0, 0], "y_mm": p[0, 1], "z_mm": p[0, 2],
               "sigma_mm": s[0].tolist()}
    else:
        cmd, err = compensate_command(im, nominal_in_same_frame(im), q)
        p, s = predict(im, cmd)
        out = {"command_deg": (cmd[0] / scale).tolist(), "residual_mm": float(err[0]), "x_mm": p[0, 0],
               "y_mm": p[0, 1], "z_mm": p[0, 2], "sigma_mm": s[0].tolist()}
    out = {k: (float(v) if isinstance(v, (float, np.floating)) else v) for k, v in out.items()}
    out["joint_units"] = ["mm" if p_ else "deg" for p_ in im.model.robot.prismatic]
    if args.json:
        print(json.dumps(out))
        return 0
    key = "joint_deg" if args.reading else "command_deg"
    label = "true joint angles (deg)" if args.reading else "compensated command (deg)"
    print(f"{label}: " + "  ".join(f"{v:.4f}" for v in out[key]))
    print(f"tool point (mm, measurement frame): x {out['x_mm']:.3f}  y {out['y_mm']:.3f}  z {out['z_mm']:.3f}  "
          f"(1 sigma {', '.join(f'{v:.3f}' for v in out['sigma_mm'])})")
    return 0
