"""Build ``report.html`` (self-contained) and ``report.pdf`` (WeasyPrint) from a run directory.

``build_report(run_dir)`` discovers what the run holds, builds one section per group of
files (robot scans, fits, classification, robot vs human, Fig. 6, skin, benchmarks),
puts failed calibrations first, lists the missing files, appends the scene files and the
package versions, and renders the jinja2 template with autoescaping on (text from scene
files appears as text). Reports are derived files and are rewritten on every call.
"""
from __future__ import annotations

import datetime as _dt
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from feeler.reports.discover import Inventory, discover

__all__ = ["Report", "build_report", "render_html", "write_pdf"]

TEMPLATE_DIR = Path(__file__).resolve().parent / "templates"


def _builders() -> dict[str, Callable]:
    from feeler.reports.sec_classify import classify_section
    from feeler.reports.sec_fits import fit_section
    from feeler.reports.sec_psycho import fig6_section, psychometric_section
    from feeler.reports.sec_robot import robot_section
    from feeler.reports.sec_tables import csv_dir_section

    return {"robot": robot_section, "fit": fit_section, "classify": classify_section,
            "psychometric": psychometric_section, "fig6": fig6_section,
            "finger": csv_dir_section, "benchmarks": csv_dir_section}



@dataclass(frozen=True)
class Report:
    """What :func:`build_report` wrote.

    Attributes:
        html (Path): ``report.html``.
        pdf (Path | None): ``report.pdf`` (None with ``pdf=False``).
        n_pages (int): pages of the PDF as laid out by WeasyPrint (0 without PDF).
        inventory (Inventory): sections present and files missing.
        failed (tuple[str, ...]): titles of sections whose calibration failed.
    """
    html: Path
    pdf: Path | None
    n_pages: int
    inventory: Inventory
    failed: tuple[str, ...]


def build_report(run_dir: str | Path, out_dir: str | Path | None = None, *, pdf: bool = True,
                 progress: Callable[[str], None] = lambda stage: None) -> Report:
    """Write ``report.html`` (and ``report.pdf``) for ``run_dir`` into ``out_dir`` (default
    ``run_dir``). ``progress(stage)`` is called before every stage.

    Raises:
        DataFileError: ``run_dir`` is not a directory, or a file of the run is corrupt
            (one line naming it).
    """
    progress("discover")
    inv = discover(run_dir)
    builders = _builders()
    sections = []
    for spec in inv.present:
        progress(spec.key)
        sections.append(builders[spec.key.split(":", 1)[0]](inv, spec))
    from feeler.reports.sec_tables import appendix_section

    sections.sort(key=lambda s: not s.failed)                 # failed calibrations first (stable)
    sections.append(appendix_section(inv))
    out = Path(out_dir) if out_dir is not None else inv.run_dir
    out.mkdir(parents=True, exist_ok=True)
    progress("html")
    html = render_html(inv, sections)
    html_path = out / "report.html"
    html_path.write_text(html, encoding="utf-8")
    pdf_path, n_pages = None, 0
    if pdf:
        progress("pdf")
        pdf_path = out / "report.pdf"
        n_pages = write_pdf(html, pdf_path)
    return Report(html=html_path, pdf=pdf_path, n_pages=n_pages, inventory=inv,
                  failed=tuple(s.title for s in sections if s.failed))


def render_html(inv: Inventory, sections) -> str:
    """The report as one HTML string (jinja2, autoescape on for every template)."""
    import jinja2

    import feeler

    env = jinja2.Environment(loader=jinja2.FileSystemLoader(TEMPLATE_DIR), autoescape=True,
                             undefined=jinja2.StrictUndefined, trim_blocks=True, lstrip_blocks=True)
    synthetic = sorted({src for s in sections for b in s.blocks if getattr(b, "level", "") == "synthetic"
                        for src in b.sources})
    return env.get_template("report.html.j2").render(
        run_name=inv.run_dir.resolve().name, run_dir=str(inv.run_dir), sections=sections,
        failed=[s for s in sections if s.failed], missing=inv.missing, synthetic=synthetic,
        version=feeler.__version__, created=_dt.datetime.now().isoformat(timespec="seconds"))


def write_pdf(html: str, path: str | Path) -> int:
    """Lay out ``html`` with WeasyPrint, write ``path``; returns the number of pages."""
    import weasyprint
    from weasyprint.urls import FatalURLFetchingError, URLFetcher

    # only inline data: URIs, and any other reference stops the rendering: no network
    fetcher = URLFetcher(allowed_protocols=("data",), fail_on_errors=True)
    try:
        document = weasyprint.HTML(string=html, url_fetcher=fetcher).render()
    except FatalURLFetchingError as exc:   # a BaseException in WeasyPrint 70
        raise RuntimeError(f"{path}: {exc}; a report may reference inline data: URIs only") from None
    document.write_pdf(path)
    return len(document.pages)
