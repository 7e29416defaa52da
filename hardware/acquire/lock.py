"""One writer per run directory: an operating-system lock held for the life of the writer.

``acquire`` and ``acquire --resume`` (and ``demo``, whose ``make demo`` overwrites
``runs/demo``) take an exclusive ``flock`` on ``RUN/.lock`` before they change anything in
``RUN`` and write their PID into it. The operating system releases
the lock when the process ends, however it ends (``kill -9`` included), so there is never a
stale lock to clean up; a second writer is refused with a one-line error naming the PID
that holds the directory.
"""
from __future__ import annotations

import fcntl
import os
import time
from pathlib import Path

from feeler.errors import InputError

__all__ = ["RunLocked", "lock_run_dir", "release_run_dir", "LOCK_NAME"]

LOCK_NAME = ".lock"


class RunLocked(InputError):
    """Another process is writing the run directory.

    Attributes:
        path (str): the run directory; ``pid`` (int | None) the process holding it.
    """

    def __init__(self, path: object, pid: int | None, then: str = "then --resume"):
        self.path, self.pid = str(path), pid
        who = f"process {pid}" if pid else "another process"
        super().__init__(f"{self.path}: {who} is writing this run directory (one writer at a time); "
                         f"wait for it to finish or stop it{', ' + then if then else ''}")


def _holder(fd: int) -> int | None:
    for _ in range(20):                     # the holder writes its PID right after locking
        text = os.pread(fd, 32, 0).decode("ascii", "replace").strip()
        if text.isdigit():
            return int(text)
        time.sleep(0.005)
    return None


def lock_run_dir(out: str | Path, then: str = "then --resume") -> int:
    """Create ``out`` if needed and lock it for this process; returns the lock's descriptor.

    Raises:
        RunLocked: another process holds the lock (its PID in the message; ``then``: what
            to do after it finished).
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    fd = os.open(out / LOCK_NAME, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        pid = _holder(fd)
        os.close(fd)
        raise RunLocked(out, pid, then) from None
    os.ftruncate(fd, 0)
    os.pwrite(fd, f"{os.getpid()}\n".encode("ascii"), 0)
    return fd


def release_run_dir(fd: int) -> None:
    """Give the lock up (closing the descriptor releases it)."""
    os.close(fd)
