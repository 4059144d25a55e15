"""Withheld-effect cases of an elastic two-arm torso (issue 24.4): data from the independent generator
(tests/fakes/tree_robot.py: plain 4x4 products, its own gravity moments, joint and lateral elasticity) with a perturbed
geometry and noise, and the robocal description of the nominal robot (its URDF, masses from the inertials).

Shared by the tests (tests/test_elastic_tree.py) and the benchmark (benchmarks/bench_tree_diagnose.py).  The one
place robocal is used here is :func:`pivot_mm`: where robocal's frame for a joint lies along its axis, to say where
the generator's joint (its URDF origin) bends -- a convention, not a truth the tests compare with.
"""
from __future__ import annotations

import csv
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from tests.fakes import tree_robot as tr

POINTS = {"L": ("hand_left_link", [0.0, 0.0, 30.0]), "R": ("hand_right_link", [10.0, 0.0, 30.0])}
COUPLED = "[joints.coupled]\ntorso_3_joint = { torso_1_joint = -1.0, torso_2_joint = -1.0 }\n"
NOISE_MM = 0.05
#: the generator's noise floor of a held-out point (3-D RMS)
FLOOR_MM = NOISE_MM * np.sqrt(3.0)

#: compliances (rad per N m) of a humanoid's upper body: a few mm at the hands (DLR's Agile Justin: joint elasticity
#: the largest single group, lateral elasticity about half of what remained)
JOINT = {"torso_2_joint": 1.0e-5, "arm_left_2_joint": 4.0e-5, "arm_right_2_joint": 4.0e-5}
LATERAL = {"torso_1_joint": 8.0e-6, "arm_left_1_joint": 3.0e-5, "arm_right_1_joint": 3.0e-5}


@dataclass
class Case:
    name: str
    elastic: tr.Elasticity
    #: masses the description does not know (link -> (kg, com in the link, m)): an end effector, a payload
    hidden_masses: dict = field(default_factory=dict)
    #: the robocal effects that model it, as ``--effect`` texts built by :func:`effect_texts`
    effects: tuple[str, ...] = ()
    #: False: the description's URDF has no inertials at all (the masses are identified as lumped mass moments)
    masses_known: bool = True
    #: ``--prior`` texts ``KIND:JOINT.PARAM=VALUE±SIGMA``: a data-sheet compliance fixes the scale of identified
    #: masses
    priors: tuple[str, ...] = ()


CASES = [
    Case("joint", tr.Elasticity(joint=JOINT), effects=tuple(f"joint_compliance:{k}" for k in JOINT)),
    Case("lateral", tr.Elasticity(lateral=LATERAL), effects=tuple(f"lateral_compliance:{k}" for k in LATERAL)),
    Case("joint+lateral", tr.Elasticity(joint=JOINT, lateral=LATERAL),
         effects=tuple(f"joint_compliance:{k}" for k in JOINT) + tuple(f"lateral_compliance:{k}" for k in LATERAL)),
    # a 2 kg gripper on the left hand that the description lacks: its weight bends the left shoulder
    Case("hidden gripper", tr.Elasticity(joint={"arm_left_2_joint": 4.0e-5, "arm_left_4_joint": 5.0e-5}),
         hidden_masses={"hand_left_link": (2.0, np.array([0.02, 0.0, 0.08]))},
         effects=("joint_compliance:arm_left_2_joint", "joint_compliance:arm_left_4_joint",
                  "mass_moment:arm_left_7_joint")),
    # a URDF without inertials: the forearm's and the wrist's weights identified as lumped mass moments, the elbow's
    # compliance from its data sheet (2 %)
    Case("no masses", tr.Elasticity(joint={"arm_left_4_joint": 5.0e-5}), masses_known=False,
         effects=("joint_compliance:arm_left_4_joint",) + tuple(f"mass_moment:arm_left_{k}_joint" for k in (4, 5, 6, 7)),
         priors=("joint_compliance:arm_left_4_joint.compliance1_rad_per_nm=5e-5±1e-6",)),
]


def description(tmp: Path, tree: tr.FakeTree, name: str = "robot", masses: bool = True) -> Path:
    """The calibration description of ``tree`` (its URDF beside it), both hands measured, torso_3 coupled;
    ``masses=False``: its URDF without inertials."""
    tree = tree if masses else replace(tree, masses={})
    (tmp / f"{name}.urdf").write_text(tr.to_urdf(tree))
    lines = [f'urdf = "{name}.urdf"', 'base_link = "base_link"', "[tool.points]"]
    lines += [f'{k} = {{ link = "{link}", xyz_mm = [{", ".join(map(str, xyz))}] }}' for k, (link, xyz) in POINTS.items()]
    path = tmp / f"{name}.toml"
    path.write_text("\n".join(lines) + "\n" + COUPLED)
    return path


def values(tree: tr.FakeTree, readings, n: int, seed: int) -> list[dict[str, float]]:
    vals = tr.random_values(tree, n, seed, names=list(readings))
    for v in vals:
        v["torso_3_joint"] = -(v["torso_1_joint"] + v["torso_2_joint"])
    return vals


def truth(case: Case, seed: int) -> tr.FakeTree:
    """The 'real' robot: the nominal one with its joint origins moved (a few tenths of mm / deg) and the masses the
    description lacks."""
    real = tr.perturbed(tr.two_arm_torso(0), 100 + seed)
    masses = dict(real.masses)
    for link, (m, com) in case.hidden_masses.items():
        m0, c0 = masses.get(link, (0.0, np.zeros(3)))
        masses[link] = (m0 + m, (m0 * c0 + m * com) / (m0 + m))
    return replace(real, masses=masses)

def write_data(path: Path, case: Case, readings, n: int, seed: int, test_every: int = 4,
               noise_mm: float = NOISE_MM) -> None:
    """Pose CSV of the elastic 'real' robot: both hands a pose, ``noise_mm`` a coordinate, every ``test_every``-th
    pose a test row (0: no split column)."""
    real = truth(case, seed)
    rng = np.random.default_rng(seed)
    names = list(readings)
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["pose", "target"] + names + ["x", "y", "z"] + (["split"] if test_every else []))
        for i, v in enumerate(values(real, names, n, 1000 + seed)):
            poses = tr.link_poses(real, v, case.elastic)
            for t, (link, xyz) in POINTS.items():
                p = tr.point_on(poses, link, xyz) + rng.normal(0, noise_mm, 3)
                split = (["test" if i % test_every == 0 else "fit"]) if test_every else []
                w.writerow([f"p{i}", t] + [f"{np.degrees(v[k]):.9f}" for k in names] + [f"{x:.6f}" for x in p]
                           + split)


def pivot_mm(robot, tree: tr.FakeTree, joint: str) -> float:
    """Where the generator's joint bends (its URDF origin) along the joint's axis, from the origin of robocal's
    frame for it (the ``pivot_mm`` option of lateral_compliance)."""
    from calib.kinematics import Kinematics
    j = robot.joint_names.index(joint)
    fp = Kinematics(robot).forward(np.zeros((1, robot.n)))
    uj = tree.joint(joint)
    T = tr.link_poses(tree, {})[uj.parent] @ tr.hom(tr.rpy_matrix(*uj.rpy), uj.xyz_m)
    return float((T[:3, 3] * 1000.0 - fp.joint_origin[0, j]) @ fp.joint_axis[0, j])


def effect_args(case: Case, robot, tree: tr.FakeTree) -> list[str]:
    """The case's effects and priors as identify arguments: ``--effect`` texts with joints by number (lateral
    compliance with its pivot), ``--prior`` with the effect's parameter name."""
    out = []
    for text in case.effects:
        kind, joint = text.split(":")
        k = robot.joint_names.index(joint) + 1
        out += ["--effect", f"{kind}:{k}:{pivot_mm(robot, tree, joint):.3f}" if kind == "lateral_compliance"
                else f"{kind}:{k}"]
    for text in case.priors:
        kind, rest = text.split(":", 1)
        joint, param = rest.split(".", 1)
        out += ["--prior", f"{kind}.j{robot.joint_names.index(joint) + 1}.{param}"]
    return out
