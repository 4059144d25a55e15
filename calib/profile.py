"""What a robot is, for the Chapter 4 procedures and their reduction: a profile read from its description.

General code asks the profile instead of assuming the thesis's Puma ("six joints"):

* ``thesis``: the description has the structure of the thesis's Puma 560 (Fig 3.5's twists, its links' lengths
  within :data:`THESIS_MATCH_MM`, the parallel pair 2-3): only then do the thesis's own formulas hold -- the
  compensation scheme and eq 4.3.15 (with point P for d3), its plan's choices (the transmission errors of joints 4
  and 6 over its ranges) and the comparison of the estimates with the thesis's numbers;
* for any robot, from its description: the reference pose the joints are swept about (the thesis's READY for its
  Puma, the middle of every joint's range otherwise), the joints swept (the revolute ones), the joints whose
  transmission error is measured (the first and last of the wrist's three: 4 and 6 on a six-axis arm) and over what
  range, the coupled pairs (the description's coupling matrix), and whether the encoder tap reads the robot (it
  carries six joints' counts).

Why a structural test and not a name: a description is a file anyone writes; the thesis's formulas need the thesis's
geometry, whatever the file calls the robot.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .robot import Robot
from .units import DEG

#: the thesis's Puma 560: Fig 3.5's twists and Fig 5.10's specified lengths (mm), placed per Fig 3.5
THESIS_ALPHA_DEG = (-90.0, 180.0, 90.0, -90.0, 90.0, 0.0)
THESIS_A_MM = (0.0, 432.0, -20.3, 0.0, 0.0, 0.0)
THESIS_D_MM = (0.0, 149.1, 0.0, 432.0, 0.0, 57.1)
#: the thesis's READY position (Fig 3.5), deg
THESIS_READY_DEG = (0.0, -90.0, 90.0, 0.0, 0.0, 0.0)
#: a description within this of every thesis length (mm) and with its twists is the thesis's structure
THESIS_MATCH_MM = 50.0
#: the thesis's transmission-error runs: joints 4 and 6 (section 5.4.2) about READY -- joint 4 inside its -110..170
#: deg limits (with the pre-flight's margin), joint 6 over most of its +-266 deg -- and joints 2 and 3 on request,
#: +-90 deg (the upper arm from horizontal to horizontal, the forearm from along it to folded back level)
THESIS_TE_RANGE_DEG = {4: (-105.0, 165.0), 6: (-150.0, 150.0), 2: (-90.0, 90.0), 3: (-90.0, 90.0)}
THESIS_TE_JOINTS = (4, 6)
#: joints the encoder tap carries (protocols.md section 6: six counts per sample)
TAP_JOINTS = 6
#: a run stays this far inside a joint's limits (the pre-flight's margin is 2 deg) and within this of its reference
TE_MARGIN_DEG = 5.0
TE_HALF_SPAN_DEG = 150.0


@dataclass(frozen=True)
class RobotProfile:
    """See the module docstring.  Joints are 1-based; angles in degrees (this is what plans are written in)."""

    name: str
    n: int
    thesis: bool
    ready_deg: tuple[float, ...]
    sweep_joints: tuple[int, ...]
    te_joints: tuple[int, ...]
    te_range_deg: dict[int, tuple[float, float]] = field(default_factory=dict)
    coupled_pairs: tuple[tuple[int, int], ...] = ()
    tapped: bool = True

    @property
    def thesis_scheme(self) -> bool:
        """The compensation scheme and eq 4.3.15 apply (the thesis's Puma structure)."""
        return self.thesis

    @property
    def point_p(self) -> bool:
        """Point P on the tool's axis is sighted for eq 4.3.15's d3."""
        return self.thesis

    @property
    def thesis_comparison(self) -> bool:
        """Reports show the thesis's numbers beside the estimates."""
        return self.thesis

    def as_dict(self) -> dict:
        """For the results document: what the reduction assumed about the robot (``reference_robot``: the method's
        own robot, the thesis's Puma structure)."""
        return {"name": self.name, "joints": self.n, "reference_robot": self.thesis, "ready_deg": list(self.ready_deg),
                "te_joints": list(self.te_joints), "coupled_pairs": [list(p) for p in self.coupled_pairs],
                "tapped": self.tapped}


def is_thesis_structure(robot: Robot) -> bool:
    """The description has the thesis's Puma structure (see the module docstring)."""
    if robot.n != 6 or robot.prismatic.any():
        return False
    alpha = np.asarray(robot.alpha_rad) / DEG
    return (np.allclose(np.cos(alpha * DEG), np.cos(np.array(THESIS_ALPHA_DEG) * DEG), atol=1e-3)
            and np.allclose(np.sin(alpha * DEG), np.sin(np.array(THESIS_ALPHA_DEG) * DEG), atol=1e-3)
            and np.all(np.abs(robot.a_mm - THESIS_A_MM) < THESIS_MATCH_MM)
            and np.all(np.abs(robot.d_mm - THESIS_D_MM) < THESIS_MATCH_MM)
            and list(np.flatnonzero(robot.hayati)) == [1])


def middle_pose_deg(robot: Robot) -> tuple[float, ...]:
    """The middle of every joint's range (deg; mm for a prismatic joint), rounded to a degree."""
    lim = robot.limits_rad / robot.edge_scale[:, None]
    return tuple(float(round(v)) for v in lim.mean(axis=1))


def te_range_deg(robot: Robot, joint: int, ready_deg) -> tuple[float, float]:
    """A transmission-error run's offsets from the reference pose (deg): the joint's range less
    :data:`TE_MARGIN_DEG`, at most :data:`TE_HALF_SPAN_DEG` either side (the angles are taken from the first step
    and must stay within half a turn of it... and a wide run fixes the run's own axis well)."""
    lo, hi = robot.limits_rad[joint - 1] / DEG - ready_deg[joint - 1]
    return (float(max(lo + TE_MARGIN_DEG, -TE_HALF_SPAN_DEG)), float(min(hi - TE_MARGIN_DEG, TE_HALF_SPAN_DEG)))


def coupled_pairs(robot: Robot) -> tuple[tuple[int, int], ...]:
    """The pairs (j, k) whose motor k turns with joint j in the description's coupling matrix (motor = diag(G) C q),
    the most distal first: the pairs the coupling procedure measures."""
    C = robot.coupling
    pairs = [(j + 1, k + 1) for k in range(robot.n) for j in range(robot.n) if j != k and abs(C[k, j]) > 0]
    return tuple(sorted(pairs, key=lambda p: (-p[1], -p[0])))


def profile_of(robot: Robot) -> RobotProfile:
    """The robot's profile from its description (see the module docstring)."""
    revolute = tuple(j + 1 for j in range(robot.n) if not robot.prismatic[j])
    tapped = robot.n == TAP_JOINTS
    if is_thesis_structure(robot):
        return RobotProfile(robot.name, robot.n, True, THESIS_READY_DEG, revolute, THESIS_TE_JOINTS,
                            dict(THESIS_TE_RANGE_DEG), coupled_pairs(robot), tapped)
    ready = middle_pose_deg(robot)
    te = tuple(j for j in dict.fromkeys((robot.n - 2, robot.n)) if j >= 1 and j in revolute)
    return RobotProfile(robot.name, robot.n, False, ready, revolute, te,
                        {j: te_range_deg(robot, j, ready) for j in revolute}, coupled_pairs(robot), tapped)
