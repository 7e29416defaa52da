"""Calibration campaign data for M1: commanded tip displacements U and measured forces F.

``calibration.csv`` has one row per point with at least the columns
``point_id, ux_mm, uy_mm, uz_mm, fx_n, fy_n, fz_n`` (axes as in the paper: x along the
scan, y the surface normal, z lateral).
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from feeler.errors import DataFileError

__all__ = ["CalibrationData", "read_calibration_csv", "DesignWarning", "weak_directions",
           "CSV_COLUMNS", "U_COLUMNS", "F_COLUMNS", "AXES"]

AXES = ("x", "y", "z")
U_COLUMNS = ("ux_mm", "uy_mm", "uz_mm")
F_COLUMNS = ("fx_n", "fy_n", "fz_n")
CSV_COLUMNS = ("point_id",) + U_COLUMNS + F_COLUMNS     # as feeler writes it; point_id may be left out


class DesignWarning(UserWarning):
    """The design leaves some directions of the matrix unidentified (prior-dominated)."""


@dataclass(frozen=True)
class CalibrationData:
    """One campaign.

    Attributes:
        u_mm (ndarray[n, 3]): commanded tip displacement, mm.
        f_n (ndarray[n, 3]): measured force, N.
        point_id (ndarray[n]): identifiers of the points ("" for a file without them).
    """
    u_mm: np.ndarray
    f_n: np.ndarray
    point_id: np.ndarray

    @property
    def n(self) -> int:
        return int(self.u_mm.shape[0])


def read_calibration_csv(path: str | Path) -> CalibrationData:
    """Read and validate ``calibration.csv``.

    Raises:
        DataFileError: missing file, unreadable CSV, missing columns, non-numeric or
            non-finite values, fewer than 4 points, or forces that are all 0 (one line
            naming the file).
    """
    import pandas as pd

    from feeler.calib.fit import read_csv_columns
    from feeler.datasets import MAX_MAGNITUDE

    path = Path(path)
    if not path.is_file():
        from feeler.rundir import what_it_is
        hint = what_it_is(path.parent if path.name == "calibration.csv" else path, expected="calibration.csv")
        raise DataFileError(path, "no such calibration file" + (f"; {hint}" if hint else ""))
    table = read_csv_columns(path, U_COLUMNS + F_COLUMNS)
    values = {}
    for col in U_COLUMNS + F_COLUMNS:
        v = pd.to_numeric(table[col], errors="coerce").to_numpy(dtype=float)
        bad = np.flatnonzero(~np.isfinite(v))
        if bad.size:
            cell = table[col].iloc[bad[0]]
            shown = (repr(cell.strip()) if isinstance(cell, str) else "an empty or NaN cell" if pd.isna(cell)
                     else f"{float(cell):g}")                 # never numpy's repr ('np.float64(nan)')
            raise DataFileError(path, f"column {col}, row {bad[0] + 1}: {shown} is not a finite number")
        huge = np.flatnonzero(np.abs(v) > MAX_MAGNITUDE)
        if huge.size:
            raise DataFileError(path, f"column {col}, row {huge[0] + 1}: {v[huge[0]]:g} lies beyond "
                                      f"±{MAX_MAGNITUDE:g} (no displacement in mm or force in N comes near)")
        values[col] = v
    if len(table) < 4:
        raise DataFileError(path, f"{len(table)} points; a 3x3 matrix needs at least 4")
    if not any(np.any(values[c]) for c in F_COLUMNS):
        # no response at all: every matrix would be 0 and the noise's posterior collapses onto 0
        raise DataFileError(path, f"columns {', '.join(F_COLUMNS)} are 0 in every row: the force gauge read "
                                  f"nothing (unplugged, or its readings not written into the file); a calibration "
                                  f"needs the measured forces")
    dead = [c for c in F_COLUMNS if not np.any(values[c])]
    if dead:
        # one axis exactly 0 in every row: its noise's posterior collapses onto 0 and its row of K is 0/0
        raise DataFileError(path, f"column {', '.join(dead)} is 0 in every row: that axis of the force gauge "
                                  f"read nothing (unplugged, or its readings not written into the file); a 3x3 "
                                  f"calibration needs the measured forces of all three axes")
    return CalibrationData(u_mm=np.column_stack([values[c] for c in U_COLUMNS]),
                           f_n=np.column_stack([values[c] for c in F_COLUMNS]),
                           point_id=(table["point_id"].to_numpy() if "point_id" in table.columns
                                     else np.full(len(table), "", dtype=object)))


def weak_directions(x: np.ndarray, *, what: str, unit: str, rel_tol: float = 1e-6,
                    warn: bool = True) -> list[np.ndarray]:
    """Directions of the design that the data do not identify.

    The Gram matrix XᵀX of the design ``x (ndarray[n, 3])`` has eigenvalues λ_k; a
    direction whose λ_k < ``rel_tol`` · λ_max carries (almost) no information, so the
    matrix along it is set by the prior. Each such unit eigenvector is returned and, with
    ``warn``, named in a :class:`DesignWarning`.
    """
    lam, vec = np.linalg.eigh(x.T @ x)
    top = max(float(lam[-1]), np.finfo(float).tiny)
    out = []
    for k in np.flatnonzero(lam < rel_tol * top):
        v = vec[:, k] * np.sign(vec[np.argmax(np.abs(vec[:, k])), k])
        out.append(v)
        if warn:
            coords = ", ".join(f"{a}={c:+.3f}" for a, c in zip(AXES, v))
            warnings.warn(f"calibration design: the {what} direction ({coords}) [{unit}] is "
                          f"unidentified (eigenvalue {max(lam[k], 0.0) / top:.1e} of the largest); "
                          f"the matrix along it comes from the prior", DesignWarning, stacklevel=3)
    return out
