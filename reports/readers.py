"""Readers of run files for the report: anything unreadable is a one-line DataFileError.

A missing file is not an error here (the report lists it as missing); a file that exists
but cannot be read — a corrupt NetCDF, a CSV with garbage or without its columns, a JSON
that does not parse — stops the report with :class:`~feeler.errors.DataFileError`
naming the file.
"""
from __future__ import annotations

import json
from pathlib import Path

from feeler.errors import DataFileError

__all__ = ["read_json", "read_table", "load_fit", "scene_text", "verdict_ok", "run_table", "run_json", "run_text"]


def read_json(path: str | Path, keys: tuple[str, ...] = ()) -> dict:
    """A JSON object with at least ``keys``."""
    path = Path(path)
    try:
        obj = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise DataFileError(path, f"not a readable JSON file ({type(exc).__name__})") from None
    if not isinstance(obj, dict):
        raise DataFileError(path, f"expected a JSON object, found {type(obj).__name__}")
    missing = [k for k in keys if k not in obj]
    if missing:
        raise DataFileError(path, f"missing key(s) {', '.join(missing)}")
    return obj


def read_table(path: str | Path, columns: tuple[str, ...] = (), numeric: tuple[str, ...] = ()):
    """A CSV (``#`` lines are comments, kept in ``attrs["comments"]``) with ``columns``,
    of which ``numeric`` must hold finite numbers.

    Returns:
        pandas.DataFrame
    """
    from feeler.datasets import missing_columns_problem, numeric_column, read_csv_file

    path = Path(path)
    frame = read_csv_file(path, comment="#")          # also a user's own file as a spreadsheet exports it
    problem = missing_columns_problem(frame, columns)
    if problem:
        raise DataFileError(path, problem)
    if columns and frame.empty:
        raise DataFileError(path, "no data rows")
    for col in numeric:
        frame[col] = numeric_column(frame, col, path).to_numpy()
    return frame


def run_table(inv, rel: str, columns: tuple[str, ...] = (), numeric: tuple[str, ...] = ()):
    """:func:`read_table` of the run's file ``rel``, read once per report (the report reads
    every input before its first figure, :func:`feeler.reports.build.read_inputs`, and the
    sections take them from the inventory's cache); each call gets its own copy."""
    key = ("table", rel, tuple(columns), tuple(numeric))
    return inv.cached(key, lambda: read_table(inv.run_dir / rel, tuple(columns), tuple(numeric))).copy()


def run_json(inv, rel: str, keys: tuple[str, ...] = ()) -> dict:
    """:func:`read_json` of the run's file ``rel``, read once per report (a copy each call)."""
    import copy

    return copy.deepcopy(inv.cached(("json", rel, tuple(keys)), lambda: read_json(inv.run_dir / rel, tuple(keys))))


def run_text(inv, rel: str) -> str:
    """:func:`scene_text` of the run's file ``rel``, read once per report."""
    return inv.cached(("text", rel), lambda: scene_text(inv.run_dir / rel))


def load_fit(directory: str | Path, inv=None):
    """A :class:`feeler.calib.fit.FitResult` (corrupt posterior.nc etc. → DataFileError);
    read once per report when the inventory ``inv`` is given."""
    from feeler.calib.fit import load

    if inv is None:
        return load(directory)
    return inv.cached(("fit", str(directory)), lambda: load(directory))


def verdict_ok(inv, part) -> bool | None:
    """The verdict of the fit in ``part``'s directory (None when there is none)."""
    if part is None or not inv.has(part.path("verdict.json")):
        return None
    return bool(run_json(inv, part.path("verdict.json"), ("ok",))["ok"])


def scene_text(path: str | Path) -> str:
    """A scene file's text, for the appendix."""
    path = Path(path)
    try:
        return path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise DataFileError(path, f"not a readable text file ({type(exc).__name__})") from None
