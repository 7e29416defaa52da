"""Child processes that a terminal's Ctrl-C must not reach.

A terminal sends SIGINT to its whole foreground process group: the emulator child of
``acquire --emulate`` and the dask worker processes of ``calibrate sensors`` heard it
with feeler itself and printed their KeyboardInterrupt tracebacks under feeler's own
one-line "interrupted". Processes started inside :func:`sigint_ignored` inherit SIGINT
ignored (an ignored signal stays ignored through exec, and Python then installs no
handler of its own, nor does asyncio's runner), so they never see it; feeler stops them
itself on the way out.

The disposition is process-wide, so a Ctrl-C pressed while the block runs is lost: keep
the block to the start of the children. Blocking the signal instead (a per-thread mask)
does not reach distributed's workers: a worker forked from a fork server started under a
blocked mask still raised KeyboardInterrupt (measured). ``calibrate sensors`` therefore
ignores SIGINT only while multiprocessing's fork server starts (0.2 s, once a process)
and forks its dask workers from it (:func:`feeler.calib.runner._local_cluster`); the
emulator's block is its ``Popen`` alone.
"""
from __future__ import annotations

import contextlib
import signal
import threading
from typing import Iterator

__all__ = ["sigint_ignored", "sigint_handler"]


@contextlib.contextmanager
def sigint_handler(handler) -> Iterator[bool]:
    """``handler`` (a callable, ``signal.SIG_IGN`` …) for SIGINT while the block runs, the
    one before put back after; yields whether it was installed (only in the main thread:
    elsewhere Python cannot set a handler, and nothing changes)."""
    if threading.current_thread() is not threading.main_thread():
        yield False
        return
    before = signal.signal(signal.SIGINT, handler)
    try:
        yield True
    finally:
        signal.signal(signal.SIGINT, signal.SIG_DFL if before is None else before)   # None: not set from Python


def sigint_ignored():
    """SIGINT ignored while the block runs, for the processes it starts (main thread only,
    :func:`sigint_handler`)."""
    return sigint_handler(signal.SIG_IGN)
