"""``--out-dh-deltas FILE.csv``: per joint the identified change of each DH parameter with its 1-sigma error, the form
a robot controller's calibration table takes (KUKA, Staubli, ABB: per-axis corrections of theta, d, a, alpha).

Only for DH descriptions: a URDF import's DH parameters are robocal's own parametrisation of the chain, which no
controller knows (its calibrated form is the URDF, ``--out-urdf``).  A parameter the fit held (not identifiable from
the data, or not asked for with ``--free``) has delta 0 and its name in the ``held`` column, never a made-up sigma.
"""
from __future__ import annotations

import csv
import io

import numpy as np

from ..errors import RobocalError
from ..fileio import atomic_write_text
from .. import names as naming

#: CSV column stem, parameter of the chain; angles in degrees, lengths in mm
COLUMNS = (("dtheta_deg", "theta_offset_rad"), ("dd_mm", "d_mm"), ("da_mm", "a_mm"), ("dalpha_deg", "alpha_rad"),
           ("dbeta_deg", "beta_rad"))


def dh_delta_rows(model, theta: np.ndarray, sigma: np.ndarray, free: set[str]) -> list[dict]:
    """One row per joint: ``joint``, ``joint_name``, each delta and its ``sigma_`` in edge units, ``held``."""
    kin, robot = model.kin, model.robot
    rows = []
    for j in range(1, robot.n + 1):
        row: dict = {"joint": j, "joint_name": naming.joint_name(robot, j)}
        held = []
        for col, par in COLUMNS:
            name = f"j{j}.{par}"
            i = kin.index[name]
            _, scale = naming.edge_unit(naming.unit_of(name))
            row[col] = float(theta[i] - kin.nominal[i]) / scale
            row[f"sigma_{col}"] = float(sigma[i]) / scale if name in free else 0.0
            if name not in free:
                held.append(col[1:].split("_")[0])
        row["held"] = " ".join(held)
        rows.append(row)
    return rows


def write_dh_deltas(path, model, theta: np.ndarray, sigma: np.ndarray, free: set[str], urdf_source=None) -> None:
    if urdf_source is not None:
        raise RobocalError(f"--out-dh-deltas: {model.robot.source} is a URDF description: its DH parameters are "
                           "robocal's own parametrisation, which no controller knows; write --out-urdf instead")
    rows = dh_delta_rows(model, theta, sigma, free)
    buf = io.StringIO()
    fields = ["joint", "joint_name"] + [c for col, _ in COLUMNS for c in (col, f"sigma_{col}")] + ["held"]
    w = csv.DictWriter(buf, fieldnames=fields, lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: (f"{v:.9g}" if isinstance(v, float) else v) for k, v in r.items()})
    atomic_write_text(path, "# DH parameter changes identified by robocal (new = description + delta); "
                            "angles in degrees, lengths in mm; sigma 1-sigma; held: not estimated\n" + buf.getvalue())
