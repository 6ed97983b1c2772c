"""Printing the report: ``maglev report --pdf`` refuses at once without Chromium, and the page count before the
appendix is read from a printed page built to have a known number of pages before its appendix heading."""

from __future__ import annotations

import pytest

from maglev.study.report import pdf


def test_report_pdf_without_chromium_is_refused_in_one_line_before_anything_runs(monkeypatch, capsys, tmp_path):
    from maglev.study.cli import main

    monkeypatch.setattr(pdf, "chromium", lambda: None)
    # the store does not even exist: the refusal comes before any ranking
    assert main(["report", "--tracking-uri", f"sqlite:///{tmp_path}/none.db", "--pdf"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == ("maglev report: --pdf needs Chromium on PATH (chromium or chromium-browser; e.g. apt-get install "
                   "chromium)")
    assert not (tmp_path / "none.db").exists()


@pytest.mark.parametrize("before", [1, 3])
def test_pages_before_the_appendix_heading_are_counted(tmp_path, before):
    if pdf.chromium() is None:
        pytest.skip("chromium not installed (apt-get install -y chromium): nothing to print")
    pages = "".join(f"<p style='break-after:page'>main page {i + 1}</p>" for i in range(before))
    page = tmp_path / "p.html"
    page.write_text(f"<!DOCTYPE html><html><body>{pages}<h1>{pdf.APPENDIX_MARKER}</h1><p>code</p>"
                    "<p style='break-before:page'>more appendix</p></body></html>")
    out = pdf.print_pdf(page, tmp_path / "p.pdf")
    texts = pdf.page_texts(out)
    assert len(texts) == before + 2
    assert pdf.pages_before_appendix(texts) == before
