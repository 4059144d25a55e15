"""A diagnosis without a split nests its k-fold figure (issue 24, item 1): in each outer fold every choice -- gross
errors, geometric set, floor, effects -- is made on its fit rows alone, so the values of a fold's test rows cannot
change what predicts them.  Data from the independent generator (sim/independent.py)."""
import numpy as np
import pytest

from calib.diagnose.data import from_arrays
from calib.diagnose.engine import diagnose
from sim.families import SIGMA_MM
from sim.independent import Spec, generate
from calib.diagnose.nested import outer_folds
from calib.loading import load_robot


def _data(points):
    robot = load_robot()
    c, pts = generate(robot, [Spec("joint_compliance", {"joint": 3}, 3.0)], 80, seed=5, sigma_mm=SIGMA_MM)
    pts = pts if points is None else points(pts)
    return from_arrays(robot, c.q, pts, noise_mm=SIGMA_MM, direction=c.direction, payload_kg=c.payload_kg,
                       temperature_c=c.temperature_c, time_s=c.time_s), pts


def test_a_folds_test_rows_cannot_move_their_own_prediction():
    """Shifting every test row of one outer fold by 50 mm shifts its held-out errors by exactly 50 mm: nothing
    fitted or chosen for that fold saw them.  (Choices made on every row -- the geometry and the effects fitted
    through 50 mm errors -- moved them.)"""
    data, pts = _data(None)
    first = diagnose(data)
    j = first.to_json()
    assert j["heldout_protocol"].startswith("nested 5-fold"), j["heldout_protocol"]
    assert [f["label"] for f in j["findings"]] == ["joint_compliance j3"]
    _, te = outer_folds(data)[0]

    def shift(p):
        p = p.copy()
        p[te, 0] += 50.0
        return p
    moved, _ = _data(shift)
    second = diagnose(moved)
    a, b = first.ladder.heldout.after_res_mm, second.ladder.heldout.after_res_mm
    np.testing.assert_allclose(b[te] - a[te], np.tile([50.0, 0.0, 0.0], (len(te), 1)), atol=1e-6)
    np.testing.assert_allclose(first.ladder.heldout.before_res_mm[te] + [50.0, 0.0, 0.0],
                               second.ladder.heldout.before_res_mm[te], atol=1e-6)
    # and the figure is the honest one: here every outer fold makes the whole set's choice (one strong compliance),
    # so the nested after is exactly the plain k-fold figure of the chosen model -- neither better (a fold's test
    # rows helping choose) nor worse (a fold choosing otherwise)
    assert j["after"]["rms_mm"] == pytest.approx(first.final_rms_mm, rel=1e-9)
