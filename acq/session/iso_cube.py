"""ISO 9283's test cube placed in a robot's working volume, and the nominal joint commands of its five poses.

Why at plan time: the uncompensated run commands what an uncalibrated controller would -- the joint command that
puts the description's tool target (with the set-up's base and tool) on each cube point -- and that is known before
the session starts; the plan keeps the points and the commands, so a resumed session replays the same test.

Where the cube goes, for any robot (no robot is special here): candidate centres are the tool target at the reference
pose and at seeded poses in the middle of the joints' ranges, best conditioned first (the smallest singular value of
the point's Jacobian in the readings: far from a singularity, where a compensated command stays close to the nominal
one) among those whose target both stations see; for the best few, the largest side (a fraction of the arm's reach) whose five points the nominal model reaches
(:func:`calib.compensate.reach`, the one inverse of the forward model) inside the joint limits with room for the
approach move and a compensation, and whose steps pass the pre-flight (in sight of both stations).  The largest cube
wins, as the standard asks (maximum volume in the working space).  A set-up's ``iso9283`` entry may fix the centre
and side, the cycles and the approach.
"""
from __future__ import annotations

import numpy as np

from calib.compensate import reach
from calib.errors import RobocalError
from calib.iso9283 import CYCLES, cube_points
from calib.model import MeasurementModel

from .preflight import PREFLIGHT_LIMITS, Preflight, arm_reach_mm
from .procedures import tool_target
from .setup import nominal_theta, reference_pose_deg
from .setup_types import BenchSetup, IsoSetup
from .steps import Step

#: cube sides tried, as fractions of the arm's reach (largest first)
SIDE_FRACTIONS = (0.4, 0.3, 0.25, 0.2, 0.15, 0.1, 0.05)
#: seeded candidate centre poses besides the reference pose, and how many of the best conditioned are tried
CANDIDATES, TRIED = 24, 4
#: a cube point the nominal model cannot reach closer than this (mm) is out of the working volume
REACH_TOL_MM = 0.01
#: room kept inside the limits for the compensated command (deg), beyond the pre-flight's margin and the approach
COMPENSATION_ROOM_DEG = 1.0
#: the approach move before each measurement (deg below the command on every joint; mm for a prismatic one)
APPROACH_DEG = 2.0


def iso_plan(robot, setup: BenchSetup, cycles: int = CYCLES, runs=("off", "on"), seed: int = 0) -> dict:
    """The plan's ``iso9283`` entry (:class:`acq.session.plan_doc.IsoPlan`) for ``robot`` on the bench ``setup``;
    raises RobocalError when no cube fits."""
    cfg = setup.iso9283 or IsoSetup()
    cycles = int(cfg.cycles if cfg.cycles is not None else cycles)
    approach = float(cfg.approach_deg if cfg.approach_deg is not None else APPROACH_DEG)
    m = MeasurementModel(robot)
    cube = _Cube(robot, m, nominal_theta(m, setup), np.asarray(setup.tool_target_mm, float), approach, setup)
    centres = [np.asarray(cfg.centre_mm, float)] if cfg.centre_mm else None
    sides = [float(cfg.side_mm)] if cfg.side_mm else \
        [round(f * arm_reach_mm(robot), -1) or 10.0 for f in SIDE_FRACTIONS]
    best = cube.largest(sides, centres, seed)
    if best is None:
        raise RobocalError(f"set-up iso9283: no ISO 9283 test cube (sides {sides[-1]:g}-{sides[0]:g} mm) fits the "
                           f"working volume of {robot.name} in sight of both stations; give iso9283.centre_mm and "
                           f"side_mm in the set-up")
    side, points, r = best
    return {"poses": [{"pose": k, "point_mm": [round(float(v), 3) for v in points[k]],
                       "q_deg": [round(float(v), 5) for v in ri / robot.reading_edge_scale]}
                      for k, ri in zip(points, r)],
            "cycles": cycles, "approach_deg": approach, "side_mm": side, "runs": list(runs)}


class _Cube:
    """The search of :func:`iso_plan` (see the module docstring)."""

    def __init__(self, robot, model: MeasurementModel, theta: np.ndarray, tool_mm: np.ndarray, approach: float,
                 setup: BenchSetup):
        self.robot, self.model, self.theta, self.setup = robot, model, theta, setup
        self.points = [(robot.point_frame(), tool_mm)]
        self.M, self.off = robot.reading_matrix, robot.reading_offset
        margin = setup.preflight.get("joint_margin_deg", PREFLIGHT_LIMITS["joint_margin_deg"])
        room = (margin + COMPENSATION_ROOM_DEG) * robot.edge_scale
        self.lo, self.hi = robot.limits_rad[:, 0] + room, robot.limits_rad[:, 1] - room
        self.approach = approach * robot.reading_edge_scale
        self.preflight = Preflight(robot, setup)

    def _start_poses(self, seed: int) -> np.ndarray:
        """Readings (internal units) of the candidate centres: the reference pose and seeded ones in the middle 60 %
        of each reading's range whose target is in sight, best conditioned first."""
        lim = self.robot.limits_rad
        ref = np.asarray(reference_pose_deg(self.setup), float) * self.robot.reading_edge_scale
        rng = np.random.default_rng(seed)
        q = lim[:, 0] + (0.2 + 0.6 * rng.random((CANDIDATES, self.robot.n))) * np.ptp(lim, axis=1)
        r = np.vstack([ref[None], np.linalg.lstsq(self.M, (q - self.off).T, rcond=None)[0].T])
        f, xyz = self.points[0]
        ev = self.model.evaluate(r @ self.M.T + self.off, None, self.theta, jacobian=True, tool_mm=xyz, link=f)
        smallest = np.linalg.svd(np.matmul(ev.joint_jacobian, self.M), compute_uv=False)[:, -1]
        order = np.argsort(-smallest, kind="stable")
        seen = [i for i in order if self._in_sight(r[i:i + 1])]              # the target in sight at the centre
        return r[seen[:TRIED]]

    def largest(self, sides: list[float], centres, seed: int):
        """(side, points, readings (5, m)) of the largest cube that fits, or None."""
        if centres is None:
            starts = self._start_poses(seed)
            f, xyz = self.points[0]
            centres = self.model.evaluate(starts @ self.M.T + self.off, None, self.theta, tool_mm=xyz,
                                          link=f).point_mm
        else:
            starts = np.tile(np.asarray(reference_pose_deg(self.setup), float) * self.robot.reading_edge_scale,
                             (len(centres), 1))
        best = None
        for start, centre in zip(starts, centres):
            got = self._fit(start, centre, [s for s in sides if best is None or s > best[0]])
            if got is not None:
                best = got
        return best

    def _fit(self, start: np.ndarray, centre: np.ndarray, sides: list[float]):
        """The largest of ``sides`` whose cube about ``centre`` fits, reached from ``start``; None if none does."""
        if not sides:
            return None
        cubes = [cube_points(centre, s) for s in sides]
        target = np.array([p for c in cubes for p in c.values()])[:, None, :]
        r, err = reach(self.model, self.theta, self.points, target, np.tile(start, (len(target), 1)), self.M,
                       self.off, iterations=15, tol_mm=REACH_TOL_MM / 10)
        r, err = r.reshape(len(sides), 5, -1), err.reshape(len(sides), 5)
        for side, c, ri, ei in zip(sides, cubes, r, err):
            if np.all(ei < REACH_TOL_MM) and self._inside(ri) and self._in_sight(ri):
                return side, c, ri
        return None

    def _inside(self, r: np.ndarray) -> bool:
        """Every joint of the poses and of their approach poses inside the limits, with room to compensate."""
        q = np.vstack([r, r - self.approach]) @ self.M.T + self.off
        return bool(np.all((q >= self.lo) & (q <= self.hi)))

    def _in_sight(self, r: np.ndarray) -> bool:
        """The pre-flight passes the cube's measurement steps (the arm clear of the sight lines, in range)."""
        target = tool_target(self.setup)
        steps = [Step(f"iso9283/P{i + 1}", "iso9283", "", "", pose_deg=tuple(ri / self.robot.reading_edge_scale),
                      targets=(target,)) for i, ri in enumerate(r)]
        return not self.preflight.check(steps)
