"""Elasticity of a whole tree (issue 24.4) against the independent generator (tests/fakes/tree_robot.py, its own gravity
moments, joint and lateral elasticity as plain rotations): the model bends as the generator does, its Jacobian is
the derivative of its points, identification recovers the compliances with honest errors and reaches the noise floor
on held-out poses with the right effects, identified masses stand in for missing ones, and a fit says when it
depends on its start."""
from __future__ import annotations

import io
import json
from contextlib import redirect_stderr, redirect_stdout

import numpy as np
import pytest

from app.cli import main
from calib.effects import effect_from_text
from calib.effects.joint_compliance import JointCompliance
from calib.effects.lateral_compliance import LateralCompliance
from calib.effects.mass_moment import MassMoment
from calib.evaluation import fit_rows
from calib.rows import context_of, point_covariance
from calib.identify import PointObservations, identify
from calib.model import MeasurementModel
from calib.posecsv import read_pose_csv
from calib.loading import load_robot
from calib.targets import TargetContext, with_targets
from calib.threads import limit
from tests import elastic_cases as ec
from tests.fakes import tree_robot as tr
from tests.fakes.oracle.chain import numeric_jacobian


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("elastic")
    nominal = tr.two_arm_torso(0)
    desc = ec.description(tmp, nominal)
    return tmp, nominal, desc, load_robot(desc)


def _rows(robot, tree, n, seed):
    vals = ec.values(tree, robot.reading_names, n, seed)
    q = robot.joints_from_readings(np.array([[v[k] for k in robot.reading_names] for v in vals]))
    return vals, np.repeat(q, 2, axis=0), TargetContext(2 * n, robot.n, target=np.tile([0, 1], n))


def _identify(argv) -> dict:
    out = io.StringIO()
    with redirect_stdout(out):
        assert main(argv + ["--json"]) == 0
    return json.loads(out.getvalue())


def test_the_model_bends_as_the_generator_does(world):
    """Joint compliance exactly, lateral compliance to second order (a tilt of 3 mrad: microns), both from the
    whole tree's gravity -- where the rigid model is millimetres off."""
    _, tree, _, robot = world
    robot, targets = with_targets(robot, ["L", "R"])
    el = tr.Elasticity(joint=ec.JOINT, lateral=ec.LATERAL)
    idx = {k: robot.joint_names.index(k) + 1 for k in robot.joint_names}
    effects = [JointCompliance(idx[k], 1.0 / c) for k, c in el.joint.items()] + \
              [LateralCompliance(idx[k], c, c, ec.pivot_mm(robot, tree, k)) for k, c in el.lateral.items()]
    vals, q, ctx = _rows(robot, tree, 25, 5)
    want = np.array([tr.point_mm(tree, v, *ec.POINTS[t], elastic=el) for v in vals for t in "LR"])
    got = MeasurementModel(robot, targets + effects).points(q, ctx)
    rigid = MeasurementModel(robot, targets).points(q, ctx)
    assert np.abs(got - want).max() < 0.02
    assert np.abs(rigid - want).max() > 3.0
    joint_only = tr.Elasticity(joint=ec.JOINT)
    want = np.array([tr.point_mm(tree, v, *ec.POINTS[t], elastic=joint_only) for v in vals for t in "LR"])
    got = MeasurementModel(robot, targets + effects[:len(ec.JOINT)]).points(q, ctx)
    np.testing.assert_allclose(got, want, atol=1e-6)


def test_jacobian_on_a_tree_matches_central_differences(world):
    """Lateral compliance of the torso (pivot off its frame) and of a shoulder, an identified mass on the forearm:
    every column, the geometric ones with the moments' change, against central differences of the model's points."""
    _, tree, _, robot = world
    robot, targets = with_targets(robot, ["L", "R"])
    j = {k: robot.joint_names.index(k) + 1 for k in robot.joint_names}
    effects = [LateralCompliance(j["torso_1_joint"], 5e-4, 3e-4, 600.0),
               LateralCompliance(j["arm_left_1_joint"], 2e-3, 1.4e-3, 250.0),
               MassMoment(j["arm_left_4_joint"], 1.0, (10.0, 20.0, -30.0))]
    model = MeasurementModel(robot, targets + effects)       # tilts of 0.1 rad: the terms are far from negligible
    _, q, ctx = _rows(robot, tree, 4, 5)
    theta = model.nominal
    J = model.evaluate(q, ctx, theta, jacobian=True, torque_derivative=True).jacobian
    steps = np.array([1e-4 if name.endswith(("_kg", "_kgmm")) else 1e-9 if name.endswith("_per_nm") else
                      1e-6 if name.endswith("_mm") else 1e-7 for name in model.names])
    num = numeric_jacobian(lambda th: model.points(q, ctx, th), theta, steps)
    scale = np.abs(num).max(axis=(0, 1))
    err = np.abs(J - num).max(axis=(0, 1))
    assert np.all(err <= 1e-5 * np.maximum(scale, 1.0)), model.names[int(np.argmax(err / np.maximum(scale, 1.0)))]
    # the default Jacobian leaves the moments' change out only when the tilts are small (the rule of the torque term)
    small = MeasurementModel(robot, targets + [LateralCompliance(j["torso_1_joint"], 1e-6, 1e-6, 600.0)])
    assert not small._keeps_torque_term(None, small.evaluate(q, ctx).loads, [e.values for e in small.effects])


def _estimates(case, seed, tmp, tree, desc, noise_mm=ec.NOISE_MM):
    """Identify the case's data (no split) through the Python API: (value, sigma, truth) of every compliance."""
    data = tmp / f"honest-{seed}.csv"
    robot = load_robot(desc)
    ec.write_data(data, case, robot.reading_names, 200, seed, test_every=0, noise_mm=noise_mm)
    args = ec.effect_args(case, robot, tree)
    full = read_pose_csv(str(data), robot.n, robot.prismatic, robot=robot)
    table, robot, offsets = fit_rows(full, robot)
    model = MeasurementModel(robot, [effect_from_text(t, robot.n) for t in args[1::2]] + offsets)
    obs = PointObservations(table.q_rad, table.points_mm, point_covariance(table), noise_mm,
                            context_of(model, table))
    with limit(1):                        # as the command runs it: one BLAS thread (calib.threads)
        ident = identify(model, obs)
    truth = {**{("joint_compliance", k): c for k, c in case.elastic.joint.items()},
             **{("lateral_compliance", k): c for k, c in case.elastic.lateral.items()}}
    out = []
    for (kind, name), c in truth.items():
        for p in ("compliance1_rad_per_nm",) if kind == "joint_compliance" else ("cx_rad_per_nm", "cy_rad_per_nm"):
            q = f"{kind}.j{robot.joint_names.index(name) + 1}.{p}"
            if q in ident.free:
                out.append((ident.value(q), ident.std(q), c))
    return out


def test_compliances_recovered_with_honest_errors(world):
    """Joint elasticity of the torso and both shoulders, lateral elasticity of the torso's yaw joint and both
    shoulders, all from the gravity of the whole tree (URDF masses): over seeded data sets, |estimate - truth| /
    sigma has the median of a normal error (0.67), 85 % or more within 2 sigma, and no estimate is far off.

    Noise 0.2 mm a coordinate (motion capture): at 0.05 mm the compliances' sigma are 0.7 % of their values and the
    model's first order (its points agree with the generator's exact rotations to 0.008 mm) shows as a bias of up to
    1.5 sigma (median 0.74, 81 % within 2 sigma over 36 estimates)."""
    tmp, tree, desc, _ = world
    case = next(c for c in ec.CASES if c.name == "joint+lateral")
    rows = [r for seed in range(4) for r in _estimates(case, seed, tmp, tree, desc, noise_mm=0.2)]
    z = np.array([abs(v - c) / s for v, s, c in rows])
    assert len(z) >= 30
    assert 0.45 < np.median(z) < 0.95, np.round(z, 2)
    assert np.mean(z < 2.0) >= 0.85 and z.max() < 4.0, np.round(z, 2)
    assert all(v > 0 for v, _, _ in rows)


@pytest.mark.parametrize("case", ec.CASES, ids=[c.name for c in ec.CASES])
def test_withheld_effect_reaches_the_noise_floor_with_the_right_effect(world, case):
    """The generator bends (or carries a gripper, or lacks every inertial in the description); identification of
    the fit rows with the right effects predicts the held-out rows within 10 % of the generator's noise floor, the
    geometry alone cannot."""
    tmp, tree, _, _ = world
    desc = ec.description(tmp, tree, name=f"robot-{case.masses_known}", masses=case.masses_known)
    robot = load_robot(desc)
    data = tmp / f"{case.name}.csv"
    ec.write_data(data, case, robot.reading_names, 400, 7)
    base = ["identify", str(data), "--robot", str(desc), "--noise-mm", str(ec.NOISE_MM)]
    rigid = _identify(base)
    right = _identify(base + ec.effect_args(case, robot, tree))
    assert right["test_rms_mm"] < 1.10 * ec.FLOOR_MM, right["test_rms_mm"]
    assert rigid["test_rms_mm"] > 1.5 * ec.FLOOR_MM
    assert "sign_findings" not in right
    if case.hidden_masses:
        mass = next(p for p in right["parameters"] if p["name"].endswith(".mass_kg"))
        assert abs(mass["value"] - 2.0) < 3 * mass["error"] and mass["error"] < 1.0


def test_a_negative_compliance_is_said(world, tmp_path):
    """Data whose shoulder stiffens under load the wrong way (a stand-in for an error the compliance absorbs): the
    estimate is negative beyond its error and identify says it in words and in the JSON."""
    _, tree, desc, robot = world
    case = ec.Case("wrong way", tr.Elasticity(joint={"arm_left_2_joint": -4e-5}),
                   effects=("joint_compliance:arm_left_2_joint",))
    data = tmp_path / "neg.csv"
    ec.write_data(data, case, robot.reading_names, 120, 3, test_every=0)
    doc = _identify(["identify", str(data), "--robot", str(desc)] + ec.effect_args(case, robot, tree))
    (finding,) = doc["sign_findings"]
    assert finding["absorbs"] and finding["parameter"].startswith("joint_compliance") and finding["value"] < 0
    out = io.StringIO()
    with redirect_stdout(out):
        main(["identify", str(data), "--robot", str(desc)] + ec.effect_args(case, robot, tree))
    assert "is positive by physics, so this effect absorbs another error" in out.getvalue()


def test_the_same_fit_from_ten_starts(world, tmp_path):
    """An elastic fit lands on the same estimate from ten starts; a two-slope compliance whose breakpoint the data
    do not show (one slope) does not, and the command says so."""
    _, tree, desc, robot = world
    case = next(c for c in ec.CASES if c.name == "joint+lateral")
    data = tmp_path / "starts.csv"
    ec.write_data(data, case, robot.reading_names, 120, 4, test_every=0)
    base = ["identify", str(data), "--robot", str(desc), "--starts", "10"]
    doc = _identify(base + ec.effect_args(case, robot, tree))
    assert doc["starts"]["stable"] and doc["starts"]["n"] == 10 and doc["starts"]["same"] == 10
    k = robot.joint_names.index("torso_2_joint") + 1
    kink = ["--effect", f"joint_compliance:{k}", "--prior", f"joint_compliance.j{k}.breakpoint_nm=150±1000",
            "--free", f"base.*,tool.*,j*.theta_offset_rad,j*.a_mm,j*.alpha_rad,j*.d_mm,target_offset.*,"
                      f"joint_compliance.j{k}.compliance*,joint_compliance.j{k}.breakpoint_nm"]
    doc = _identify(base + kink)
    assert not doc["starts"]["stable"] and doc["starts"]["same"] < 10


def test_an_identified_mass_needs_a_scale(world, tmp_path):
    """Without masses in the description, a payload or a prior on a compliance, an identified mass and the
    compliance that feels it trade one against the other: one line, naming the effect and what to give."""
    tmp, tree, _, _ = world
    desc = ec.description(tmp_path, tree, masses=False)
    robot = load_robot(desc)
    case = next(c for c in ec.CASES if c.name == "no masses")
    data = tmp_path / "bare.csv"
    ec.write_data(data, case, robot.reading_names, 60, 2, test_every=0)
    args = [a for a in ec.effect_args(case, robot, tree) if "=" not in a and a != "--prior"]
    err = io.StringIO()
    with redirect_stderr(err):
        assert main(["identify", str(data), "--robot", str(desc)] + args) == 2
    line = err.getvalue()
    assert line.count("\n") == 1 and "mass_moment" in line and "--prior" in line


def test_mass_moment_weighs_like_a_point_mass(world):
    """The mass moment's bodies load every joint as a mass m at c = (m c) / m in the link's frame does (a plain
    sum over the generator's links with that mass added)."""
    _, tree, _, robot = world
    j = robot.joint_names.index("arm_left_4_joint") + 1
    m, mc = 2.0, np.array([30.0, -20.0, 100.0])
    model = MeasurementModel(robot, [MassMoment(j, m, mc)])
    bare = MeasurementModel(robot)
    _, q, _ = _rows(robot, tree, 3, 8)
    q = q[::2]
    fp = model.kin.forward(q)
    extra = model.loads(fp, model.context(len(q))).joint_torque_nm - bare.loads(fp, bare.context(len(q))).joint_torque_nm
    point = model.kin.point_on(fp, [j], (mc / m)[None])[:, 0] * 1e-3                # (N, 3) m
    g = fp.gravity()
    for k in range(robot.n):
        carries = model._moved[k, j]
        want = np.einsum("nc,nc->n", np.cross(point - fp.joint_origin[:, k] * 1e-3, m * g), fp.joint_axis[:, k])
        np.testing.assert_allclose(extra[:, k], want if carries else 0.0, atol=1e-9)


def _diagnose_case(world, tmp_path, name: str, n: int = 300, test_every: int = 0, extra: tuple = ()) -> dict:
    """``robocal diagnose --json`` of the named case (``n`` poses, both hands; ``test_every``: every so many-th pose a
    test row of the data's own split, 0: no split)."""
    _, _, desc, robot = world
    case = next(c for c in ec.CASES if c.name == name)
    data = tmp_path / "diag.csv"
    ec.write_data(data, case, robot.reading_names, n, 1, test_every=test_every)
    out = io.StringIO()
    with redirect_stdout(out):
        assert main(["diagnose", str(data), "--robot", str(desc), "--noise-mm", str(ec.NOISE_MM), "--json",
                     *extra]) == 0
    return json.loads(out.getvalue())


def test_diagnose_names_the_compliant_joints(world, tmp_path):
    """diagnose on the joint-elasticity case (no split: 5-fold) names the three compliant joints among every
    joint and lateral compliance of the tree and reaches the noise floor within 10 %."""
    robot = world[3]
    doc = _diagnose_case(world, tmp_path, "joint")
    want = {f"joint_compliance j{robot.joint_names.index(k) + 1}" for k in ec.JOINT}
    assert {f["label"] for f in doc["findings"]} == want
    assert doc["final_rms_mm"] < 1.10 * doc["noise_floor_mm"]


def test_diagnose_names_lateral_elasticity_beside_joint_elasticity(world, tmp_path):
    """diagnose on the joint+lateral case with a split (300 fit poses, every choice on them; 100 test poses scored
    once at the end): the three joint compliances and the three lateral ones are named, nothing else, and the test
    rows reach the generator's noise floor within 10 %.

    The step this needs: torso_2_joint's lateral compliance comes first and its joint compliance then removes a
    quarter of the gap still open but 5 % of the baseline's, which the material rule refused (the test rows ended at
    1.84x the floor); a confident step with a significant held-out gain is now judged against the gap
    still open (calib.diagnose.findings.material_reason).  Room for 8 steps: on the way, greedy selection takes
    torso_3's joint compliance and the right shoulder pitch's lateral compliance (a near tie with the shoulder's own,
    0.3178 against 0.3183 mm), which the shoulders' lateral compliances then supersede and the backward step drops;
    with a limit of 6 it stopped with them at 3x the floor, so the default is 8."""
    robot = world[3]
    doc = _diagnose_case(world, tmp_path, "joint+lateral", n=400, test_every=4)
    want = {f"{kind} j{robot.joint_names.index(k) + 1}" for kind, names in
            (("joint_compliance", ec.JOINT), ("lateral_compliance", ec.LATERAL)) for k in names}
    assert {f["label"] for f in doc["findings"]} == want, sorted(f["label"] for f in doc["findings"])
    assert not any(f["doubtful"] for f in doc["findings"])
    assert doc["n_test"] == 200 and doc["after"]["n"] == 200             # 100 test poses, both hands
    assert doc["after"]["rms_mm"] == doc["ladder"][-1]["test_rms_mm"]
    assert doc["after"]["rms_mm"] < 1.10 * ec.FLOOR_MM, doc["after"]["rms_mm"] / ec.FLOOR_MM


def test_the_urdf_pivot_of_every_joint_is_where_the_generator_bends(world):
    """Robot.urdf_pivot_mm (read from the URDF): the point it names on robocal's axis of each joint is the
    generator's own joint origin, in 3-D, and that axis is the generator's joint axis (the generator's plain 4x4
    products, not robocal's formula for the pivot)."""
    from calib.kinematics import Kinematics
    _, tree, _, robot = world
    fp = Kinematics(robot).forward(np.zeros((1, robot.n)))
    poses = tr.link_poses(tree, {})
    for name in ec.LATERAL:
        k = robot.joint_names.index(name)
        uj = tree.joint(name)
        T = poses[uj.parent] @ tr.hom(tr.rpy_matrix(*uj.rpy), uj.xyz_m)        # the joint's frame, metres
        axis = T[:3, :3] @ (np.asarray(uj.axis, float) / np.linalg.norm(uj.axis))
        np.testing.assert_allclose(abs(fp.joint_axis[0, k] @ axis), 1.0, atol=1e-9)
        pivot = fp.joint_origin[0, k] + robot.urdf_pivot_mm[k] * fp.joint_axis[0, k]
        np.testing.assert_allclose(pivot, T[:3, 3] * 1000.0, atol=1e-6)
    assert np.any(np.abs(robot.urdf_pivot_mm) > 100.0)           # the case the hook is for: pivots far from frames


def test_diagnose_names_lateral_elasticity_alone(world, tmp_path):
    """The lateral case alone (no split): its three lateral compliances named, no stand-in joint compliance, and the
    noise floor reached within 10 % -- the candidates bend at the URDF joint's origin, as the generator does."""
    robot = world[3]
    doc = _diagnose_case(world, tmp_path, "lateral")
    confident = {f["label"] for f in doc["findings"] if not f.get("doubtful")}
    want = {f"lateral_compliance j{robot.joint_names.index(k) + 1}" for k in ec.LATERAL}
    assert confident == want, sorted(f["label"] for f in doc["findings"])
    assert doc["final_rms_mm"] < 1.10 * doc["noise_floor_mm"]
