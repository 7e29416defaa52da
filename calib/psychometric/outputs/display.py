"""The thresholds table as printed: numbers where they hold, bounds where they do not.

``thresholds.csv`` keeps every column numeric (NaN, ±inf where a quantity is undefined or
not reached). Printed, no cell shows NaN:

- ``dt_*`` is the comparison design's (PSE → 75 %): nAFC has no PSE, and the columns are
  left out of an nAFC table (:func:`shown_columns`);
- the threshold at ``pc`` (:func:`threshold_cells`): the posterior mean and 95 % interval
  when every draw reaches P = pc; the median when a few do not (< 2.5 %: the interval is
  still finite); a bound ``> lb`` when more do (the 97.5 % upper end is +inf: the lapse
  keeps P below pc), its upper end printed ``unbounded`` (the CSV keeps ``inf``, a number
  a program reads back); ``—`` when not even the lower end is finite, or when the unreached
  mass lies below the floor (pc < ½ in the comparison design), which the verdict names
  (:func:`feeler.calib.psychometric.outputs.checks.threshold_problems`); the slope at a
  point some draws never reach is ``—``;
- ``gof_p`` and ``deviance`` of a population mean (hierarchical ``all``): ``—``.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

__all__ = ["DASH", "UNBOUNDED", "threshold_cells", "threshold_note", "shown_columns", "display_table"]

DASH = "—"
#: the printed upper end of a threshold's interval that is +inf (a reader took "inf" for a number)
UNBOUNDED = "unbounded"
_DT = ("dt_um", "dt_lb_um", "dt_ub_um")


def _fmt(v: float) -> str:
    return DASH if not np.isfinite(v) else f"{v:.3f}"


def threshold_cells(row) -> dict[str, str]:
    """``threshold_um``, ``threshold_lb_um``, ``threshold_ub_um``, ``slope_per_um`` of one
    table row (a namedtuple or Series) as printed (see the module doc)."""
    mean, lb, ub, med = row.threshold_um, row.threshold_lb_um, row.threshold_ub_um, row.threshold_median_um
    below = not str(row.design).endswith("AFC") and row.pc < 0.5
    slope = _fmt(row.slope_per_um) if np.isfinite(mean) else DASH
    if np.isfinite(mean):
        est = _fmt(mean)
    elif below or not np.isfinite(lb):
        return dict.fromkeys(("threshold_um", "threshold_lb_um", "threshold_ub_um", "slope_per_um"), DASH)
    elif np.isfinite(ub):
        est = _fmt(med)
    else:
        est = f"> {lb:.3f}"
    return {"threshold_um": est, "threshold_lb_um": _fmt(lb), "threshold_ub_um": UNBOUNDED if ub == np.inf else _fmt(ub),
            "slope_per_um": slope}


def threshold_note(row) -> str:
    """The note under the table for a row whose threshold some draws never reach ("" if none)."""
    u, pc = float(row.threshold_unreached), float(row.pc)
    if not u > 0 or np.isfinite(row.threshold_um):
        return ""
    head = f"{row.subject} at {row.standard_speed_mm_s:g}/{row.comparison_speed_mm_s:g} mm/s"
    below = not str(row.design).endswith("AFC") and pc < 0.5
    if below:
        return (f"{head}: for {100 * u:.1f} % of the posterior P stays above {pc:g} (the lapse): the threshold is "
                f"not shown (see the verdict)")
    if not np.isfinite(row.threshold_lb_um):
        return (f"{head}: {100 * u:.1f} % of the posterior never reaches P = {pc:g} (the lapse): the threshold is "
                f"not pinned down (see the verdict)")
    if np.isfinite(row.threshold_ub_um):
        return (f"{head}: {100 * u:.1f} % of the posterior never reaches P = {pc:g} (the lapse): the threshold "
                f"is its median, the slope is not shown")
    return (f"{head}: the threshold at P = {pc:g} is a bound, > {row.threshold_lb_um:.3f} µm: {100 * u:.1f} % of "
            f"the posterior never reaches P = {pc:g} (the lapse keeps P below it); the slope is not shown")


def shown_columns(table: pd.DataFrame, columns) -> list[str]:
    """``columns`` without the DT columns when every row is nAFC."""
    nafc = table["design"].astype(str).str.endswith("AFC").all() if len(table) else False
    return [c for c in columns if not (nafc and c in _DT)]


def display_table(table: pd.DataFrame, columns) -> tuple[pd.DataFrame, list[str]]:
    """(the table of strings to print, its notes) for :func:`shown_columns` of ``columns``."""
    cols = shown_columns(table, columns)
    out = table[cols].copy().astype(object)
    for i, row in enumerate(table.itertuples(index=False)):
        for c in cols:
            v = getattr(row, c)
            if isinstance(v, (float, np.floating)):
                out.iat[i, cols.index(c)] = _fmt(v)
        for c, text in threshold_cells(row).items():
            if c in cols:
                out.iat[i, cols.index(c)] = text
    notes = [n for n in (threshold_note(r) for r in table.itertuples(index=False)) if n]
    return out, notes
