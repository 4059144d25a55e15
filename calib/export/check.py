"""The written URDF read back by robocal's own importer: its forward kinematics against the calibrated model's.

Why a reload and not a trust in the arithmetic: the file is what other software will read; reading it back through
the URDF importer (:func:`calib.urdf.read_urdf`, then the chain or tree import) checks the numbers as written (17 significant digits), the frame
conventions (roll-pitch-yaw, metres) and that nothing else in the file changed the chain.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..kinematics import Kinematics
from ..urdf import analyse_tree, read_urdf, robot_from_analysis

#: the agreement the check demands (mm): far below any measurement, far above double-precision rounding
TOLERANCE_MM = 1e-6


def reload_max_mm(path: Path, base_link: str, point_links: dict[str, str], tool_on_links: dict[str, np.ndarray],
                  base_in_measurement: np.ndarray, calibrated, q: np.ndarray) -> float:
    """Largest distance (mm) between every tool point of the reloaded file (each on its link, placed with the side
    file's base) and the calibrated model's, over the joint values ``q`` (N, n) of the calibrated robot."""
    tree = read_urdf(path)
    back = robot_from_analysis(analyse_tree(tree, base_link, list(dict.fromkeys(point_links.values()))),
                               {k: (point_links[k], v) for k, v in tool_on_links.items()}, source=str(path))
    if back.n != calibrated.n:
        return float("inf")
    # the same links in the same order (one import of the same tree): the same joint values, whatever reading
    # conventions or couplings the description adds on top (those are the side file's)
    q = np.atleast_2d(np.asarray(q, float))
    qb = q
    kb, kc = Kinematics(back), Kinematics(calibrated)
    B = np.asarray(base_in_measurement, float)
    worst = 0.0
    for name, p_cal in calibrated.tool_points_mm.items():
        mine = kc.forward(q, kc.params_with_tool(p_cal), calibrated.point_frame(name)).point
        theirs = kb.forward(qb, kb.params_with_tool(back.tool_points_mm[name]), back.point_frame(name)).point
        theirs = theirs @ B[:3, :3].T + B[:3, 3]
        worst = max(worst, float(np.max(np.linalg.norm(mine - theirs, axis=1))))
    return worst


def check_poses(robot, q: np.ndarray | None, n_random: int = 50, seed: int = 0) -> np.ndarray:
    """The joint values a check runs on: the fitted poses, or (none given) zero and random values inside the limits."""
    if q is not None and len(q):
        return np.atleast_2d(np.asarray(q, float))
    lim = np.where(np.asarray(robot.prismatic, bool)[:, None], robot.limits_rad,
                   np.clip(robot.limits_rad, -np.pi, np.pi))
    rng = np.random.default_rng(seed)
    return np.vstack([np.zeros(robot.n), rng.uniform(lim[:, 0], lim[:, 1], (n_random, robot.n))])

