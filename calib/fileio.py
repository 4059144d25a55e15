"""Writing output files atomically: a reader (or a crash) never sees half a file.

Every output is written to a temporary file in the same directory, flushed to disk and then renamed over the target
(``os.replace`` is atomic on one file system).  If anything fails on the way, the temporary file is removed and the
previous content of the target, if any, is untouched.  A write that fails names the path in a one-line
:class:`~calib.errors.RobocalError`.
"""
from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path
from typing import Iterator

from .errors import RobocalError


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_path(path: str | Path, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; when the block ends without an error it replaces ``path``.

    For writers that want a file name (sqlite, matplotlib): ``with atomic_path(out) as tmp: fig.savefig(tmp)``.
    """
    target = Path(path)
    directory = target.parent if str(target.parent) else Path(".")
    try:
        fd, name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=suffix or ".part", dir=directory)
    except OSError as exc:
        raise RobocalError(f"{target}: cannot write: {exc.strerror or exc}") from None
    os.close(fd)
    tmp = Path(name)
    try:
        yield tmp
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, target)
    except OSError as exc:
        raise RobocalError(f"{target}: cannot write: {exc.strerror or exc}") from None
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()


def atomic_write_bytes(path: str | Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (temporary file, fsync, rename)."""
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())


def atomic_write_text(path: str | Path, text: str, encoding: str = "utf-8") -> None:
    """Write ``text`` to ``path`` atomically (UTF-8 by default, ``\\n`` line ends as given)."""
    atomic_write_bytes(path, text.encode(encoding))
