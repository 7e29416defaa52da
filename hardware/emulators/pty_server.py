"""Serve a :class:`GrblEmulator` on a pseudo-terminal, in this process or a child process.

``serve_pty`` opens a pty pair (raw mode, no echo), reports the slave's device path
(e.g. ``/dev/pts/7``) and shuttles bytes until stopped; a driver opens that path exactly
as it would open ``/dev/ttyUSB0``. ``emulator_process`` runs it in a separate process
(``multiprocessing`` spawn) for tests and ``--emulate`` runs, yielding the device path.
The child dies with its parent: on Linux it asks for ``SIGTERM`` when the parent dies
(``PR_SET_PDEATHSIG``), and on every platform it stops once its parent pid changes, so a
test run or a campaign killed with ``kill -9`` leaves no emulator behind.
"""
from __future__ import annotations

import contextlib
import ctypes
import multiprocessing
import os
import select
import signal
import sys
import time
import tty
from dataclasses import dataclass
from typing import Callable, Iterator

from feeler.children import sigint_ignored
from feeler.hardware.emulators.faults import Fault
from feeler.hardware.emulators.grbl import GrblConfig, GrblEmulator

__all__ = ["serve_pty", "emulator_process", "EmulatorProcess"]


def serve_pty(emulator: GrblEmulator, on_ready: Callable[[str], None],
              should_stop: Callable[[], bool] = lambda: False) -> None:
    """Run ``emulator`` on a new pty until ``should_stop()`` or a ``vanish`` fault.

    ``on_ready(path)`` is called once with the slave device path. The emulator keeps its
    own slave descriptor open so that hosts may open and close the port repeatedly.
    """
    master, slave = os.openpty()
    tty.setraw(slave)
    os.set_blocking(master, False)
    try:
        on_ready(os.ttyname(slave))
        _shuttle(emulator, master, should_stop)
    finally:
        for fd in (master, slave):
            with contextlib.suppress(OSError):
                os.close(fd)


def _shuttle(emulator: GrblEmulator, master: int, should_stop: Callable[[], bool]) -> None:
    pending = bytearray()
    while not should_stop() and not emulator.vanished:
        wait = 0.0 if pending else emulator.next_due_s(time.monotonic())
        readable, _, _ = select.select([master], [], [], wait)
        if readable:
            try:
                emulator.receive(os.read(master, 4096), time.monotonic())
            except BlockingIOError:
                pass
        emulator.tick(time.monotonic())
        pending += emulator.pop_output(time.monotonic())
        if pending and not emulator.vanished:
            try:
                del pending[: os.write(master, pending)]
            except BlockingIOError:
                time.sleep(0.001)


@dataclass(frozen=True)
class EmulatorProcess:
    """A running emulator: ``path`` (str) is its device, ``process`` the child."""

    path: str
    process: multiprocessing.process.BaseProcess

    def alive(self) -> bool:
        return self.process.is_alive()


_PR_SET_PDEATHSIG = 1


def _die_with_parent() -> None:
    """Ask Linux for SIGTERM when the parent dies (note: when the parent *thread* that
    started the child exits; ``emulator_process`` is a context manager, so it is stopped
    before that thread can end)."""
    if sys.platform.startswith("linux"):
        with contextlib.suppress(OSError, AttributeError):
            ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0)


def _child(config: GrblConfig, faults: tuple[Fault, ...], seed: int, parent_pid: int, conn) -> None:
    stop = []
    signal.signal(signal.SIGINT, signal.SIG_IGN)        # Ctrl-C is the parent's to handle: it stops us
    signal.signal(signal.SIGTERM, lambda *_: stop.append(True))
    _die_with_parent()
    # the ppid check also covers a parent that died before prctl ran, and non-Linux systems
    serve_pty(GrblEmulator(config, faults, seed), conn.send,
              lambda: bool(stop) or os.getppid() != parent_pid)


@contextlib.contextmanager
def emulator_process(config: GrblConfig = GrblConfig(), faults: tuple[Fault, ...] = (),
                     seed: int = 0, start_timeout_s: float = 30.0) -> Iterator[EmulatorProcess]:
    """Run an emulator in a child process tied to this one; yields once its pty path is known."""
    ctx = multiprocessing.get_context("spawn")
    here, there = ctx.Pipe(duplex=False)
    process = ctx.Process(target=_child, args=(config, tuple(faults), seed, os.getpid(), there),
                          daemon=True, name="grbl-emulator")
    with sigint_ignored():                  # the child inherits SIGINT ignored: Ctrl-C is ours to handle
        process.start()
    try:
        deadline = time.monotonic() + start_timeout_s
        while not here.poll(0.05):
            if not process.is_alive():
                raise RuntimeError(f"emulator process exited with code {process.exitcode} before it started")
            if time.monotonic() > deadline:
                raise RuntimeError(f"emulator did not start within {start_timeout_s} s")
        yield EmulatorProcess(here.recv(), process)
    finally:
        process.terminate()
        process.join(5.0)
        if process.is_alive():
            process.kill()
            process.join()
        here.close()
