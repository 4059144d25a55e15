"""The terminal summary of a reprocessed session: the accuracy before and after, then a few lines per procedure (full
names, degrees for angles, a verdict), so an operator on an 80-column terminal reads the answer at a glance.  The full
table of every estimate goes to the JSON and the report, or to the terminal with ``--verbose``."""
from __future__ import annotations

import os
import sys
from typing import TYPE_CHECKING

from calib.kinds import describe

from offline.iso_report import iso_lines
from offline.numbers import legend, below_floor_sentence, same_floor, value_pm
from offline.sections import DETERMINED, HELD, NEGLIGIBLE, SECTIONS, UNDETERMINED, WEAK, beside_the_thesis, bound_text, \
    needs_action, section_bounds, section_estimates, section_problems, section_verdict, shown, shows, verdict_of

if TYPE_CHECKING:
    from rich.console import Console
    from rich.table import Table

#: a section with at most this many estimates lists them all; a larger one shows its counts and weakest few
LIST_UP_TO = 6
WEAKEST = 3
_COLOUR = {DETERMINED: "green", NEGLIGIBLE: "green", WEAK: "yellow", UNDETERMINED: "red"}
NAME_WIDTH = 34


def _value_text(e: dict, labels=None) -> str:
    """``value ± error unit`` rounded to the error, then the truth (rounded alike) and the deviation in σ."""
    s = shown(e, labels)
    text = s.value_text
    if s.extra:
        text += f" ({s.extra})"
    if e.get("single_slope"):
        text += " one slope over every load"
    if s.truth is not None and s.error:
        text += f"  truth {s.beside(s.truth)} ({s.sigmas(s.truth):+.1f}σ)"
    return text


def _estimate_lines(e: dict, labels, lead: str = "") -> list[tuple[str, str]]:
    """An estimate's line (its name, value, unit) and, below it, what it means."""
    s = shown(e, labels)
    out = [("", f"  {lead}{s.name:<{NAME_WIDTH}} {_value_text(e, labels)}")]
    if s.meaning:
        out.append(("dim", f"  {' ' * len(lead)}  {s.meaning}"))
    return out


def _bound_truth(b: dict) -> str:
    """The emulated truth beside a bound: its value, or what the twin's scenario says instead (a rigid link)."""
    if b.get("truth") is not None:
        return f"  truth {b['truth']:.3g} ({'inside' if b['truth'] >= b['value'] else 'OUTSIDE'} the bound)" \
            if b.get("side", "lower") == "lower" else f"  truth {b['truth']:.3g}"
    return f"  truth: {b['truth_note']}" if b.get("truth_note") else ""


def accuracy_lines(acc: dict | None, tolerance_mm: float | None = None) -> list[str]:
    """The accuracy before and after on held-out poses, the one instrument floor, and why "after" may be below it."""
    if not acc:
        return ["accuracy: not measured (no pose set, or too few poses to hold some out)"]
    lines = [f"accuracy on {acc['n_test']} held-out poses: before {acc['before_rms_mm']:.3f} mm RMS, after "
             f"{acc['after_rms_mm']:.3f} mm RMS (95 % {acc['after_p95_mm']:.3f}, max {acc['after_max_mm']:.3f} mm); "
             f"instrument floor {acc['floor_mm']:.3f} mm"]
    why = below_floor_sentence(acc)
    if why:
        lines.append(why)
    return lines + tolerance_lines(acc, tolerance_mm)


def tolerance_lines(acc: dict | None, tolerance_mm: float | None) -> list[str]:
    """Whether the held-out poses meet a position tolerance (none without a tolerance or an accuracy)."""
    if not acc or tolerance_mm is None:
        return []
    if acc["after_max_mm"] <= tolerance_mm:
        return [f"tolerance {tolerance_mm:g} mm: met on every held-out pose"]
    return [f"tolerance {tolerance_mm:g} mm: NOT met (max {acc['after_max_mm']:.3f} mm)"]


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


def diagnosis_lines(diag: dict | None, acc: dict | None = None) -> list[tuple[str, str]]:
    """The diagnosis of the pose set in a few lines: the gap, each finding with its flags, what is unexplained.  The
    instrument floor is the accuracy's (one floor per pose set): named, not stated a second time, when ``acc`` has
    it."""
    if not diag:
        return []
    same = same_floor(acc, diag)
    floor = "against the instrument floor above" if same else f"instrument floor {diag['noise_floor_mm']:.3f} mm"
    out = [("bold", f"Diagnosis of the sim-to-real gap: held-out {diag['baseline_rms_mm']:.3f} mm with the geometry "
                    f"alone, {diag['final_rms_mm']:.3f} mm with the findings, {floor} "
                    f"({diag.get('stop_reason', '')})")]
    for f in diag.get("findings", []):
        flags = finding_flags(f)
        out.append(("yellow" if f.get("doubtful") else "", f"  {f['label']}: held-out RMS {f['rms_after_mm']:.3f} mm"
                    + (f" — {flags}" if flags else "")))
    if diag.get("unexplained"):
        out.append(("yellow", f"  unexplained: {diag['unexplained']}"))
    return out


def _section_lines(sec, res: dict) -> list[tuple[str, str]]:
    """A section's verdict line, its bounds, its estimates (all of a small section; the counts, the weakest few
    and the held ones of a large one), what to do and its notes."""
    est, probs, bounds = res.get("estimates", []), res.get("problems", []), res.get("bounds", [])
    labels = res.get("joint_labels")
    mine, sp, sb = section_estimates(sec, est), section_problems(sec, probs), section_bounds(sec, bounds)
    if not mine and not sp and not sb:
        return []
    v, why = section_verdict(sec, est, probs, bounds, beside_the_thesis(res), labels)
    out = [(f"bold {_COLOUR[v]}", f"{sec.title}: {v}" + ("" if v == DETERMINED else f" — {why}"))]
    out += [("", f"  {bound_text(b, labels)}" + _bound_truth(b)) for b in sb]
    held = [e for e in mine if e.get("held")]
    estimated = [e for e in mine if not e.get("held")]
    if len(mine) <= LIST_UP_TO:
        for e in estimated:
            out += _estimate_lines(e, labels)
    else:
        counts = {k: sum(verdict_of(e) == k for e in estimated) for k in (DETERMINED, WEAK, UNDETERMINED)}
        counts["held"] = len(held)
        out.append(("", f"  {len(mine)} estimates: " + ", ".join(f"{n} {k}" for k, n in counts.items() if n)))
        rank = {DETERMINED: 0, WEAK: 1, UNDETERMINED: 2}
        weakest = sorted(estimated, key=lambda e: -rank[verdict_of(e)])
        for e in [e for e in weakest if verdict_of(e) != DETERMINED][:WEAKEST]:
            out += _estimate_lines(e, labels, "weakest: ")
    if held:
        out.append(("dim", f"  {HELD}: " + ", ".join(shown(e, labels).name for e in held)))
    if needs_action(v) and sec.advice:
        out.append(("dim", f"  what to do: {sec.advice}"))
    out += [("yellow", f"  note: {p.split(':', 1)[1].strip()}") for p in sp if p.split(":", 1)[1].strip() != why]
    return out


def summary_lines(res: dict) -> list[tuple[str, str]]:
    """(style, text) lines of the compact summary: the title, the legend, the accuracy, one block per section, the
    diagnosis and the notes no section took."""
    out: list[tuple[str, str]] = [("bold", f"{res['session']['title']}"), ("dim", legend(beside_the_thesis(res)))]
    out += [("bold", line) for line in accuracy_lines(res.get("accuracy"))]
    out += [("bold", line) for line in iso_lines(res)]              # ISO 9283 AP and RP, off and on
    shown_sections = [sec for sec in SECTIONS if shows(sec, res)]
    for sec in shown_sections:
        out += _section_lines(sec, res)
    out += diagnosis_lines(res.get("diagnosis"), res.get("accuracy"))
    probs = res.get("problems", [])
    known = {p for sec in shown_sections for p in section_problems(sec, probs)}
    out += [("yellow", f"note: {p}") for p in probs if p not in known]
    return out


#: the verbose table carries each estimate's meaning when the terminal is at least this wide (the summary and the
#: report always do); on a narrow one it would fold every row into a column of single words
MEANING_COLUMNS = 140


def estimates_table(res: dict, width: int = MEANING_COLUMNS) -> Table:
    """Every estimate in one table (``--verbose``): its name, value ± 1σ, unit, truth, verdict and, on a terminal
    ``width`` wide enough, its meaning."""
    # rich costs 0.05-0.08 s to import: only the verbose table and a terminal's styles need it
    from rich.table import Table

    meaning = width >= MEANING_COLUMNS
    t = Table(title=f"estimates from {res['session']['title']}")
    t.add_column("estimate", overflow="fold")
    for c in ("value ± 1σ", "unit", "truth"):
        t.add_column(c, no_wrap=True)
    t.add_column("verdict", overflow="fold")
    if meaning:
        t.add_column("meaning", overflow="fold")
    for row in estimate_rows(res):
        t.add_row(*(row if meaning else row[:-1]))
    return t


def estimate_rows(res: dict) -> list[tuple[str, str, str, str, str, str]]:
    """(name, value ± 1σ, unit, truth, verdict, meaning) of every estimate, then every one-sided bound, as people
    read them: the rows of the verbose table and of the operator's results table."""
    labels = res.get("joint_labels")
    rows = []
    for e in res.get("estimates", []):
        s = shown(e, labels)
        value = f"{s.value:.6g}" if s.error is None else value_pm(s.value, s.error)
        rows.append((s.name, value, s.unit_text, "" if s.truth is None or s.error is None else s.beside(s.truth),
                     s.verdict, s.meaning))
    for b in res.get("bounds", []):                  # no effect measurable: a one-sided bound
        d = describe(b["name"], labels)
        sign = "≥" if b.get("side", "lower") == "lower" else "≤"
        rows.append((d.name, f"{sign} {b['value'] / d.scale:.3g} ({100 * b['confidence']:g} %, one-sided)",
                     d.unit_text, "" if b.get("truth") is None else f"{b['truth'] / d.scale:.3g}", NEGLIGIBLE,
                     d.meaning))
    return rows


def print_summary(res: dict, verbose: bool = False, console: Console | None = None) -> None:
    """The compact summary (default), after every estimate in one table (``verbose``).  Emoji codes are text (a
    note reading ``:ok:`` stays ``:ok:``).  Where rich would print no styles (standard output not a terminal, no
    FORCE_COLOR or TTY_COMPATIBLE=1) the lines are printed as rich prints them unstyled (:func:`unstyled`), without
    importing rich."""
    if console is None and not verbose and not styled_stdout():
        for _, text in summary_lines(res):
            print(unstyled(text))
        return
    # rich costs 0.05-0.08 s to import: only a terminal's styles and the verbose table need it
    from rich.console import Console

    console = console or Console(stderr=False)
    if verbose:
        console.print(estimates_table(res, console.width))
    for style, text in summary_lines(res):
        console.print(text, style=style or None, highlight=False, markup=False, soft_wrap=True, emoji=False)


def styled_stdout(environ=None) -> bool:
    """Whether rich would write styles to standard output: its terminal test (rich 13-15's ``Console.is_terminal``:
    TTY_COMPATIBLE 1/0, then a non-empty FORCE_COLOR, then ``isatty``), answered without importing rich."""
    env = os.environ if environ is None else environ
    if env.get("TTY_COMPATIBLE", "") in ("0", "1"):
        return env["TTY_COMPATIBLE"] == "1"
    if env.get("FORCE_COLOR") is not None:
        return env["FORCE_COLOR"] != ""
    try:
        return sys.stdout.isatty()
    except (AttributeError, ValueError):          # no stream, or one already closed
        return False


#: the control characters rich's Text leaves out (bell, backspace, vertical tab, form feed, carriage return)
_CONTROL = dict.fromkeys((7, 8, 11, 12, 13))


def unstyled(text: str) -> str:
    """``text`` as rich's console prints it without styles (markup, highlighting and emoji off, soft wrap): control
    characters dropped and tabs expanded to 8 columns (a test holds the two equal)."""
    return text.translate(_CONTROL).expandtabs(8)
