"""The HTML report of a reprocessed session: tables of estimates (with truth when emulated) and figures.

Figures are matplotlib PNGs embedded as base64, so the report is one self-contained file: circle fits and axes, DH
deviations, transmission-error curves, stiffness curves (loading and unloading), coupling, pose residuals and the
estimation errors against the truth.
"""
from __future__ import annotations

import base64
import html
import io
import json
from pathlib import Path

import numpy as np

from calib.fileio import atomic_write_text


def _png(fig) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    import matplotlib.pyplot as plt
    plt.close(fig)
    return "<img src='data:image/png;base64," + base64.b64encode(buf.getvalue()).decode() + "'/>"


def _figures(f: dict) -> list[tuple[str, str]]:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    out = []
    if f.get("sweeps"):
        fig = plt.figure(figsize=(6, 5))
        ax = fig.add_subplot(projection="3d")
        for j, s in f["sweeps"].items():
            P = np.array(s["points_mm"])
            c, n, r = np.array(s["centre_mm"]), np.array(s["normal"]), s["radius_mm"]
            ax.scatter(*P.T, s=10, label=f"joint {j}")
            e1 = np.cross(n, [1, 0, 0] if abs(n[0]) < 0.9 else [0, 1, 0])
            e1 /= np.linalg.norm(e1)
            e2 = np.cross(n, e1)
            t = np.linspace(0, 2 * np.pi, 100)
            circ = c + r * (np.outer(np.cos(t), e1) + np.outer(np.sin(t), e2))
            ax.plot(*circ.T, lw=0.8)
            ax.plot(*np.array([c - 150 * n, c + 150 * n]).T, "k--", lw=0.6)
        ax.set_xlabel("X mm"), ax.set_ylabel("Y mm"), ax.set_zlabel("Z mm")
        ax.legend(fontsize=7)
        out.append(("Joint sweeps: circle fits and axes", _png(fig)))
    if f.get("dh"):
        rows = [d for d in f["dh"] if d["nominal"] == d["nominal"]]
        fig, ax = plt.subplots(figsize=(8, 3))
        x = np.arange(len(rows))
        scale = [1.0 if d["name"].endswith("_mm") else 180 / np.pi for d in rows]
        ax.errorbar(x, [(d["value"] - d["nominal"]) * s for d, s in zip(rows, scale)],
                    [d["error"] * s for d, s in zip(rows, scale)], fmt="o", label="estimated - nominal")
        if any(d["truth"] is not None for d in rows):
            ax.plot(x, [((d["truth"] or d["nominal"]) - d["nominal"]) * s for d, s in zip(rows, scale)], "x",
                    label="truth - nominal")
        ax.set_xticks(x, [d["name"] for d in rows], rotation=90, fontsize=7)
        ax.set_ylabel("mm or deg")
        ax.legend(fontsize=7)
        out.append(("DH deviations from the description (circle point analysis)", _png(fig)))
    if f.get("transmission"):
        fig, ax = plt.subplots(figsize=(6, 3))
        for j, t in f["transmission"].items():
            ax.errorbar(t["encoder_deg"], t["error_deg"], t["sigma_deg"], fmt="o", ms=3, label=f"joint {j}")
        ax.set_xlabel("encoder joint angle, deg"), ax.set_ylabel("measured - encoder, deg")
        ax.legend(fontsize=7)
        out.append(("Transmission error", _png(fig)))
    if f.get("compliance"):
        fig, ax = plt.subplots(figsize=(6, 3))
        for j, c in f["compliance"].items():
            T, d, u = np.array(c["torque_nm"]), np.array(c["deflection_deg"]), np.array(c["unloading"], bool)
            ax.plot(T[~u], d[~u], "o-", label=f"joint {j} loading")
            ax.plot(T[u], d[u], "s--", label=f"joint {j} unloading")
        ax.set_xlabel("torque N m"), ax.set_ylabel("deflection deg")
        ax.legend(fontsize=7)
        out.append(("Joint stiffness: loading and unloading", _png(fig)))
    if f.get("link"):
        L = f["link"]
        fig, ax = plt.subplots(figsize=(6, 3))
        ax.scatter(L["x_mm"], L["deflection_mm"], c=L["load_n"])
        ax.set_xlabel("gauge position mm"), ax.set_ylabel("deflection mm")
        out.append((f"Link compliance: EI = {L['EI_Nmm2']:.3g} N mm^2", _png(fig)))
    if f.get("coupling"):
        fig, ax = plt.subplots(figsize=(5, 3))
        ks = list(f["coupling"])
        ax.bar(ks, [f["coupling"][k]["sigma"] for k in ks])
        ax.set_xlabel("pair jk"), ax.set_ylabel("sigma_jk")
        out.append(("Wrist coupling", _png(fig)))
    if f.get("poses"):
        fig, ax = plt.subplots(figsize=(6, 3))
        ax.bar(range(len(f["poses"]["residual_mm"])), f["poses"]["residual_mm"])
        ax.set_xlabel("pose"), ax.set_ylabel("|residual| mm")
        out.append((f"Pose-set identification residuals (rms {f['poses']['rms_mm']:.3f} mm)", _png(fig)))
    return out


def _estimation_errors(est: list[dict]):
    import matplotlib.pyplot as plt
    rows = [e for e in est if e["truth"] is not None and e["error"] > 0 and not e.get("held")]
    if not rows:
        return None
    z = [(e["value"] - e["truth"]) / e["error"] for e in rows]
    fig, ax = plt.subplots(figsize=(8, 3))
    ax.bar(range(len(z)), np.clip(z, -10, 10))
    ax.axhline(2, color="r", lw=0.6), ax.axhline(-2, color="r", lw=0.6)
    ax.set_xticks(range(len(z)), [e["name"] for e in rows], rotation=90, fontsize=6)
    ax.set_ylabel("(estimate - truth) / error")
    return ("Estimation errors against the twin's truth (clipped at 10)", _png(fig))


def write_report(result: dict, out_dir: str | Path) -> Path:
    """Write ``report.html``, ``results.json`` and ``robot.json`` (identified description) into ``out_dir``."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    figs = _figures(result.get("figures", {}))
    ee = _estimation_errors(result["estimates"])
    if ee:
        figs.append(ee)
    def _truth(e):
        t = "" if e["truth"] is None else f"{e['truth']:.6g}"
        if e.get("truth_raw") is not None:
            t += f" (gauge; raw {e['truth_raw']:.6g})"
        return t

    def _err(e):
        # a held parameter was not estimated: no error to print, and value - truth is not an estimation error
        return "held" if e.get("held") else f"{e['error']:.3g}"

    rows = "".join(
        f"<tr><td>{html.escape(e['name'])}</td><td>{e['value']:.6g}</td><td>{_err(e)}</td>"
        f"<td>{html.escape(e['unit'])}</td><td>{_truth(e)}</td><td>{html.escape(e.get('note', ''))}</td></tr>"
        for e in result["estimates"])
    s = result["session"]
    prov = result["provenance"]
    probs = "".join(f"<li>{html.escape(p)}</li>" for p in result.get("problems", [])) or "<li>none</li>"
    body = [f"<h1>robocal calibration report</h1><p>Session {html.escape(s['title'])} ({s['guid']}), "
            f"{s['steps_accepted']} accepted steps, status {s['exit_status']}. Reprocessed with robocal "
            f"{prov['code_version']} in {prov['elapsed_s']:.1f} s.</p><h2>Problems</h2><ul>{probs}</ul>",
            "<h2>Estimates</h2><table border=1 cellspacing=0><tr><th>name</th><th>value</th><th>error (1 sigma)</th>"
            f"<th>unit</th><th>truth</th><th>note</th></tr>{rows}</table><p>'held': not estimated, kept at the design "
            "value because the data cannot determine it (the estimated parameters absorb its deviation, which is why "
            "their truth is given in the gauge of the held ones).</p>"]
    for title, img in figs:
        body.append(f"<h2>{html.escape(title)}</h2>{img}")
    path = out / "report.html"
    atomic_write_text(path, "<!doctype html><html><head><meta charset='utf-8'><title>robocal report</title></head>"
                      "<body>" + "".join(body) + "</body></html>")
    atomic_write_text(out / "results.json", json.dumps({k: v for k, v in result.items() if k != "figures"}, indent=1))
    if result.get("robot"):
        atomic_write_text(out / "robot.json", json.dumps(result["robot"], indent=1))
    return path
