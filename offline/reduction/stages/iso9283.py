"""ISO 9283 pose accuracy and repeatability from the stored sightings of the ``iso9283`` procedure: per run
(compensation off, on) and pose, AP and RP (:func:`calib.iso9283.pose_figures`, ISO 9283 sections 7.2.1 and 7.2.2)
of the located target against the commanded point of the cube.  Positions only (theodolites measure points)."""
from __future__ import annotations

from calib.estimators.points import StationFit
from calib.iso9283 import pose_figures

from offline.reduction.context import Located, Reduction
from offline.reduction.registry import Stage

#: the plan's run name -> the results' key
RUNS = {"off": "uncompensated", "on": "compensated"}


def reduce_iso9283(ctx: Reduction, steps: list[dict]) -> dict | None:
    """``{"uncompensated": [per pose], "compensated": [per pose]}``, each pose ``{"pose", "ap_mm", "rp_mm", "apx_mm",
    "apy_mm", "apz_mm", "n", "command_mm"}``; the attained points of every step in ``trace`` (for an independent
    check)."""
    if not steps:
        return None
    groups: dict[tuple[str, str], tuple[list, list]] = {}
    rows = []
    # this stage's steps alone (300 of them in a session), with the stations taken as exact: AP and RP read the
    # attained points only, never their covariances, and the points are the same floats either way (the same
    # intersection of the same batch with the same stations); what the stations' uncertainty would add to the
    # covariances costs eight more intersections of the batch (central differences), three quarters of the stage,
    # which runs after the session's last step
    located = Located(steps, StationFit.exact(ctx.outputs["stations"].stations))
    for st in steps:
        m = st["spec"]["meta"]
        pt = located(st).get("P") if st["readings"] else None
        if pt is None:
            continue
        groups.setdefault((m["run"], m["pose"]), (list(m["point_mm"]), []))[1].append(pt[0])
        rows.append({"run": m["run"], "pose": m["pose"], "cycle": m["cycle"], "command_mm": list(m["point_mm"]),
                     "attained_mm": [float(v) for v in pt[0]]})
    out: dict[str, list] = {key: [] for key in RUNS.values()}
    for (run, pose), (command, attained) in sorted(groups.items(), key=lambda kv: (kv[0][0] != "off", kv[0][1])):
        if len(attained) < 2:
            ctx.said(f"ISO 9283: pose {pose} with compensation {run} has {len(attained)} measurement: no "
                     "repeatability from one")
            continue
        f = pose_figures(pose, command, attained)
        out[RUNS[run]].append({"pose": pose, "ap_mm": round(f.ap_mm, 4), "rp_mm": round(f.rp_mm, 4),
                               "apx_mm": round(f.apx_mm, 4), "apy_mm": round(f.apy_mm, 4),
                               "apz_mm": round(f.apz_mm, 4), "n": f.n, "command_mm": command})
    ctx.trace["iso9283"] = {"rows": rows}
    plan = ctx.data.plan.get("iso9283") or {}
    ctx.figs["iso9283"] = {**out, "cycles": plan.get("cycles"), "side_mm": plan.get("side_mm")}
    return out


STAGE = Stage("iso9283", reduce_iso9283, procedures=("iso9283",), needs=("stations",), gives="iso9283",
              label="ISO 9283")
