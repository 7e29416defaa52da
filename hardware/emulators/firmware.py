"""Serve the real Grbl 1.1h firmware (grbl-sim, a host program) on a pseudo-terminal.

``../shared/grbl-sim/build.sh DIR`` builds the unchanged Grbl 1.1h sources with grbl-sim
into ``DIR/grbl/grbl-sim/grbl_sim.exe`` (it prints that path). The program speaks Grbl's
serial protocol on its standard input and output; :func:`serve_firmware` makes those the
master side of a pty, so a driver opens the slave's device path (``/dev/pts/N``) exactly as
it would open ``/dev/ttyUSB0`` — what ``socat PTY,... EXEC:...`` does, without socat. It is
what ``feeler emulate firmware`` runs, and what ``tests/hardware`` do with their fixture.

What the program needs (``../shared/grbl-sim/README.md``): a working directory of its own
(it keeps its settings, ``$$``, in ``EEPROM.DAT`` there: a new directory boots with Grbl's
defaults); about a second before it reads any input, so the path is announced only once it
has answered a status query; one CPU (its main loop and its emulated interrupts are two host
threads that share the firmware's state without the board's atomicity: on two busy cores a
stepper start is now and then lost and it reports Run forever without moving).
"""
from __future__ import annotations

import contextlib
import ctypes
import functools
import os
import select
import signal
import subprocess
import time
import tty
from pathlib import Path
from typing import Callable

from feeler.errors import ArgumentError

__all__ = ["serve_firmware", "BANNER_END", "read_until", "pin_and_die_with_parent"]

BANNER_END = b"['$' for help]\r\n"


def read_until(fd: int, done: Callable[[bytes], bool], timeout_s: float) -> bytes:
    """Bytes read from ``fd`` until ``done(data)`` is true or ``timeout_s`` passes."""
    data = b""
    deadline = time.monotonic() + timeout_s
    while not done(data) and (left := deadline - time.monotonic()) > 0:
        if select.select([fd], [], [], min(left, 0.05))[0]:
            data += os.read(fd, 4096)
    return data


def pin_and_die_with_parent(cpu: int) -> None:  # pragma: no cover - runs in the child before exec
    """A child's set-up before exec (``preexec_fn=functools.partial(pin_and_die_with_parent, cpu)``):
    SIGKILL when its parent dies (PR_SET_PDEATHSIG), and one CPU, ``cpu``."""
    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL, 0, 0, 0)      # PR_SET_PDEATHSIG
    with contextlib.suppress(OSError, AttributeError):
        os.sched_setaffinity(0, {cpu})


def serve_firmware(exe: str | Path, workdir: str | Path, on_ready: Callable[[str], None],
                   should_stop: Callable[[], bool] = lambda: False, *, ready_timeout_s: float = 60.0) -> int:
    """Run ``exe`` (grbl_sim.exe) in ``workdir`` on a new pty until ``should_stop()`` or the
    program ends; ``on_ready(path)`` gets the slave's device path once the firmware has
    booted and answered ``?``. The program is stopped by its PID when this returns (and
    dies with this process). Returns its exit status (None while running: 0).

    Raises:
        ArgumentError: ``exe`` is not an executable file.
        RuntimeError: the firmware did not answer within ``ready_timeout_s``.
    """
    exe = Path(exe)
    if not (exe.is_file() and os.access(exe, os.X_OK)):
        raise ArgumentError("EXE", str(exe), "grbl_sim.exe as `bash ../shared/grbl-sim/build.sh DIR` builds it "
                            "(it prints the path: DIR/grbl/grbl-sim/grbl_sim.exe)")
    workdir = Path(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    master, slave = os.openpty()
    tty.setraw(slave)
    try:
        process = subprocess.Popen([str(exe.resolve()), "-n", "-s", "/dev/null", "-b", "/dev/null"],
                                   stdin=master, stdout=master, stderr=subprocess.DEVNULL, cwd=workdir,
                                   preexec_fn=functools.partial(pin_and_die_with_parent, max(os.sched_getaffinity(0))))
    finally:
        os.close(master)
    try:
        boot = read_until(slave, lambda d: BANNER_END in d, ready_timeout_s)
        os.write(slave, b"?")
        boot += read_until(slave, lambda d: d.endswith(b">\r\n"), ready_timeout_s)
        if not boot.endswith(b">\r\n"):
            raise RuntimeError(f"{exe} (pid {process.pid}) did not answer '?' within {ready_timeout_s:g} s: "
                               f"{boot[-200:]!r}")
        read_until(slave, lambda d: False, 0.05)         # a quiet line for the driver
        on_ready(os.ttyname(slave))
        while not should_stop() and process.poll() is None:
            time.sleep(0.1)
    finally:
        if process.poll() is None:
            process.kill()
        process.wait()
        with contextlib.suppress(OSError):
            os.close(slave)
    return 0 if process.returncode in (None, -signal.SIGKILL) else process.returncode
