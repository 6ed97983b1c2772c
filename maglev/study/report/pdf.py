"""The report as an A4 PDF: headless Chromium's print-to-PDF of the HTML page, with its print stylesheet.

The lab allows six pages plus the attached code; the page's print stylesheet puts the
appendix on a new page after the ``APPENDIX_MARKER`` heading, so :func:`pages_before_appendix`
can count the main report, and prints of it only the attached code and the cautions (every run,
the further figures and the decisions' evidence stay in the HTML).
"""

from __future__ import annotations

import re
import shutil
import subprocess
import tempfile
from pathlib import Path

from maglev.study.store import SweepError

APPENDIX_MARKER = "Appendices"  # the heading that starts the appendix (on a page of its own)
PAGE_LIMIT = 6  # the lab's maximum, attached code excluded


class PdfError(SweepError):
    """The PDF could not be printed (no Chromium, or it failed): ``maglev report`` prints it as one line."""


def chromium() -> str | None:
    """The Chromium executable on PATH, or None."""
    for name in ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable"):
        found = shutil.which(name)
        if found:
            return found
    return None


def print_pdf(page: Path, out: Path, timeout: float = 180.0) -> Path:
    """Print the HTML file ``page`` to the PDF ``out`` with headless Chromium (A4, the page's print stylesheet)."""
    exe = chromium()
    if exe is None:
        raise PdfError("--pdf needs Chromium on PATH (chromium or chromium-browser; e.g. apt-get install chromium)")
    out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="maglev-chromium-") as profile:
        cmd = [exe, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run", "--disable-background-networking",
               "--disable-component-update", "--disable-sync", f"--user-data-dir={profile}",
               "--no-pdf-header-footer", f"--print-to-pdf={out}", Path(page).resolve().as_uri()]
        try:
            proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
        except subprocess.TimeoutExpired as exc:
            raise PdfError(f"Chromium did not print {page} within {timeout:.0f} s") from exc
    if not out.is_file() or out.stat().st_size == 0:
        raise PdfError(f"Chromium printed no PDF for {page} (exit {proc.returncode}): {proc.stderr.strip()[-500:]}")
    return out


def page_texts(pdf: Path) -> list[str]:
    """The text of each page of ``pdf`` (pypdf)."""
    from pypdf import PdfReader

    return [p.extract_text() or "" for p in PdfReader(str(pdf)).pages]


def pages_before_appendix(texts: list[str]) -> int:
    """How many of a printed report's pages (their :func:`page_texts`: reading a PDF's text takes ≈ 1.4 s for
    the report's, so a caller reads it once) come before the one that starts with the appendix heading (all of
    them without one)."""
    for i, text in enumerate(texts):
        if re.search(rf"^\s*{APPENDIX_MARKER}\b", text, flags=re.M):
            return i
    return len(texts)
