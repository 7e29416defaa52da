"""WeasyPrint's font-subsetting notice (five 'Using fontTools instead of HarfBuzz-Subset'
lines on every PDF report and demo) is kept from the user; its other warnings are not."""
from __future__ import annotations

import logging
from feeler.reports.pdf_notices import font_subsetting_notices_dropped

NOTICE = ('Using fontTools instead of HarfBuzz-Subset for font "%s". This will be unsupported in future versions '
          'of WeasyPrint. Please install HarfBuzz-Subset >= 4.1.0 with your package manager.')


def test_only_the_font_subsetting_notice_is_dropped(caplog):
    weasy = logging.getLogger("weasyprint")
    with caplog.at_level(logging.DEBUG):
        with font_subsetting_notices_dropped():
            weasy.warning(NOTICE, "DejaVu Sans")
            weasy.warning(NOTICE, "DejaVu Sans Mono")
            weasy.warning("Ignored `foo: bar` at 3:1, unknown property.")
            weasy.error("Failed to load image at 'x.png'")
        weasy.warning(NOTICE, "DejaVu Sans")                     # outside: as WeasyPrint logs it
    shown = [(r.name, r.levelno, r.getMessage()) for r in caplog.records]
    assert ("weasyprint", logging.WARNING, "Ignored `foo: bar` at 3:1, unknown property.") in shown
    assert ("weasyprint", logging.ERROR, "Failed to load image at 'x.png'") in shown
    notices = [m for name, _, m in shown if name == "weasyprint" and "HarfBuzz-Subset" in m]
    assert len(notices) == 1                                      # only the one logged outside
    assert ("feeler.reports.pdf_notices", logging.DEBUG,
            "WeasyPrint subset 2 font(s) with fontTools (no HarfBuzz-Subset >= 4.1.0): DejaVu Sans, "
            "DejaVu Sans Mono") in shown
    assert logging.getLogger("weasyprint").filters == []         # left as found


def test_a_pdf_written_without_harfbuzz_subset_logs_no_notice(tmp_path, monkeypatch, caplog):
    """WeasyPrint as on a machine without HarfBuzz-Subset >= 4.1.0 (as the audit's was):
    the PDF is written with fontTools and nothing reaches the user's log handlers."""
    import weasyprint.pdf.fonts

    from feeler.reports.build import write_pdf

    monkeypatch.setattr(weasyprint.pdf.fonts, "harfbuzz_subset", None)       # the fontTools path
    html = ("<html><body><h1 id='sec-a'>Report</h1><p>Sans text.</p>"
            "<pre style='font-family: monospace'>mono text</pre></body></html>")
    with caplog.at_level(logging.WARNING):
        pages = write_pdf(html, tmp_path / "report.pdf")
    assert pages == (("sec-a",),) and (tmp_path / "report.pdf").read_bytes()[:5] == b"%PDF-"
    assert [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING] == []
