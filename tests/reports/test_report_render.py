"""Real rendering: escaping, self-containedness, the PDF rasterised page by page (no blank
page, no page below a fill threshold except a section's last), and the HTML opened from
file:// in headless Chromium at 800 and 1400 px (no console errors, no horizontal
overflow)."""
from __future__ import annotations

import io
import json
import os
import re

import numpy as np
import pypdfium2 as pdfium
import pytest
from PIL import Image

from chromium_cdp import OVERFLOW_JS, chromium_path, open_page
from feeler.reports.build import MANIFEST, write_pdf

ON_CI = os.environ.get("CI", "").lower() == "true"
FILL = 0.55          # a page's content must reach this far down, unless a section ends on it


def _gray(image: Image.Image) -> np.ndarray:
    return np.asarray(image.convert("L"), float)


def _blank(image: Image.Image) -> bool:
    return float(_gray(image).std()) < 2.0


def fill(image: Image.Image, margin: float = 0.045) -> float:
    """How far down the page (0–1, inside the printed area) its last non-white row is."""
    g = _gray(image)
    top, bottom = int(margin * g.shape[0]), int((1 - margin) * g.shape[0])
    rows = np.flatnonzero((g[top:bottom] < 235).any(axis=1))
    return 0.0 if rows.size == 0 else (rows[-1] + 1) / (bottom - top)


def test_scene_text_is_escaped(report, evil_name):
    html = (report / "report.html").read_text(encoding="utf-8")
    assert evil_name not in html and "<script" not in html.lower()
    assert "&lt;script&gt;alert(1)&lt;/script&gt;:" in html                      # robot section
    assert 'name = &#34;&lt;script&gt;alert(1)&lt;/script&gt;&#34;' in html       # appendix copy


def test_html_is_self_contained(report):
    html = (report / "report.html").read_text(encoding="utf-8")
    assert not re.search(r"https?://|//[a-z0-9.-]+\.[a-z]{2,}/", html, re.IGNORECASE)
    refs = re.findall(r"""(?:src|href)\s*=\s*["']([^"']*)""", html, re.IGNORECASE)
    assert refs and all(r.startswith("data:image/png;base64,") for r in refs)
    assert "@import" not in html and "url(" not in html


def test_pdf_pages_are_drawn_and_filled(report):
    manifest = json.loads((report / MANIFEST).read_text(encoding="utf-8"))
    starts = manifest["page_sections"]
    pdf = pdfium.PdfDocument(report / "report.pdf")
    assert len(pdf) == manifest["pages"] == len(starts) and starts[0] == ["sec-front"]
    assert sum(len(s) for s in starts) == len(set(sum(starts, []))) >= 8       # each section starts once
    low = []
    for i in range(len(pdf)):
        image = pdf[i].render(scale=0.5).to_pil()
        assert not _blank(image), f"page {i + 1} is blank"
        last_of_section = i + 1 == len(pdf) or bool(starts[i + 1])
        if not last_of_section and fill(image) < FILL:
            low.append((i + 1, round(fill(image), 2)))
    assert low == [], f"pages below {FILL} filled in the middle of a section: {low}"


def test_fill_measure_sees_a_short_page(tmp_path):
    write_pdf("<html><body><p>one line</p></body></html>", tmp_path / "short.pdf")
    write_pdf("<html><body>" + "<p>line</p>" * 80 + "</body></html>", tmp_path / "long.pdf")
    short = pdfium.PdfDocument(tmp_path / "short.pdf")[0].render(scale=0.5).to_pil()
    long = pdfium.PdfDocument(tmp_path / "long.pdf")[0].render(scale=0.5).to_pil()
    assert fill(short) < 0.1 and fill(long) > 0.9 and not _blank(short)


def test_blank_detector_sees_a_blank_page(tmp_path):
    pages = write_pdf("<html><body></body></html>", tmp_path / "blank.pdf")
    pdf = pdfium.PdfDocument(tmp_path / "blank.pdf")
    assert len(pages) == len(pdf) == 1 and _blank(pdf[0].render(scale=0.4).to_pil())


def test_pdf_refuses_external_references(tmp_path):
    with pytest.raises(RuntimeError, match="example.org.*inline data: URIs only"):
        write_pdf('<img src="http://example.org/x.png">', tmp_path / "x.pdf")


def _need_chromium():
    if chromium_path() is None:
        if ON_CI:
            pytest.fail("chromium is not installed (run .ci/install-browser as root)")
        pytest.skip("chromium is not installed; run .ci/install-browser as root to enable this test")


def test_chromium_shows_the_report_without_errors_or_overflow(report, tmp_path):
    _need_chromium()
    errors, png, values = open_page((report / "report.html").resolve().as_uri(), width=800, evaluate=OVERFLOW_JS,
                                    widths=(800, 1400))
    assert errors == []
    for width, value in values.items():
        layout = json.loads(value)
        assert width - 20 <= layout["width"] <= width                 # the viewport (a scrollbar aside)
        assert layout["scroll"] <= layout["width"] and layout["bad"] == [], (width, layout)
    shot = Image.open(io.BytesIO(png))
    assert shot.height >= 500 and not _blank(shot)


def test_overflow_probe_sees_a_wide_element(tmp_path):
    _need_chromium()
    page = tmp_path / "wide.html"
    page.write_text('<html><body><div id="w" style="width: 1200px">x</div></body></html>', encoding="utf-8")
    _, _, value = open_page(page.as_uri(), width=800, evaluate=OVERFLOW_JS)
    layout = json.loads(value)
    assert layout["scroll"] > layout["width"] and any(b.startswith("DIV#w") for b in layout["bad"])


def test_chromium_harness_reports_errors(tmp_path):
    _need_chromium()
    page = tmp_path / "bad.html"
    page.write_text('<html><body><img src="missing.png"><script>console.error("boom"); nope();</script>'
                    '<img src="http://feeler.invalid/x.png"></body></html>', encoding="utf-8")
    errors, _ = open_page(page.as_uri())
    text = "\n".join(errors)
    assert "console.error: boom" in text and "nope is not defined" in text
    assert "missing.png" in text and "feeler.invalid" in text
