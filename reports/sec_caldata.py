"""A sensor calibration campaign without its M1 fit: the imposed tip displacements against
the measured forces, axis by axis (what ``feeler calibrate sensor`` would fit)."""
from __future__ import annotations

from feeler.reports.model import Note, Section, make_figure, subplots

__all__ = ["caldata_section", "caldata_inputs"]


def _calibration(inv, part):
    """The part's calibration.csv, read once per report."""
    from feeler.calib.matrix import read_calibration_csv

    rel = part.path("calibration.csv")
    return inv.cached(("calibration", rel), lambda: read_calibration_csv(inv.run_dir / rel))


def caldata_inputs(inv, spec) -> None:
    """Read the campaign before the report's first figure."""
    _calibration(inv, spec.parts[0])


def caldata_section(inv, spec) -> Section:
    from feeler.reports.discover import hint_paths, new_output, shown_path

    part = spec.parts[0]
    base, _ = hint_paths(inv.run_dir, list(inv.parts))
    rel = part.path("calibration.csv")
    data = _calibration(inv, part)
    fig, axes = subplots(3, width_in=7.0 / 3, height_in=2.2)
    for j, ax in enumerate(axes):
        for i in range(3):
            ax.plot(data.f_n[:, j], data.u_mm[:, i], "o", ms=3, color=f"C{i}", label=f"U_{'xyz'[i]}")
        ax.set(xlabel=f"F_{'xyz'[j]} (N)", title=f"against F_{'xyz'[j]}")
        ax.tick_params(labelsize=6)
        ax.legend(fontsize=6)
    axes[0].set_ylabel("imposed U (mm)")
    return Section(spec.key, spec.title, (
        Note(f"{len(data.u_mm)} calibration points; fit them with `feeler calibrate sensor "
             f"{shown_path(inv.run_dir / part.rel)} --out {shown_path(new_output(base, 'm1'))}`.", sources=(rel,)),
        make_figure("Imposed displacement against measured force", fig, (rel,),
                    "Each point: one imposed tip displacement and the three-axis force read back.")))
