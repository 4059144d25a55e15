"""An independent branched robot: a torso of three joints (the third coupled to the first two), two 7-joint arms and
a two-joint head, written as a URDF and moved by plain 4x4 products of its own joint table (the oracle's rotations,
tests/fakes/oracle/chain.py).

Nothing here imports robocal: the truth a test compares robocal's tree kinematics, identification, gravity torques
and URDF export with is made from the joint table directly (origin xyz/rpy, axis, joint value), the way a URDF
parser would, with a perturbed copy standing for the real robot.  Units: the URDF in metres, the points in mm.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from .oracle.chain import axis_angle, hom, rpy_matrix

__all__ = ["Elasticity", "FakeJoint", "FakeTree", "axis_angle", "hom", "rpy_matrix"]


@dataclass
class FakeJoint:
    name: str
    parent: str
    child: str
    xyz_m: np.ndarray
    rpy: np.ndarray
    axis: np.ndarray
    type: str = "revolute"             # revolute, prismatic, fixed
    lower: float = -2.5
    upper: float = 2.5
    mimic: tuple[str, float, float] | None = None


@dataclass
class FakeTree:
    name: str
    joints: list[FakeJoint]
    masses: dict[str, tuple[float, np.ndarray]] = field(default_factory=dict)   # link -> (kg, com in the link, m)

    @property
    def links(self) -> list[str]:
        out = [self.joints[0].parent]
        for j in self.joints:
            out.append(j.child)
        return list(dict.fromkeys(out))

    def joint(self, name: str) -> FakeJoint:
        return next(j for j in self.joints if j.name == name)


def link_poses(tree: FakeTree, values: dict[str, float], elastic: "Elasticity | None" = None,
               g=(0.0, 0.0, -9.80665)) -> dict[str, np.ndarray]:
    """Every link's frame (4x4, metres) in the root link for joint values by name (mimic joints follow).

    ``elastic``: the robot gives way to the gravity load of everything beyond each joint, evaluated in the
    undeflected pose (:func:`joint_moments`): a joint with a joint compliance c turns by ``c tau`` more than its
    value; one with a lateral compliance tilts about its origin by the rotation vector ``c (M - (M . z) z)``, the
    bending part of the moment it carries, before it turns."""
    loads = joint_moments(tree, values, g) if elastic is not None else {}
    out = {tree.joints[0].parent: np.eye(4)}
    for j in tree.joints:                          # listed parents first
        q = values.get(j.name, 0.0)
        if j.mimic is not None:
            leader, mult, off = j.mimic
            q = mult * values.get(leader, 0.0) + off
        T = out[j.parent] @ hom(rpy_matrix(*j.rpy), j.xyz_m)
        if j.name in loads:
            M, z = loads[j.name]
            q += elastic.joint.get(j.name, 0.0) * float(M @ z)
            tilt = elastic.lateral.get(j.name, 0.0) * (M - (M @ z) * z)          # world frame, rad
            if np.linalg.norm(tilt) > 0:
                local = T[:3, :3].T @ tilt
                T = T @ hom(axis_angle(local, np.linalg.norm(local)))
        if j.type == "revolute":
            T = T @ hom(axis_angle(j.axis, q))
        elif j.type == "prismatic":
            T = T @ hom(t=np.asarray(j.axis, float) / np.linalg.norm(j.axis) * q)
        out[j.child] = T
    return out


@dataclass
class Elasticity:
    """Compliances (rad per N m) by joint name: about the joint's axis (``joint``) and, the same about both axes
    perpendicular to it, under the bending moment (``lateral``)."""

    joint: dict[str, float] = field(default_factory=dict)
    lateral: dict[str, float] = field(default_factory=dict)


def point_mm(tree: FakeTree, values: dict[str, float], link: str, xyz_mm, base_in_world=np.eye(4),
             elastic: Elasticity | None = None) -> np.ndarray:
    """A point fixed on ``link`` (its frame, mm) in the measurement frame (mm); ``elastic``: see :func:`link_poses`."""
    return point_on(link_poses(tree, values, elastic), link, xyz_mm, base_in_world)


def point_on(poses: dict[str, np.ndarray], link: str, xyz_mm, base_in_world=np.eye(4)) -> np.ndarray:
    """A point fixed on ``link`` (its frame, mm) of link poses from :func:`link_poses`, in the measurement frame."""
    T = base_in_world @ poses[link]
    return T[:3, :3] @ np.asarray(xyz_mm, float) + T[:3, 3] * 1000.0


def gravity_torques(tree: FakeTree, values: dict[str, float], g=(0.0, 0.0, -9.80665)) -> dict[str, float]:
    """Torque (N m) about every moving joint's axis from the weights of every link below it (the whole subtree:
    the other arm and the head for a torso joint), by a plain sum over the links."""
    return {name: float(M @ z) for name, (M, z) in joint_moments(tree, values, g).items()}


def joint_moments(tree: FakeTree, values: dict[str, float], g=(0.0, 0.0, -9.80665)) -> dict[str, tuple]:
    """(moment (3,) N m about the joint's origin of the weights of every link below it, unit axis (3,)) of every
    revolute joint, in the root frame, by a plain sum over the links of the undeflected robot."""
    poses = link_poses(tree, values)
    # each link's mass and first moment (m, m p) in the root frame: the weights below a joint about its origin o
    # are (sum m p - (sum m) o) x g
    first = {}
    for link, (m, com) in tree.masses.items():
        if link in poses:
            first[link] = (m, m * (poses[link][:3, :3] @ com + poses[link][:3, 3]))
    out = {}
    for j in tree.joints:
        if j.type != "revolute":
            continue
        T = poses[j.parent] @ hom(rpy_matrix(*j.rpy), j.xyz_m)
        z = T[:3, :3] @ (np.asarray(j.axis, float) / np.linalg.norm(j.axis))
        o = T[:3, 3]
        below = [first[link] for link in _subtree(tree, j.child) if link in first]
        m = sum(b[0] for b in below)
        mp = sum((b[1] for b in below), np.zeros(3))
        out[j.name] = (np.cross(mp - m * o, np.asarray(g, float)), z)
    return out


def _subtree(tree: FakeTree, link: str) -> list[str]:
    out = [link]
    for j in tree.joints:
        if j.parent == link:
            out += _subtree(tree, j.child)
    return out


def to_urdf(tree: FakeTree) -> str:
    """The tree as URDF text (every link with its inertial when it has a mass)."""
    lines = ['<?xml version="1.0"?>', f'<robot name="{tree.name}">']
    for link in tree.links:
        m, com = tree.masses.get(link, (0.0, np.zeros(3)))
        if m > 0:
            lines += [f'  <link name="{link}"><inertial><origin xyz="{_v(com)}" rpy="0 0 0"/>'
                      f'<mass value="{m!r}"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/>'
                      '</inertial></link>']
        else:
            lines.append(f'  <link name="{link}"/>')
    for j in tree.joints:
        body = [f'    <parent link="{j.parent}"/>', f'    <child link="{j.child}"/>',
                f'    <origin xyz="{_v(j.xyz_m)}" rpy="{_v(j.rpy)}"/>']
        if j.type != "fixed":
            body += [f'    <axis xyz="{_v(j.axis)}"/>',
                     f'    <limit lower="{j.lower!r}" upper="{j.upper!r}" effort="10" velocity="1"/>']
        if j.mimic is not None:
            body.append(f'    <mimic joint="{j.mimic[0]}" multiplier="{j.mimic[1]!r}" offset="{j.mimic[2]!r}"/>')
        lines += [f'  <joint name="{j.name}" type="{j.type}">'] + body + ['  </joint>']
    lines.append("</robot>")
    return "\n".join(lines) + "\n"


def _v(x) -> str:
    return " ".join(repr(float(v)) for v in x)


def two_arm_torso(seed: int = 0) -> FakeTree:
    """A humanoid upper body: base -> torso_1 (yaw) -> torso_2 (pitch) -> torso_3 (pitch, held at -(torso_1 +
    torso_2) by the description's coupling in the tests) -> chest, from which a left and a right 7-joint arm and a
    two-joint head leave; masses on every link.  ``seed`` jitters the mounting offsets so that no axis is exactly
    where a DH convention would put it."""
    rng = np.random.default_rng(seed)

    def jit(scale=0.01):
        return rng.normal(0.0, scale, 3)

    J = []
    J.append(FakeJoint("mount", "world", "base_link", np.array([0.0, 0.0, 0.0]), np.zeros(3), np.zeros(3), "fixed"))
    J.append(FakeJoint("torso_1_joint", "base_link", "torso_1_link", np.array([0.02, 0.0, 0.6]), np.zeros(3),
                       np.array([0, 0, 1.0])))
    J.append(FakeJoint("torso_2_joint", "torso_1_link", "torso_2_link", np.array([0.0, 0.0, 0.15]) + jit(0.005),
                       np.zeros(3), np.array([0, 1.0, 0])))
    J.append(FakeJoint("torso_3_joint", "torso_2_link", "torso_3_link", np.array([0.0, 0.0, 0.3]) + jit(0.005),
                       np.zeros(3), np.array([0, 1.0, 0])))
    J.append(FakeJoint("chest_joint", "torso_3_link", "chest_link", np.array([0.0, 0.0, 0.2]), np.zeros(3),
                       np.zeros(3), "fixed"))
    for side, s in (("left", 1.0), ("right", -1.0)):
        parent = "chest_link"
        spec = [  # (xyz from the previous link, rpy, axis)
            (np.array([0.0, s * 0.2, 0.1]), np.array([s * -0.3, 0.0, 0.0]), np.array([0, 0, 1.0])),
            (np.array([0.03, 0.0, 0.12]), np.zeros(3), np.array([0, 1.0, 0])),
            (np.array([0.0, 0.0, 0.25]), np.zeros(3), np.array([0, 0, 1.0])),
            (np.array([0.02, 0.0, 0.2]), np.zeros(3), np.array([0, 1.0, 0])),
            (np.array([0.0, 0.0, 0.2]), np.array([0.0, 0.0, 0.2]), np.array([0, 0, 1.0])),
            (np.array([0.0, 0.0, 0.1]), np.zeros(3), np.array([1.0, 0, 0])),
            (np.array([0.0, 0.0, 0.08]), np.zeros(3), np.array([0, 0, 1.0])),
        ]
        for k, (xyz, rpy, ax) in enumerate(spec, 1):
            child = f"arm_{side}_{k}_link"
            J.append(FakeJoint(f"arm_{side}_{k}_joint", parent, child, xyz + jit(0.003), rpy + jit(0.01), ax))
            parent = child
        J.append(FakeJoint(f"hand_{side}_joint", parent, f"hand_{side}_link", np.array([0.0, 0.0, 0.06]),
                           np.zeros(3), np.zeros(3), "fixed"))
    J.append(FakeJoint("head_1_joint", "chest_link", "head_1_link", np.array([0.0, 0.0, 0.15]), np.zeros(3),
                       np.array([0, 0, 1.0])))
    J.append(FakeJoint("head_2_joint", "head_1_link", "head_2_link", np.array([0.0, 0.0, 0.05]), np.zeros(3),
                       np.array([0, 1.0, 0])))
    tree = FakeTree("fake_two_arm_torso", J)
    for j in J:
        if j.child.startswith(("torso", "chest")):
            tree.masses[j.child] = (8.0, np.array([0.0, 0.0, 0.1]))
        elif j.child.startswith("arm"):
            tree.masses[j.child] = (1.5, np.array([0.01, 0.0, 0.05]))
        elif j.child.startswith("head"):
            tree.masses[j.child] = (2.0, np.array([0.03, 0.0, 0.05]))
        elif j.child.startswith("hand"):
            tree.masses[j.child] = (0.8, np.array([0.0, 0.0, 0.04]))
    return tree


def lifting_column(seed: int = 0) -> FakeTree:
    """A lifting column carrying a 6R arm, as a vendor URDF writes it: the column's leader joint drives a slider on
    a side branch (no link on the arm's path), and the two telescoping stages on the path mimic it."""
    rng = np.random.default_rng(seed)
    J = [
        FakeJoint("column_drive_joint", "base_link", "drive_link", np.array([0.1, 0.0, 0.1]), np.zeros(3),
                  np.array([0, 0, 1.0]), "prismatic", 0.0, 0.4),
        FakeJoint("stage_1_joint", "base_link", "stage_1_link", np.array([0.0, 0.0, 0.3]), np.zeros(3),
                  np.array([0, 0, 1.0]), "prismatic", 0.0, 0.4, mimic=("column_drive_joint", 0.5, 0.0)),
        FakeJoint("stage_2_joint", "stage_1_link", "stage_2_link", np.array([0.0, 0.0, 0.3]), np.zeros(3),
                  np.array([0, 0, 1.0]), "prismatic", 0.0, 0.4, mimic=("column_drive_joint", 0.5, 0.0)),
    ]
    parent = "stage_2_link"
    spec = [(np.array([0, 0, 0.1]), np.array([0, 0, 1.0])), (np.array([0.05, 0, 0.1]), np.array([0, 1.0, 0])),
            (np.array([0, 0, 0.4]), np.array([0, 1.0, 0])), (np.array([0.03, 0, 0.35]), np.array([0, 0, 1.0])),
            (np.array([0, 0, 0.1]), np.array([0, 1.0, 0])), (np.array([0, 0, 0.08]), np.array([0, 0, 1.0]))]
    for k, (xyz, ax) in enumerate(spec, 1):
        child = f"arm_{k}_link"
        J.append(FakeJoint(f"arm_{k}_joint", parent, child, xyz + rng.normal(0, 0.002, 3), rng.normal(0, 0.01, 3),
                           ax))
        parent = child
    return FakeTree("fake_lifting_column", J)


def perturbed(tree: FakeTree, seed: int, xyz_mm: float = 1.0, rpy_deg: float = 0.2) -> FakeTree:
    """The 'real' robot: every moving joint's origin moved by a few tenths of a millimetre / degree."""
    rng = np.random.default_rng(seed)
    out = []
    for j in tree.joints:
        if j.type == "fixed" and j.name in ("mount",):
            out.append(j)
            continue
        out.append(replace(j, xyz_m=j.xyz_m + rng.normal(0, xyz_mm * 1e-3, 3),
                           rpy=j.rpy + rng.normal(0, np.radians(rpy_deg), 3)))
    return replace(tree, joints=out)


def random_values(tree: FakeTree, n: int, seed: int, names: list[str] | None = None) -> list[dict[str, float]]:
    """n random configurations (joint values by name) inside 80 % of each moving, non-mimic joint's range."""
    rng = np.random.default_rng(seed)
    movers = [j for j in tree.joints if j.type != "fixed" and j.mimic is None and (names is None or j.name in names)]
    out = []
    for _ in range(n):
        v = {}
        for j in movers:
            mid, half = (j.lower + j.upper) / 2, (j.upper - j.lower) / 2 * 0.8
            v[j.name] = float(rng.uniform(mid - half, mid + half))
        out.append(v)
    return out
