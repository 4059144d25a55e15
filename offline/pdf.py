"""The report as PDF: the HTML report itself, printed by a renderer that lays out HTML and CSS.

Why not a PDF drawn separately: the PDF then was the terminal's text and bare figures -- another document than the
report, saying less.  Printing the one HTML file gives the same document from the same source (the answer, every
section with its tables and verdicts, the diagnosis, provenance); the report's print stylesheet keeps a table with
its title across page breaks.

Renderers, tried in order (a registry, not a chain of names): a headless Chromium-family browser found on PATH
(``chromium``, ``chromium-browser``, ``google-chrome``; ``$ROBOCAL_BROWSER`` names another), then WeasyPrint when it
is installed.  With neither, ``--pdf`` is one line, exit 2, naming what to install -- checked before any work starts
(:func:`require_renderer`).
"""
from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from calib.errors import RobocalError
from calib.fileio import atomic_path

#: seconds a browser may take to print the report (a 2-core machine under load takes ~10)
BROWSER_TIMEOUT_S = 180.0
BROWSERS = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")


@dataclass(frozen=True)
class Renderer:
    """A way to print an HTML file to PDF: ``render(html_path, pdf_path)``."""

    name: str
    render: Callable[[Path, Path], None]


def _browser() -> str | None:
    own = os.environ.get("ROBOCAL_BROWSER")
    if own:
        return shutil.which(own) or (own if Path(own).is_file() else None)
    return next((found for b in BROWSERS if (found := shutil.which(b))), None)


def _chromium(exe: str) -> Renderer:
    def render(html: Path, pdf: Path) -> None:
        with tempfile.TemporaryDirectory(prefix="robocal-pdf-") as profile:
            cmd = [exe, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run", "--disable-sync",
                   "--disable-background-networking", "--disable-component-update", "--disable-extensions",
                   f"--user-data-dir={profile}", "--no-pdf-header-footer", "--print-to-pdf-no-header",
                   f"--print-to-pdf={pdf}", html.resolve().as_uri()]
            try:
                r = subprocess.run(cmd, capture_output=True, text=True, timeout=BROWSER_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                raise RobocalError(f"--pdf: {exe} did not print {html} within {BROWSER_TIMEOUT_S:g} s") from None
        if not pdf.exists() or pdf.stat().st_size == 0:
            last = (r.stderr.strip().splitlines() or ["no output"])[-1]
            raise RobocalError(f"--pdf: {exe} printed no PDF of {html} (exit {r.returncode}: {last})")
    return Renderer(f"headless {Path(exe).name}", render)


def _weasyprint() -> Renderer:
    def render(html: Path, pdf: Path) -> None:
        # optional renderer, not a dependency: imported only when it is the one chosen
        import weasyprint
        weasyprint.HTML(filename=str(html)).write_pdf(str(pdf))
    return Renderer("WeasyPrint", render)


def _has_weasyprint() -> bool:
    try:
        import weasyprint  # noqa: F401
    except Exception:                          # noqa: BLE001 - missing, or its system libraries are
        return False
    return True


#: (is it available, how to build it), in order of preference
RENDERERS: list[tuple[Callable[[], object], Callable[[], Renderer]]] = [
    (_browser, lambda: _chromium(_browser())),
    (_has_weasyprint, _weasyprint),
]


def find_renderer() -> Renderer | None:
    for available, build in RENDERERS:
        if available():
            return build()
    return None


def require_renderer() -> Renderer:
    """The renderer ``--pdf`` will use, or the one-line error saying what to install (before any work is done)."""
    r = find_renderer()
    if r is None:
        raise RobocalError("--pdf: no PDF renderer found: install Chromium (apt-get install chromium; or name a "
                           "browser in ROBOCAL_BROWSER) or WeasyPrint (pip install weasyprint), or open report.html "
                           "in a browser and print it")
    return r


def html_to_pdf(html: Path, pdf: Path, renderer: Renderer | None = None) -> Path:
    """Print ``html`` (the written report) to ``pdf``, atomically: a failed print leaves no half file."""
    renderer = renderer or require_renderer()
    pdf = Path(pdf)
    with atomic_path(pdf, suffix=".pdf") as tmp:
        renderer.render(Path(html), Path(tmp))
    return pdf
