"""HTML report with PNG figures (matplotlib, Agg backend: no display needed)."""
from __future__ import annotations

import html
import json
from pathlib import Path

import numpy as np

from calib.errors import RobocalError
from calib.names import joint_label, prose, with_joint_names
from .render import render
from calib.provenance import provenance_html
from calib.units import DEG


def _plt():
    # matplotlib costs ~0.5-1 s at import; only the HTML report's figures need it
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # after the backend is chosen
    return plt


def _dir(path) -> Path:
    p = Path(path)
    try:
        p.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise RobocalError(f"--report {path}: cannot create the directory: {exc}") from None
    return p


def write_report(d, out_dir, provenance: dict | None = None) -> Path:
    """index.html + PNGs: residual vs each joint, the breakdown factors, the shrink curve; ``provenance``
    (:func:`calib.provenance.provenance`) goes into the JSON and a footer."""
    plt = _plt()
    out = _dir(out_dir)
    j = d.to_json()
    figs = []
    before = np.linalg.norm(d.geometric.residual_mm, axis=1)
    after = np.linalg.norm(d.selection.final.residual_mm, axis=1)
    n = d.data.robot.n
    cols = min(4, n)
    rows = int(np.ceil(n / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 2.6 * rows), squeeze=False)
    for k in range(rows * cols):
        ax = axes[k // cols][k % cols]
        if k >= n:
            ax.axis("off")
            continue
        x = d.data.q_rad[:, k] * (1.0 if d.data.robot.prismatic[k] else 1 / DEG)
        ax.scatter(x, before, s=8, label="geometric")
        ax.scatter(x, after, s=8, label="final")
        ax.axhline(j["noise_floor_mm"], color="k", lw=0.8, ls="--")
        ax.set_xlabel(f"{joint_label(d.data.robot, k + 1)} ({'mm' if d.data.robot.prismatic[k] else 'deg'})")
        ax.set_ylabel("held-out |r| (mm)")
    axes[0][0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "residual_vs_joints.png", dpi=90)
    plt.close(fig)
    figs.append(("Held-out residual length against each joint (dashed: noise floor)", "residual_vs_joints.png"))

    facs = [f for f in d.factors if not f.name.startswith("joint ") or "direction" in f.name]
    facs += sorted([f for f in d.factors if f.name.startswith("joint ") and "direction" not in f.name],
                   key=lambda f: f.p_value)[:4]
    if facs:
        fig, axes = plt.subplots(len(facs), 1, figsize=(7, 1.9 * len(facs)), squeeze=False)
        for ax, f in zip(axes[:, 0], facs):
            x = np.arange(len(f.groups))
            ax.bar(x - 0.2, [g.rms_before_mm for g in f.groups], 0.4, label="geometric")
            ax.bar(x + 0.2, [g.rms_after_mm for g in f.groups], 0.4, label="final")
            ax.axhline(j["noise_floor_mm"], color="k", lw=0.8, ls="--")
            ax.set_xticks(x, [g.label for g in f.groups], fontsize=7)
            ax.set_title(prose(f"{f.name} (Kruskal-Wallis p = {f.p_value:.2g})", d.data.robot), fontsize=9)
            ax.set_ylabel("RMS mm", fontsize=8)
        axes[0, 0].legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(out / "breakdown.png", dpi=90)
        plt.close(fig)
        figs.append(("Held-out RMS by condition", "breakdown.png"))

    steps = ["geometric"] + [prose(f["label"], d.data.robot) + (" (doubtful)" if f["doubtful"] else "")
                             for f in j["findings"]]
    vals = [j["baseline_rms_mm"]] + [f["rms_after_mm"] for f in j["findings"]]
    fig, ax = plt.subplots(figsize=(max(4, 1.6 * len(steps)), 3))
    ax.plot(range(len(steps)), vals, "o-")
    ax.axhline(j["noise_floor_mm"], color="k", ls="--", lw=0.8, label="noise floor")
    ax.axhline(j["heldout_floor_mm"], color="gray", ls=":", lw=0.8, label="held-out floor")
    ax.set_xticks(range(len(steps)), steps, rotation=20, ha="right", fontsize=7)
    ax.set_ylabel("held-out RMS (mm)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "shrink.png", dpi=90)
    plt.close(fig)
    figs.append(("Held-out RMS after each accepted effect", "shrink.png"))

    if j.get("ladder"):
        figs.insert(0, ("The model step by step: held-out error at each step (mean, RMS, max)",
                        _ladder_png(plt, j, out)))

    body = [f"<h1>robocal diagnose: {html.escape(j['source'])}</h1>", *_ladder_html(j),
            "<pre>" + html.escape(render(d)) + "</pre>"]
    body += [f"<h2>{html.escape(t)}</h2><img src='{f}'>" for t, f in figs]
    if provenance is not None:
        body.append(provenance_html(provenance))
        j["provenance"] = provenance
    (out / "index.html").write_text("<!doctype html><meta charset='utf-8'><title>robocal diagnose</title>"
                                    + "\n".join(body), encoding="utf-8")
    (out / "diagnosis.json").write_text(json.dumps(with_joint_names(j, d.data.robot), indent=1, default=float),
                                        encoding="utf-8")
    return out / "index.html"


def _ladder_png(plt, j: dict, out: Path) -> str:
    """Mean, RMS and max of the held-out error at each step of the ladder."""
    steps = j["ladder"]
    x = np.arange(len(steps))
    fig, ax = plt.subplots(figsize=(max(5, 1.5 * len(steps)), 3.2))
    for key, lab, mark in (("test_mean_mm", "mean", "o-"), ("test_rms_mm", "RMS", "s-"), ("test_max_mm", "max", "^--")):
        ax.plot(x, [s[key] for s in steps], mark, label=lab)
    ax.axhline(j["noise_floor_mm"], color="k", lw=0.8, ls=":", label="noise floor")
    ax.set_yscale("log")
    ax.set_xticks(x, [s["model"] for s in steps], rotation=20, ha="right", fontsize=7)
    ax.set_ylabel("held-out error (mm)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "ladder.png", dpi=90)
    plt.close(fig)
    return "ladder.png"


def _ladder_html(j: dict) -> list[str]:
    """Before/after, the ladder and the leave-one-group-out table as HTML tables (the owner's first screen)."""
    e = html.escape

    def num(v):
        return "-" if v is None else f"{v:.4f}"
    out = []
    if j.get("before"):
        b, a = j["before"], j["after"]
        out.append(f"<h2 id='accuracy'>Accuracy before and after ({e(j['heldout_protocol'])})</h2>"
                   f"<p>{e(j['error_convention'])}</p><table border='1' cellpadding='3'>"
                   "<tr><th></th><th>n</th><th>mean mm</th><th>RMS mm</th><th>p95 mm</th><th>max mm</th></tr>"
                   + "".join(f"<tr><td>{lab}</td><td>{s['n']}</td><td>{num(s['mean_mm'])}</td><td>{num(s['rms_mm'])}"
                             f"</td><td>{num(s['p95_mm'])}</td><td>{num(s['max_mm'])}</td></tr>"
                             for lab, s in (("before (located nominal)", b), ("after (calibrated)", a)))
                   + "</table>")
        u = j.get("uncertainty") or {}
        if u.get("median_abs_z") is not None:
            out.append(f"<p id='honesty'>Predicted sigma of the held-out points: median |error|/sigma "
                       f"{u['median_abs_z']:.2f} (0.67 when honest), {100 * u['within_2sigma']:.0f} % within 2 sigma "
                       f"(95 % when honest). {e(u['convention'])}.</p>")
    if j.get("ladder"):
        out.append("<h2 id='ladder'>The ladder</h2><table border='1' cellpadding='3'><tr><th>model</th><th>added</th>"
                   "<th>parameters</th><th>mean mm</th><th>RMS mm</th><th>max mm</th><th>significance</th></tr>"
                   + "".join(f"<tr><td>{e(s['model'])}</td><td>{e(s['added'])}</td><td>{s['n_params']}</td>"
                             f"<td>{num(s['test_mean_mm'])}</td><td>{num(s['test_rms_mm'])}</td>"
                             f"<td>{num(s['test_max_mm'])}</td><td>{e(s['significance'])}</td></tr>"
                             for s in j["ladder"]) + "</table>")
        out.append("<h3 id='leave-one-out'>Leave one group out</h3><table border='1' cellpadding='3'><tr>"
                   "<th>final model without</th><th>RMS mm</th><th>mean mm</th><th>loss (RMS) mm</th></tr>"
                   + "".join(f"<tr><td>{e(g['without'])}</td><td>{num(g['test_rms_mm'])}</td>"
                             f"<td>{num(g['test_mean_mm'])}</td><td>{num(g['loss_rms_mm'])}</td></tr>"
                             for g in j["leave_one_group_out"]) + "</table>")
    return out


def write_validation_report(v, out_dir) -> Path:
    """validation.html + confusion.png + shrink histogram."""
    plt = _plt()
    out = _dir(out_dir)
    rows, cols, M = v.confusion()
    fig, ax = plt.subplots(figsize=(8, 4.5))
    ax.imshow(M, cmap="Blues")
    for i in range(M.shape[0]):
        for k in range(M.shape[1]):
            if M[i, k]:
                ax.text(k, i, str(M[i, k]), ha="center", va="center", fontsize=9)
    ax.set_xticks(range(len(cols)), cols, rotation=30, ha="right", fontsize=8)
    ax.set_yticks(range(len(rows)), rows, fontsize=8)
    ax.set_xlabel("named first")
    ax.set_ylabel("withheld")
    ax.set_title(f"right first {100 * v.first_right_rate:.1f} %, false alarms {100 * v.false_alarm_rate:.1f} %, "
                 f"median shrink {100 * v.median_shrink:.0f} %", fontsize=9)
    fig.tight_layout()
    fig.savefig(out / "confusion.png", dpi=90)
    plt.close(fig)
    sh = [r.shrink for r in v.effect_results if np.isfinite(r.shrink)]
    fig, ax = plt.subplots(figsize=(5, 3))
    ax.hist(np.clip(sh, -0.5, 1.5), bins=20)
    ax.axvline(0.8, color="r", ls="--", lw=0.8)
    ax.set_xlabel("share of the excess gap removed")
    ax.set_ylabel("cases")
    fig.tight_layout()
    fig.savefig(out / "shrink_hist.png", dpi=90)
    plt.close(fig)
    (out / "validation.html").write_text(
        "<!doctype html><meta charset='utf-8'><title>robocal diagnose --validate</title>"
        f"<pre>{html.escape(v.render())}</pre><img src='confusion.png'><img src='shrink_hist.png'>",
        encoding="utf-8")
    (out / "validation.json").write_text(json.dumps(v.to_json(), indent=1, default=float), encoding="utf-8")
    return out / "validation.html"
