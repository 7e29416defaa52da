"""The real Grbl 1.1h firmware (grbl-sim, ``../shared/grbl-sim``) for hardware-in-the-loop tests.

:func:`firmware_exe` builds it once into ``.cache/grbl-sim/<hash of the sources>/`` under a
file lock (parallel test processes wait for one build), or skips the calling test with the
reason when the sources, ``make`` or a C compiler are missing. :class:`Firmware` serves one
instance on a pseudo-terminal: the program's stdin and stdout are the pty's master, so the
driver opens the slave's device path exactly as it would open ``/dev/ttyUSB0``. Each
instance runs in its own working directory (it keeps ``EEPROM.DAT`` there), dies with this
process (``PR_SET_PDEATHSIG``, and end-of-file on its stdin when the slave closes) and is
stopped by its PID.

What the firmware does that a test must allow for (``../shared/grbl-sim/README.md``): it
reads no input during its first simulated second; it moves in approximately real time and
several times slower on a loaded machine; every input pin reads active (``Pn:PXYZRHS``), so
``$H`` ends in ``ALARM:8``; the bytes 0xFF and 0x06 stop it.
"""
from __future__ import annotations

import contextlib
import fcntl
import functools
import hashlib
import os
import shutil
import subprocess
import time
import tty
from pathlib import Path

import pytest

from feeler.hardware.emulators.firmware import BANNER_END, pin_and_die_with_parent, read_until

__all__ = ["ROOT", "SOURCES", "firmware_exe", "firmware_cpu", "Firmware", "read_until", "BANNER_END", "UNLOCK"]

ROOT = Path(__file__).resolve().parents[2]
SOURCES = Path(os.environ.get("FEELER_GRBL_SIM", ROOT.parent / "shared" / "grbl-sim"))
_BUILT: dict[Path, Path] = {}
UNLOCK = b"[MSG:'$H'|'$X' to unlock]\r\n"


def _sources_hash(src: Path) -> str:
    digest = hashlib.sha256()
    for path in sorted(p for p in src.rglob("*") if p.is_file()):
        digest.update(str(path.relative_to(src)).encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()[:16]


def firmware_exe(src: Path = SOURCES) -> Path:
    """Path of ``grbl_sim.exe``, built on first use (skips the test if it cannot be built)."""
    if src in _BUILT:
        return _BUILT[src]
    if not (src / "build.sh").is_file():
        pytest.skip(f"real-firmware test: grbl-sim sources not found at {src} (set FEELER_GRBL_SIM)")
    missing = [tool for tool in ("make", "bash") if shutil.which(tool) is None]
    if shutil.which("gcc") is None and shutil.which("cc") is None:
        missing.append("a C compiler (gcc)")
    if missing:
        pytest.skip(f"real-firmware test: cannot build grbl-sim without {', '.join(missing)}")
    cache = ROOT / ".cache" / "grbl-sim"
    cache.mkdir(parents=True, exist_ok=True)
    out = cache / _sources_hash(src)
    with open(cache / ".lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)            # one build; the others wait, then reuse it
        done = subprocess.run(["bash", str(src / "build.sh"), str(out)], capture_output=True, text=True)
    if done.returncode != 0:
        pytest.fail(f"grbl-sim build failed in {out}: {done.stderr.strip()[-800:]}")
    _BUILT[src] = Path(done.stdout.strip().splitlines()[-1])
    return _BUILT[src]


def firmware_cpu(cpus, worker: str | None) -> int:
    """The one CPU a grbl-sim runs on (see :class:`Firmware`): counted down from the highest
    of ``cpus`` by the pytest-xdist worker's number (``worker``: ``"gw1"``, or None outside
    xdist), so the two workers' simulators do not share one CPU."""
    cpus = sorted(cpus)
    n = int(worker[2:]) if worker and worker.startswith("gw") and worker[2:].isdigit() else 0
    return cpus[-1 - n % len(cpus)]


class Firmware:
    """One running grbl-sim on a pty: ``path`` is its device, ``pid`` its process.

    The program runs on one CPU. grbl-sim runs Grbl's main loop and its emulated timer
    interrupts on two host threads that share the firmware's state without the AVR's
    atomicity; run truly in parallel on a loaded host, a stepper interrupt now and then
    loses an update and the simulator reports Run forever without moving (3 stalls in 13
    30-mm moves with both cores busy; none in 19 on one CPU). On one CPU the two threads
    interleave as an interrupt and a main loop do on the board's one core.

    Args:
        workdir (Path): a fresh directory (its ``EEPROM.DAT`` holds the settings).
        exe (Path): the built program (default: :func:`firmware_exe`).
        ready_timeout_s (float): how long the first status report may take (the firmware
            reads nothing during its first simulated second, slower on a loaded machine).
    """

    def __init__(self, workdir: Path, exe: Path | None = None, ready_timeout_s: float = 60.0):
        self.workdir, self.exe, self.ready_timeout_s = Path(workdir), exe, ready_timeout_s
        self.workdir.mkdir(parents=True, exist_ok=True)
        self._start()

    def _start(self) -> None:
        exe, ready_timeout_s = self.exe, self.ready_timeout_s
        master, self._slave = os.openpty()
        tty.setraw(self._slave)
        self.path = os.ttyname(self._slave)
        self.process = subprocess.Popen(
            [str(exe or firmware_exe()), "-n", "-s", "/dev/null", "-b", "/dev/null"],
            stdin=master, stdout=master, stderr=subprocess.DEVNULL, cwd=self.workdir,
            preexec_fn=functools.partial(pin_and_die_with_parent,      # one CPU: see the class docstring
                                         firmware_cpu(os.sched_getaffinity(0), os.environ.get("PYTEST_XDIST_WORKER"))))
        os.close(master)
        self.pid = self.process.pid
        self.boot = b""
        try:
            self._wait_ready(ready_timeout_s)
        except BaseException:
            self.stop()
            raise

    def _wait_ready(self, timeout_s: float) -> None:
        """Read the boot output, then wait until a ``?`` is answered and the line is quiet."""
        fd = self._slave
        boot = read_until(fd, lambda d: b"['$' for help]\r\n" in d, timeout_s)
        os.write(fd, b"?")
        boot += read_until(fd, lambda d: d.endswith(b">\r\n"), timeout_s)
        if not boot.endswith(b">\r\n"):
            raise RuntimeError(f"grbl-sim {self.pid} did not answer '?' within {timeout_s} s: {boot!r}")
        self.boot = boot[: boot.rindex(b"<")]          # everything it sent before the report
        read_until(fd, lambda d: False, 0.05)

    @property
    def fd(self) -> int:
        """This process's own descriptor of the device (not to be used while a driver is)."""
        return self._slave

    def prepare(self, timeout_s: float = 60.0) -> None:
        """Back at machine zero, Grbl's defaults, idle, report counters at zero (replies dropped).

        A simulator whose motion has stalled (see :meth:`stalled`) is restarted once first.
        """
        try:
            self._prepare(timeout_s)
        except RuntimeError:
            if not self.stalled():
                raise
            self.restart()
            self._prepare(timeout_s)

    def _report(self) -> bytes | None:
        """One status report ``<...>`` answering a ``?`` of ours (pending bytes dropped
        first), or None without an answer within 10 s. Only while no driver reads the device."""
        fd = self._slave
        read_until(fd, lambda d: False, 0.05)
        os.write(fd, b"?")
        got = read_until(fd, lambda d: d.endswith(b">\r\n"), 10.0)
        return got[got.rfind(b"<"):] if got.endswith(b">\r\n") else None

    def idle_at(self) -> tuple[float, ...] | None:
        """The machine position when the simulator reports Idle, else None (busy, or no
        answer to ``?``). Only while no driver has the device open."""
        with contextlib.suppress(OSError):
            fields = (self._report() or b"<>").strip(b"<>\r\n").split(b"|")
            if fields[0] == b"Idle" and len(fields) > 1 and fields[1].startswith(b"MPos:"):
                return tuple(float(v) for v in fields[1][5:].split(b","))
        return None

    def stalled(self, probe_s: float = 2.0) -> bool:
        """Whether the simulator is stuck: no answer to ``?``, or in Run/Jog with the
        machine position unchanged over ``probe_s``.

        grbl-sim runs Grbl's main loop and its emulated timer interrupts on two host
        threads without the AVR's atomicity; on a loaded host a stepper start can be lost,
        after which it reports Run forever and no reset recovers it. A real Grbl in Run
        always moves (its position counts the steps it sends), so Run without motion is a
        fault of the simulator, never a state a driver has to handle.
        """
        with contextlib.suppress(OSError):
            first = self._report()
            if first is None:
                return True
            time.sleep(probe_s)
            second = self._report()
            if second is None:
                return True
            moving = first.startswith((b"<Run", b"<Jog")) and second.startswith((b"<Run", b"<Jog"))
            return moving and first.split(b"|")[1] == second.split(b"|")[1]
        return True

    def restart(self) -> None:
        """Kill the program and start a fresh one in the same directory (a new pty path)."""
        self.stop()
        self._start()

    def _prepare(self, timeout_s: float) -> None:
        fd = self._slave
        home = [(b"$%d=%d\n" % (n, v), b"ok\r\n") for n, v in ((110, 3000), (111, 3000), (112, 3000),
                                                              (120, 1000), (121, 1000), (122, 1000))]
        home += [(b"G53 G0 X0 Y0 Z0\n", b"ok\r\n"), (b"G4 P0\n", b"ok\r\n")]
        wipe = [(b"$RST=*\n", BANNER_END), (b"$X\n", b"ok\r\n")]
        read_until(fd, lambda d: False, 0.05)
        for send, end in [(b"\x18", BANNER_END), *wipe, *home, *wipe, (b"\x18", BANNER_END)]:
            os.write(fd, send)
            got = read_until(fd, lambda d: d.endswith(end) or d.endswith(end + UNLOCK), timeout_s)
            if end not in got:
                raise RuntimeError(f"grbl-sim {self.pid}: no {end!r} after {send!r}: {got!r}")
        read_until(fd, lambda d: False, 0.3)

    def power_cycle(self) -> None:
        """Stop the program and start it again in the same directory (its EEPROM kept).

        The simulator writes EEPROM.DAT through a buffered stream: it is stopped with
        Ctrl-F (0x06), on which it exits and flushes, so the last setting written survives.
        """
        with contextlib.suppress(OSError):
            os.write(self._slave, b"\x06")
        with contextlib.suppress(subprocess.TimeoutExpired):
            self.process.wait(30)
        self.stop()
        self._start()

    def stop(self) -> None:
        """Stop the program (by its PID) and release the pty."""
        if self.process.poll() is None:
            self.process.kill()
        self.process.wait()
        with contextlib.suppress(OSError):
            os.close(self._slave)

    def __enter__(self) -> "Firmware":
        return self

    def __exit__(self, *exc) -> None:
        self.stop()
