"""Reading a text file the operator gave us (TOML, JSON, CSV): one boundary for the encoding and the size.

UTF-8 is read with or without a byte-order mark (spreadsheets on Windows write one).  Anything else is named as the
wrong encoding with the line and column of the first bad byte; a file with NUL bytes is named as binary, not text; a
file larger than ``MAX_BYTES`` is refused before it is read into memory.  Every failure is one
:class:`~calib.errors.RobocalError` line naming the file.
"""
from __future__ import annotations

import os
from pathlib import Path

from .errors import RobocalError

MAX_BYTES = 512 * 1024 * 1024


def line_column(data: bytes, offset: int) -> tuple[int, int]:
    """1-based line and column (in bytes) of ``offset`` in ``data``."""
    line = data.count(b"\n", 0, offset) + 1
    return line, offset - (data.rfind(b"\n", 0, offset) + 1) + 1


def decode_text(data: bytes, source: str) -> str:
    """``data`` as text: UTF-8 with an optional BOM; a binary file or another encoding is one clear line."""
    if b"\x00" in data:
        line, col = line_column(data, data.index(b"\x00"))
        raise RobocalError(f"{source}: line {line}, column {col}: a NUL byte: this is a binary file, not text")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        start = exc.start + (3 if data.startswith(b"\xef\xbb\xbf") else 0)
        line, col = line_column(data, start)
        raise RobocalError(f"{source}: line {line}, column {col}: byte 0x{data[start]:02x} is not UTF-8: the file "
                           f"is in the wrong encoding (save it as UTF-8)") from None


def read_text(path: str | Path, max_bytes: int = MAX_BYTES) -> str:
    """The text of a file the operator named (see the module docstring for what is refused)."""
    src = str(path)
    try:
        if os.path.isdir(src):
            raise RobocalError(f"{src}: is a directory, not a file")
        size = os.path.getsize(src)
        if size > max_bytes:
            raise RobocalError(f"{src}: {size} bytes is larger than the {max_bytes} bytes robocal reads")
        with open(src, "rb") as fh:
            data = fh.read(max_bytes + 1)
    except FileNotFoundError:
        raise RobocalError(f"{src}: file not found") from None
    except OSError as exc:
        raise RobocalError(f"{src}: cannot read: {exc.strerror or exc}") from None
    return decode_text(data, src)
