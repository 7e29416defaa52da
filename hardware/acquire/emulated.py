"""The Grbl emulator of ``feeler acquire --emulate``, in a child process tied to its parent.

Like :func:`feeler.hardware.emulators.emulator_process` (spawned, serving a real pty), but
the child asks Linux for ``SIGTERM`` when its parent dies (``PR_SET_PDEATHSIG``), so a
campaign killed with ``kill -9`` does not leave an emulator behind; it also stops when its
parent's pid changes (other platforms).
"""
from __future__ import annotations

import contextlib
import ctypes
import multiprocessing
import os
import signal
import sys
from typing import Iterator

from feeler.hardware.emulators import GrblConfig, GrblEmulator, serve_pty

__all__ = ["campaign_emulator", "FAST_STAGE"]

_PR_SET_PDEATHSIG = 1


def _child(config: GrblConfig, faults: tuple, parent_pid: int, conn) -> None:
    stop = []
    signal.signal(signal.SIGTERM, lambda *_: stop.append(True))
    if sys.platform.startswith("linux"):
        ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0)
    serve_pty(GrblEmulator(config, faults, 0), conn.send,
              lambda: bool(stop) or os.getppid() != parent_pid)


#: the emulated machine of ``feeler acquire --emulate``: a quick desktop stage (all axes
#: 6000 mm/min, 2000 mm/s², travel 200 × 200 × 50 mm) so that emulated campaigns run fast
FAST_STAGE = GrblConfig(max_rate_mm_min=(6000.0, 6000.0, 6000.0), accel_mm_s2=(2000.0, 2000.0, 2000.0))


@contextlib.contextmanager
def campaign_emulator(config: GrblConfig = FAST_STAGE, faults: tuple = (),
                      start_timeout_s: float = 30.0) -> Iterator[str]:
    """Run a Grbl emulator (with injected ``faults``, :class:`~feeler.hardware.emulators.Fault`)
    in a child process; yields its pty device path.

    Start it at the plan's first position with ``dataclasses.replace(FAST_STAGE, start_mm=...)``.
    """
    ctx = multiprocessing.get_context("spawn")
    here, there = ctx.Pipe(duplex=False)
    process = ctx.Process(target=_child, args=(config, tuple(faults), os.getpid(), there), daemon=True,
                          name="grbl-emulator")
    process.start()
    try:
        if not here.poll(start_timeout_s):
            raise RuntimeError(f"emulator did not start within {start_timeout_s} s")
        yield here.recv()
    finally:
        process.terminate()
        process.join(5.0)
        if process.is_alive():
            process.kill()
            process.join()
        here.close()
