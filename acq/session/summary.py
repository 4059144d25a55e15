"""The terminal summary of a reprocessed session: the accuracy before and after, then a few lines per procedure (full
names, degrees for angles, a verdict), so an operator on an 80-column terminal reads the answer at a glance.  The full
table of every estimate goes to the JSON and the report, or to the terminal with ``--verbose``."""
from __future__ import annotations

import math

from rich.console import Console
from rich.table import Table

from .iso_report import iso_lines
from .sections import DETERMINED, NEGLIGIBLE, SECTIONS, UNDETERMINED, WEAK, beside_the_thesis, bound_text, \
    needs_action, section_bounds, section_estimates, section_problems, section_verdict, shown, shows, verdict_of

#: a section with at most this many estimates lists them all; a larger one shows its counts and weakest few
LIST_UP_TO = 6
WEAKEST = 3
_COLOUR = {DETERMINED: "green", NEGLIGIBLE: "green", WEAK: "yellow", UNDETERMINED: "red"}


def _short_name(e: dict) -> str:
    """The name within its section (the section's heading says the procedure): ``ruler.L`` -> ``L``."""
    return shown(e).name.split(".", 1)[-1]


def value_pm(value: float, error: float | None) -> str:
    """``value ± error`` with the error to two significant digits and the value to the same decimal place (the
    metrologist's convention); magnitudes far from 1 in exponent form."""
    if error is None or not math.isfinite(error) or error <= 0:
        return f"{value:.6g}" + ("" if error is None else f" ± {error:.2g}")
    if abs(value) >= 1e6 or (0 < abs(value) < 1e-3 and error < 1e-3):
        return f"{value:.4g} ± {error:.2g}"
    decimals = 1 - int(math.floor(math.log10(error)))
    if decimals > 0:
        return f"{value:.{decimals}f} ± {error:.{decimals}f}"
    step = 10.0 ** (-decimals)
    return f"{round(value / step) * step:.0f} ± {round(error / step) * step:.0f}"


def _value_text(e: dict) -> str:
    s = shown(e)
    text = (f"{s.value:.6g} held" if s.error is None else value_pm(s.value, s.error)) + (f" {s.unit}" if s.unit
                                                                                          else "")
    if s.extra:
        text += f" ({s.extra})"
    if e.get("single_slope"):
        text += " one slope over every load"
    if s.truth is not None and s.error:
        text += f"  truth {s.truth:.6g} ({(s.value - s.truth) / s.error:+.1f}σ)"
    return text


def _bound_truth(b: dict) -> str:
    """The emulated truth beside a bound: its value, or what the twin's scenario says instead (a rigid link)."""
    if b.get("truth") is not None:
        return f"  truth {b['truth']:.6g} ({'inside' if b['truth'] >= b['value'] else 'OUTSIDE'} the bound)" \
            if b.get("side", "lower") == "lower" else f"  truth {b['truth']:.6g}"
    return f"  truth: {b['truth_note']}" if b.get("truth_note") else ""


def accuracy_lines(acc: dict | None, tolerance_mm: float | None = None) -> list[str]:
    if not acc:
        return ["accuracy: not measured (no pose set, or too few poses to hold some out)"]
    lines = [f"accuracy on {acc['n_test']} held-out poses: before {acc['before_rms_mm']:.3f} mm RMS, after "
             f"{acc['after_rms_mm']:.3f} mm RMS (95 % {acc['after_p95_mm']:.3f}, max {acc['after_max_mm']:.3f} mm); "
             f"instrument floor {acc['floor_mm']:.3f} mm"]
    if tolerance_mm is not None:
        ok = acc["after_max_mm"] <= tolerance_mm
        lines.append(f"tolerance {tolerance_mm:g} mm: {'met' if ok else 'NOT met'} on every held-out pose"
                     if ok else f"tolerance {tolerance_mm:g} mm: NOT met (max {acc['after_max_mm']:.3f} mm)")
    return lines


def finding_flags(f: dict) -> str:
    """What a finding's flags say, in words (see docs/diagnosis.md)."""
    words = []
    if f.get("doubtful"):
        words.append("doubtful")
    if f.get("aliases"):
        words.append("looks like " + ", ".join(f["aliases"]))
    if f.get("stability") is not None:
        words.append(f"parameters vary {100 * f['stability']:.0f} % across folds")
    return "; ".join(words)


def diagnosis_lines(diag: dict | None) -> list[tuple[str, str]]:
    """The diagnosis of the pose set in a few lines: the gap, each finding with its flags, what is unexplained."""
    if not diag:
        return []
    out = [("bold", f"Diagnosis of the sim-to-real gap: held-out {diag['baseline_rms_mm']:.3f} mm with the geometry "
                    f"alone, {diag['final_rms_mm']:.3f} mm with the findings; instrument floor "
                    f"{diag['noise_floor_mm']:.3f} mm ({diag.get('stop_reason', '')})")]
    for f in diag.get("findings", []):
        flags = finding_flags(f)
        out.append(("yellow" if f.get("doubtful") else "", f"  {f['label']}: held-out RMS {f['rms_after_mm']:.3f} mm"
                    + (f" — {flags}" if flags else "")))
    if diag.get("unexplained"):
        out.append(("yellow", f"  unexplained: {diag['unexplained']}"))
    return out


def summary_lines(res: dict) -> list[tuple[str, str]]:
    """(style, text) lines of the compact summary."""
    out: list[tuple[str, str]] = [("bold", f"{res['session']['title']}")]
    out += [("bold", line) for line in accuracy_lines(res.get("accuracy"))]
    out += [("bold", line) for line in iso_lines(res)]              # ISO 9283 AP and RP, off and on
    est, probs, bounds = res.get("estimates", []), res.get("problems", []), res.get("bounds", [])
    shown_sections = [sec for sec in SECTIONS if shows(sec, res)]
    for sec in shown_sections:
        mine = section_estimates(sec, est)
        sp = section_problems(sec, probs)
        sb = section_bounds(sec, bounds)
        if not mine and not sp and not sb:
            continue
        v, why = section_verdict(sec, est, probs, bounds, beside_the_thesis(res))
        out.append((f"bold {_COLOUR[v]}", f"{sec.title}: {v}" + ("" if v == DETERMINED else f" — {why}")))
        out += [("", f"  {bound_text(b)}" + _bound_truth(b)) for b in sb]
        if len(mine) <= LIST_UP_TO:
            out += [("", f"  {_short_name(e):<12} {_value_text(e)}") for e in mine]
        else:
            counts = {k: sum(verdict_of(e) == k for e in mine if not e.get("held"))
                      for k in (DETERMINED, WEAK, UNDETERMINED)}
            counts["held"] = sum(bool(e.get("held")) for e in mine)
            out.append(("", f"  {len(mine)} estimates: " + ", ".join(f"{n} {k}" for k, n in counts.items() if n)))
            rank = {DETERMINED: 0, WEAK: 1, UNDETERMINED: 2}
            weakest = sorted((e for e in mine if not e.get("held")), key=lambda e: -rank[verdict_of(e)])
            for e in [e for e in weakest if verdict_of(e) != DETERMINED][:WEAKEST]:
                out.append(("", f"  weakest: {_short_name(e)} {_value_text(e)}"))
            held = [_short_name(e) for e in mine if e.get("held")]
            if held:
                out.append(("", "  held at design values: " + ", ".join(held)))
        if needs_action(v) and sec.advice:
            out.append(("dim", f"  what to do: {sec.advice}"))
        out += [("yellow", f"  note: {p.split(':', 1)[1].strip()}") for p in sp
                if p.split(":", 1)[1].strip() != why]
    out += diagnosis_lines(res.get("diagnosis"))
    known = {p for sec in shown_sections for p in section_problems(sec, probs)}
    out += [("yellow", f"note: {p}") for p in probs if p not in known]
    return out


def print_summary(res: dict, verbose: bool = False, console: Console | None = None) -> None:
    """The compact summary (default) or every estimate in one table (``verbose``)."""
    console = console or Console(stderr=False)
    if verbose:
        t = Table(title=f"estimates from {res['session']['title']}")
        for c in ("name", "value", "error (1 sigma)", "unit", "truth", "verdict"):
            t.add_column(c, overflow="fold")
        for e in res["estimates"]:
            s = shown(e)
            t.add_row(e["name"], f"{s.value:.6g}", "held" if s.error is None else f"{s.error:.2g}", s.unit,
                      "" if s.truth is None else f"{s.truth:.6g}", s.verdict)
        console.print(t)
    for style, text in summary_lines(res):
        console.print(text, style=style or None, highlight=False, markup=False, soft_wrap=True)
