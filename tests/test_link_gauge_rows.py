"""The link-compliance stage's design rows keep each gauge's unloaded Jacobian by pose, point and link (a loading
series hangs its masses at one pose): the rows are, bit for bit, those of evaluating the model loaded and unloaded
for every step and gauge, and the unloaded evaluations are asked once per gauge."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from calib.effects import JointCompliance, LinkCompliance
from calib.loads import hung_masses, point_force_context
from calib.model import MeasurementModel
from offline.reduction.joints import reading_q
from offline.reduction.run import run_stage, start_reduction
from offline.reduction.session import load_session
from offline.reduction.stages import all_stages, link
from offline.reduction.torques import swept_geometry

SESSION = Path(__file__).resolve().parents[1] / "examples" / "demo-session.db"


def test_gauge_rows_are_the_model_evaluated_for_every_step_and_gauge(monkeypatch):
    ctx = start_reduction(load_session(str(SESSION)))
    for stage in all_stages():
        if stage.name == "link":
            break
        run_stage(ctx, stage)
    steps = ctx.steps_of(("link_compliance",))
    j = ctx.setup.link.joint
    joints = sorted({i for i in (ctx.outputs.get("compliance") or {}) if i <= j} | {j})
    calls = []
    evaluate = MeasurementModel.evaluate
    monkeypatch.setattr(MeasurementModel, "evaluate", lambda self, *a, **k: calls.append(1) or evaluate(self, *a, **k))
    y, X, _, _ = link.gauge_rows(ctx, steps, j, joints)
    monkeypatch.setattr(MeasurementModel, "evaluate", evaluate)

    model = MeasurementModel(ctx.robot, [LinkCompliance(j, 1e18)] + [JointCompliance(i, 1e12) for i in joints])
    geo_model, geo, _ = swept_geometry(ctx)
    theta = model.nominal.copy()
    theta[: model.n_geometric] = geo[: geo_model.n_geometric]
    cols = [model.index[f"link_compliance.j{j}.compliance_per_nmm2"]] + \
        [model.index[f"joint_compliance.j{i}.compliance1_rad_per_nm"] for i in joints]
    g = model.gravity_n_per_kg(theta)
    want = []
    for st in steps:
        s = st["spec"]["setup"]
        q = reading_q(st, ctx.robot)[None]
        loaded = model.context(1, **point_force_context(hung_masses(s.get("loads", [])), g))
        for gauge in s.get("gauges", []):
            if st["inputs"].get(f"{gauge['name']}_mm") is None:
                continue
            axis = np.asarray(gauge["axis"], float) / np.linalg.norm(gauge["axis"])
            J = [model.evaluate(q, c, theta, jacobian=True, tool_mm=np.asarray(gauge["point_mm"], float),
                                link=int(gauge["link"])).jacobian[0] for c in (loaded, model.context(1))]
            want.append(axis @ (J[0] - J[1])[:, cols])
    assert len(want) == len(y) > 3
    assert np.array_equal(X, np.array(want).reshape(X.shape))
    gauges = {(g["name"], g["link"]) for st in steps for g in st["spec"]["setup"].get("gauges", [])}
    assert len(calls) == len(y) + len(gauges)          # one unloaded evaluation per gauge at the series' one pose
