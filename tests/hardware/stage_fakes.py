"""Test doubles for the stage driver: a port that replays a byte-exact script."""
from __future__ import annotations

import time

__all__ = ["ScriptedPort", "W", "R"]


def W(data: bytes) -> tuple[str, bytes]:
    """Script step: the host must write exactly ``data`` next."""
    return ("w", data)


def R(data: bytes) -> tuple[str, bytes]:
    """Script step: the device sends ``data`` (readable after the preceding write)."""
    return ("r", data)


class ScriptedPort:
    """A pyserial-like port replaying ``script`` (a list of ``W``/``R`` steps).

    Every write must equal the next ``W`` step; the ``R`` steps that follow it become
    readable. A write while earlier replies are still unread fails (the host must read
    what the script says comes first). ``read`` returns nothing after ``POLL`` seconds,
    like a pyserial port with a short timeout.
    """

    POLL = 0.001

    def __init__(self, script):
        self.script = list(script)
        self.pos = 0
        self.rx = bytearray()
        self.written = bytearray()
        self.write_timeout = 1.0
        self.closed = False
        self._release()

    def _release(self) -> None:
        while self.pos < len(self.script) and self.script[self.pos][0] == "r":
            self.rx += self.script[self.pos][1]
            self.pos += 1

    def write(self, data: bytes) -> int:
        assert not self.rx, f"host wrote {data!r} before reading {bytes(self.rx)!r}"
        assert self.pos < len(self.script), f"unexpected write {data!r} after the script"
        kind, expected = self.script[self.pos]
        assert (kind, data) == ("w", expected), f"wrote {data!r}, script step {self.script[self.pos]!r}"
        self.written += data
        self.pos += 1
        self._release()
        return len(data)

    def flush(self) -> None:
        pass

    @property
    def in_waiting(self) -> int:
        return len(self.rx)

    def read(self, size: int) -> bytes:
        if not self.rx:
            time.sleep(self.POLL)
            return b""
        out = bytes(self.rx[:size])
        del self.rx[:size]
        return out

    def reset_input_buffer(self) -> None:
        self.rx.clear()

    def close(self) -> None:
        self.closed = True

    def done(self) -> bool:
        """Every step was played and every reply read."""
        return self.pos == len(self.script) and not self.rx
