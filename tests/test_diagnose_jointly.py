"""Several joint elasticities found together (issue 24, item 2), on the independent generator (plain 4x4 products
and cross products for the gravity torques: no code shared with robocal's model)."""
from calib.diagnose.data import from_arrays
from calib.diagnose.engine import diagnose
from sim.independent import Spec, generate
from calib.loading import load_robot

TRUTH = (2, 3, 4, 5, 6)


def test_small_compliances_on_several_joints_are_accepted_as_one_group():
    """Every joint from 2 to 6 bends under gravity, each by 0.8x the noise floor: one by one most fall under the
    acceptance rule's material share; together they pass, as one group, one ladder step."""
    robot = load_robot()
    specs = [Spec("joint_compliance", {"joint": j}, 0.8) for j in TRUTH]
    c, pts = generate(robot, specs, 150, seed=2, sigma_mm=0.05)
    data = from_arrays(robot, c.q, pts, noise_mm=0.05, direction=c.direction, payload_kg=c.payload_kg,
                       temperature_c=c.temperature_c, time_s=c.time_s)
    j = diagnose(data, level="auto", outliers="reject").to_json()
    found = [(f["effect"], f["joint"]) for f in j["findings"]]
    assert all(kind == "joint_compliance" and joint in TRUTH for kind, joint in found), found
    grouped = [f for f in j["findings"] if f["found_jointly_with"]]
    assert len(grouped) >= 2, j["findings"]
    step = [s for s in j["ladder"] if s["added"] == "joint_compliance (found jointly)"]
    assert len(step) == 1 and step[0]["model"].count("joint_compliance") == len(grouped)
    assert step[0]["p_value"] < 1e-6
    assert j["after"]["rms_mm"] < 0.6 * j["ladder"][2]["test_rms_mm"]       # against the geometry alone
