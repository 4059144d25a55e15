"""``--pdf`` is the report (issue 26, item 6): the HTML report printed by a real renderer -- the answer, every
section with its tables and verdicts, the diagnosis and the provenance are in the PDF's text, its pages render to
images -- and without a renderer ``--pdf`` is one line, exit 2, before any work."""
import re
import shutil
import subprocess
import sys

import pytest

from offline.pdf import find_renderer
from tests.test_accuracy_report import EXAMPLE

RENDERER = find_renderer()
needs_renderer = pytest.mark.skipif(RENDERER is None or shutil.which("pdftotext") is None
                                    or shutil.which("pdftoppm") is None,
                                    reason="no PDF renderer (chromium, weasyprint) or no poppler-utils")


@pytest.fixture(scope="module")
def printed(tmp_path_factory):
    """The example session's report with its diagnosis, written as HTML and printed to PDF."""
    from app.commands.reprocess import session_diagnosis
    from offline.report import write_report
    from app.reprocess import reprocess
    res = reprocess(str(EXAMPLE))
    res["diagnosis"] = session_diagnosis(str(EXAMPLE))
    out = tmp_path_factory.mktemp("pdf")
    html = write_report(res, out, tolerance_mm=0.5, pdf=True)
    return html, out / "report.pdf"


def _pdf_text(pdf) -> str:
    text = subprocess.run(["pdftotext", "-layout", str(pdf), "-"], capture_output=True, text=True,
                          check=True).stdout
    return " ".join(text.split())


@needs_renderer
def test_the_pdf_is_the_html_report_printed(printed, tmp_path):
    html, pdf = printed
    assert pdf.read_bytes()[:5] == b"%PDF-"
    text = _pdf_text(pdf)
    page = html.read_text(encoding="utf-8")
    # the same document: the answer, each section's title, tables and verdicts, the diagnosis, the provenance
    for words in ("Calibration report", "The answer", "position error (mm)", "after calibration", "Tolerance 0.5 mm",
                  "Theodolite pre-calibration", "Joint axes and DH parameters", "Transmission error",
                  "Joint stiffness", "Link compliance", "Wrist cross coupling", "Beside the thesis",
                  "Verdict: determined", "Diagnosis of the sim-to-real gap", "joint_compliance j3", "Provenance",
                  "robocal_version"):
        assert words in text, words
        assert words in page or words.replace("'", "&#x27;") in page, words      # ... from the same source
    # every page renders, and there are as many as a report of this length needs (not a text dump)
    subprocess.run(["pdftoppm", "-r", "30", "-png", str(pdf), str(tmp_path / "page")], check=True)
    pages = sorted(tmp_path.glob("page-*.png"))
    assert len(pages) >= 5 and all(p.stat().st_size > 2_000 for p in pages)


@needs_renderer
def test_a_title_is_never_the_last_line_of_a_page(printed):
    """Page breaks keep a title with what it titles: no page ends on a section's or a table's heading."""
    html, pdf = printed
    titles = {t.strip() for t in re.findall(r"<h[23]>([^<]*)</h[23]>", html.read_text(encoding="utf-8"))}
    assert "Beside the thesis" in titles and len(titles) >= 8
    raw = subprocess.run(["pdftotext", "-layout", str(pdf), "-"], capture_output=True, text=True, check=True).stdout
    for page in raw.split("\f"):
        lines = [ln.strip() for ln in page.splitlines() if ln.strip()]
        assert not lines or lines[-1] not in titles, page[-300:]


def test_without_a_renderer_pdf_is_one_line_and_exit_2_before_any_work(tmp_path):
    """No browser on PATH and no WeasyPrint: refused at once (the example's reprocess takes seconds; not started)."""
    env = {"PATH": str(tmp_path), "ROBOCAL_BROWSER": "", "PYTHONPATH": ":".join(sys.path)}
    probe = "import offline.pdf as p; p.RENDERERS[1] = (lambda: False, None); import app.cli as c, sys; " \
            "sys.exit(c.main(sys.argv[1:]))"
    r = subprocess.run([sys.executable, "-c", probe, "reprocess", str(EXAMPLE), "--report", str(tmp_path / "r"),
                        "--pdf"], capture_output=True, text=True, timeout=60, env=env)
    assert r.returncode == 2, r.stderr
    assert r.stderr.startswith("robocal: error: --pdf: no PDF renderer found: install Chromium")
    assert len(r.stderr.strip().splitlines()) == 1 and not (tmp_path / "r").exists()


def test_pdf_without_report_is_refused(tmp_path):
    r = subprocess.run([sys.executable, "-m", "app.cli", "reprocess", str(EXAMPLE), "--pdf"], capture_output=True,
                       text=True, timeout=60)
    assert r.returncode == 2 and "--pdf needs --report DIR" in r.stderr
