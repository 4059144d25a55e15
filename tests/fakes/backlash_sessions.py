"""Independent truth for play in the drives: several measurement sessions of one program on a Puma whose joints have
play that gravity loads (issue 27).  Imports nothing from ``calib``: the chain is :class:`ThesisPuma`'s plain 4x4
products and its gravity torques (a lumped end-effector mass at the tool point included); the play and the approach
directions come from the robot's own motion sequence.

The physics, one pose at a time:

* the robot moves straight from each pose to the next (the program's sequence); a joint that moves turns its motor
  the way it moves, so the drive's play opens on the side it came from;
* the link rests where its load torque pushes it -- ``+b/2 * sign(tau)`` -- when that torque exceeds the drive's
  preload, and where the motor left it -- ``-b/2 * (sign of its last move)`` -- when it does not;
* the load torque is every link's weight and a lumped end-effector mass at the tool point (one the description does
  not know), about the joint's axis: ``z_{j-1} . sum (r_i - o_{j-1}) x m_i g``;
* the robot came to the first pose of a session from a home pose the file does not record (the first row's approach
  is known to the robot, not to the data).

A session is the program's poses in its own order (the same program run on another day; the first session in the
program's order), seen from its own instrument set-up, with the instrument's noise.  The placebo writes each row's
direction of the NEXT move, which carries no information on the play.
"""
from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .oracle.effects import play_offset
from .thesis_puma import DEG, ThesisPuma, base_matrix

PUMA_TOML = Path(__file__).resolve().parents[2] / "calib" / "data" / "puma560.toml"
#: joint ranges of the program (deg): a workspace in front of the robot, wrist well away from its singularity
RANGES_DEG = ((-60, 60), (-150, -30), (30, 150), (-90, 90), (20, 100), (-90, 90))
#: a joint move is either none or at least this large (deg): every move carries the drive across its play
MIN_MOVE_DEG = 4.0


@dataclass
class Play:
    """Play of width ``width_rad`` in joint ``joint`` (1-based): gravity holds the link where the load torque exceeds
    ``preload_nm`` (inf: never, the plain backlash), the last approach elsewhere."""

    joint: int
    width_rad: float
    preload_nm: float = np.inf


@dataclass
class Arm:
    """The Puma with a lumped end-effector mass at its tool point and play in some joints."""

    plays: list[Play] = field(default_factory=list)
    tool_mass_kg: float = 0.0
    tool_xyz_t: tuple[float, float, float] = (0.0, 0.0, -120.0)      # ^6E: the tool 120 mm out along z6
    puma: ThesisPuma = field(default_factory=lambda: ThesisPuma.from_toml(PUMA_TOML))

    def __post_init__(self):
        self.puma.tool_xyz_t = self.tool_xyz_t

    def torques(self, q: np.ndarray) -> np.ndarray:
        """(6,) gravity torque about each joint axis (N m), the tool mass included; one pose."""
        return self.puma.gravity_torques(q, self.tool_mass_kg)

    def true_angles(self, q: np.ndarray, approach: np.ndarray) -> np.ndarray:
        """Joint angles of one pose given its readings and each joint's last motion (+1/-1)."""
        th = q.copy()
        tau = self.torques(q)
        for p in self.plays:
            j = p.joint - 1
            th[j] += play_offset(p.width_rad, tau[j], p.preload_nm, approach[j])
        return th


def program(n: int, seed: int) -> np.ndarray:
    """(n, 6) a program of poses (rad): each step moves a random subset of the joints by at least MIN_MOVE_DEG."""
    rng = np.random.default_rng(seed)
    lo, hi = np.array(RANGES_DEG, float).T * DEG
    q = [rng.uniform(lo, hi)]
    while len(q) < n:
        nxt = q[-1].copy()
        move = rng.random(6) < 0.75
        move[rng.integers(6)] = True
        nxt[move] = rng.uniform(lo, hi)[move]
        small = move & (np.abs(nxt - q[-1]) < MIN_MOVE_DEG * DEG)
        nxt[small] = np.clip(q[-1][small] + np.sign(rng.standard_normal(small.sum())) * 2 * MIN_MOVE_DEG * DEG,
                             lo[small], hi[small])
        q.append(nxt)
    return np.array(q)


def approach_of(seq: np.ndarray, home: np.ndarray, next_move: bool = False) -> np.ndarray:
    """(N, 6) each pose's approach direction from the motion sequence: the sign of the joint's last move (coming
    from ``home`` before the first pose); ``next_move``: the placebo, the sign of its next move (0 after the last)."""
    path = np.vstack([home, seq])
    out = np.zeros_like(seq)
    if next_move:
        for i in range(len(seq)):
            later = np.vstack([seq[i:], seq[-1:]])
            for j in range(6):
                steps = np.diff(later[:, j])
                nz = steps[steps != 0]
                out[i, j] = np.sign(nz[0]) if nz.size else 0.0
        return out
    last = np.zeros(6)
    for i in range(1, len(path)):
        step = path[i] - path[i - 1]
        last = np.where(step != 0, np.sign(step), last)
        out[i - 1] = last
    return out


@dataclass
class Session:
    q_rad: np.ndarray          # (N, 6) readings, in measurement order
    points_mm: np.ndarray      # (N, 3) measured, instrument frame
    approach: np.ndarray       # (N, 6) the truth's directions (the first row's from home)
    time_s: np.ndarray


def session(arm: Arm, poses: np.ndarray, seed: int, noise_mm: float = 0.05,
            base=(1500.0, -300.0, -400.0, 0.3, 0.0, 0.0)) -> Session:
    """The poses measured in the given order from an instrument placed at ``base`` (x, y, z mm, yaw, pitch,
    roll rad)."""
    rng = np.random.default_rng(seed)
    home = np.array([0.0, -90.0, 90.0, 0.0, 45.0, 0.0]) * DEG
    appr = approach_of(poses, home)
    arm.puma.base = base_matrix(base[:3], *base[3:])
    pts = np.array([arm.puma.tool_point(arm.true_angles(q, a)) for q, a in zip(poses, appr)])
    pts = pts + rng.normal(0.0, noise_mm, pts.shape)
    t = 1000.0 + 20.0 * np.arange(len(poses)) + rng.uniform(0, 5, len(poses))
    return Session(poses, pts, appr, t)


def sessions(arm: Arm, n_program: int = 60, n_sessions: int = 3, seed: int = 0,
             noise_mm: float = 0.05) -> list[Session]:
    """Several sessions of one program: the first in the program's order, the others each in their own order
    (another day's run of the same poses), each from its own instrument set-up."""
    prog = program(n_program, seed)
    rng = np.random.default_rng(seed + 1000)
    out = []
    for s in range(n_sessions):
        order = np.arange(n_program) if s == 0 else rng.permutation(n_program)
        base = (1500.0 + 40 * s, -300.0 + 25 * s, -400.0 - 10 * s, 0.3 + 0.05 * s, 0.01 * s, -0.01 * s)
        out.append(session(arm, prog[order], seed + 10 * s + 1, noise_mm, base))
    return out


def write_csv(path: Path, s: Session, *, time: bool = True, placebo: bool = False, noise_mm: float = 0.05) -> Path:
    """The session as a pose CSV in measurement order: q1..q6 (deg), x, y, z (mm), sigma_*_mm, and a ``time``
    column (``time=False``: none; the rows' order is then the only clue).  ``placebo``: dir1..dir6 of the NEXT move
    (the file then carries directions that say nothing about the play)."""
    cols = [f"q{j}" for j in range(1, 7)] + ["x", "y", "z", "sigma_x_mm", "sigma_y_mm", "sigma_z_mm"]
    rows = [list(q / DEG) + list(p) + [noise_mm] * 3 for q, p in zip(s.q_rad, s.points_mm)]
    if time:
        cols.append("time")
        rows = [r + [t] for r, t in zip(rows, s.time_s)]
    if placebo:
        nxt = approach_of(s.q_rad, s.q_rad[0], next_move=True)
        cols += [f"dir{j}" for j in range(1, 7)]
        rows = [r + list(d) for r, d in zip(rows, nxt)]
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(cols)
        w.writerows([[f"{v:.9g}" for v in r] for r in rows])
    return path
