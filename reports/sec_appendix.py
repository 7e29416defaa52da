"""The appendix: the run's scene files verbatim, the list of figures with the files each
came from (the manifest, also written as ``report-manifest.json``) and the package versions."""
from __future__ import annotations

import platform
from importlib import metadata

from feeler.reports.model import Note, Section, Table
from feeler.reports.readers import run_text

__all__ = ["appendix_section", "appendix_inputs", "versions", "PACKAGES", "figure_list"]

PACKAGES = ("feeler", "numpy", "scipy", "pandas", "xarray", "h5netcdf", "arviz", "pymc", "pytensor",
            "emcee", "numba", "matplotlib", "scikit-fem", "jinja2", "weasyprint")


def versions() -> tuple[tuple[str, str], ...]:
    """(package, installed version or "not installed") of :data:`PACKAGES`, then Python."""
    rows = []
    for name in PACKAGES:
        try:
            rows.append((name, metadata.version(name)))
        except metadata.PackageNotFoundError:
            rows.append((name, "not installed"))
    return tuple(rows) + (("python", platform.python_version()),)


def figure_list(manifest: list[dict]) -> Table:
    """One row per figure of the report: its number, title, section and source files."""
    rows = tuple((str(m["number"]), m["title"], m["section"], ", ".join(m["sources"])) for m in manifest)
    return Table("Figures and the files they come from", ("figure", "title", "section", "files"), rows, (),
                 caption="Also in report-manifest.json beside the report.")


def _scenes(inv) -> list[tuple[str, str | None]]:
    """(scene file, the earlier one it repeats but for its seed and name, or None) of the
    run's parts, in order."""
    from feeler.reports.discover import design

    out, designs, done = [], {}, set()
    for part in inv.parts:
        rel = part.path("scene.toml")
        if rel in done or not inv.has(rel):
            continue
        done.add(rel)
        d = design(inv.run_dir, part)
        out.append((rel, designs.get(d)))
        designs.setdefault(d, rel)
    return out


def appendix_inputs(inv) -> None:
    """Read the scene files the appendix prints, before the report's first figure."""
    for rel, same in _scenes(inv):
        if same is None:
            run_text(inv, rel)


def appendix_section(inv, manifest: list[dict]) -> Section:
    """Scene files, the figure list and the package versions."""
    blocks = []
    for rel, same in _scenes(inv):
        if same is not None:
            blocks.append(Note(f"{rel}: as {same} except its seed (and name).", sources=(rel,)))
        else:
            blocks.append(Note(run_text(inv, rel), level="code", sources=(rel,)))
    if not blocks:
        blocks.append(Note("No scene files in this run."))
    if manifest:
        blocks.append(figure_list(manifest))
    # the note in the title, not a caption: a caption alone made the PDF's last page (an outside review)
    blocks.append(Table("Package versions, installed when this report was made (not a file of the run)",
                        ("package", "version"), versions(), ()))
    return Section("appendix", "Appendix: scene files, figures and versions", tuple(blocks))
