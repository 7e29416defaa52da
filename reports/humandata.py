"""Human 2AFC data and their psychometric fits, read tolerantly for the report.

``trials.csv`` (subject, standard_um, standard_speed_mm_s, comparison_um,
comparison_speed_mm_s, n_trials, n_comparison_higher) and ``thresholds.csv`` (subject,
standard_speed_mm_s, comparison_speed_mm_s, pse_um, dt_um and their bounds; more columns
may appear and are kept). The pooled rows are the ``all`` rows. A value written as a
bound (``"> 25"``) stays a bound. The synthetic label is one clean sentence built from
the file's comment lines.
"""
from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

__all__ = ["HumanData", "human_data", "Value", "parse_value", "synthetic_label", "condition_words"]

THRESH_COLS = ("subject", "standard_speed_mm_s", "comparison_speed_mm_s", "pse_um", "dt_um")
_BOUND = re.compile(r"^\s*([<>]=?|≥|≤)\s*([-+0-9.eE]+)\s*(\S*)\s*$")


@dataclass(frozen=True)
class Value:
    """A number that may be a bound: ``bound`` is "", ">" or "<" (≥/≤ read as >/<)."""
    value: float
    bound: str = ""


def parse_value(raw) -> Value:
    """``1.03`` → Value(1.03); ``"> 25"`` → Value(25, ">"); anything else → NaN."""
    if isinstance(raw, (int, float, np.number)) and not isinstance(raw, bool):
        return Value(float(raw))
    text = str(raw).strip()
    m = _BOUND.match(text)
    if m:
        return Value(float(m.group(2)), ">" if m.group(1) in (">", ">=", "≥") else "<")
    try:
        return Value(float(text))
    except ValueError:
        return Value(float("nan"))


def synthetic_label(comments) -> str:
    """One sentence from comment lines that say the data are synthetic ("" otherwise)."""
    lines = [c.strip().rstrip(".") for c in comments if c.strip()]
    if not any("synthetic" in c.lower() for c in lines):
        return ""
    rest = [c for c in lines if not c.upper().startswith("SYNTHETIC 2AFC DATA GENERATED")]
    text = "; ".join(rest).replace(" um ", " µm ").replace(" um)", " µm)").replace("um vs", "µm vs")
    return "SYNTHETIC human data, not human measurements" + (f" ({text})." if text else ".")


def condition_words(standard_speed, comparison_speed) -> str:
    """"standard at 40 mm/s vs comparison at 20 mm/s"."""
    return f"standard at {float(standard_speed):g} mm/s vs comparison at {float(comparison_speed):g} mm/s"


@dataclass(frozen=True)
class HumanData:
    """Attributes: trials (DataFrame or None) and trials_rel; thresholds (all rows or None)
    and thresholds_rel; pooled (the ``all`` rows, else every row); label (synthetic
    sentence or ""); m4 (the M4 fit part, for its verdict, or None)."""
    trials: object
    trials_rel: str
    thresholds: object
    thresholds_rel: str
    pooled: object
    label: str
    m4: object

    def standard_um(self, row) -> float:
        """The standard height of a thresholds row (its own column, else the trials')."""
        if "standard_um" in row and np.isfinite(parse_value(row["standard_um"]).value):
            return parse_value(row["standard_um"]).value
        if self.trials is None:
            return float("nan")
        t = self.trials[self.trials["standard_speed_mm_s"] == float(row["standard_speed_mm_s"])]
        values = t["standard_um"].unique()
        return float(values[0]) if len(values) == 1 else float("nan")

    def value(self, row, column: str) -> Value:
        return parse_value(row[column]) if column in row else Value(float("nan"))


def _thresholds(path):
    from feeler.reports.readers import read_table

    table = read_table(path, THRESH_COLS, ("standard_speed_mm_s", "comparison_speed_mm_s"))
    pooled = table[table["subject"].astype(str) == "all"]
    return table, (pooled if len(pooled) else table)


def _load(inv) -> HumanData:
    from feeler.psydata import read_trials

    trials_part = inv.first("psychophysics", prefer="psychophysics")
    thr_part = inv.first("thresholds", prefer="m4")
    trials = read_trials(inv.run_dir / trials_part.path("trials.csv")) if trials_part else None
    table = pooled = None
    if thr_part is not None:
        table, pooled = _thresholds(inv.run_dir / thr_part.path("thresholds.csv"))
    comments = (trials.attrs.get("comments", []) if trials is not None else []) or \
        (table.attrs.get("comments", []) if table is not None else [])
    m4 = next((p for p in inv.of("fit", "m4") if thr_part is None or p.rel == thr_part.rel), None)
    return HumanData(trials=trials, trials_rel=trials_part.path("trials.csv") if trials_part else "",
                     thresholds=table, thresholds_rel=thr_part.path("thresholds.csv") if thr_part else "",
                     pooled=pooled, label=synthetic_label(comments), m4=m4)


def human_data(inv) -> HumanData:
    """The run's human data (the first trials.csv and thresholds.csv found), read once."""
    return inv.cached("human", lambda: _load(inv))
