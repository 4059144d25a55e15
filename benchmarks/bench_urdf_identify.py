"""Benchmark: import a URDF and identify a 500-pose, 11-joint chain through the CLI path (target: under 5 s).

The chain: a generated arm-like 11-joint URDF (10 revolute joints and one prismatic, random origins, axes along frame
axes turned by multiples of 90 deg, fixed joints in between, inertials), written to a temporary file.  Data: 500 poses of the same chain with its joint origins
perturbed by ~1 mm / 0.1 deg (the "real robot", predicted by Pinocchio when it is installed, else by robocal's chain
with perturbed parameters), 0.02 mm noise, as a pose CSV with joint-name columns and a fit/test split.  Timed:
``robocal identify DATA.csv --robot FILE.urdf --json`` in-process (URDF import + CSV + identification + report),
with the interpreter's imports warm (as for a second command in a session).

Baseline (the issue's target): 5 s on the 2-core machine.
"""
from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import tempfile
import time

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import numpy as np  # noqa: E402

TARGET_S = 5.0


def chain_urdf(rng, n: int = 11, perturb: float = 0.0, seed_perturb: int = 0) -> str:
    """A serial URDF: n moving joints (joint 4 prismatic), a fixed joint before each, masses on every link."""
    pr = np.random.default_rng(seed_perturb)
    links = ['<link name="base"/>']
    joints = []
    parent = "base"
    for k in range(1, n + 1):
        # an arm-like chain: link offsets of 10-30 cm, axes along a frame axis, joints turned by multiples of 90 deg
        xyz = rng.uniform(-0.1, 0.1, 3) + [0, 0, 0.15]
        rpy = rng.integers(-1, 2, 3) * np.pi / 2
        axis = np.eye(3)[rng.integers(0, 3)]
        if perturb:
            xyz = xyz + pr.normal(0, perturb * 1e-3, 3)
            rpy = rpy + pr.normal(0, perturb * 1.7e-3, 3)
        mid = f"m{k}"
        links.append(f'<link name="{mid}"/>')
        joints.append(f'<joint name="fix{k}" type="fixed"><parent link="{parent}"/><child link="{mid}"/>'
                      f'<origin xyz="0 0 0.01"/></joint>')
        kind = "prismatic" if k == 4 else "revolute"
        lim = '<limit lower="0" upper="0.3" effort="1" velocity="1"/>' if kind == "prismatic" else \
            '<limit lower="-2.5" upper="2.5" effort="1" velocity="1"/>'
        links.append(f'<link name="l{k}"><inertial><mass value="{1 + k * 0.2}"/><origin xyz="0.05 0 0.02"/>'
                     f'<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>')
        joints.append(f'<joint name="joint_{k}" type="{kind}"><parent link="{mid}"/><child link="l{k}"/>'
                      f'<origin xyz="{" ".join(map(str, xyz))}" rpy="{" ".join(map(str, rpy))}"/>'
                      f'<axis xyz="{" ".join(map(str, axis))}"/>{lim}</joint>')
        parent = f"l{k}"
    return '<robot name="chain11">\n' + "\n".join(links + joints) + "\n</robot>\n"


def tip_points(urdf_path: str, names: list[str], q: np.ndarray, tip: str) -> np.ndarray:
    try:
        import pinocchio as pin
    except ImportError:
        from calib.kinematics import Kinematics
        from calib.urdf import robot_from_urdf
        robot = robot_from_urdf(urdf_path)
        return Kinematics(robot).points(q)
    model = pin.buildModelFromUrdf(urdf_path)
    data = model.createData()
    fid = model.getFrameId(tip)
    out = []
    for row in q:
        qq = pin.neutral(model)
        for name, v in zip(names, row):
            qq[model.joints[model.getJointId(name)].idx_q] = v / 1000.0 if name == "joint_4" else v
        pin.framesForwardKinematics(model, data, qq)
        out.append(data.oMf[fid].translation * 1000.0)
    return np.array(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--poses", type=int, default=500)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    from app.cli import main as cli

    rng = np.random.default_rng(args.seed)
    state = rng.bit_generator.state
    tmp = tempfile.mkdtemp(prefix="bench_urdf_")
    nominal = os.path.join(tmp, "chain11.urdf")
    truth = os.path.join(tmp, "truth.urdf")
    open(nominal, "w").write(chain_urdf(rng))
    rng.bit_generator.state = state
    open(truth, "w").write(chain_urdf(rng, perturb=1.0, seed_perturb=1))
    names = [f"joint_{k}" for k in range(1, 12)]
    q = rng.uniform(-2.4, 2.4, (args.poses, 11))
    q[:, 3] = rng.uniform(0, 300, args.poses)                        # the prismatic joint, mm
    p = tip_points(truth, names, q, "l11") + rng.normal(0, 0.02, (args.poses, 3))
    data = os.path.join(tmp, "data.csv")
    n_fit = int(0.8 * args.poses)
    with open(data, "w") as fh:
        fh.write(",".join(names) + ",x,y,z,split\n")
        for i in range(args.poses):
            qe = [np.degrees(v) if k != 3 else v for k, v in enumerate(q[i])]
            fh.write(",".join(f"{v:.9f}" for v in qe) + "," + ",".join(f"{v:.6f}" for v in p[i])
                     + ("," + ("fit" if i < n_fit else "test")) + "\n")
    with contextlib.redirect_stdout(io.StringIO()):
        cli(["fk", "--robot", nominal] + ["0"] * 11)                # warm the imports (yourdfpy, scipy)
    out = io.StringIO()
    t0, c0 = time.perf_counter(), time.process_time()
    with contextlib.redirect_stdout(out):
        rc = cli(["identify", data, "--robot", nominal, "--noise-mm", "0.02", "--json"])
    dt, dc = time.perf_counter() - t0, time.process_time() - c0
    doc = json.loads(out.getvalue()) if rc == 0 else {}
    print(f"URDF import + identify, {args.poses} poses, 11-joint chain: {dt:.2f} s wall, {dc:.2f} s CPU "
          f"(target < {TARGET_S:.0f} s; wall > CPU when the machine is shared); "
          f"held-out RMS {doc.get('test_rms_mm', float('nan')):.4f} mm over {doc.get('n_test')} poses, "
          f"fit RMS {doc.get('fit_rms_mm', float('nan')):.4f} mm")


if __name__ == "__main__":
    main()
