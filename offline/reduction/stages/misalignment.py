"""Fig 5.10's misalignment rows (eqs 4.3.10-4.3.13): each measured axis against its design direction at the
reference pose, with errors from the axes' covariances (:func:`calib.estimators.misalignment.misalignment_table`).
Runs when every joint was swept."""
from __future__ import annotations

import numpy as np

from calib.estimators.misalignment import ROW, misalignment_table
from calib.units import DEG

from offline.reduction.context import Reduction
from offline.reduction.registry import Stage
from offline.reduction.stages.sweeps import SweptAxes


def reduce_misalignment(ctx: Reduction, steps: list[dict]) -> None:
    swept: SweptAxes | None = ctx.outputs.get("axes")
    n = ctx.robot.n
    if swept is None or len(swept.axes) < n:
        return
    zd, xf = swept.design_frames()
    N = np.array([swept.axes[j + 1].value[3:6] for j in range(n)])
    U = np.zeros((3 * n, 3 * n))
    for j in range(n):
        U[3 * j:3 * j + 3, 3 * j:3 * j + 3] = swept.axes[j + 1].cov[3:6, 3:6]
    res = misalignment_table(N, U, zd, xf, n_mc=ctx.n_mc)
    ctx.est.add_set("misalign.", res)
    ctx.figs["misalignment"] = [
        {"joint": j + 1, **{r.replace("_rad", "_deg"): float(res[f"j{j + 1}.{r}"].value) / DEG
                            for r in ROW if f"j{j + 1}.{r}" in res.names},
         "error_deg": float(max(res[k].error for k in res.names if k.startswith(f"j{j + 1}."))) / DEG}
        for j in range(n)]


STAGE = Stage("misalignment", reduce_misalignment, needs=("axes",))
