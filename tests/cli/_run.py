"""Run the real ``feeler`` command line in a subprocess (what a user types)."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

__all__ = ["ENV", "ROOT", "feeler", "python_x"]

ROOT = Path(__file__).resolve().parents[2]
ENV = {**os.environ, "MPLBACKEND": "Agg", "NUMBA_CACHE_DIR": str(ROOT / ".cache" / "numba")}


def feeler(*args, cwd: Path = ROOT, timeout: float = 300) -> subprocess.CompletedProcess:
    """``python -m feeler ARGS`` → CompletedProcess with text stdout/stderr."""
    return subprocess.run([sys.executable, "-m", "feeler", *map(str, args)], cwd=cwd, env=ENV,
                          capture_output=True, text=True, timeout=timeout)


def python_x(code: str, *flags: str, timeout: float = 300) -> subprocess.CompletedProcess:
    """``python FLAGS -c CODE`` in the checkout."""
    return subprocess.run([sys.executable, *flags, "-c", code], cwd=ROOT, env=ENV, capture_output=True,
                          text=True, timeout=timeout)
