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
    p.add_argument("q", nargs="+", metavar="Q", help="joint readings in degrees (mm for a prismatic joint), one per reading of the description")
    p.add_argument("--reading", action="store_true",
                   help="the angles are encoder readings: print the true joint angles (eq 6.1 generalised)")
    p.add_argument("--json", action="store_true", help="print the result as one JSON object")


def run(args) -> int:
    from calib.compensate import compensate_readings, corrected_readings, load_model, nominal_in_same_frame, predict

    im = load_model(args.model)
    robot = im.model.robot
    m = robot.n_readings
    if len(args.q) != m:
        raise RobocalError(f"compensate: expected {m} joint readings ({', '.join(robot.reading_names)}), "
                           f"got {len(args.q)}")
    try:
        r = np.array([[float(v) for v in args.q]])
    except ValueError:
        raise RobocalError("compensate: joint angles must be numbers (degrees)") from None
    if not np.isfinite(r).all():
        raise RobocalError("compensate: joint angles must be finite")
    rscale = robot.reading_edge_scale             # rad per degree; 1 for a prismatic reading (mm)
    r = r * rscale
    q = robot.joints_from_readings(r)
    robot.check_readings(q / robot.edge_scale, "compensate")
    # the joints a person commands and reads: every link with its own variable (not a tree's branch link)
    own = [k for k, v in enumerate(robot.variable_of) if v == k]
    units = ["mm" if robot.prismatic[k] else "deg" for k in own]
    if args.reading:
        true = corrected_readings(im, q)[0]
        p, s = predict(im, q)
        out = {"joint_deg": (true[own] / robot.edge_scale[own]).tolist(), "x_mm": p[0, 0], "y_mm": p[0, 1],
               "z_mm": p[0, 2], "sigma_mm": s[0].tolist()}
    else:
        cmd, err = compensate_readings(im, nominal_in_same_frame(im), r)
        p, s = predict(im, robot.joints_from_readings(cmd))
        out = {"command_deg": (cmd[0] / rscale).tolist(), "residual_mm": float(err[0]), "x_mm": p[0, 0],
               "y_mm": p[0, 1], "z_mm": p[0, 2], "sigma_mm": s[0].tolist()}
        units = ["mm" if pr else "deg" for pr in robot.reading_prismatic]
    out = {k: (float(v) if isinstance(v, (float, np.floating)) else v) for k, v in out.items()}
    out["joint_units"] = units
    from calib.names import joint_label, reading_label
    out["joint_names"] = ([reading_label(robot, i + 1) for i in range(m)] if not args.reading
                          else [joint_label(robot, k + 1) for k in own])
    if args.json:
        print(json.dumps(out))
        return 0
    key = "joint_deg" if args.reading else "command_deg"
    label = "true joint values" if args.reading else "compensated command"
    print(f"{label}: " + "  ".join(f"{name} {v:.4f} {unit}" for name, v, unit in
                                   zip(out["joint_names"], out[key], out["joint_units"])))
    print(f"tool point (mm, measurement frame): x {out['x_mm']:.3f}  y {out['y_mm']:.3f}  z {out['z_mm']:.3f}  "
          f"(1 sigma {', '.join(f'{v:.3f}' for v in out['sigma_mm'])})")
    return 0
