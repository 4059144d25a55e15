"""Every result in words and units (issue 26, item 5), checked on what a person reads: the terminal summary (compact
and ``--verbose``) and the HTML report of the stored demo session ``examples/demo-session.db``.

Nothing here compares with the formatter's own tables: the checks are on the printed text -- no code name of a
parameter (``dh.j1``, ``ident.``, ``rad_per_count``, ``further45``) reaches it, every ``value ± error`` is followed by
a unit or the word dimensionless, the value has exactly the decimals of its error's second significant digit, a
truth beside it is rounded the same way, the legend is said once, the instrument floor is stated once, no time is
seconds since 1970, held parameters are shown as held and do not weaken their section, and a difference from the
thesis beyond 3σ is explained or, for another robot, not shown."""
from __future__ import annotations

import copy
import html
import io
import math
import re
from pathlib import Path

import pytest
from rich.console import Console

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "demo-session.db"

#: what a code name looks like: a section prefix with a dot, a joint token with a dot, internal unit suffixes
INTERNAL = re.compile(r"\b(?:dh|ident|misalign|comp|te|ruler|coupling|resolution|compliance|link|base|tool)\.\w"
                      r"|\bj\d+\.\w|rad_per|_per_nm|further\d|sigma\d\d|E_a_slope|\w_(?:rad|mm|nm|Nmm2|deg)\b")
#: the units a value may be followed by (display units of the report's and the summary's estimates)
UNITS = ("mm", "deg", "cycles/rev", "%", "N m/rad", "N m", "deg/deg", "arcsec/count", "deg/(N m)", "dimensionless",
         "N mm²")
PM = re.compile(r"(?<![\w.])(-?\d+(?:\.\d+)?(?:e[+-]\d+)?) ± (\d+(?:\.\d+)?(?:e[+-]\d+)?)(?:[ |]+([^|\n(]*))?")
UNIX_TIME = re.compile(r"(?<![\d.])1[6-9]\d{8}(?:\.\d+)?(?![\d])")


@pytest.fixture(scope="module")
def result():
    from app.reprocess import reprocess
    return reprocess(str(EXAMPLE))


def terminal(res: dict, verbose: bool = False, width: int = 160) -> str:
    from offline.summary import print_summary
    buf = io.StringIO()
    print_summary(res, verbose=verbose, console=Console(file=buf, width=width, color_system=None))
    return buf.getvalue()


def visible(page: str) -> str:
    """The report's text as a browser shows it (no stylesheet, no embedded images), one table row a line."""
    page = re.sub(r"<style>.*?</style>", "", page, flags=re.S)
    page = re.sub(r"<img[^>]*>", "", page)
    page = re.sub(r"</(tr|p|h\d|li|div|section|figcaption|table)>", "\n", page)
    page = re.sub(r"</t[dh]>", " | ", page)
    return html.unescape(re.sub(r"<[^>]+>", "", page))


@pytest.fixture(scope="module")
def report_text(result, tmp_path_factory):
    from offline.report import write_report
    out = tmp_path_factory.mktemp("report")
    return visible(write_report(result, out).read_text(encoding="utf-8"))


def decimals(text: str) -> int:
    return len(text.split(".")[1]) if "." in text and "e" not in text else 0


def check_rounding(text: str) -> int:
    """Every line's first ``value ± error`` in fixed notation (robocal's; a thesis's number beside it is printed as
    the thesis printed it): the error has two significant digits and the value its decimals; returns how many were
    checked."""
    n = 0
    for v, e, _ in (m.groups() for m in map(PM.search, text.splitlines()) if m):
        if "e" in v or "e" in e:
            continue
        digits = e.replace(".", "").lstrip("0")
        assert len(digits) == 2 or float(e) >= 10, f"{v} ± {e}: the error is not to two significant digits"
        assert decimals(v) == decimals(e), f"{v} ± {e}: the value is not rounded to its error"
        n += 1
    return n


def test_no_code_name_reaches_the_terminal(result):
    for text in (terminal(result), terminal(result, verbose=True, width=220)):
        found = INTERNAL.findall(text)
        assert not found, found[:10]
        assert not UNIX_TIME.search(text)


def test_no_code_name_or_unix_time_reaches_the_report(report_text):
    found = INTERNAL.findall(report_text)
    assert not found, found[:10]
    assert not UNIX_TIME.search(report_text), UNIX_TIME.search(report_text)
    assert re.search(r"reprocessed \| \d{4}-\d\d-\d\dT\d\d:\d\d:\d\d[+-]\d\d:\d\d", report_text)


def test_every_value_has_a_unit_in_the_terminal(result):
    text = terminal(result)
    lines = [t for t in text.splitlines() if re.search(r"\d ± \d", t)]
    assert len(lines) >= 30
    for line in lines:
        m = re.search(r"\d ± \S+ (.*)", line)
        assert m and m.group(1).startswith(UNITS), f"no unit: {line!r}"


def test_every_value_has_a_unit_in_the_report(report_text):
    rows = [t for t in report_text.splitlines() if re.search(r"\d ± \d", t) and t.count("|") >= 4]
    assert len(rows) >= 100
    for row in rows:
        cells = [c.strip() for c in row.split("|")]
        i = next(k for k, c in enumerate(cells) if re.search(r"\d ± \d", c))
        after = cells[i].split(" ± ", 1)[1].split(" ", 1)
        unit = after[1] if len(after) > 1 else cells[i + 1]         # "1.2 ± 0.3 mm" or a unit column
        assert unit.startswith(UNITS), f"no unit: {row!r}"


def test_the_named_quantities_are_in_their_own_units(result, report_text):
    """The three the issue names: the transmission error's frequency in cycles per revolution, the encoder resolution
    in arc seconds per count (16.9″ for the twin's joint 6, not 0.0047 deg), the cross coupling in words."""
    text = terminal(result)
    for out in (text, report_text):
        assert re.search(r"joint 4 transmission-error frequency\D+0\.\d+ ± 0\.\d+[ |]+cycles/rev", out)
        res_line = re.search(r"joint 6 encoder resolution\D+(\d+\.\d+) ± [\d.]+[ |]+arcsec/count", out)
        assert res_line and 16.0 < float(res_line.group(1)) < 17.5
        assert "coupling σ56 (joint 6 per joint 5)" in out
        assert "further coupling correction σ45" in out


def test_numbers_are_rounded_to_their_error(result, report_text):
    assert check_rounding(terminal(result)) >= 30
    assert check_rounding(terminal(result, verbose=True, width=220)) >= 100
    assert check_rounding(report_text) >= 100


def test_a_truth_is_rounded_like_its_value_and_zero_is_0(result):
    """A truth of -2.8e-33 (a parameter the twin leaves at zero, computed) is printed 0, and every truth has the
    decimals of the value on its line."""
    from offline.summary import summary_lines
    res = copy.deepcopy(result)
    e = next(e for e in res["estimates"] if e["name"] == "ruler.hB_mm")
    e["truth"] = -2.75869e-33
    text = "\n".join(t for _, t in summary_lines(res))
    assert re.search(r"station B height hB +\S+ ± \S+ mm  truth 0 \(", text)
    assert "e-33" not in text
    n = 0
    for line in text.splitlines():
        m = re.search(r"(-?\d+\.?\d*) ± (\S+) .*truth (-?\d+\.?\d*) \(", line)
        if m and m.group(3) != "0":
            assert decimals(m.group(3)) == decimals(m.group(1)), line
            n += 1
    assert n >= 15


def test_the_legend_is_said_once_at_the_top(result, report_text):
    text = terminal(result)
    assert text.count("Legend:") == 1 and "Legend:" in "\n".join(text.splitlines()[:3])
    assert "(1σ)" in text and "units of that σ" in text
    assert report_text.count("Legend:") == 1
    assert report_text.index("Legend:") < report_text.index("The answer")


def test_one_instrument_floor(result, report_text):
    """The floor is stated once, and "after" below it is explained in a sentence (the stored session's after, 0.100
    mm, is below its floor, 0.122 mm)."""
    acc = result["accuracy"]
    assert acc["after_rms_mm"] < acc["floor_mm"]
    text = terminal(result)
    assert len(re.findall(r"floor \d", text)) == 1
    assert "After is below the instrument floor because" in text
    assert len(re.findall(r"instrument floor \| \d", report_text)) == 1
    assert report_text.count(f"{acc['floor_mm']:.3f}") == 1
    assert "After is below the instrument floor because" in report_text


def test_the_diagnosis_states_the_same_floor_not_a_second_one(result):
    """The accuracy's floor and the diagnosis's are one (the same points): the diagnosis names it."""
    from offline.summary import summary_lines
    res = {**result, "diagnosis": {"baseline_rms_mm": 0.267, "final_rms_mm": 0.103, "findings": [],
                                   "noise_floor_mm": result["accuracy"]["floor_mm"], "stop_reason": "at the floor"}}
    text = "\n".join(t for _, t in summary_lines(res))
    assert len(re.findall(r"floor \d", text)) == 1 and "against the instrument floor above" in text


def test_the_accuracy_floor_is_over_every_pose_of_the_set():
    """calib.accuracy states the floor of the whole pose set, the diagnosis's formula over the same points."""
    import numpy as np

    from calib.accuracy import before_after
    from calib.identify import PointObservations, default_free
    from calib.model import MeasurementModel
    from calib.loading import load_robot
    from tests.test_accuracy_report import generated_poses
    q, pts = generated_poses(40, 3, 0.02)
    cov = np.tile(np.eye(3), (40, 1, 1)) * (0.02 ** 2)
    cov[::2] *= 4.0                                 # every other pose twice as noisy: a subset would differ
    model = MeasurementModel(load_robot())
    acc = before_after(model, PointObservations(q, pts, cov_mm2=cov), default_free(model, effects=False))
    # every pose's 3-D variance 3 sigma^2, half of them four times that: the RMS over all 40, written out
    assert acc.floor_mm == pytest.approx(np.sqrt(3 * 0.02 ** 2 * (1 + 4) / 2), rel=1e-12)


def held_result(result) -> dict:
    """The stored session's results with the pose set's weak estimate made determined: only held ones are left."""
    res = copy.deepcopy(result)
    for e in res["estimates"]:
        if e["name"].startswith("ident.") and not e.get("held"):
            e["error"] = min(e["error"], 1e-4 * max(abs(e["value"]), 1e-6))
    return res


def test_held_parameters_are_held_not_failures(result, tmp_path):
    from offline.report import report_html
    from offline.summary import summary_lines
    res = held_result(result)
    assert sum(bool(e.get("held")) for e in res["estimates"]) >= 1
    lines = summary_lines(res)
    head = next((s, t) for s, t in lines if t.startswith("Identification from the pose set"))
    assert head[1].endswith(": determined") and "red" not in head[0]
    held = next((s, t) for s, t in lines if "held at design value (not determined by these poses):" in t)
    assert "red" not in held[0] and "joint 1 zero offset θ" in held[1]
    page = report_html(res)
    sec = page[page.index("id='poses'"):]
    assert "Verdict: determined" in sec
    cells = re.findall(r"<td class='name (\w+)'>held at design value", sec)
    assert cells and set(cells) == {"held"}
    assert "<td class='name not'>" not in sec and "Verdict: not determined" not in sec


def test_thesis_differences_beyond_3_sigma_are_explained(result, report_text):
    """The twin's joint 4 stiffness is not the thesis's: a difference of many σ carries its sentence."""
    row = next(t for t in report_text.splitlines() if t.startswith("K4 below 45 lb in"))
    z = float(row.split("|")[4])
    assert abs(z) > 3 and "the twin's truth" in row and "is not the thesis's robot" in row
    for line in report_text.splitlines():
        cells = [c.strip() for c in line.split("|")]
        if len(cells) > 5 and re.fullmatch(r"[+-]\d+\.\d", cells[4]) and abs(float(cells[4])) > 3:
            assert "not the thesis's robot" in cells[5] or "not the one the thesis measured" in cells[5], line


def test_another_robot_is_not_set_beside_the_thesis(result):
    from offline.report import report_html
    res = copy.deepcopy(result)
    res["profile"] = {**(res.get("profile") or {}), "reference_robot": False}
    page = visible(report_html(res))
    assert "Beside the thesis" not in page and "§5.7" not in page


def test_an_unknown_parameter_is_still_in_words():
    """A parameter no kind knows (a new effect) is spelt out with its joint named and its unit, not its code name."""
    from calib.kinds import describe
    d = describe("ident.new_effect.j3.gain_rad", ["joint 1", "joint 2", "elbow"])
    assert d.name == "new effect elbow gain" and d.unit == "deg" and math.isclose(d.scale, math.pi / 180)
    assert not INTERNAL.search(d.name)
