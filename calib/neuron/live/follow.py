"""Follow ``samples.csv`` of a run another process is still writing.

The acquisition (:mod:`feeler.hardware.acquire.lock`) holds an exclusive ``flock`` on
``RUN/.lock`` for as long as it writes the run, and the operating system releases it
however the writer ends. So a run is still being written exactly while that lock is
held: :func:`writer_active`. :func:`follow_rows` yields each complete line of
``samples.csv`` as a dict, keeps a partial last line until its newline arrives, and
ends once the writer has let go and everything it wrote has been read (a line the
writer left cut is dropped, as the acquisition's own resume drops it).
"""
from __future__ import annotations

import csv
import fcntl
import os
import time
from pathlib import Path

from feeler.datasets import csv_dialect, repeated_header_problem
from feeler.errors import DataFileError

__all__ = ["writer_active", "follow_rows", "completed_scans"]


def writer_active(run: str | Path) -> bool:
    """True while a process holds the run directory's writer lock."""
    path = Path(run) / ".lock"
    try:
        fd = os.open(path, os.O_RDONLY)
    except FileNotFoundError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    finally:
        os.close(fd)                      # also releases our shared lock at once
    return False


def completed_scans(run: str | Path) -> set[int] | None:
    """The scan ids an acquisition finished (their ``scan_done`` events in ``RUN/journal.jsonl``),
    or None without a journal. A line cut by a crash is skipped."""
    import json

    path = Path(run) / "journal.jsonl"
    if not path.is_file():
        return None
    done = set()
    for line in path.read_text(encoding="utf-8", errors="replace").splitlines():
        try:
            ev = json.loads(line)
        except ValueError:
            continue
        if isinstance(ev, dict) and ev.get("event") == "scan_done" and "scan_id" in ev:
            done.add(int(ev["scan_id"]))
    return done


def follow_rows(run: str | Path, *, poll_s: float = 0.2, wait_s: float = 30.0, active=None, sleep=time.sleep,
                stats: dict | None = None):
    """Rows of ``RUN/samples.csv`` (dicts of strings keyed by its header) as they are written.

    Args:
        poll_s (float): seconds between looks while the writer is quiet, > 0.
        wait_s (float): how long to wait for ``samples.csv`` to appear, s.
        active (callable | None): is the writer still running? (default :func:`writer_active`).
        stats (dict | None): receives ``partial_lines_dropped``.

    Raises:
        DataFileError: no ``samples.csv`` after ``wait_s`` with no writer, or no header.
    """
    run = Path(run)
    path = run / "samples.csv"
    active = active or (lambda: writer_active(run))
    waited = 0.0
    while not path.exists():
        if (run / "scans.csv").is_file() and not active():   # a finished run: nothing will be written
            raise DataFileError(path, f"no such file, and {run} holds a finished run (scans.csv) that no "
                                      f"acquisition is writing: decode it without --follow")
        if waited >= wait_s and not active():
            raise DataFileError(path, f"no such file after {wait_s:g} s, and no acquisition is writing {run}")
        sleep(poll_s)
        waited += poll_s
    buf, header, lineno = "", None, 0
    with open(path, newline="") as f:
        while True:
            chunk = f.read()
            if not chunk:
                if active():
                    sleep(poll_s)
                    continue
                chunk = f.read()           # anything written just before the writer let go
                if not chunk:
                    break
            buf += chunk
            *lines, buf = buf.split("\n")
            for line in lines:
                lineno += 1
                if not line.strip() or line.lstrip().startswith("#"):     # a logger's notes: comments
                    continue
                if header is None:
                    sep, decimal = csv_dialect(line)                # a lab's own logger may write ';' and 0,5
                    header = [h.strip() for h in next(csv.reader([line.lstrip("\ufeff")], delimiter=sep))]
                    continue
                values = next(csv.reader([line], delimiter=sep))
                if [v.strip() for v in values] == header:          # a logger restarted onto the same file
                    raise DataFileError(path, repeated_header_problem([lineno],
                                                                      why="a logger restarted onto this file?"))
                if decimal != ".":
                    values = [v.replace(decimal, ".") for v in values]
                if len(values) != len(header):
                    raise DataFileError(path, f"a line of {len(values)} fields under a header of {len(header)}")
                yield dict(zip(header, values))
    if header is None:
        raise DataFileError(path, "no header line")
    if stats is not None:
        stats["partial_lines_dropped"] = int(bool(buf.strip()))
