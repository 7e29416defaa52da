"""What an M4 fit directory holds beyond the posterior: its thresholds table, read
tolerantly (columns the fit adds are shown too), and its per-subject curve images
(``curves/index.csv``: subject, standard_um, standard_speed_mm_s, comparison_speed_mm_s,
file), every one listed shown.
"""
from __future__ import annotations

import base64

import numpy as np

from feeler.reports.humandata import THRESH_COLS, parse_value
from feeler.reports.model import Gallery, Table, fmt, interval
from feeler.reports.readers import run_table

__all__ = ["thresholds_table", "thresholds_frame", "curves_gallery", "curve_items", "CURVE_INDEX"]

CURVE_INDEX = "curves/index.csv"
CURVE_WIDTH_IN = 3.3        # the width the fit draws each curve at (calib.psychometric.outputs.plots)
#: further columns shown when the file has them (a page has room for about a dozen); the
#: caption names the rest of the file's columns
SHOWN = {"standard_um": "standard (µm)", "estimand": "estimand", "backend": "backend", "pc": "at P",
         "threshold_um": "threshold at P (µm)", "slope_per_um": "slope at P (1/µm)", "gof_p": "fit p (deviance)"}
_PAIRS = (("PSE (µm)", "pse_um", "pse_lb_um", "pse_ub_um"), ("DT (µm)", "dt_um", "dt_lb_um", "dt_ub_um"))


def thresholds_frame(inv, part):
    """The fit's thresholds.csv, with its columns checked (read once per report)."""
    return run_table(inv, part.path("thresholds.csv"), THRESH_COLS)


def thresholds_table(inv, part) -> Table:
    """Every row of thresholds.csv: PSE and DT as intervals, then the :data:`SHOWN` columns the
    file has; the caption names its other columns."""
    rel = part.path("thresholds.csv")
    t = thresholds_frame(inv, part)
    used = {c for _, *cs in _PAIRS for c in cs} | {"subject", "standard_speed_mm_s", "comparison_speed_mm_s"}
    extra = [c for c in SHOWN if c in t.columns]
    rest = [c for c in t.columns if c not in used and c not in extra]
    rows = []
    for _, r in t.iterrows():
        cells = [str(r["subject"]), f"{fmt(r['standard_speed_mm_s'])} / {fmt(r['comparison_speed_mm_s'])}"]
        for _, m, lo, hi in _PAIRS:
            v = parse_value(r[m])
            cells.append(f"{v.bound} {fmt(v.value, 3)}" if v.bound else
                         interval(v.value, *(parse_value(r[c]).value if c in r else np.nan for c in (lo, hi))))
        cells += [_cell(r, c) for c in extra]
        rows.append(tuple(cells))
    return Table("Thresholds per subject and condition (95 % intervals)",
                 ("subject", "standard / comparison mm/s", *(p[0] for p in _PAIRS), *(SHOWN[c] for c in extra)), tuple(rows), (rel,),
                 caption="The 'all' rows are the pooled estimates (their estimand column, where present, says "
                         "which)." + (f" Also in {rel}: {', '.join(rest)}." if rest else ""))


def _cell(r, c: str) -> str:
    """One :data:`SHOWN` cell: a number, a word as written, a bound "> lb" for a threshold
    the lapse keeps some draws from reaching (its mean undefined, its upper end inf), else
    "—"; never "nan" (an audit's --pc 0.99 printed it)."""
    v = parse_value(r[c]).value
    if np.isfinite(v):
        return fmt(v, 4)
    if isinstance(r[c], str) and r[c].strip().lower() not in ("", "nan", "inf", "-inf"):
        return r[c]
    if c == "threshold_um" and "threshold_lb_um" in r and "threshold_ub_um" in r:
        lb, ub = parse_value(r["threshold_lb_um"]).value, parse_value(r["threshold_ub_um"]).value
        if np.isfinite(lb) and ub == np.inf:
            return f"> {fmt(lb, 4)}"
    return "—"


def curve_items(inv, part) -> tuple | None:
    """(title, data: URI, run-relative PNG) of every curve the fit's curves/index.csv lists,
    each PNG checked (None when there is no index); read once per report."""
    rel = part.path(CURVE_INDEX)
    if not inv.has(rel):
        return None
    return inv.cached(("curves", rel), lambda: _curve_items(inv, part, rel))


def curves_gallery(inv, part) -> Gallery | None:
    """Every PNG listed in the fit's curves/index.csv (None when there is no index)."""
    rel = part.path(CURVE_INDEX)
    items = curve_items(inv, part)
    if items is None:
        return None
    # two a row at about the size the fit draws them (3.3 in): four a row printed their
    # annotations at 3-4 pt (an outside reader of the report)
    return Gallery("Psychometric curve of every subject and condition", tuple(items),
                   (rel,) + tuple(i[2] for i in items), caption=f"Images written by the fit, as listed in {rel}.",
                   width_in=CURVE_WIDTH_IN)


def _curve_items(inv, part, rel: str) -> tuple:
    from feeler.errors import DataFileError

    index = run_table(inv, rel, ("subject", "standard_um", "standard_speed_mm_s", "comparison_speed_mm_s", "file"))
    items = []
    for r in index.itertuples(index=False):
        png = part.path(str(r.file))  # relative to the fit directory, as the fit writes it
        path = inv.run_dir / png
        data = path.read_bytes() if path.is_file() else b""
        if not data.startswith(b"\x89PNG\r\n\x1a\n"):
            raise DataFileError(path, f"listed in {rel} but not a readable PNG")
        title = (f"{r.subject} · {fmt(r.standard_um)} µm at {fmt(r.standard_speed_mm_s)} vs "
                 f"{fmt(r.comparison_speed_mm_s)} mm/s")
        items.append((title, "data:image/png;base64," + base64.b64encode(data).decode("ascii"), png))
    return tuple(items)
