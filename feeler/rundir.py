"""Output directories of runs: create them, and never overwrite data without ``force``."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Iterable

import numpy as np

from feeler.errors import OverwriteError

__all__ = ["prepare_out_dir", "write_json"]


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
