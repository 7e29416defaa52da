"""Checks every command runs on its output path before any work (issue 16 items 3, 4).

A fit that runs for minutes and then cannot write its result has wasted the user's
time: ``--out`` at an existing file, in a read-only or immutable directory, or at an
earlier result without ``--force`` is refused first, in one line.
"""
from __future__ import annotations

import os
import tempfile
from pathlib import Path

from feeler.errors import ArgumentError, OverwriteError

__all__ = ["check_out_dir"]


def check_out_dir(out: str | os.PathLike, files=(), *, force: bool = False, name: str = "--out") -> Path:
    """Refuse ``out`` unless it is (or can become) a writable directory; nothing is created.

    Args:
        out: the output directory a command will write.
        files (iterable of str): file names the command writes into ``out``; one that
            already exists is refused unless ``force``.
        force (bool): overwriting earlier results is allowed.
        name (str): the argument, for the message.

    Raises:
        ArgumentError: ``out`` (or a parent) is a file, or the directory that would hold
            the output is not writable (read-only, immutable, no permission).
        OverwriteError: one of ``files`` exists in ``out`` and not ``force``.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ArgumentError(name, str(out), "a directory to write into, not an existing file")
    if out.is_dir() and not force:
        for f in files:
            if (out / f).exists():
                raise OverwriteError(out / f)
    probe_in = out
    while not probe_in.exists():                     # the nearest existing ancestor
        if probe_in.parent == probe_in:
            break
        probe_in = probe_in.parent
    if not probe_in.is_dir():
        raise ArgumentError(name, str(out), f"a directory path, but {probe_in} is a file")
    try:                                             # os.access says yes to root on read-only mounts
        fd, probe = tempfile.mkstemp(prefix=".feeler-write-check-", dir=probe_in)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        why = exc.strerror or type(exc).__name__
        raise ArgumentError(name, str(out), f"a directory feeler can write into ({probe_in}: {why})") from None
    return out
