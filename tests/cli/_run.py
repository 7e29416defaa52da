"""Run the real ``feeler`` command line in a subprocess (what a user types)."""
from __future__ import annotations

import os
import pty
import subprocess
import sys
from pathlib import Path

__all__ = ["ENV", "ROOT", "feeler", "python_x", "in_a_pty", "refused_in_one_line"]

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


def in_a_pty(argv: list[str], env: dict | None = None, *, stdout: bool = True, timeout: float = 120) -> str:
    """What ``argv`` writes on a fresh pseudo-terminal (0 rows, 0 columns): its stderr, and
    its stdout too unless ``stdout`` is False (then discarded). ``env`` default: :data:`ENV`
    without COLUMNS and LINES. The command must exit 0."""
    master, slave = pty.openpty()
    env = {k: v for k, v in ENV.items() if k not in ("COLUMNS", "LINES")} if env is None else env
    proc = subprocess.Popen(argv, cwd=ROOT, env=env, stdin=subprocess.DEVNULL,
                            stdout=slave if stdout else subprocess.DEVNULL, stderr=slave)
    os.close(slave)
    chunks = []
    while True:
        try:
            data = os.read(master, 4096)
        except OSError:                                 # EIO: the child closed the pty
            break
        if not data:
            break
        chunks.append(data)
    assert proc.wait(timeout=timeout) == 0
    os.close(master)
    return b"".join(chunks).decode("utf-8", "replace")


def refused_in_one_line(capsys, argv, *needles) -> str:
    """``feeler.cli.main(argv)`` in-process exits 2 with one ``feeler: error:`` line holding
    every one of ``needles``, and no traceback → that line."""
    from feeler.cli import main

    assert main([str(a) for a in argv]) == 2
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.startswith("feeler: error: ")]
    assert len(lines) == 1 and "Traceback" not in err, err
    for n in needles:
        assert n in lines[0], lines[0]
    return lines[0]
