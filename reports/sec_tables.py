"""Sections of plain tables (the skin ladder, benchmarks) and the appendix (scene files,
package versions).

Every CSV under ``finger/`` and ``benchmarks/`` is shown as a table named by its file; a
CSV with a ``t_s`` column and numeric columns beside it (e.g. ``finger/strain.csv``) is
also drawn as a history against time.
"""
from __future__ import annotations

import platform
from importlib import metadata

from feeler.reports.model import Figure, Note, Section, Table, figure_uri, subplots, table_from_frame
from feeler.reports.readers import read_table, scene_text

__all__ = ["csv_dir_section", "appendix_section", "PACKAGES"]

PACKAGES = ("feeler", "numpy", "scipy", "pandas", "xarray", "h5netcdf", "arviz", "pymc", "pytensor",
            "emcee", "numba", "matplotlib", "scikit-fem", "jinja2", "weasyprint")


def csv_dir_section(inv, spec) -> Section:
    """One table per CSV of the section's folder, plus a history plot of t_s tables."""
    folder = spec.required[0]
    blocks = []
    for path in sorted((inv.run_dir / folder).glob("*.csv")):
        rel = f"{folder}/{path.name}"
        frame = read_table(path)
        if frame.empty or len(frame.columns) == 0:
            blocks.append(Note(f"{rel}: no rows.", sources=(rel,)))
            continue
        numeric = [c for c in frame.columns if c != "t_s" and frame[c].dtype.kind in "fi"]
        if "t_s" in frame.columns and frame["t_s"].dtype.kind in "fi" and numeric:
            fig, ax = subplots()
            for c in numeric[:8]:
                ax.plot(frame["t_s"], frame[c], label=str(c))
            ax.set(xlabel="t (s)", title=path.stem)
            ax.legend(fontsize=7)
            blocks.append(Figure(f"{path.stem} against time", figure_uri(fig), (rel,)))
        else:
            blocks.append(table_from_frame(frame, title=path.stem, sources=(rel,)))
    return Section(spec.key, spec.title, tuple(blocks))


def versions() -> tuple[tuple[str, str], ...]:
    """(package, installed version or "not installed") of :data:`PACKAGES`, then Python."""
    rows = []
    for name in PACKAGES:
        try:
            rows.append((name, metadata.version(name)))
        except metadata.PackageNotFoundError:
            rows.append((name, "not installed"))
    return tuple(rows) + (("python", platform.python_version()),)


def appendix_section(inv) -> Section:
    """The run's scene files verbatim and the package versions used to make the report."""
    blocks = []
    for path in sorted(inv.run_dir.glob("*/scene.toml")):
        rel = path.relative_to(inv.run_dir).as_posix()
        blocks.append(Note(scene_text(path), level="code", sources=(rel,)))
    if not blocks:
        blocks.append(Note("No scene files in this run."))
    blocks.append(Table("Package versions", ("package", "version"), versions(), (),
                        caption="Installed when this report was made (not a file of the run)."))
    return Section("appendix", "Appendix: scene files and versions", tuple(blocks))
