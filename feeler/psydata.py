"""2AFC trial tables: the CSV schema for human (or synthetic) psychophysics data.

One row per (subject, standard, comparison) cell::

    subject, standard_um, standard_speed_mm_s, comparison_um, comparison_speed_mm_s,
    n_trials, n_comparison_higher

``n_comparison_higher`` counts the trials in which the comparison was judged higher.
Lines starting with ``#`` are comments (the synthetic datasets say so there). Extra
columns are ignored. Rows with ``n_trials = 0`` are allowed (they contribute nothing to a
likelihood), as are cells where every answer was right or every answer wrong.
"""
from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pandas as pd

from feeler.errors import DataFileError

__all__ = ["TRIAL_COLUMNS", "read_trials", "write_trials", "synthetic_note"]

TRIAL_COLUMNS = ("subject", "standard_um", "standard_speed_mm_s", "comparison_um",
                 "comparison_speed_mm_s", "n_trials", "n_comparison_higher")
_POSITIVE = ("standard_um", "standard_speed_mm_s", "comparison_um", "comparison_speed_mm_s")
_COUNTS = ("n_trials", "n_comparison_higher")


def read_trials(path: str | Path) -> pd.DataFrame:
    """Read and validate a trial table.

    Returns:
        DataFrame with exactly ``TRIAL_COLUMNS``: ``subject`` str, heights and speeds
        float64 (µm, mm/s), counts int64; ``attrs["comments"]`` holds the ``#`` lines.
    Raises:
        DataFileError: missing file or columns, empty table, non-numeric value, negative
            or non-integer count, n_comparison_higher > n_trials, non-positive height or
            speed (one line naming the file, the line and the column).
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise DataFileError(path, "no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise DataFileError(path, f"cannot read: {exc}") from None
    lines = [(i, line) for i, line in enumerate(text.splitlines(), start=1)
             if line.strip() and not line.lstrip().startswith("#")]
    if not lines:
        raise DataFileError(path, "no header line; expected columns " + ", ".join(TRIAL_COLUMNS))
    rows = list(csv.reader([line for _, line in lines]))
    header = [h.strip() for h in rows[0]]
    missing = [c for c in TRIAL_COLUMNS if c not in header]
    if missing:
        raise DataFileError(path, f"line {lines[0][0]}: missing column(s) {', '.join(missing)}; "
                                  f"required: {', '.join(TRIAL_COLUMNS)}")
    if len(rows) == 1:
        raise DataFileError(path, "no data rows")
    index = {c: header.index(c) for c in TRIAL_COLUMNS}
    data: dict[str, list] = {c: [] for c in TRIAL_COLUMNS}
    for (lineno, _), row in zip(lines[1:], rows[1:]):
        if len(row) != len(header):
            raise DataFileError(path, f"line {lineno}: {len(row)} fields, header has {len(header)}")
        subject = row[index["subject"]].strip()
        if not subject:
            raise DataFileError(path, f"line {lineno}, column subject: empty")
        data["subject"].append(subject)
        for col in _POSITIVE:
            data[col].append(_number(path, lineno, col, row[index[col]], positive=True))
        n, k = (_count(path, lineno, col, row[index[col]]) for col in _COUNTS)
        if k > n:
            raise DataFileError(path, f"line {lineno}, column n_comparison_higher: {k} > "
                                      f"n_trials {n}")
        data["n_trials"].append(n)
        data["n_comparison_higher"].append(k)
    frame = pd.DataFrame(data, columns=list(TRIAL_COLUMNS))
    frame = frame.astype({c: "float64" for c in _POSITIVE} | {c: "int64" for c in _COUNTS}
                         | {"subject": str})
    frame.attrs["comments"] = [line.lstrip()[1:].strip() for line in text.splitlines()
                               if line.lstrip().startswith("#")]
    return frame


def synthetic_note(trials: pd.DataFrame) -> str:
    """The file's comment lines when they say the data are synthetic, else ""."""
    comments = trials.attrs.get("comments", [])
    return "\n".join(comments) if any("synthetic" in c.lower() for c in comments) else ""


def _number(path, lineno: int, col: str, text: str, *, positive: bool) -> float:
    try:
        value = float(text)
    except ValueError:
        raise DataFileError(path, f"line {lineno}, column {col}: {text.strip()!r} is not a "
                                  f"number") from None
    if not math.isfinite(value) or (positive and value <= 0):
        raise DataFileError(path, f"line {lineno}, column {col}: {value!r} must be finite "
                                  f"and > 0")
    return value


def _count(path, lineno: int, col: str, text: str) -> int:
    value = _number(path, lineno, col, text, positive=False)
    if value < 0 or value != int(value):
        raise DataFileError(path, f"line {lineno}, column {col}: {text.strip()!r} must be a "
                                  f"whole number >= 0")
    return int(value)


def write_trials(path: str | Path, trials: pd.DataFrame, *, comment: str = "") -> None:
    """Write ``trials`` (the ``TRIAL_COLUMNS``) as CSV, ``comment`` lines first as ``# ...``."""
    path = Path(path)
    with path.open("w", encoding="utf-8", newline="") as fh:
        for line in comment.splitlines():
            fh.write(f"# {line}\n")
        out = trials.loc[:, list(TRIAL_COLUMNS)].copy()
        for col in _COUNTS:
            out[col] = np.asarray(out[col], dtype=np.int64)
        out.to_csv(fh, index=False, float_format="%.6g", lineterminator="\n")
