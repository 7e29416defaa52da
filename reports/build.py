"""Build ``report.html`` (self-contained), ``report.pdf`` (WeasyPrint) and
``report-manifest.json`` from a run directory.

``build_report(run_dir)`` discovers what the run holds, opens with the first page
(claims, verdicts, what the run holds and lacks), then one section per part — failed
calibrations first —, the appendix, and renders the jinja2 template with autoescaping on
(text from the run's files appears as text). Figures are numbered in order; the manifest
names each with its section, the files it came from and any layout problem found when
it was drawn. Reports are derived files and are rewritten on every call, all three
together: they are written under temporary names and renamed at the end, so an error or
a Ctrl-C on the way (in the PDF, say) leaves the previous report as it was. A directory
holding nothing the report can show is refused (one line naming what it holds and what
the report reads), before anything is written.
"""
from __future__ import annotations

import datetime as _dt
import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from feeler.reports.discover import Inventory, discover
from feeler.reports.staged import staged

__all__ = ["Report", "build_report", "render_html", "write_pdf", "BUILDERS", "INPUTS", "section_id",
           "nothing_to_show", "read_inputs", "OWN_FILES"]

TEMPLATE_DIR = Path(__file__).resolve().parent / "templates"
MANIFEST = "report-manifest.json"
OWN_FILES = ("report.html", "report.pdf", MANIFEST)          # what a report writes (not the run's)
_LISTED = 6                                                  # files named in the error, at most

#: builder name of a section spec -> "module:function" (imported when used)
BUILDERS = {"robot": "sec_robot:robot_section", "fit": "sec_fits:fit_section",
            "classify": "sec_classify:classify_section", "compare": "sec_compare:compare_section",
            "finger": "sec_finger:finger_section", "speed": "sec_speed:speed_section",
            "calibration-data": "sec_caldata:caldata_section"}
#: builder name -> "module:function" that reads and checks every file the section will use
#: (kept in the inventory's cache, where the section finds them), run before any figure
INPUTS = {"robot": "sec_robot:robot_inputs", "fit": "sec_fits:fit_inputs",
          "classify": "sec_classify:classify_inputs", "compare": "sec_compare:compare_inputs",
          "finger": "sec_finger:finger_inputs", "speed": "sec_speed:speed_inputs",
          "calibration-data": "sec_caldata:caldata_inputs"}


@dataclass(frozen=True)
class Report:
    """What :func:`build_report` wrote.

    Attributes:
        html (Path): ``report.html``. pdf (Path | None): ``report.pdf`` (None with ``pdf=False``).
        manifest (Path): ``report-manifest.json``.
        n_pages (int): pages of the PDF (0 without PDF).
        page_sections (tuple[tuple[str, ...], ...]): per PDF page, the ids of the sections
            that start on it (empty without PDF).
        inventory (Inventory): what the run holds and lacks.
        failed (tuple[str, ...]): titles of sections whose calibration failed.
        figures (tuple[dict, ...]): the manifest's figure entries.
    """
    html: Path
    pdf: Path | None
    manifest: Path
    n_pages: int
    page_sections: tuple
    inventory: Inventory
    failed: tuple[str, ...]
    figures: tuple


def section_id(key: str) -> str:
    """The HTML id of a section (``sec-`` + the key with anything odd replaced)."""
    return "sec-" + re.sub(r"[^A-Za-z0-9_-]+", "-", key).strip("-")


_NUMBER = re.compile(r"[\s\d.,eE+\-−–±\[\]%×∞<>]*\d[\s\d.,eE+\-−–±\[\]%×∞<>]*")


def is_number(cell: str) -> bool:
    """Whether a table cell holds a number (or an interval of numbers): right-aligned."""
    return bool(_NUMBER.fullmatch(str(cell)))


def _builder(name: str, table: dict | None = None) -> Callable:
    import importlib

    module, func = (BUILDERS if table is None else table)[name].split(":")
    return getattr(importlib.import_module(f"feeler.reports.{module}"), func)


def _manifest(sections) -> list[dict]:
    entries, number = [], 0
    for s in sections:
        for b in s.blocks:
            if b.kind == "figure":
                number += 1
                entries.append({"number": number, "id": f"fig-{number}", "title": b.title, "section": s.title,
                                "sources": list(b.sources), "layout_problems": list(b.problems),
                                "drawn_by": "feeler"})
            elif b.kind == "gallery":
                for title, _, src in b.items:
                    number += 1
                    entries.append({"number": number, "id": f"fig-{number}", "title": title, "section": s.title,
                                    "sources": [src], "layout_problems": [], "drawn_by": "the run (image file)"})
    return entries


def nothing_to_show(inv: Inventory):
    """The one-line error for a run directory with no part the report can show: what it
    holds (files the report does not read named with what they are) and what it reads.

    Returns:
        DataFileError
    """
    from feeler.errors import DataFileError
    from feeler.reports.parts import READS, walk

    what = dict(inv.unread)
    found = [f"{rel}/{p.name}" if rel else p.name for d, rel in walk(inv.run_dir) for p in sorted(d.iterdir())
             if p.is_file() and p.name not in OWN_FILES]
    found.sort(key=lambda f: f not in what)                   # the ones we can say something about first
    named = [f"{f} ({what[f]})" if f in what else f for f in found[:_LISTED]]
    more = f" and {len(found) - _LISTED} more" if len(found) > _LISTED else ""
    holds = f"it holds {', '.join(named)}{more}" if found else "it holds no files"
    return DataFileError(inv.run_dir, f"nothing the report can show: {holds}; `feeler report` reads "
                                      f"{', '.join(READS)} (here or two directory levels down)")


def build_report(run_dir: str | Path, out_dir: str | Path | None = None, *, pdf: bool = True,
                 progress: Callable[[str], None] = lambda stage: None) -> Report:
    """Write the report of ``run_dir`` into ``out_dir`` (default ``run_dir``).
    ``progress(stage)`` is called before every stage: "section i/n: <title>", each figure
    it draws ("section i/n, figure k: <title>", k counted over the report), "first page",
    "html", and the PDF's own steps ("pdf: laying out page p", ... :mod:`~feeler.reports.pdf_steps`).

    Raises:
        DataFileError: ``run_dir`` is not a directory, holds nothing the report can show
            (:func:`nothing_to_show`), or a file of the run is corrupt (one line naming it).
    """
    from feeler.reports.model import on_figure, report_style
    from feeler.reports.sec_appendix import appendix_section
    from feeler.reports.sec_front import front_section

    progress("reading the run")
    inv = discover(run_dir)
    if not inv.parts:
        raise nothing_to_show(inv)
    read_inputs(inv, progress)
    sections, drawn, where = [], [0], [""]

    def figure(title: str) -> None:
        drawn[0] += 1
        progress(f"{where[0]}, figure {drawn[0]}: {title}")
    with report_style(), on_figure(figure):
        for i, spec in enumerate(inv.present, 1):
            where[0] = f"section {i}/{len(inv.present)}"
            progress(f"{where[0]}: {spec.title}")
            sections.append(_builder(spec.builder)(inv, spec))
    sections.sort(key=lambda s: not s.failed)                 # failed calibrations first (stable)
    progress("first page")
    sections.insert(0, front_section(inv))
    manifest = _manifest(sections)
    sections.append(appendix_section(inv, manifest))
    out = Path(out_dir) if out_dir is not None else inv.run_dir
    out.mkdir(parents=True, exist_ok=True)
    progress("html")
    html = render_html(inv, sections, manifest)
    pages = ()
    with staged(out) as files:               # all three in place at the end, or none (Ctrl-C in the PDF)
        files.path("report.html").write_text(html, encoding="utf-8")
        if pdf:
            pages = write_pdf(html, files.path("report.pdf"), progress=progress)
        files.path(MANIFEST).write_text(json.dumps({"run_dir": str(inv.run_dir), "figures": manifest,
                                                    "pages": len(pages), "page_sections": [list(p) for p in pages]},
                                                   indent=2, ensure_ascii=False) + "\n", encoding="utf-8")
        files.install()
    html_path, pdf_path, man_path = out / "report.html", out / "report.pdf" if pdf else None, out / MANIFEST
    return Report(html=html_path, pdf=pdf_path, manifest=man_path, n_pages=len(pages), page_sections=tuple(pages),
                  inventory=inv, failed=tuple(s.title for s in sections if s.failed), figures=tuple(manifest))


def read_inputs(inv: Inventory, progress: Callable[[str], None] = lambda stage: None) -> None:
    """Read and check every file of the run the report will use before its first figure:
    a corrupt one stopped the report only when its section came, after seconds of figures
    (a fit, then also scans, tables, JSON files, curves and scene files). Every fit first
    (posterior, summary, verdict), then each section's inputs (:data:`INPUTS`), the first
    page's and the appendix's. Kept in the inventory's cache, so the sections do not read
    them again.

    Raises:
        DataFileError, SceneError: the first unreadable file, in one line naming it.
    """
    from feeler.reports.readers import load_fit
    from feeler.reports.sec_appendix import appendix_inputs
    from feeler.reports.sec_front import front_inputs

    fits = inv.of("fit")
    if fits:
        progress(f"reading {len(fits)} fit{'s' if len(fits) != 1 else ''}")
    for part in fits:
        load_fit(inv.run_dir / part.rel, inv)
    if any(spec.builder != "fit" for spec in inv.present):
        progress("reading the run's other files")
    for spec in inv.present:
        _builder(spec.builder, INPUTS)(inv, spec)
    front_inputs(inv)
    appendix_inputs(inv)


def render_html(inv: Inventory, sections, manifest) -> str:
    """The report as one HTML string (jinja2, autoescape on for every template)."""
    import jinja2

    import feeler

    env = jinja2.Environment(loader=jinja2.FileSystemLoader(TEMPLATE_DIR), autoescape=True,
                             undefined=jinja2.StrictUndefined, trim_blocks=True, lstrip_blocks=True)
    numbers = iter(m["number"] for m in manifest)
    synthetic = sorted({src for s in sections for b in s.blocks if getattr(b, "level", "") == "synthetic"
                        for src in b.sources})
    return env.get_template("report.html.j2").render(
        run_name=inv.run_dir.resolve().name, run_dir=str(inv.run_dir), sections=sections,
        failed=[s for s in sections if s.failed], synthetic=synthetic, section_id=section_id, is_number=is_number,
        next_number=lambda: next(numbers), version=feeler.__version__,
        created=_dt.datetime.now().isoformat(timespec="seconds"))


def write_pdf(html: str, path: str | Path,
              progress: Callable[[str], None] = lambda stage: None) -> tuple[tuple[str, ...], ...]:
    """Lay out ``html`` with WeasyPrint and write ``path``; returns, per page, the ids of
    the sections that start on it. ``progress(stage)`` before each of WeasyPrint's steps
    (:func:`feeler.reports.pdf_steps.weasyprint_steps`: parsing, each page, writing).
    WeasyPrint's notice about its font subsetter is not shown (:mod:`~feeler.reports.pdf_notices`)."""
    progress("pdf: loading WeasyPrint")
    import weasyprint
    from weasyprint.urls import FatalURLFetchingError, URLFetcher

    from feeler.reports.pdf_notices import font_subsetting_notices_dropped
    from feeler.reports.pdf_steps import weasyprint_steps

    # only inline data: URIs, and any other reference stops the rendering: no network
    fetcher = URLFetcher(allowed_protocols=("data",), fail_on_errors=True)
    with weasyprint_steps(progress), font_subsetting_notices_dropped():
        try:
            document = weasyprint.HTML(string=html, url_fetcher=fetcher).render()
        except FatalURLFetchingError as exc:   # a BaseException in WeasyPrint 70
            raise RuntimeError(f"{path}: {exc}; a report may reference inline data: URIs only") from None
        document.write_pdf(path)
    seen, pages = set(), []
    for page in document.pages:
        starts = tuple(sorted(a for a in page.anchors if a.startswith("sec-") and a not in seen))
        seen.update(starts)
        pages.append(starts)
    return tuple(pages)
