"""Options every command reading a pose CSV shares (not a command: the scanner skips ``_`` modules)."""
from __future__ import annotations

from calib.posecsv import ANGLE_UNITS, LENGTH_UNITS


def add_unit_arguments(p) -> None:
    """``--angle-unit`` / ``--length-unit``: the units of the CSV's joint and position columns (default deg, mm)."""
    p.add_argument("--angle-unit", choices=list(ANGLE_UNITS), default=None,
                   help="unit of the CSV's revolute joint columns (default: the file's '# angle_unit = ...' line, "
                        "else deg)")
    p.add_argument("--length-unit", choices=list(LENGTH_UNITS), default=None,
                   help="unit of the CSV's x, y, z and prismatic joint columns (default: the file's "
                        "'# length_unit = ...' line, else mm)")


def units(args) -> dict:
    """Keyword arguments for :func:`calib.posecsv.read_pose_csv`."""
    return {"angle_unit": getattr(args, "angle_unit", None), "length_unit": getattr(args, "length_unit", None)}


def model_and_table(args, command: str):
    """The calibrated model (``args.model``) and the pose table (``args.data``) it is checked against, the data's
    plausibility checked first (metres or radians never give a number with exit 0): what evaluate and locate share."""
    from calib.compensate import load_model
    from calib.evaluation import with_polar_points
    from calib.plausibility import check_data, enforce
    from calib.posecsv import read_pose_csv

    im = load_model(args.model)
    robot = im.model.robot
    table = with_polar_points(read_pose_csv(args.data, robot.n, robot.prismatic, robot=robot, **units(args)))
    enforce(check_data(im.model, table.q_rad, table.points_mm, args.data, prismatic=robot.prismatic),
            args.force_implausible, command)
    return im, table


def add_order_arguments(p) -> None:
    """``--order``, ``--time-column``, ``--direction-threshold-deg/-mm``: approach directions from the measurement
    order (:mod:`calib.approach`)."""
    from calib.approach import DEFAULT_THRESHOLD_DEG, DEFAULT_THRESHOLD_MM, ORDERS

    p.add_argument("--order", choices=ORDERS, default="auto",
                   help="where the measurement order comes from, to infer each joint's approach direction when the "
                        "file has no dir* columns: auto (default: the time column if there is one), rows (the rows "
                        "are in measurement order), time, none")
    p.add_argument("--time-column", metavar="NAME", default=None,
                   help="the column holding each row's measurement time (default: time, or a t_start* column)")
    p.add_argument("--direction-threshold-deg", type=float, default=DEFAULT_THRESHOLD_DEG, metavar="DEG",
                   help=f"a revolute joint's move must exceed this to set its approach side: the smallest play that "
                        f"can be tested (default {DEFAULT_THRESHOLD_DEG:g})")
    p.add_argument("--direction-threshold-mm", type=float, default=DEFAULT_THRESHOLD_MM, metavar="MM",
                   help=f"the same for a prismatic joint (default {DEFAULT_THRESHOLD_MM:g})")


def order_options(args) -> dict:
    """Keyword arguments for :func:`calib.diagnose.data.load_data` (and read_pose_csv) from the order options."""
    from calib.units import DEG

    return {"order": getattr(args, "order", "none"), "time_column": getattr(args, "time_column", None),
            "direction_threshold": (getattr(args, "direction_threshold_deg", 0.5) * DEG,
                                    getattr(args, "direction_threshold_mm", 0.5))}
