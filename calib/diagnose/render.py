"""The diagnosis as text tables for the terminal (what the operator reads first)."""
from __future__ import annotations

from ..names import prose, quantity_words
from .engine import Diagnosis
from .findings import DOUBTFUL_SPREAD

from calib.accuracy import before_after_line


def _p(p: float) -> str:
    return f"{p:.2g}" if p == p else "-"


def render(d: Diagnosis, max_factor_rows: int = 40) -> str:
    j = d.to_json()
    first = f"robocal diagnose {j['source']}: "
    if "before" in j:
        first += before_after_line(j)
    rows = f" ({j['rows']} measured points)" if j.get("rows", j["poses"]) != j["poses"] else ""
    out = [first, f"{j['poses']} poses{rows}, robot {j['robot']}; held-out test: {j['heldout']}; geometric parameter set: "
                  f"{j['geometry_level']}; point noise from {j['noise_from']}", ""]
    out += ["1. The gap (geometric model, poses it was not fitted to)",
            f"   held-out RMS {j['baseline_rms_mm']:.4f} mm, max {j['baseline_max_mm']:.4f} mm",
            f"   noise floor of the instruments {j['noise_floor_mm']:.4f} mm "
            f"(held-out floor with parameter noise {j['heldout_floor_mm']:.4f} mm)",
            f"   excess over the floor: {j['baseline_rms_mm'] - j['noise_floor_mm']:+.4f} mm"]
    if j.get("reduced_chi2_words"):
        out.append(f"   final fit: {j['reduced_chi2_words']}")
    out.append("")
    out.append("2. Where it lies (held-out residual RMS in mm by condition; p: Kruskal-Wallis over the groups, "
               "small = the gap depends on it)")
    rows = 0
    for f in sorted(d.factors, key=lambda f: f.p_value if f.p_value == f.p_value else 1.0):
        if rows >= max_factor_rows:
            out.append("   ... (see --json or --report for every factor)")
            break
        out.append(f"   {f.name}  (p = {_p(f.p_value)}, strongest in the {f.statistic})")
        out.append(f"     {'group':<28}{'n':>5}{'geometric':>12}{'final':>10}{'max':>10}")
        for g in f.groups:
            out.append(f"     {g.label:<28}{g.n:>5}{g.rms_before_mm:>12.4f}{g.rms_after_mm:>10.4f}"
                       f"{g.max_before_mm:>10.4f}")
            rows += 1
    out.append("")
    out.append("3. Which effect (greedy forward selection; score: held-out gap; test: nested F, Bonferroni)")
    if not j["findings"]:
        out.append("   no unmodelled effect found")
    for i, f in enumerate(j["findings"], 1):
        pars = ", ".join(_quantity(k, v) for k, v in f["parameters"].items()
                         if isinstance(v, (int, float)) and "sigma_" not in k and not k.endswith("_sigma"))
        out.append(f"   {i}. {f['label']}: held-out RMS -> {f['rms_after_mm']:.4f} mm, p = {_p(f['p_value'])}; "
                   f"{pars}")
        flags = [f"fold spread {100 * f['stability']:.0f} %" if f["stability"] is not None
                 else "fold spread not measured (the data's own split: one fit)"]
        if f.get("stated_spread") is not None and f["stated_spread"] > DOUBTFUL_SPREAD:
            flags.append(f"stated error {100 * f['stated_spread']:.0f} % of the value")
        if f["aliases"]:
            flags.append("looks like " + ", ".join(f["aliases"]) + " (the data cannot tell them apart)")
        if f.get("leftover"):
            flags.append(f["leftover"])
        out.append(f"      {'DOUBTFUL: ' if f['doubtful'] else ''}" + "; ".join(flags))
    out.append(f"   stopped: {j['stop_reason']}")
    if j["not_tested"]:
        out.append("   not tested:")
        out += [f"     - {s}" for s in j["not_tested"]]
    if j["guard_notes"]:
        out.append("   held back by the guard:")
        out += [f"     - {s}" for s in j["guard_notes"][:12]]
        if len(j["guard_notes"]) > 12:
            out.append(f"     - ... {len(j['guard_notes']) - 12} more")
    out.append("")
    out.append("4. How far it shrinks")
    if d.ladder is not None:
        out.append(f"   the model step by step, each step refitted and scored on the held-out rows ("
                   f"{d.ladder.protocol}; mm)")
        out += d.ladder.lines(d.data.robot)
        u = j.get("uncertainty") or {}
        if u.get("median_abs_z") is not None:
            out.append(f"   predicted sigma of the held-out points: median |error|/sigma {u['median_abs_z']:.2f} "
                       f"(0.67 when honest), {100 * u['within_2sigma']:.0f} % within 2 sigma (95 % when honest)")
    out.append(f"   geometric {j['baseline_rms_mm']:.4f} mm" + "".join(
        f" -> +{f['label']} {f['rms_after_mm']:.4f} mm" for f in j["findings"]))
    shrink = j["excess_gap_shrink"]
    out.append(f"   final held-out RMS {j['final_rms_mm']:.4f} mm (max {j['final_max_mm']:.4f}) against the "
               f"instruments' floor {j['noise_floor_mm']:.4f} mm" + (f"; {100 * shrink:.0f} % of the excess gap removed"
                                                  if shrink == shrink else ""))
    u = j["unexplained"]
    if u and u["gap_left"]:
        out.append(f"   unexplained: {u['excess_mm']:.4f} mm above {u['floor_is']} {u['floor_mm']:.4f} mm -- something none "
                   f"of the accepted effects describes is left (or the noise model is optimistic)")
    elif u:
        out.append("   unexplained cause: the gap is closed, but by " + ", ".join(x["finding"] for x in u["stand_in"])
                   + ", which only stands in for something outside the effect library (flagged doubtful above)")
    if u:
        if u["where"]:
            out.append("     where: " + "; ".join(f"{w['factor']} (p = {_p(w['p_value'])})" for w in u["where"]))
        for c in u["closest_candidates"]:
            out.append(f"     closest: {c['candidate']} (held-out {c['rms_mm']:.4f} mm): {c['reason']}")
    if j["noise_estimated_mm"] is not None:
        ne = j["noise_estimate"]
        out.append(f"   noise per coordinate: given {ne['given_mm']:.4f} mm, from the data {ne['estimated_mm']:.4f} mm "
                   f"({ne['from']})")
    if d.noise is not None:
        out += [f"   note: {line}" for line in d.noise.set_aside_lines()]
    out += [f"   note: {line}" for line in d.outlier_report.lines()]
    if j.get("confirmation"):
        out += [""] + render_confirmation(j["confirmation"])
    for n in j["notes"]:
        out.append(f"   note: {n}")
    return prose("\n".join(out), d.data.robot)        # joints as the description names them (calib.names)


def _params(p: dict | None) -> str:
    """A refit's parameters as ``name value +- sigma`` (edge units), '-' when the session could not fit them."""
    if not p:
        return "-"
    keys = [k for k in p if not k.endswith("_sigma") and "sigma_" not in k and isinstance(p[k], (int, float))]
    parts = []
    for k in keys:
        sig = next((p[c] for c in [f"{k}_sigma"] + [k[:i] + "_sigma" + k[i:] for i in range(len(k)) if k[i] == "_"]
                    if c in p), None)
        word, unit = quantity_words(k)
        parts.append(f"{word} {p[k]:.4g}" + (f" +- {sig:.2g}" if isinstance(sig, (int, float)) else "")
                     + (f" {unit}" if unit else ""))
    return ", ".join(parts)


def render_confirmation(sessions: list[dict]) -> list[str]:
    """Section 5: per finding a table of the sessions (RMS before and after it, confirmed, its parameters refitted
    on that session alone and whether they agree with the diagnosed data's)."""
    out = ["5. Confirmed on other sessions (base re-located on each; the findings' parameters as fitted on the data, "
           "then refitted on each session alone)",
           f"   {'session':<48}{'poses':>6}{'geometric':>11}{'final':>9}"]
    for c in sessions:
        fin = f"{c['final_rms_mm']:.4f}" if c.get("final_rms_mm") is not None else "-"
        out.append(f"   {c['source'][-48:]:<48}{c['poses']:>6}{c['geometric_rms_mm']:>11.4f}{fin:>9}")
    for k, f in enumerate(sessions[0]["findings"] if sessions else []):
        name = f" ({f['joint_name']})" if f.get("joint_name") else ""
        train = (f.get("refit") or {}).get("training")
        out += ["", f"   {f['label']}{name}: fitted on the data {_params(train)}",
                f"     {'session':<40}{'before':>9}{'with it':>9}{'shrink mm':>10}  {'confirmed':<14}"
                f"refitted on the session alone"]
        for c in sessions:
            g = c["findings"][k]
            r = g.get("refit")
            agree = "" if not r else ("  agrees" if r["agree"] else "  DISAGREES")
            out.append(f"     {c['source'][-40:]:<40}{g['rms_before_mm']:>9.4f}{g['rms_after_mm']:>9.4f}"
                       f"{g['shrink_mm']:>+10.4f}  {'yes' if g['confirmed'] else 'NOT confirmed':<14}"
                       f"{_params(r['session'] if r else None)}{agree}")
    return out


def _quantity(key: str, value: float) -> str:
    """``width_deg``, 1.726 -> ``width 1.726 deg``: a parameter in words with its unit."""
    word, unit = quantity_words(key)
    return f"{word} {value:.4g}" + (f" {unit}" if unit else "")
