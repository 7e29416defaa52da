"""Real rendering: escaping, self-containedness, the PDF rasterised page by page, and the
HTML opened from file:// in headless Chromium (console errors, non-blank screenshot)."""
from __future__ import annotations

import io
import os
import re

import numpy as np
import pypdfium2 as pdfium
import pytest
from PIL import Image

from chromium_cdp import chromium_path, open_page
from conftest import EVIL
from feeler.reports.build import write_pdf

ON_CI = os.environ.get("CI", "").lower() == "true"


def _blank(image: Image.Image) -> bool:
    return float(np.asarray(image.convert("L"), float).std()) < 2.0


def test_scene_text_is_escaped(report):
    html = report.html.read_text(encoding="utf-8")
    assert EVIL not in html and "<script" not in html.lower()
    assert "Scene &lt;script&gt;alert(1)&lt;/script&gt;:" in html                    # robot section
    assert 'name = &#34;&lt;script&gt;alert(1)&lt;/script&gt;&#34;' in html           # appendix copy


def test_html_is_self_contained(report):
    html = report.html.read_text(encoding="utf-8")
    assert not re.search(r"https?://|//[a-z0-9.-]+\.[a-z]{2,}/", html, re.IGNORECASE)
    refs = re.findall(r"""(?:src|href)\s*=\s*["']([^"']*)""", html, re.IGNORECASE)
    assert refs and all(r.startswith("data:image/png;base64,") for r in refs)
    assert "@import" not in html and "url(" not in html


def test_pdf_pages_are_all_drawn(report):
    pdf = pdfium.PdfDocument(report.pdf)
    sections = len(report.inventory.present) + 1                    # + appendix, each from a new page
    assert len(pdf) == report.n_pages and len(pdf) >= sections + 1   # + the title page
    for i in range(len(pdf)):
        assert not _blank(pdf[i].render(scale=0.4).to_pil()), f"page {i + 1} is blank"


def test_blank_detector_sees_a_blank_page(tmp_path):
    n = write_pdf("<html><body></body></html>", tmp_path / "blank.pdf")
    pdf = pdfium.PdfDocument(tmp_path / "blank.pdf")
    assert n == len(pdf) == 1 and _blank(pdf[0].render(scale=0.4).to_pil())


def test_pdf_refuses_external_references(tmp_path):
    with pytest.raises(RuntimeError, match="example.org.*inline data: URIs only"):
        write_pdf('<img src="http://example.org/x.png">', tmp_path / "x.pdf")


def _need_chromium():
    if chromium_path() is None:
        if ON_CI:
            pytest.fail("chromium is not installed (run .ci/install-browser as root)")
        pytest.skip("chromium is not installed; run .ci/install-browser as root to enable this test")


def test_chromium_opens_the_report_without_errors(report, tmp_path):
    _need_chromium()
    errors, png = open_page(report.html.resolve().as_uri())
    assert errors == []
    shot = Image.open(io.BytesIO(png))
    assert shot.width >= 500 and shot.height >= 1000 and not _blank(shot)
    shot.save(tmp_path / "screenshot.png")


def test_chromium_harness_reports_errors(tmp_path):
    _need_chromium()
    page = tmp_path / "bad.html"
    page.write_text('<html><body><img src="missing.png"><script>console.error("boom"); nope();</script>'
                    '<img src="http://feeler.invalid/x.png"></body></html>', encoding="utf-8")
    errors, _ = open_page(page.as_uri())
    text = "\n".join(errors)
    assert "console.error: boom" in text and "nope is not defined" in text
    assert "missing.png" in text and "feeler.invalid" in text
