"""The broadened validation on the independent generator (sim/independent.py shares no code with the
model): a small seeded subset, one case of every family; no family may have more than 5 % (confidently) wrong (here:
none); a wrong finding flagged doubtful is its own verdict, never counted right."""
import numpy as np

from sim.families import FAMILIES, family_cases, judge, run_families
from sim.independent import Arm, Spec, generate
from calib.model import MeasurementModel
from calib.loading import load_robot

SUBSET = ("TE j4", "JC j3 + TE j2", "BL j3 x0.3", "quadratic error j2", "clean, t3 + 1 %", "JC j3, 50 poses",
          "clean, noise given x2", "clean")


def test_the_generator_agrees_with_the_model_on_the_plain_chain():
    """Two independent codes for the same chain: the diagnosis's geometric fit then has nothing to absorb."""
    robot = load_robot()
    rng = np.random.default_rng(1)
    arm = Arm.perturbed(robot, rng)
    arm.a, arm.d, arm.alpha, arm.beta, arm.offset = robot.a_mm, robot.d_mm, robot.alpha_rad, 0 * robot.a_mm, 0 * robot.a_mm
    arm.base = np.eye(4)
    q = rng.uniform(-1, 1, (10, 6))
    m = MeasurementModel(robot)
    th = m.nominal.copy()
    for k, v in zip(("x_mm", "y_mm", "z_mm"), (50.0, 20.0, 100.0)):
        th[m.index[f"tool.{k}"]] = v
    np.testing.assert_allclose(arm.tool(arm.frames(q)), m.points(q, theta=th), atol=1e-8)


def test_effect_size_is_set_by_the_floor():
    robot = load_robot()
    c, clean = generate(robot, [], 60, seed=3, sigma_mm=1e-9)
    _, eff = generate(robot, [Spec("backlash", {"joint": 3}, 2.0)], 60, seed=3, sigma_mm=1e-9)
    # sigma 1e-9: the effect's RMS is 2 x sqrt(3) x 1e-9 -- tiny, but exactly that
    assert abs(np.sqrt(np.mean(np.sum((eff - clean) ** 2, 1))) / (2 * np.sqrt(3) * 1e-9) - 1) < 1e-3


def test_judging():
    jc, te = ("joint_compliance", 3), ("transmission_error", 2)
    assert judge({jc}, [(jc, True)]) == "right"
    assert judge({jc, te}, [(jc, False)]) == "honest"
    assert judge({jc}, [(jc, False), (te, False)]) == "wrong"
    # a wrong finding flagged doubtful is still wrong: its own count, never right or honest
    assert judge({jc}, [(jc, False), (te, True)]) == "wrong_doubtful"
    assert judge(set(), [(te, True)]) == "wrong_doubtful"
    assert judge({jc, te}, [(jc, True), (("backlash", 2), True)]) == "wrong_doubtful"
    assert judge({jc}, [(jc, True)]) == "right"
    assert judge(set(), []) == "right"


def test_no_family_has_more_than_five_percent_wrong():
    v = run_families(family_cases(seeds=1, first_seed=1, labels=SUBSET), workers=2)
    assert {r.case.family for r in v.results} == set(FAMILIES)
    for fam in FAMILIES:
        assert v.wrong_share(fam) <= 0.05, v.render()
    right = sum(r.verdict == "right" for r in v.results)
    assert right >= len(v.results) - 2, v.render()
