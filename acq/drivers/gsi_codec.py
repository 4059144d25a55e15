"""Leica GSI-8 / GSI-16 words and GSI Online commands: pure parsing and formatting (protocols.md §2).

A word is ``WI(2-3) | info(3-4 chars: compensator, input mode, unit) | sign | data(8 or 16) | blank``; a block is a
line of words, GSI-16 blocks start with ``*``.  Angles and distances carry implied decimals set by the unit code.

Why words are read one by one: real files carry any printable character in point names, codes and remarks ('/' in
a remark, '?' in a DNA code, '_' in a point name), and one word this codec cannot read must not throw away the Hz
and V next to it.  So a block is split by word size and each word that does not follow the grammar is kept as an
*unknown* word (``known=False``, its characters in ``raw``); only a line that cannot be split into words is an
error.  Asking an unknown word for a value raises :class:`GsiError`, so it never becomes a reading.  Angles come out
in radians, distances in metres: gon and degrees exist only here.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass

TERM = b"\r\n"
GON = math.pi / 200.0
DEG = math.pi / 180.0
MIL = 2 * math.pi / 6400.0

#: unit code -> (kind, implied decimals, metres per unit for lengths / units per full circle for angles)
UNITS: dict[str, tuple[str, int, float]] = {
    "0": ("length", 3, 1.0), "1": ("length", 3, 0.3048), "2": ("angle", 5, 400.0), "3": ("angle", 5, 360.0),
    "4": ("dms", 5, 360.0), "5": ("angle", 4, 6400.0), "6": ("length", 4, 1.0), "7": ("length", 4, 0.3048),
    "8": ("length", 5, 1.0),
}
ANGLE_UNIT_CODE = {"gon": "2", "deg": "3", "dms": "4", "mil": "5"}


class GsiError(ValueError):
    """A GSI line or word that does not follow the grammar; the message is the cause."""


@dataclass(frozen=True)
class Word:
    wi: int            # -1 for an unknown word whose index is not even digits
    info: str          # the characters between WI and sign (3 for 2-digit WIs incl. the '.', 3 for 3-digit WIs)
    sign: str
    data: str
    known: bool = True     # False: the word does not follow the grammar; ``raw`` keeps it as read
    raw: str = ""

    @property
    def unit(self) -> str:
        return self.info[-1:]

    def angle_rad(self) -> float:
        kind, dec, full = _unit(self)
        if kind == "angle":
            val = _digits(self) / 10 ** dec / full * math.tau     # so 400.00000 gon is exactly 2 pi
        elif kind == "dms":
            n = _digits(self)                 # DDDMMSSs
            tenth_s = n % 10
            s = (n // 10) % 100
            m = (n // 1000) % 100
            d = n // 100000
            if m >= 60 or s >= 60:
                raise GsiError(f"WI{self.wi}: {self.data!r} is not a DDD.MMSSs angle")
            val = (d + m / 60 + (s + tenth_s / 10) / 3600) / full * math.tau
        else:
            raise GsiError(f"WI{self.wi} unit {self.unit!r} is not an angle unit")
        return -val if self.sign == "-" else val

    def length_m(self) -> float:
        kind, dec, scale = _unit(self)
        if kind != "length":
            raise GsiError(f"WI{self.wi} unit {self.unit!r} is not a length unit")
        val = _digits(self) / 10 ** dec * scale
        return -val if self.sign == "-" else val

    def text(self) -> str:
        """The data as text (point name, code, serial number): leading zeros and padding blanks removed."""
        if not self.known:
            raise GsiError(f"word {self.raw!r} does not follow the GSI grammar")
        return self.data.lstrip("0 ").rstrip() or "0"


def _unit(w: Word) -> tuple[str, int, float]:
    if not w.known:
        raise GsiError(f"word {w.raw!r} does not follow the GSI grammar")
    try:
        return UNITS[w.unit]
    except KeyError:
        raise GsiError(f"WI{w.wi}: unknown unit code {w.unit!r}") from None


def _digits(w: Word) -> int:
    if not w.data.isdigit():
        raise GsiError(f"WI{w.wi}: data {w.data!r} is not numeric")
    return int(w.data)


#: data may hold any printable character (point names, codes, remarks); the blank after it ends the word
_WORD = {16: re.compile(r"(\d{2})([0-9.]{4})([+-])([\x20-\x7e]{8}) \Z"),
         24: re.compile(r"(\d{2})([0-9.]{4})([+-])([\x20-\x7e]{16}) \Z")}
_WI_DIGITS = re.compile(r"(\d{2,3})")


def _text(line: bytes | str) -> str:
    """Bytes as latin-1: every byte is one character, so a stray byte spoils one word, not the line."""
    return line.decode("latin-1") if isinstance(line, bytes) else line


def parse_block(line: bytes | str) -> list[Word]:
    """Words of one GSI line (terminator removed).  ``*`` prefix -> GSI-16; a missing trailing blank is tolerated.

    Raises :class:`GsiError` only when the line cannot be split into words; a word that does not follow the
    grammar comes back with ``known=False``.
    """
    line = _text(line)
    gsi16 = line.startswith("*")
    body = line[1:] if gsi16 else line
    size = 24 if gsi16 else 16
    if not body.endswith(" "):
        body += " "
    if not body.strip() or len(body) % size:
        raise GsiError(f"GSI line length {len(body)} is not a multiple of {size}: {line[:40]!r}")
    return [_word(body[i:i + size], size) for i in range(0, len(body), size)]


def _word(chunk: str, size: int) -> Word:
    m = _WORD[size].match(chunk)
    if not m:
        wi = _WI_DIGITS.match(chunk)
        return Word(int(wi.group(1)) if wi else -1, "", "", "", known=False, raw=chunk)
    wi2, info, sign, data = m.groups()
    if wi2 in ("11", "41"):                       # point / code word: pos 3-6 is the block number
        return Word(int(wi2), info, sign, data, raw=chunk)
    if info[0].isdigit():                        # 3-digit WI (531, 538, 913 ...)
        return Word(int(wi2 + info[0]), info[1:], sign, data, raw=chunk)
    return Word(int(wi2), info[1:], sign, data, raw=chunk)


def format_word(wi: int, info: str, value: int | str, gsi16: bool, sign: str = "+") -> str:
    """One word with its trailing blank (``info``: compensator, input mode, unit (3 chars); block number for WI 11)."""
    width = 16 if gsi16 else 8
    data = str(value).rjust(width, "0")[-width:]
    if wi in (11, 41):
        head = f"{wi:02d}" + info.rjust(4, "0")[-4:]
    elif wi >= 100:
        head = f"{wi:d}" + info[-3:]
    else:
        head = f"{wi:02d}." + info[-3:]
    return f"{head}{sign}{data} "


def angle_value(rad: float, unit: str = "gon") -> int:
    """Integer data of an angle in ``unit`` with the implied decimals."""
    if unit == "gon":
        return round(rad / GON * 1e5)
    if unit == "deg":
        return round(rad / DEG * 1e5)
    if unit == "mil":
        return round(rad / MIL * 1e4)
    if unit == "dms":
        tenths = round(rad / DEG * 36000)
        d, rem = divmod(tenths, 36000)
        m, rem = divmod(rem, 600)
        return d * 100000 + m * 1000 + rem
    raise GsiError(f"unknown angle unit {unit!r}")


# -- GSI Online -----------------------------------------------------------------------------------------------------
def get_command(wis: list[int], measure: bool = True) -> bytes:
    return ("GET/" + ("M" if measure else "I") + "".join(f"/WI{wi}" for wi in wis)).encode("ascii") + TERM


def set_command(param: int, value: int) -> bytes:
    return f"SET/{param}/{value}".encode("ascii") + TERM


def conf_command(param: int) -> bytes:
    return f"CONF/{param}".encode("ascii") + TERM


@dataclass(frozen=True)
class OnlineReply:
    """``kind``: "ok" (``?``), "warning"/"error" (``@Wnnn``/``@Ennn``, ``code``), "conf" (value), "words"."""

    kind: str
    code: int = 0
    value: int = 0
    words: tuple[Word, ...] = ()


_CODE = re.compile(r"@([WE])(\d{1,4})\Z")
_CONF = re.compile(r"(\d{4})/(\d{4})\Z")
#: the one code protocols.md documents; others are [UNVERIFIED] and reported by number
ONLINE_CODES = {427: "invalid command"}


def parse_online_reply(line: bytes) -> OnlineReply:
    text = _text(line)
    if text == "?":
        return OnlineReply("ok")
    m = _CODE.match(text)
    if m:
        return OnlineReply("warning" if m.group(1) == "W" else "error", code=int(m.group(2)))
    m = _CONF.match(text)
    if m:
        return OnlineReply("conf", code=int(m.group(1)), value=int(m.group(2)))
    return OnlineReply("words", words=tuple(parse_block(text)))
