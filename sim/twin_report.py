"""A calibration-relevant summary of a twin: how far the real robot is from its description, effect by effect,
against the floor set by the theodolites.

This is the main job's embedded default until the emulated sessions exist: it exercises the one forward model, the
twin and the intersection end to end and prints what a metrologist wants to know before calibrating.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calib.model import MeasurementModel
from calib.posecsv import write_pose_csv
from calib.theodolite import intersect
from sim.twin import Twin
from calib.units import DEG


@dataclass
class GapRow:
    what: str
    rms_mm: float
    max_mm: float


def _rms(d: np.ndarray) -> tuple[float, float]:
    n = np.linalg.norm(d, axis=-1)
    return float(np.sqrt(np.mean(n ** 2))), float(np.max(n))


def summarise(twin: Twin, n_poses: int = 200, export: str | None = None) -> dict:
    """Everything the summary prints, as plain data (units in the keys)."""
    robot = twin.robot
    q = twin.random_poses(n_poses)
    ctx = twin.context(n_poses, direction=twin.rng.choice([-1.0, 1.0], (n_poses, robot.n)))
    meas = twin.measure(q, ctx)
    truth = twin.theta
    model = twin.model
    ng = model.n_geometric
    # the description with the true base and tool (what a perfect set-up survey would give)
    geo_nominal = model.kin.nominal.copy()
    for k in ("base.", "tool."):
        for i, name in enumerate(model.kin.names):
            if name.startswith(k):
                geo_nominal[i] = truth[i]
    geom_only = MeasurementModel(robot)
    p_desc = geom_only.points(meas.q_read_rad, ctx, geo_nominal)
    p_geo = geom_only.points(meas.q_read_rad, ctx, truth[:ng])
    rows = [GapRow("description vs real robot (true base and tool)", *_rms(p_desc - meas.point_true_mm)),
            GapRow("geometry alone (DH deviations)", *_rms(p_desc - p_geo))]
    for e, s in zip(model.effects, model.effect_slices):
        th = truth.copy()
        for e2, s2 in zip(model.effects, model.effect_slices):
            if e2 is not e:
                th[s2] = 0.0
        p_e = model.points(meas.q_read_rad, ctx, th)
        rows.append(GapRow(f"{e.label} alone", *_rms(p_e - p_geo)))
    # what the theodolites resolve
    k = len(twin.stations)
    inter = intersect(twin.stations, [(meas.readings_rad[:, 2 * i], meas.readings_rad[:, 2 * i + 1])
                                      for i in range(k)])
    err = inter.point_mm - meas.point_true_mm
    if export:
        extra = {f"dir{j + 1}": ctx.direction[:, j] for j in range(robot.n)}
        extra.update({f"sigma_{c}_mm": inter.sigma_mm[:, i] for i, c in enumerate("xyz")})
        write_pose_csv(export, meas.q_read_rad, inter.point_mm, extra)
    sig = inter.sigma_mm
    dev = []
    names = model.kin.names
    for i, name in enumerate(names[:ng]):
        if name.startswith(("base.", "tool.")):
            continue
        d = truth[i] - model.kin.nominal[i]
        if abs(d) > 1e-12:
            unit = "deg" if name.endswith("_rad") else "mm"
            scale = 1 / DEG if unit == "deg" else 1.0
            dev.append({"parameter": name.replace("_rad", "_deg"), "nominal": model.kin.nominal[i] * scale,
                        "true": truth[i] * scale, "deviation": d * scale, "unit": unit})
    return {
        "robot": robot.name,
        "scenario": twin.scenario.name,
        "seed": twin.scenario.seed,
        "poses": n_poses,
        "effects": [e.describe() for e in model.effects],
        "effects_disabled": list(twin.scenario.disabled),
        "geometry_deviations": dev,
        "gap": [{"what": r.what, "rms_mm": r.rms_mm, "max_mm": r.max_mm} for r in rows],
        "instrument": {
            "sigma_arcsec": twin.stations[0].sigma_hz_rad / DEG * 3600,
            "point_sigma_median_mm": np.median(sig, axis=0).tolist(),
            "point_error_rms_mm": np.sqrt(np.mean(err ** 2, axis=0)).tolist(),
            "miss_distance_median_mm": float(np.median(inter.miss_mm)),
            "intersection_angle_median_deg": float(np.median(inter.angle_rad) / DEG),
        },
        "joint_torque_max_nm": np.max(np.abs(model.evaluate(meas.q_read_rad, ctx, truth).loads.joint_torque_nm),
                                      axis=0).tolist() if any(getattr(e, "needs_loads", False)
                                                              for e in model.effects) else None,
    }


def render(summary: dict) -> str:
    """The summary as text for the terminal."""
    out = [f"robocal twin: {summary['robot']} — scenario '{summary['scenario']}' (seed {summary['seed']}), "
           f"{summary['poses']} random poses", ""]
    out.append("Effects in the truth: " + ("; ".join(summary["effects"]) or "none"))
    if summary["effects_disabled"]:
        out.append("Switched off: " + ", ".join(summary["effects_disabled"]))
    out += ["", "Geometry of the real robot against its description:"]
    out.append(f"  {'parameter':<24}{'nominal':>12}{'true':>12}{'deviation':>12}  unit")
    for d in summary["geometry_deviations"]:
        out.append(f"  {d['parameter']:<24}{d['nominal']:>12.4f}{d['true']:>12.4f}{d['deviation']:>12.4f}  {d['unit']}")
    out += ["", "Sim-to-real gap at the tool point (what calibration must remove):"]
    out.append(f"  {'source':<52}{'RMS mm':>10}{'max mm':>10}")
    for g in summary["gap"]:
        out.append(f"  {g['what']:<52}{g['rms_mm']:>10.3f}{g['max_mm']:>10.3f}")
    ins = summary["instrument"]
    s = ins["point_sigma_median_mm"]
    e = ins["point_error_rms_mm"]
    out += ["", f"Theodolites ({ins['sigma_arcsec']:.1f}\" readings): median intersection angle "
                f"{ins['intersection_angle_median_deg']:.1f} deg, miss distance {ins['miss_distance_median_mm']:.3f} mm",
            f"  predicted point sigma (median) X {s[0]:.3f}  Y {s[1]:.3f}  Z {s[2]:.3f} mm",
            f"  actual point error (RMS)      X {e[0]:.3f}  Y {e[1]:.3f}  Z {e[2]:.3f} mm"]
    if summary["joint_torque_max_nm"]:
        t = summary["joint_torque_max_nm"]
        out.append("")
        out.append("Largest gravity torque per joint (N m): " + "  ".join(f"j{i + 1} {v:.1f}" for i, v in enumerate(t)))
    return "\n".join(out)
