"""The per-scan table of ``feeler classify`` and ``feeler decode``, and the unit check
both make before they answer.

Columns: ``scan_id``, ``step_mm`` (when labelled), ``plate_mm`` (most probable plate at the
scan's end), ``p_<plate>mm`` for every plate, ``height_mm``, ``lo90_mm``, ``hi90_mm``
(decoded step and 90 % interval at the scan's end), ``flagged`` and ``flag`` (why the scan
lies outside the fit's training envelope; empty when inside).
"""
from __future__ import annotations

import numpy as np

from feeler.errors import DataFileError

__all__ = ["plate_column", "unit_mistake", "labelled_summary"]


def plate_column(step_mm: float) -> str:
    """``p_0.1mm``: the column of a plate's probability."""
    return f"p_{step_mm:g}mm"


def unit_mistake(path, scan_ids, flags) -> None:
    """Raise a one-line DataFileError for the first scan whose flags name a unit mistake
    (``flags``: one list of reasons per scan)."""
    for sid, reasons in zip(scan_ids, flags):
        for r in reasons:
            if "probably in" in r:
                raise DataFileError(path, f"scan_id {sid}: {r}; the scan CSV takes t_s in s and uy_mm, x_mm in mm "
                                          "(README, 'Scan CSV format')")


def labelled_summary(table, plates_mm) -> str | None:
    """Accuracy and 90 % coverage over the labelled scans of ``table`` that are not
    flagged (outside the fit's training envelope, where its numbers mean nothing), with
    how many flagged ones were left out; None without labels."""
    if "step_mm" not in table.columns:
        return None
    lab = table[np.isfinite(table["step_mm"].to_numpy(float))]
    if lab.empty:
        return None
    flagged = lab["flagged"].to_numpy(bool) if "flagged" in lab.columns else np.zeros(len(lab), bool)
    if flagged.all():
        return (f"{len(lab)} labelled scans, all flagged (outside the fit's training envelope: see the flags): "
                f"no accuracy to report")
    left_out = f"; {int(flagged.sum())} flagged scan(s) left out" if flagged.any() else ""
    lab = lab[~flagged]
    step = lab["step_mm"].to_numpy(float)
    known = np.isclose(step[:, None], np.asarray(plates_mm)[None, :]).any(axis=1)
    hit = np.isclose(lab["plate_mm"].to_numpy(float), step)
    inside = (step >= lab["lo90_mm"].to_numpy(float)) & (step <= lab["hi90_mm"].to_numpy(float))
    plates = np.asarray(plates_mm, float)
    extra = ""
    if (~known).any():
        extra = f" ({int((~known).sum())} labelled with a step the fit has no plate for"
        if np.isclose(step[~known, None] / 1000, plates[None, :], atol=1e-9).any(axis=1).all():
            extra += f": steps {step[~known].min():g}-{step[~known].max():g} against plates " \
                     f"{plates.min():g}-{plates.max():g} mm, so the labels are probably in um (expected mm)"
        extra += ")"
    hits = (f"{hit[known].mean() * 100:.1f} % classified as their labelled plate" if known.all() else
            f"{hit[known].mean() * 100:.1f} % of the {int(known.sum())} labelled with a trained plate classified as it"
            if known.any() else "none labelled with a trained plate")
    return (f"{len(lab)} labelled scans: {hits}; {inside.mean() * 100:.1f} % of labels inside their 90 % interval"
            f"{extra}{left_out}")
