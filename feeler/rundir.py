"""Output directories of runs: create them, and never overwrite data without ``force``."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Iterable

import numpy as np

from feeler.errors import OverwriteError

__all__ = ["prepare_out_dir", "write_json", "what_it_is"]


def prepare_out_dir(out: str | Path, files: Iterable[str], *, force: bool) -> Path:
    """Create ``out`` and check that none of ``files`` exists in it unless ``force``.

    Raises:
        OverwriteError: the first of ``files`` that already exists (when not ``force``).
    """
    out = Path(out)
    if not force:
        for name in files:
            if (out / name).exists():
                raise OverwriteError(out / name)
    out.mkdir(parents=True, exist_ok=True)
    return out


def write_json(path: str | Path, obj: Any) -> None:
    """Write ``obj`` as indented JSON, turning numpy scalars and arrays into lists."""
    def default(o):
        if isinstance(o, np.ndarray):
            return o.tolist()
        if isinstance(o, np.generic):
            return o.item()
        if isinstance(o, Path):
            return str(o)
        raise TypeError(f"not JSON serialisable: {type(o).__name__}")
    Path(path).write_text(json.dumps(obj, indent=2, default=default) + "\n", encoding="utf-8")


# what a user may hand one command that another one takes: (file in a run directory, or
# columns that identify a CSV; what it is; the command that takes it)
_KINDS = (
    ("posterior.nc", None, "a fit", "fits are read by `feeler classify`, `discriminate`, `decode` and `report`"),
    ("scans.csv", ("scan_id", "uy_mm"), "robot scans", "`feeler calibrate neuron` fits them and "
                                                        "`feeler classify FIT` classifies them"),
    ("calibration.csv", ("fx_n", "ux_mm"), "a sensor-calibration dataset", "`feeler calibrate sensor` fits it"),
    ("trials.csv", ("subject", "comparison_um"), "a psychophysics trial table",
     "`feeler fit psychophysics` and `feeler fit finger-route` fit it"),
)


def what_it_is(path: str | Path, *, header: list[str] | None = None, expected: str = "") -> str:
    """A clause for an error message when ``path`` is a dataset or fit meant for another
    command: "runs/x holds robot scans (scans.csv): `feeler calibrate neuron` fits them
    ..." — or "" when it is none of them. ``header``: a CSV's columns, when already read;
    ``expected``: the file of the kind the caller wanted (e.g. ``trials.csv``), not named."""
    path = Path(path)
    for name, columns, what, use in _KINDS:
        if name == expected:
            continue
        if path.is_dir() and (path / name).is_file():
            return f"{path} holds {what} ({name}): {use}"
        if header is not None and columns and all(c in header for c in columns):
            return f"{path.name} is {what}: {use}"
    if header is None and path.is_file() and path.suffix == ".csv":
        from feeler.datasets import header_columns
        cols = header_columns(path)
        return what_it_is(path, header=cols, expected=expected) if cols else ""
    return ""
