"""How a result's numbers and times are written for people, in the terminal and the report alike: a value rounded to
its error, a truth rounded the same way (0 when it is zero within that rounding), the legend that says what ± and σ
mean, times as ISO 8601 with their zone, and why an accuracy "after" may be below the instrument floor.

Why one module: the summary and the report are two views of the same results; a rule written twice (two digits of
the error, the value to the same decimal) drifts between them.
"""
from __future__ import annotations

import datetime as dt
import math

def legend(thesis: bool = False) -> str:
    """What ± and the deviation in σ mean, said once at the top of the summary and of the report (the thesis's
    numbers are named only for a robot set beside the thesis)."""
    beside = "the emulated truth, or the thesis's" if thesis else "the emulated truth"
    return ("Legend: value ± error is the estimate and its standard deviation (1σ); (+1.4σ) is how far the estimate "
            f"lies from the number beside it ({beside}), in units of that σ; values are rounded to two significant "
            "digits of their error.")


def _place(error: float) -> int:
    """The decimal place of the error's second significant digit (10**place)."""
    return int(math.floor(math.log10(error))) - 1


#: an error whose second digit lies further right than this many decimals is written in exponent form
MAX_DECIMALS = 6


def _exponent_form(value: float, error: float) -> bool:
    return abs(value) >= 1e6 or -_place(error) > MAX_DECIMALS


def _at(x: float, place: int, exponent: bool) -> str:
    """``x`` rounded to 10**place: fixed decimals, or a mantissa for a magnitude far from 1."""
    if exponent:
        e = int(math.floor(math.log10(abs(x)))) if x else place + 1
        return f"{x:.{max(e - place, 0)}e}"
    if place < 0:
        return f"{x:.{-place}f}"
    step = 10.0 ** place
    return f"{round(x / step) * step:.0f}"


def value_pm(value: float, error: float | None) -> str:
    """``value ± error`` with the error to two significant digits and the value to the same decimal place (the
    metrologist's convention); magnitudes far from 1 in exponent form."""
    if error is None or not math.isfinite(error) or error <= 0:
        return f"{value:.6g}" + ("" if error is None else f" ± {error:.2g}")
    p, expo = _place(error), _exponent_form(value, error)
    return f"{_at(value, p, expo)} ± {error:.2g}" if expo else f"{_at(value, p, False)} ± {_at(error, p, False)}"


def like_value(x: float, value: float, error: float | None) -> str:
    """A number beside ``value ± error`` (a truth, the thesis's number) rounded as the value is: ``0`` when it is
    zero at that rounding (a truth of -2.8e-33 is 0)."""
    if error is None or not math.isfinite(error) or error <= 0:
        return "0" if abs(x) < 1e-12 * max(abs(value), 1.0) else f"{x:.6g}"
    p = _place(error)
    if round(x / 10.0 ** p) == 0:
        return "0"
    return _at(x, p, _exponent_form(value, error))


def rounded(x: float, sig: int = 3) -> str:
    """A number with no error of its own (a bound, a figure) to ``sig`` significant digits."""
    return f"{x:.{sig}g}"


def when(unix_s: float | None) -> str:
    """A time as people read it: ISO 8601 in the machine's local time with its zone (never seconds since 1970)."""
    if unix_s is None:
        return "unknown"
    return dt.datetime.fromtimestamp(float(unix_s), dt.timezone.utc).astimezone().isoformat(timespec="seconds")


def below_floor_sentence(acc: dict) -> str:
    """Why an "after" below the instrument floor is no contradiction (empty when it is not below)."""
    if not acc or acc.get("after_rms_mm") is None or acc["after_rms_mm"] >= acc.get("floor_mm", 0.0):
        return ""
    n = acc.get("n_test") or 0
    scatter = f", and the RMS of {n} held-out poses scatters by about ±{100 / math.sqrt(6 * n):.0f} % (1σ)" if n \
        else ""
    return ("After is below the instrument floor because the floor counts each point's whole stated error, including "
            "the stations' calibration that every point of the set shares and the fitted base absorbs" + scatter + ".")


def same_floor(acc: dict | None, diag: dict | None) -> bool:
    """Whether a diagnosis's floor is the accuracy's (one floor per pose set: then it is named, not stated twice)."""
    if not acc or not diag or acc.get("floor_mm") is None:
        return False
    return abs(acc["floor_mm"] - diag["noise_floor_mm"]) <= 5e-4 * max(diag["noise_floor_mm"], 1e-9)
