"""The target-offset effect: built through the registry, moves only its target's rows, analytic Jacobian."""
import numpy as np

from calib.effects import effect_from_spec, effect_from_text, effect_spec
from calib.model import MeasurementModel
from calib.targets import TargetContext


def test_registry_round_trip():
    e = effect_from_text("target_offset:2")
    assert e.target == 2 and e.label == "target_offset.t2"
    spec = effect_spec(e)
    again = effect_from_spec(spec, {f"target_offset.t2.{k}": v for k, v in zip(("dx_mm", "dy_mm", "dz_mm"), (1.5, 2, 3))},
                             "test")
    assert again.target == 2 and again.values.tolist() == [1.5, 2, 3]


def test_moves_only_its_rows_with_the_right_jacobian(puma):
    from calib.effects.target_offset import TargetOffset
    m = MeasurementModel(puma, [TargetOffset(1, (10.0, -5.0, 3.0))])
    rng = np.random.default_rng(1)
    q = rng.uniform(-1, 1, (6, 6))
    ctx = TargetContext(6, 6, target=[0, 1, 0, 1, 1, 0])
    ev = m.evaluate(q, ctx, jacobian=True)
    plain = m.points(q)
    R = m.kin.forward(q).flange_R
    want = plain + np.where(np.array([0, 1, 0, 1, 1, 0], bool)[:, None], R @ np.array([10.0, -5.0, 3.0]), 0.0)
    np.testing.assert_allclose(ev.point_mm, want, atol=1e-9)
    # numerical Jacobian of the offset parameters
    th = m.nominal
    s = m.effect_slices[0]
    for k in range(3):
        d = np.zeros_like(th)
        d[s.start + k] = 1e-4
        num = (m.points(q, ctx, th + d) - m.points(q, ctx, th - d)) / 2e-4
        np.testing.assert_allclose(ev.jacobian[:, :, s.start + k], num, atol=1e-6)
