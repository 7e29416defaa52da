"""Scans to decode, labelled or not, read from a CSV in long format (one row per sample).

Decoding needs only ``scan_id``, ``t_s`` (s) and ``uy_mm`` (the sensor's normal (vertical)
displacement U_y, mm); ``x_mm`` (stage position, mm) lets the stage speed be checked and
places a decision along the scan; ``step_mm`` (the plate's step, mm) and ``speed_mm_s``
(commanded speed, mm/s) are labels: when present they add the accuracy and coverage
summary. Scans may differ in length; rows of a scan need not be contiguous but its times
must increase. A run directory written by ``feeler acquire`` holds ``samples.csv`` with
every attempt of a scan: only each scan's last attempt is kept. A directory of one CSV file
per scan (:func:`feeler.datasets.scan_files`) reads as its files in name order, each
record naming its file.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from feeler.datasets import SCAN_FILE_COLUMNS
from feeler.errors import DataFileError

__all__ = ["REQUIRED", "OPTIONAL", "ScanRecord", "read_scan_records", "records_from_frame", "no_scans_problem"]

REQUIRED = ("scan_id", "t_s", "uy_mm")
OPTIONAL = ("x_mm", "step_mm", "speed_mm_s")


@dataclass(frozen=True)
class ScanRecord:
    """One scan.

    Attributes:
        scan_id (int): its id.
        t_s, uy_mm (ndarray[n]): sample times (s, increasing) and U_y (mm).
        x_mm (ndarray[n] | None): stage position, mm.
        step_mm, speed_mm_s (float | None): labels (plate step, mm; commanded speed, mm/s).
        file (str | None): the file it came from, in a directory of one file per scan.
        name (str | None): the id as the file wrote it when ids are names (``touch-01``);
            ``scan_id`` then numbers the scans in order of first appearance.
    """
    scan_id: int
    t_s: np.ndarray
    uy_mm: np.ndarray
    x_mm: np.ndarray | None = None
    step_mm: float | None = None
    speed_mm_s: float | None = None
    file: str | None = None
    name: str | None = None


def read_scan_records(path: str | Path) -> list[ScanRecord]:
    """Scans of a CSV, or of a run directory's ``scans.csv`` (else its ``samples.csv``).

    Raises:
        DataFileError: missing file or column (naming the required ones), non-numeric or
            NaN values, times not increasing within a scan (as the fit's reader names them:
            :func:`feeler.datasets.scan_time_problem`), a label not constant in a scan.
    """
    import dataclasses

    from feeler.datasets import read_csv_file, scan_file_frames, scan_files

    path = Path(path)
    files = scan_files(path)
    if files:
        return [dataclasses.replace(records_from_frame(frame, f)[0], file=f.name)
                for f, frame in zip(files, scan_file_frames(files))]
    if path.is_dir():
        if not (path / "scans.csv").exists() and not (path / "samples.csv").exists():
            raise DataFileError(path, no_scans_problem(path))
        path = path / "scans.csv" if (path / "scans.csv").exists() else path / "samples.csv"
    return records_from_frame(read_csv_file(path), path)


def no_scans_problem(directory: Path) -> str:
    """The line for a directory that holds no scans in any form feeler reads."""
    from feeler.rundir import what_it_is

    hint = what_it_is(directory, expected="scans.csv")
    return ("holds no scans.csv (nor the samples.csv of a run in progress, nor CSV files of one scan each with "
            f"columns {', '.join(SCAN_FILE_COLUMNS)})" + (f"; {hint}" if hint else ""))


def records_from_frame(frame, path) -> list[ScanRecord]:
    """:class:`ScanRecord` s of a long-format frame (``path`` names it in errors)."""
    import pandas as pd

    from feeler.datasets import named_scan_ids, numeric_column, scan_id_text, scan_time_problem, varying_label_problem

    missing = [c for c in REQUIRED if c not in frame.columns]
    if missing:
        from feeler.datasets import renamed_hint
        from feeler.rundir import what_it_is

        kind = what_it_is(Path(path), header=list(frame.columns), expected="scans.csv")
        raise DataFileError(path, f"missing column(s) {', '.join(missing)}; required: {', '.join(REQUIRED)} "
                                  f"(t_s in s, uy_mm in mm); optional: {', '.join(OPTIONAL)}"
                                  + renamed_hint(frame.columns, missing) + (f"; {kind}" if kind else ""))
    if len(frame) == 0:
        raise DataFileError(path, "no rows")
    cols = [c for c in REQUIRED + OPTIONAL + ("attempt",) if c in frame.columns]
    frame, names = named_scan_ids(frame[cols].copy(), path)
    for col in cols:              # labels may be left blank (unlabelled scans); times and U_y may not
        frame[col] = numeric_column(frame, col, path, blank_ok=col not in REQUIRED and col != "x_mm")
    row = pd.Series(np.arange(1, len(frame) + 1), index=frame.index)      # each row's data row in the file
    if "attempt" in frame.columns:                   # samples.csv: each scan's last attempt
        last = frame.groupby("scan_id")["attempt"].transform("max")
        frame = frame[frame["attempt"] == last]
    out = []
    for sid, g in frame.groupby("scan_id", sort=False):
        t = g["t_s"].to_numpy(float)
        problem = scan_time_problem(scan_id_text(sid, names), t, row[g.index].to_numpy(),
                                    g["step_mm"] if "step_mm" in g.columns else None)
        if problem:
            raise DataFileError(path, problem)
        labels = {}
        for col in ("step_mm", "speed_mm_s"):
            if col in g.columns:
                v = g[col].to_numpy(float)
                if np.isnan(v).all():
                    continue
                if np.any(v != v[0]):
                    raise DataFileError(path, varying_label_problem(col, scan_id_text(sid, names), v))
                labels[col] = float(v[0])
        out.append(ScanRecord(scan_id=int(sid), t_s=t, uy_mm=g["uy_mm"].to_numpy(float),
                              x_mm=g["x_mm"].to_numpy(float) if "x_mm" in g.columns else None,
                              name=names[int(sid)] if names else None, **labels))
    return out
