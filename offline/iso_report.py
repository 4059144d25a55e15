"""ISO 9283 pose accuracy and repeatability in words: the terminal lines and the report's section, from the results'
``iso9283`` (:mod:`offline.reduction.stages.iso9283`) -- one source, so the terminal and the report say the same."""
from __future__ import annotations

import html

#: the definitions, cited, in one sentence (positions only: theodolites measure points)
DEFINITIONS = ("Pose accuracy AP (ISO 9283:1998 §7.2.1) is the distance from the commanded position to the "
               "barycentre of the positions attained over the cycles; pose repeatability RP (§7.2.2) is l̄ + 3 S_l, "
               "the mean distance l̄ of the attained positions from their barycentre plus three standard deviations "
               "S_l of those distances (positions only: the theodolites measure points, not orientations).")
RUNS = (("uncompensated", "compensation off"), ("compensated", "compensation on"))


def _range(rows: list[dict], key: str) -> str:
    lo, hi = min(r[key] for r in rows), max(r[key] for r in rows)
    return f"{hi:.3f} mm" if abs(hi - lo) < 5e-4 else f"{lo:.3f}-{hi:.3f} mm"


def _how(iso: dict, figs: dict | None) -> str:
    rows = next((iso[k] for k, _ in RUNS if iso.get(k)), [])
    n = max((r["n"] for r in rows), default=0)
    side = (figs or {}).get("side_mm")
    return f"{len(rows)} poses, {n} cycles each" + (f", cube side {side:g} mm" if side else "")


def iso_lines(res: dict) -> list[str]:
    """One or two terminal lines: AP and RP over the poses, compensation off and on (nothing when not measured)."""
    iso = res.get("iso9283")
    if not iso or not any(iso.get(k) for k, _ in RUNS):
        return []
    parts = [f"{words}: AP {_range(iso[k], 'ap_mm')}, RP {_range(iso[k], 'rp_mm')}" for k, words in RUNS if iso.get(k)]
    return [f"ISO 9283 (AP §7.2.1, RP §7.2.2; {_how(iso, res.get('figures', {}).get('iso9283'))}): "
            + "; ".join(parts) + at_floor(res)]


def at_floor(res: dict) -> str:
    """A clause when every compensated AP is within twice the instruments' stated floor (their 3-D point error,
    RMS): the measured figure is then of the order of the instruments' error, an upper bound on the robot's own
    (on the demo's twin the true compensated AP is 0.02-0.05 mm, the measured 0.08-0.13 mm)."""
    floor = (res.get("accuracy") or {}).get("floor_mm")
    on = (res.get("iso9283") or {}).get("compensated") or []
    if floor is None or not on or max(r["ap_mm"] for r in on) >= 2.0 * floor:
        return ""
    return (f" (compensated AP of the order of the instrument floor {floor:.3f} mm: mostly the instruments' error, "
            "an upper bound on the robot's)")


def iso_html(res: dict) -> str:
    """The report's ISO 9283 section: AP and RP per pose, off and on, with the definitions cited."""
    iso = res.get("iso9283")
    if not iso or not any(iso.get(k) for k, _ in RUNS):
        return ""
    by_pose: dict[str, dict] = {}
    for key, _ in RUNS:
        for r in iso.get(key) or []:
            by_pose.setdefault(r["pose"], {})[key] = r

    def cells(r: dict | None) -> str:
        return "<td>-</td><td>-</td>" if r is None else f"<td>{r['ap_mm']:.3f}</td><td>{r['rp_mm']:.3f}</td>"

    rows = "".join(f"<tr><td class='name'>{html.escape(p)}</td>" + "".join(cells(v.get(k)) for k, _ in RUNS)
                   + "</tr>" for p, v in sorted(by_pose.items()))
    head = "".join(f"<th>AP {w} (mm)</th><th>RP {w} (mm)</th>" for _, w in RUNS)
    return (f"<section id='iso9283'><h2>ISO 9283 pose accuracy and repeatability</h2>"
            f"<p>The five poses of the ISO 9283 test cube ({html.escape(_how(iso, res.get('figures', {}).get('iso9283')))}"
            f"), each approached from one direction, sighted with both theodolites; compensation off commands the "
            f"nominal joint command, compensation on the calibrated model's command for the same point.</p>"
            f"<table><tr><th class='name'>pose</th>{head}</tr>{rows}</table>"
            + (f"<p>{html.escape(_sentence(at_floor(res)))}</p>" if at_floor(res) else "")
            + f"<p class='muted'>{html.escape(DEFINITIONS)}</p></section>")


def _sentence(clause: str) -> str:
    text = clause.strip(" ()")
    return text[:1].upper() + text[1:] + "."
