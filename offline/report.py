"""The calibration report of a reprocessed session: one HTML file that can be mailed (figures embedded as PNG, a small
stylesheet that reads on screen and prints to PDF), optionally the same page printed to a PDF beside it.

It opens with the answer -- the robot, the session, the instruments and their stated noise, and how accurate the robot
was before calibration and is after, on poses the fit did not use, against the instrument floor and a tolerance, with
a map of the error over the workspace -- then one section per procedure (:mod:`offline.sections`): what was done,
its figures (one unit per axis), its estimates in the units a metrologist reads with a verdict, the thesis's own
numbers beside them, and, when the stage failed, which stage, what the numbers were and what to do.
"""
from __future__ import annotations

import base64
import html
import io
import json
import re
from pathlib import Path
from typing import Callable

import numpy as np

from acq.session.records import session_record
from calib.fileio import atomic_write_text
from calib.kinds import describe
from calib.units import DEG

from offline.iso_report import iso_html
from offline.numbers import legend, below_floor_sentence, same_floor, value_pm, when
from offline.pdf import html_to_pdf
from offline.sections import DETERMINED, HELD, NEGLIGIBLE, SECTIONS, UNDETERMINED, WEAK, Section, beside_the_thesis, \
    bound_text, needs_action, section_bounds, section_estimates, section_problems, section_verdict, shown, shows, \
    thesis_rows
from offline.summary import finding_flags

STYLE = """
body { font-family: system-ui, -apple-system, "Segoe UI", sans-serif; max-width: 60rem; margin: 1.5rem auto;
       padding: 0 1rem; color: #1b1b1b; line-height: 1.4; }
h1 { font-size: 1.6rem; margin-bottom: 0.2rem; } h2 { border-bottom: 2px solid #2b5797; padding-bottom: 0.2rem;
     margin-top: 2rem; } h3 { margin-bottom: 0.3rem; }
table { border-collapse: collapse; margin: 0.5rem 0; font-size: 0.9rem; }
th, td { border: 1px solid #c8c8c8; padding: 0.15rem 0.5rem; text-align: right; }
th { background: #eef2f8; } td.name, th.name { text-align: left; }
.answer { background: #f3f7fc; border: 1px solid #2b5797; border-radius: 6px; padding: 0.6rem 1rem; }
.verdict { font-weight: 600; } .determined { color: #1a7f37; } .weakly { color: #9a6700; }
.not { color: #cf222e; } .held { color: #666; } .problem { background: #fff4f4; border-left: 4px solid #cf222e; padding: 0.3rem 0.8rem; }
.muted { color: #666; font-size: 0.85rem; } figure { margin: 0.5rem 0; } img { max-width: 100%; }
.keep { break-inside: avoid; }
/* print (--pdf is this page printed): a title never ends a page without what it titles, a table or a figure is not
   cut when it fits a page, a long table repeats its header row */
@page { size: A4; margin: 14mm 12mm; }
@media print { body { max-width: none; margin: 0; font-size: 10pt; } .answer { break-inside: avoid; }
  h1, h2, h3 { break-after: avoid; page-break-after: avoid; }
  figure, table, tr, .keep, .problem, p.verdict { break-inside: avoid; page-break-inside: avoid; }
  thead { display: table-header-group; } img { max-height: 120mm; } }
"""

FigureFn = Callable[[dict, dict], "list[tuple[str, object]]"]
#: figures by key: fn(figures data, result) -> [(caption, matplotlib figure)]
FIGURES: dict[str, FigureFn] = {}


def figure(key: str):
    def register(fn: FigureFn) -> FigureFn:
        FIGURES[key] = fn
        return fn
    return register


def _plt():
    # matplotlib costs ~0.5-1 s at import; only the report's figures need it
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # after the backend is chosen
    return plt


def _png(fig) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    _plt().close(fig)
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode()


# -- figures -----------------------------------------------------------------------------------------------------
@figure("ruler")
def _ruler_fig(f: dict, res: dict):
    r = f.get("ruler")
    if not r or not r.get("residual_arcsec"):
        return []
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6, 2.6))
    res_as = np.asarray(r["residual_arcsec"], float).ravel()
    ax.plot(res_as, "o", ms=3)
    ax.axhline(0, color="k", lw=0.5)
    ax.set_xlabel("reading"), ax.set_ylabel("residual (arcsec)")
    return [("Ruler fit: residual of every reading", fig)]


def _joint(res: dict, j, capital: bool = False) -> str:
    """Joint ``j`` (1-based) as the session's description names it (``joint_labels`` of the reprocess result,
    :func:`calib.names.joint_label`), ``joint j`` for a result without them."""
    labels = res.get("joint_labels") or []
    k = int(j)
    if 1 <= k <= len(labels) and not labels[k - 1].startswith("joint "):
        return labels[k - 1]
    return f"{'J' if capital else 'j'}oint {k}"


@figure("sweeps")
def _sweeps_fig(f: dict, res: dict):
    if not f.get("sweeps"):
        return []
    plt = _plt()
    fig = plt.figure(figsize=(6, 5))
    ax = fig.add_subplot(projection="3d")
    for j, s in f["sweeps"].items():
        P = np.array(s["points_mm"])
        c, n, r = np.array(s["centre_mm"]), np.array(s["normal"]), s["radius_mm"]
        ax.scatter(*P.T, s=10, label=_joint(res, j))
        e1 = np.cross(n, [1, 0, 0] if abs(n[0]) < 0.9 else [0, 1, 0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(n, e1)
        t = np.linspace(0, 2 * np.pi, 100)
        circ = c + r * (np.outer(np.cos(t), e1) + np.outer(np.sin(t), e2))
        ax.plot(*circ.T, lw=0.8)
        ax.plot(*np.array([c - 150 * n, c + 150 * n]).T, "k--", lw=0.6)
    ax.set_xlabel("X (mm)"), ax.set_ylabel("Y (mm)"), ax.set_zlabel("Z (mm)")
    ax.legend(fontsize=7)
    return [("Joint sweeps: the circles the targets describe and the joint axes", fig)]


def _dh_fig(f: dict, lengths: bool, labels=None):
    rows = [d for d in f.get("dh", []) if d["nominal"] == d["nominal"] and d["name"].endswith("_mm") == lengths]
    if not rows:
        return []
    plt = _plt()
    scale = 1.0 if lengths else 1.0 / DEG
    unit = "mm" if lengths else "deg"
    fig, ax = plt.subplots(figsize=(8, 2.8))
    x = np.arange(len(rows))
    ax.errorbar(x, [(d["value"] - d["nominal"]) * scale for d in rows], [d["error"] * scale for d in rows],
                fmt="o", label="estimated − nominal")
    if any(d["truth"] is not None for d in rows):
        ax.plot(x, [((d["truth"] if d["truth"] is not None else d["nominal"]) - d["nominal"]) * scale for d in rows],
                "x", label="truth − nominal (emulated)")
    ax.axhline(0, color="k", lw=0.5)
    ax.set_xticks(x, [describe(f"dh.{d['name']}", labels).name for d in rows], rotation=90, fontsize=7)
    ax.set_ylabel(f"deviation ({unit})")
    ax.legend(fontsize=7)
    what = "lengths a, d" if lengths else "angles θ offset, α, β"
    return [(f"DH {what}: deviation from the description ({unit})", fig)]


@figure("dh_lengths")
def _dh_lengths(f: dict, res: dict):
    return _dh_fig(f, True, res.get("joint_labels"))


@figure("dh_angles")
def _dh_angles(f: dict, res: dict):
    return _dh_fig(f, False, res.get("joint_labels"))


@figure("transmission")
def _te_fig(f: dict, res: dict):
    out = []
    plt = _plt()
    for j, t in (f.get("transmission") or {}).items():
        if not t.get("encoder_deg"):
            continue
        fig, ax = plt.subplots(figsize=(6, 2.8))
        enc = np.asarray(t["encoder_deg"], float)
        ax.errorbar(enc, t["error_deg"], t.get("sigma_deg"), fmt="o", ms=3, label="measured − encoder")
        if t.get("fit_deg") is not None:
            order = np.argsort(enc)
            ax.plot(enc[order], np.asarray(t["fit_deg"], float)[order], "-", label="harmonic fit")
        ax.set_xlabel(f"{_joint(res, j)} encoder angle (deg)"), ax.set_ylabel("transmission error (deg)")
        ax.legend(fontsize=7)
        out.append((f"Transmission error of {_joint(res, j)}", fig))
    return out


@figure("compliance")
def _compliance_fig(f: dict, res: dict):
    out = []
    plt = _plt()
    for j, c in (f.get("compliance") or {}).items():
        T, d = np.asarray(c["torque_nm"], float), np.asarray(c["deflection_deg"], float)
        u = np.asarray(c.get("unloading", [False] * len(T)), bool)
        fig, ax = plt.subplots(figsize=(6, 2.8))
        ax.plot(T[~u], d[~u], "o-", label="loading")
        if u.any():
            ax.plot(T[u], d[u], "s--", label="unloading")
        ax.set_xlabel(f"torque about {_joint(res, j)} (N m)"), ax.set_ylabel("deflection (deg)")
        ax.legend(fontsize=7)
        span = float(np.ptp(T)) if len(T) else 0.0
        note = "" if span > 1e-6 else " — the loads produced no torque about this joint at this pose"
        out.append((f"{_joint(res, j, True)}: deflection against the torque the loads produce{note}", fig))
    return out


@figure("link")
def _link_fig(f: dict, res: dict):
    L = f.get("link")
    if not L:
        return []
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6, 2.8))
    sc = ax.scatter(L["x_mm"], L["deflection_mm"], c=L.get("load_n"), cmap="viridis")
    fig.colorbar(sc, ax=ax, label="load (N)")
    ax.set_xlabel("gauge position along the link (mm)"), ax.set_ylabel("deflection (mm)")
    what = (f"EI = {L['EI_Nmm2']:.3g} N mm²" if L.get("EI_Nmm2") is not None else
            f"no significant bending: EI ≥ {L['EI_lower_bound_Nmm2']:.3g} N mm², "
            f"{100 * L.get('confidence', 0.95):g} % one-sided")
    return [(f"Link compliance: gauge deflections ({what})", fig)]


@figure("coupling")
def _coupling_fig(f: dict, res: dict):
    if not f.get("coupling"):
        return []
    plt = _plt()
    ks = list(f["coupling"])
    fig, ax = plt.subplots(figsize=(5, 2.6))
    ax.bar([f"σ{k}" for k in ks], [f["coupling"][k]["sigma"] for k in ks])
    ax.set_ylabel("σ_jk (encoder counts of k per count of j, 1)")
    return [("Wrist cross coupling", fig)]


@figure("resolution")
def _resolution_fig(f: dict, res: dict):
    """Fig 5.14: the measured angle less the fitted line, against the counts (what one count is worth is the line's
    slope; what is left is the transmission error over the run and the noise)."""
    out = []
    plt = _plt()
    for j, r in (f.get("resolution") or {}).items():
        fig, ax = plt.subplots(figsize=(6, 2.6))
        ax.errorbar(r["counts"], r["residual_deg"], r.get("sigma_deg"), fmt="o", ms=3)
        ax.axhline(0.0, color="k", lw=0.5)
        ax.set_xlabel(f"{_joint(res, j)} encoder counts"), ax.set_ylabel("angle − fitted line (deg)")
        out.append((f"{_joint(res, j, True)}: {np.degrees(r['rad_per_count']) * 3600:.4g} arc seconds per count; the measured angle "
                    f"less the fitted line", fig))
    return out


@figure("poses")
def _poses_fig(f: dict, res: dict):
    p = f.get("poses")
    if not p:
        return []
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6, 2.6))
    ax.bar(range(1, len(p["residual_mm"]) + 1), p["residual_mm"])
    ax.set_xlabel("pose"), ax.set_ylabel("|residual| (mm)")
    return [(f"Identification residuals on the fit (RMS {p['rms_mm']:.3f} mm)", fig)]


@figure("accuracy_map")
def _accuracy_map(f: dict, res: dict):
    a, p = f.get("accuracy"), f.get("poses")
    if not a or not p or not p.get("points_mm"):
        return []
    plt = _plt()
    P = np.asarray(p["points_mm"], float)[np.asarray(a["test_index"], int)]
    before, after = np.asarray(a["before_err_mm"]), np.asarray(a["after_err_mm"])
    vmax = float(max(before.max(), after.max()))
    fig, axes = plt.subplots(1, 2, figsize=(8, 3.2), sharex=True, sharey=True)
    for ax, err, name in ((axes[0], before, "before (nominal description)"), (axes[1], after, "after calibration")):
        sc = ax.scatter(P[:, 0], P[:, 1], c=err, cmap="viridis", vmin=0.0, vmax=vmax, s=40)
        ax.set_title(name, fontsize=9)
        ax.set_xlabel("X (mm)")
    axes[0].set_ylabel("Y (mm)")
    fig.colorbar(sc, ax=axes, label="position error (mm)")
    return [("Position error over the measured workspace, held-out poses (one colour scale)", fig)]


# -- text ----------------------------------------------------------------------------------------------------------
def _verdict_class(v: str) -> str:
    return {DETERMINED: "determined", NEGLIGIBLE: "determined", HELD: "held", WEAK: "weakly", UNDETERMINED: "not"}[v]


def accuracy_verdict(acc: dict, tolerance_mm: float | None) -> str:
    """The accuracy in words: against the tolerance if given, and against the instrument floor."""
    words = []
    gain = acc["before_rms_mm"] / acc["after_rms_mm"] if acc["after_rms_mm"] > 0 else np.inf
    words.append(f"Calibration reduced the RMS position error on poses it did not use from "
                 f"{acc['before_rms_mm']:.3f} mm to {acc['after_rms_mm']:.3f} mm ({gain:.0f}× smaller).")
    ratio = acc["after_rms_mm"] / acc["floor_mm"] if acc["floor_mm"] > 0 else np.inf
    if ratio <= 1.5:
        words.append("What remains is at the instruments' own floor: the model explains everything they can see.")
        words.append(below_floor_sentence(acc))
    else:
        words.append(f"What remains is {ratio:.1f}× the instruments' floor: an effect the model does not include "
                     f"remains (see the diagnosis: robocal diagnose).")
    if tolerance_mm is not None:
        ok = acc["after_max_mm"] <= tolerance_mm
        words.append(f"Tolerance {tolerance_mm:g} mm: {'met on every held-out pose' if ok else 'NOT met'} "
                     f"(largest error {acc['after_max_mm']:.3f} mm).")
    return " ".join(w for w in words if w)


def _robot_name(res: dict) -> str | None:
    """The description's name, from the identified model document's nominal description."""
    doc = res.get("robot")
    text = doc.get("nominal_robot_toml", "") if isinstance(doc, dict) else ""
    found = re.search(r'^name\s*=\s*"([^"]*)"', text, re.M)
    return found.group(1) if found else None


def _stated_noise(record) -> str | None:
    st = (record.setup.get("stations") or {}) if record is not None else {}
    sig = st.get("sigma_arcsec") if isinstance(st, dict) else None
    return f"theodolite readings {sig:g}″ (1σ) per angle" if isinstance(sig, (int, float)) else None


def _answer(res: dict, record, tolerance_mm: float | None, figs_png: dict | None = None) -> str:
    s = res["session"]
    acc = res.get("accuracy")
    created = ""
    if record is not None and record.created_unix_s:
        created = when(record.created_unix_s)
    robot = _robot_name(res)
    inst = []
    if record is not None:
        for d in record.devices:
            who = d["identity"].get("name", "") + (f" #{d['identity']['serial']}" if d["identity"].get("serial")
                                                    else "")
            inst.append(f"{d['role']}: {d['driver']} {who}".strip())
    noise = _stated_noise(record)
    rows = [("Session", f"{s['title']} ({s['guid'][:8]}), {s['steps_accepted']} steps accepted, {s['exit_status']}"),
            ("Recorded", created or "unknown"), ("Robot", robot or "as described in the session's set-up"),
            ("Instruments", "; ".join(inst) or "not recorded")]
    if noise:
        rows.append(("Stated noise", noise))
    table = "".join(f"<tr><th class='name'>{html.escape(k)}</th><td class='name'>{html.escape(v)}</td></tr>"
                    for k, v in rows)
    if acc:
        tol = "" if tolerance_mm is None else f"<tr><td class='name'>tolerance</td><td colspan=4>{tolerance_mm:g}" \
                                                f" mm</td></tr>"
        acc_table = (
            "<table><tr><th class='name'>position error (mm)</th><th>RMS</th><th>95 %</th><th>max</th>"
            "<th>poses</th></tr>"
            f"<tr><td class='name'>before (nominal)</td><td>{acc['before_rms_mm']:.3f}</td>"
            f"<td>{acc['before_p95_mm']:.3f}</td><td>{acc['before_max_mm']:.3f}</td><td>{acc['n_test']}</td></tr>"
            f"<tr><td class='name'>after calibration</td><td>{acc['after_rms_mm']:.3f}</td>"
            f"<td>{acc['after_p95_mm']:.3f}</td><td>{acc['after_max_mm']:.3f}</td><td>{acc['n_test']}</td></tr>"
            f"<tr><td class='name'>instrument floor</td><td>{acc['floor_mm']:.3f}</td><td colspan=3></td></tr>"
            f"{tol}</table><p class='verdict'>{html.escape(accuracy_verdict(acc, tolerance_mm))}</p>")
    else:
        acc_table = ("<p class='verdict not'>The accuracy before and after was not measured: the session has no pose "
                     "set large enough to hold poses out. Record the Chapter 6 pose set to measure it.</p>")
    maps = "".join(f"<figure><img alt='{html.escape(c)}' src='{src}'/><figcaption>{html.escape(c)}</figcaption>"
                   f"</figure>" for c, src in (figs_png or {}).get("accuracy_map", []))
    return (f"<section class='answer' id='answer'><h2>The answer</h2><table>{table}</table>{acc_table}{maps}"
            f"</section>")


def _estimates_table(ests: list[dict], labels=None) -> str:
    """The section's estimates: name, value ± 1σ rounded to the error, unit, emulated truth, verdict, meaning."""
    has_truth = any(e.get("truth") is not None for e in ests)
    head = "<tr><th class='name'>estimate</th><th>value ± 1σ</th><th class='name'>unit</th>" + \
           ("<th>truth (emulated)</th>" if has_truth else "") + "<th class='name'>verdict</th>" \
           "<th class='name'>meaning</th></tr>"
    rows = []
    for e in ests:
        s = shown(e, labels)
        value = f"{s.value:.6g}" if s.error is None else value_pm(s.value, s.error)
        unit = s.unit_text + (f" ({s.extra})" if s.extra else "")
        truth = ("" if s.truth is None or s.error is None else s.beside(s.truth)) if has_truth else None
        rows.append(f"<tr><td class='name'>{html.escape(s.name)}</td><td>{html.escape(value)}</td>"
                    f"<td class='name'>{html.escape(unit)}</td>" + ("" if truth is None else f"<td>{truth}</td>")
                    + f"<td class='name {_verdict_class(s.verdict)}'>{html.escape(s.verdict)}</td>"
                    f"<td class='name muted'>{html.escape(s.meaning)}</td></tr>")
    return f"<table><thead>{head}</thead>{''.join(rows)}</table>"      # thead: repeated on every printed page


def _thesis_table(rows: list[dict]) -> str:
    if not rows:
        return ""
    out = ["<div class='keep'><h3>Beside the thesis</h3><table><tr><th class='name'>quantity</th>"
           "<th>robocal ± 1σ</th><th>thesis</th><th>difference</th><th>in σ</th><th class='name'>note</th></tr>"]
    for r in rows:
        unit = "" if not r["unit"] else f" {r['unit']}"
        sig = "" if r["sigmas"] is None else f"{r['sigmas']:+.1f}"
        th_err = "" if r["thesis_error"] is None else f" ± {r['thesis_error']:g}"
        note = r["note"] + (f" (lb in/rad: {r['lbin'][0]:.4g} vs {r['lbin'][1]:.4g})" if r.get("lbin") else "")
        ours = value_pm(r["robocal"], r["error"])
        diff = "" if r["error"] is None else f"{r['difference']:+.2g}"
        out.append(f"<tr><td class='name'>{html.escape(r['label'])}</td><td>{html.escape(ours)}{unit}</td>"
                   f"<td>{r['thesis']:.6g}{th_err}{unit}</td><td>{diff}</td><td>{sig}</td>"
                   f"<td class='name'>{html.escape(note)}</td></tr>")
    out.append("</table></div>")
    return "".join(out)


def _what_was_done(sec: Section, record) -> str:
    if record is None:
        return ""
    rec = record.procedures.get(sec.key) or (record.procedures.get("sweeps") if sec.key == "sweep" else None)
    if rec is None:
        return "<p class='muted'>No steps of this procedure were recorded.</p>"
    parts = [f"{rec.accepted} steps accepted"]
    if rec.skipped:
        parts.append(f"{rec.skipped} skipped")
    if rec.repeats:
        parts.append(f"{rec.repeats} repeats")
    parts.append(f"{rec.failed_checks} failed checks on accepted attempts" if rec.failed_checks
                 else "no failed check")
    txt = ", ".join(parts) + "."
    if rec.accepted_with_failed:
        txt += " The operator accepted despite a failed check at " + ", ".join(rec.accepted_with_failed[:5]) + \
               ("…" if len(rec.accepted_with_failed) > 5 else "") + "."
    return f"<p class='muted'>{html.escape(txt)}</p>"


def _section_html(sec: Section, res: dict, record, figs_png: dict[str, list[tuple[str, str]]]) -> str:
    est, probs, bounds = res.get("estimates", []), res.get("problems", []), res.get("bounds", [])
    mine = section_estimates(sec, est)
    sp = section_problems(sec, probs)
    sb = section_bounds(sec, bounds)
    if not mine and not sp and not sb and (record is None or sec.key not in record.procedures):
        return ""
    labels = res.get("joint_labels")
    v, why = section_verdict(sec, est, probs, bounds, beside_the_thesis(res), labels)
    anchor = sec.key if not sec.only_with_results else f"{sec.key}-{sec.prefixes[0].rstrip('.')}"
    out = [f"<section id='{anchor}'><h2>{html.escape(sec.title)}</h2>",
           f"<p>{html.escape(sec.what)}</p>", _what_was_done(sec, record),
           f"<p class='verdict {_verdict_class(v)}'>Verdict: {v}" + ("" if v == DETERMINED else
                                                                     f" — {html.escape(why)}") + "</p>"]
    for p in sp:
        stage, _, msg = p.partition(":")
        out.append(f"<div class='problem'><b>The {html.escape(stage.strip())} stage did not give a result:</b> "
                   f"{html.escape(msg.strip())}<br>What to do: {html.escape(sec.advice)}</div>")
    if needs_action(v) and not sp and sec.advice:
        out.append(f"<p class='muted'>What to do: {html.escape(sec.advice)}</p>")
    for b in sb:
        out.append(f"<p class='verdict {_verdict_class(v)}'>{html.escape(bound_text(b, labels))}."
                   + (f" {html.escape(b['note'][0].upper() + b['note'][1:])}." if b.get("note") else "")
                   + (f" <span class='muted'>Emulated truth: {b['truth']:.4g} {html.escape(b.get('unit', ''))}"
                      f"</span>" if b.get("truth") is not None else
                      f" <span class='muted'>Emulated truth: {html.escape(b['truth_note'])}</span>"
                      if b.get("truth_note") else "") + "</p>")
    for key in sec.figures:
        for caption, src in figs_png.get(key, []):
            out.append(f"<figure><img alt='{html.escape(caption)}' src='{src}'/><figcaption>{html.escape(caption)}"
                       f"</figcaption></figure>")
    if mine:
        out.append(_estimates_table(mine, labels))
    out.append(_thesis_table(thesis_rows(sec, mine, beside_the_thesis(res), labels)))
    out.append("</section>")
    return "".join(out)


def _diagnosis_html(diag: dict | None, acc: dict | None = None) -> str:
    """The diagnosis section (present when the session was reprocessed with ``--diagnose``); its floor is the
    accuracy's (one floor per pose set), named rather than stated again when ``acc`` has it."""
    if not diag:
        return ""
    same = same_floor(acc, diag)
    floor = "the instrument floor stated above" if same else \
        f"an instrument floor of {diag['noise_floor_mm']:.3f} mm"
    rows = "".join(
        f"<tr><td class='name'>{html.escape(f['label'])}</td><td>{f['rms_after_mm']:.3f}</td>"
        f"<td>{f.get('p_value', float('nan')):.2g}</td><td>{100 * (f.get('excess_share') or 0):.0f} %</td>"
        f"<td class='name {'weakly' if f.get('doubtful') else 'determined'}'>{html.escape(finding_flags(f) or 'stable')}"
        f"</td></tr>" for f in diag.get("findings", []))
    table = ("<table><tr><th class='name'>finding</th><th>held-out RMS after (mm)</th><th>p</th>"
             f"<th>share of the excess</th><th class='name'>flags</th></tr>{rows}</table>") if rows else \
        "<p>No unmodelled effect found.</p>"
    unexplained = diag.get("unexplained")
    un = f"<p class='verdict weakly'>Unexplained: {html.escape(str(unexplained))}</p>" if unexplained else ""
    return (f"<section id='diagnosis'><h2>Diagnosis of the sim-to-real gap</h2>"
            f"<p>On poses each fit did not use: {diag['baseline_rms_mm']:.3f} mm RMS with the geometry alone, "
            f"{diag['final_rms_mm']:.3f} mm with the findings below, against {floor} — {html.escape(str(diag.get('stop_reason', '')))}.</p>{table}{un}"
            "<p class='muted'>A finding is accepted only when it is significant, shrinks the held-out excess over "
            "the floor materially and keeps its parameters across folds; <i>doubtful</i> marks one that the data "
            "cannot tell apart from another candidate (its alias), whose stated error exceeds a quarter of its value, "
            "or whose own driver still orders the residual beyond the noise.</p></section>")


def _estimation_errors(est: list[dict], labels=None):
    rows = [e for e in est if e.get("truth") is not None and e["error"] > 0 and not e.get("held")]
    if not rows:
        return None
    plt = _plt()
    z = [(e["value"] - e["truth"]) / e["error"] for e in rows]
    fig, ax = plt.subplots(figsize=(8, 3))
    ax.bar(range(len(z)), np.clip(z, -10, 10))
    ax.axhline(2, color="r", lw=0.6), ax.axhline(-2, color="r", lw=0.6)
    ax.set_xticks(range(len(z)), [describe(e["name"], labels).name for e in rows], rotation=90, fontsize=6)
    ax.set_ylabel("(estimate − truth) / error (1)")
    med = float(np.median(np.abs(z)))
    return (f"Estimation errors against the emulated truth (clipped at 10): median |z| {med:.2f}, 0.67 is honest", fig)


def _provenance_html(res: dict) -> str:
    prov = res.get("provenance") or {}
    items = "".join(f"<tr><th class='name'>{html.escape(k)}</th><td class='name'>{html.escape(v)}</td></tr>"
                    for k, v in provenance_rows(prov))
    return f"<section id='provenance'><h2>Provenance</h2><table>{items}</table></section>"


def provenance_rows(prov: dict) -> list[tuple[str, str]]:
    """The provenance as people read it: a time (``..._unix_s``) as ISO 8601 with its zone and a duration
    (``..._s``) in seconds to three digits, under their names without the unit; every other entry as it is."""
    out = []
    for k, v in prov.items():
        key, number = str(k), isinstance(v, (int, float)) and not isinstance(v, bool)
        if key.endswith("_unix_s") and number:
            out.append((key[: -len("_unix_s")], when(v)))
        elif key.endswith("_s") and number:
            out.append((key[: -len("_s")], f"{v:.3g} s"))
        else:
            out.append((key, str(v)))
    return out


def render_figures(res: dict) -> dict[str, list[tuple[str, object]]]:
    f = res.get("figures", {})
    out = {}
    for key, fn in FIGURES.items():
        try:
            out[key] = fn(f, res)
        except (KeyError, ValueError, TypeError, IndexError):       # a figure never stops the report
            out[key] = []
    return out


def report_html(res: dict, tolerance_mm: float | None = None, record=None) -> str:
    """The whole report as one HTML document (figures embedded)."""
    figs = {k: [(c, _png(fig)) for c, fig in v] for k, v in render_figures(res).items()}
    body = [f"<h1>Calibration report</h1><p class='muted'>robocal — {html.escape(res['session']['title'])}</p>",
            f"<p class='muted' id='legend'>{html.escape(legend(beside_the_thesis(res)))}</p>",
            _answer(res, record, tolerance_mm, figs)]
    present = [sec for sec in SECTIONS if shows(sec, res)]
    body += [_section_html(sec, res, record, figs) for sec in present]
    body.append(iso_html(res))                              # ISO 9283 AP and RP per pose, off and on
    body.append(_diagnosis_html(res.get("diagnosis"), res.get("accuracy")))
    known = {p for sec in present for p in section_problems(sec, res.get("problems", []))}
    others = [p for p in res.get("problems", []) if p not in known]
    if others:
        body.append("<section id='notes'><h2>Notes</h2><ul>" + "".join(f"<li>{html.escape(p)}</li>" for p in others)
                    + "</ul></section>")
    ee = _estimation_errors(res.get("estimates", []), res.get("joint_labels"))
    if ee is not None:
        body.append(f"<section id='honesty'><h2>Are the stated errors honest?</h2><figure><img alt='estimation "
                    f"errors' src='{_png(ee[1])}'/><figcaption>{html.escape(ee[0])}</figcaption></figure></section>")
    body.append(_provenance_html(res))
    return ("<!doctype html><html lang='en'><head><meta charset='utf-8'><meta name='viewport' "
            "content='width=device-width, initial-scale=1'><title>robocal calibration report</title>"
            f"<style>{STYLE}</style></head><body>" + "".join(body) + "</body></html>")


def write_report(result: dict, out_dir: str | Path, tolerance_mm: float | None = None, pdf: bool = False) -> Path:
    """Write ``report.html``, ``results.json`` and ``robot.json`` (identified description) into ``out_dir``; with
    ``pdf`` also ``report.pdf``: the same HTML printed (:mod:`offline.pdf`), so both are one document."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    record = None
    path_db = result.get("session", {}).get("path")
    if path_db:
        try:
            record = session_record(path_db)
        except Exception:                     # noqa: BLE001 - the report stands without the step counts
            record = None
    path = out / "report.html"
    atomic_write_text(path, report_html(result, tolerance_mm, record))
    atomic_write_text(out / "results.json", json.dumps({k: v for k, v in result.items() if k != "figures"}, indent=1))
    if result.get("robot"):
        atomic_write_text(out / "robot.json", json.dumps(result["robot"], indent=1))
    if pdf:
        html_to_pdf(path, out / "report.pdf")
    return path
