"""Transport layer: bytes over a pyserial port with deadlines on ``time.monotonic()``.

Any pyserial URL (``loop://``, ``socket://host:port``, ``rfc2217://...``) or device path
(``/dev/ttyUSB0``, the emulator's ``/dev/pts/N``) opens the same way. Every read and
write is logged at DEBUG on the ``feeler.hardware.stage`` logger. A line that is still
incomplete at its deadline is a short read: :class:`StageTimeout` with ``partial`` set.
"""
from __future__ import annotations

import errno
import logging
import time

import serial

try:  # tcdrain on a vanished pty raises termios.error, which is not an OSError
    from termios import error as _TermiosError
except ImportError:  # pragma: no cover - not POSIX
    _TermiosError = OSError

from feeler.hardware.stage.errors import PortError, StageDisconnected, StageTimeout

__all__ = ["Transport", "open_port", "POLL_S"]

log = logging.getLogger("feeler.hardware.stage")
_PORT_ERRORS = (serial.SerialException, OSError, _TermiosError)

#: granularity of blocking reads, seconds (a read returns as soon as bytes arrive)
POLL_S = 0.01
#: more time for a line already begun at its deadline: 80 characters take 7 ms at 115200
#: baud; a busy host or grbl-sim's pty may hold the rest a little longer
LINE_GRACE_S = 0.05

_OPEN_PROBLEMS = {
    errno.ENOENT: "does not exist (is the device plugged in? list ports with "
                  "'python -m serial.tools.list_ports')",
    errno.EACCES: "permission denied (join the 'dialout' group or fix the device mode)",
    errno.EPERM: "permission denied (join the 'dialout' group or fix the device mode)",
    errno.EAGAIN: "busy: another program holds it open (exclusive lock refused)",
    errno.EBUSY: "busy: another program holds it open",
}


def open_port(url: str, *, baudrate: int = 115200, exclusive: bool = True) -> serial.SerialBase:
    """Open ``url`` (device path or pyserial URL) or raise a one-line :class:`PortError`."""
    try:
        port = serial.serial_for_url(url, baudrate=baudrate, timeout=POLL_S,
                                     write_timeout=2.0, exclusive=exclusive)
    except serial.SerialException as exc:
        code = getattr(exc, "errno", None)
        if code in _OPEN_PROBLEMS:
            raise PortError(url, _OPEN_PROBLEMS[code]) from None
        if "configure port" in str(exc):
            raise PortError(url, "not a serial device (terminal settings refused)") from None
        raise PortError(url, f"cannot open: {exc}") from None
    except ValueError as exc:
        raise PortError(url, f"not a device path or pyserial URL: {exc}") from None
    except OSError as exc:  # some URL handlers raise plain OSError
        raise PortError(url, _OPEN_PROBLEMS.get(exc.errno, f"cannot open: {exc}")) from None
    log.debug("%s opened at %d baud", url, baudrate)
    return port


class Transport:
    """Bytes in and out of one open port.

    Args:
        port: an open pyserial port (or any object with ``read(n)``, ``write(b)``,
            ``in_waiting`` and ``close()``; reads must return within about ``POLL_S``).
        name (str): the port's path or URL, used in log lines and errors.
    """

    def __init__(self, port, name: str):
        self.port, self.name = port, name
        self._buf = bytearray()

    @classmethod
    def open(cls, url: str, *, baudrate: int = 115200, exclusive: bool = True) -> "Transport":
        return cls(open_port(url, baudrate=baudrate, exclusive=exclusive), url)

    def write(self, data: bytes) -> None:
        """Write all of ``data``; a vanished port is :class:`StageDisconnected`."""
        log.debug("%s <- %r", self.name, data)
        try:
            written = self.port.write(data)
            self.port.flush()
        except serial.SerialTimeoutException:
            raise StageTimeout(f"write of {data!r} to {self.name}", self.port.write_timeout) from None
        except _PORT_ERRORS as exc:
            raise StageDisconnected(self.name, str(exc)) from None
        if written is not None and written != len(data):
            raise StageDisconnected(self.name, f"wrote {written} of {len(data)} bytes")

    def read_line(self, timeout_s: float, what: str = "reply") -> bytes:
        """Return the next line without its ``\\r\\n``, waiting at most ``timeout_s``.

        A line begun before the deadline gets :data:`LINE_GRACE_S` more to end. At the
        deadline the bytes already waiting are taken before it counts as passed: a process
        descheduled across its deadline on a loaded host finds there the reply that came in
        time, which is no timeout.

        Raises:
            StageTimeout: nothing complete before the deadline (``partial`` holds the
                bytes of an incomplete line, which are discarded).
            StageDisconnected: the port vanished.
        """
        deadline = time.monotonic() + timeout_s
        graced = looked = False
        while True:
            end = self._buf.find(b"\n")
            if end >= 0:
                line = bytes(self._buf[:end]).rstrip(b"\r")
                del self._buf[: end + 1]
                log.debug("%s -> %r", self.name, line)
                return line
            if time.monotonic() >= deadline and not looked:
                looked = True                       # once: what came while this process did not run
                self._take_waiting()
                continue
            if time.monotonic() >= deadline and self._buf and not graced:
                # a line already begun ("o" of an "ok" at the deadline) ends within a few byte
                # times: discarding its start would turn the rest into a damaged line and lose
                # the reply
                deadline, graced = time.monotonic() + LINE_GRACE_S, True
            if time.monotonic() >= deadline:
                partial = bytes(self._buf)
                self._buf.clear()
                if partial:
                    log.debug("%s -> short read %r", self.name, partial)
                raise StageTimeout(f"{what} from {self.name}", timeout_s, partial)
            self._buf += self._read_some()

    def discard_input(self, quiet_s: float) -> bytes:
        """Drop buffered input, then whatever arrives until ``quiet_s`` passes in silence."""
        dropped = bytearray(self._buf)
        self._buf.clear()
        last = time.monotonic()
        while self._waiting() or time.monotonic() - last < quiet_s:
            chunk = self._read_some()
            if chunk:
                dropped += chunk
                last = time.monotonic()
        if dropped:
            log.debug("%s -> discarded %r", self.name, bytes(dropped))
        return bytes(dropped)

    def _take_waiting(self) -> None:
        """Move the bytes the port already holds into the buffer, without waiting."""
        if self._waiting():
            self._buf += self._read_some()

    def _waiting(self) -> int:
        try:
            return self.port.in_waiting
        except _PORT_ERRORS as exc:
            raise StageDisconnected(self.name, str(exc)) from None

    def _read_some(self) -> bytes:
        try:
            return self.port.read(max(1, self.port.in_waiting))
        except _PORT_ERRORS as exc:
            raise StageDisconnected(self.name, str(exc)) from None

    def close(self) -> None:
        try:
            self.port.close()
        except _PORT_ERRORS as exc:  # closing a vanished port: nothing left to release
            log.debug("%s close: %s", self.name, exc)
        log.debug("%s closed", self.name)
