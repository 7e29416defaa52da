"""Protocol layer: Grbl 1.1 line framing, replies, flow control, reset and unlock.

:class:`GrblProtocol` sends G-code lines with character-counting flow control (the sum of
the lengths of unacknowledged lines, ``\\n`` included, stays within the controller's
receive buffer, ``RX_BUFFER_BYTES - 1`` = 127 bytes), matches every ``ok``/``error:N`` to
the oldest line in flight, sends the real-time ``?``, ``!``, ``~`` and Ctrl-X bytes, and
turns controller status into exceptions in exactly one place, :meth:`GrblProtocol._check`.

Damaged or lost replies that the driver recovers from (a status report queried again, a
move re-sent by the device layer) are counted in :attr:`GrblProtocol.recovered`, keyed
``"<reply>_<damage>"`` (:func:`damage_of`), so a campaign can report them as bad lines.
"""
from __future__ import annotations

import logging
from collections import Counter, deque

from feeler.errors import ArgumentError
from feeler.hardware.stage.errors import ProtocolError, StageAlarm, StageTimeout
from feeler.hardware.stage.replies import (Alarm, Banner, Error, Message, Ok, Reply, Setting,
                                           Status, parse_reply)
from feeler.hardware.stage.transport import Transport

__all__ = ["GrblProtocol", "RX_BUFFER_BYTES", "MAX_LINE_CHARS", "DAMAGES", "damage_of", "parse_reply"]

log = logging.getLogger("feeler.hardware.stage")

RX_BUFFER_BYTES = 128
MAX_LINE_CHARS = 78
_REALTIME = set("?!~\x18")

#: how a reply can be damaged: not valid Grbl (garbled, or a cut line run into the next),
#: cut short with no line end before the deadline (truncated), or never arrived (lost)
DAMAGES = ("malformed", "short_read", "lost")


def damage_of(exc: Exception) -> str | None:
    """Which of :data:`DAMAGES` ``exc`` reports, or None for a real answer (``error:N``)."""
    if isinstance(exc, ProtocolError):
        return "malformed" if exc.code is None else None
    if isinstance(exc, StageTimeout):
        return "short_read" if exc.partial else "lost"
    return None


class GrblProtocol:
    """Grbl conversation over a :class:`Transport`.

    Args:
        transport: the byte layer.
        reply_timeout_s (float): deadline for each awaited reply, seconds.
        status_retries (int): extra ``?`` queries after a lost or damaged status report.

    Attributes:
        recovered (Counter[str]): damaged or lost replies recovered from so far, keyed
            ``"status_<damage>"`` (queried again) or ``"ok_<damage>"`` (move re-sent,
            counted by :meth:`count_recovered`), ``<damage>`` one of :data:`DAMAGES`.
    """

    def __init__(self, transport: Transport, *, reply_timeout_s: float = 2.0,
                 status_retries: int = 2):
        self.transport = transport
        self.reply_timeout_s, self.status_retries = reply_timeout_s, status_retries
        self.in_flight: deque[str] = deque()
        self.messages: deque[Message] = deque(maxlen=64)
        self.last_alarm: int | None = None
        self.recovered: Counter[str] = Counter()

    def count_recovered(self, reply: str, exc: Exception) -> None:
        """Count one damaged or lost ``reply`` (e.g. ``"ok"``) that is being recovered."""
        self.recovered[f"{reply}_{damage_of(exc)}"] += 1

    @property
    def in_flight_bytes(self) -> int:
        """Bytes of unacknowledged lines now in the controller's receive buffer."""
        return sum(len(line) + 1 for line in self.in_flight)

    # ---- the one place where controller status becomes an exception
    def _check(self, reply: Reply) -> Reply:
        """Account for ``reply``; raise for ``error:N`` and ``ALARM:N``."""
        if isinstance(reply, (Ok, Error)):
            sent = self.in_flight.popleft() if self.in_flight else ""
            if isinstance(reply, Error):
                raise ProtocolError(reply.code, f"error:{reply.code}".encode(), sent)
        elif isinstance(reply, Alarm):
            self.last_alarm = reply.code
            self.in_flight.clear()  # the controller drops its buffers; a reset follows
            raise StageAlarm(reply.code)
        elif isinstance(reply, Message):
            self.messages.append(reply)
            log.info("%s: [%s:%s]", self.transport.name, reply.kind, reply.text)
        return reply

    def _read_reply(self, what: str, timeout_s: float | None = None) -> Reply:
        while True:
            line = self.transport.read_line(timeout_s or self.reply_timeout_s, what)
            if line:  # Grbl precedes its banner with an empty line
                return self._check(parse_reply(line))

    # ---- lines
    def send(self, line: str, *, wait: bool = True) -> list[Reply]:
        """Send one line; with ``wait``, return the replies up to and including its ``ok``.

        Raises:
            ArgumentError: ``line`` is not one printable ASCII line of at most 78 chars.
            ProtocolError, StageAlarm, StageTimeout: see :meth:`_check`.
        """
        _check_line(line)
        collected = self._make_room(len(line) + 1)
        self.transport.write(line.encode("ascii") + b"\n")
        self.in_flight.append(line)
        if wait:
            collected += self.flush()
        return collected

    def stream(self, lines) -> list[Reply]:
        """Send many lines, keeping the receive buffer full but never overfull."""
        collected: list[Reply] = []
        for line in lines:
            collected += self.send(line, wait=False)
        return collected + self.flush()

    def flush(self, timeout_s: float | None = None) -> list[Reply]:
        """Wait until every line in flight is acknowledged."""
        collected: list[Reply] = []
        while self.in_flight:
            collected.append(self._read_reply(f"reply to {self.in_flight[0]!r}", timeout_s))
        return collected

    def _make_room(self, nbytes: int) -> list[Reply]:
        collected: list[Reply] = []
        while self.in_flight and self.in_flight_bytes + nbytes > RX_BUFFER_BYTES - 1:
            collected.append(self._read_reply(f"reply to {self.in_flight[0]!r}"))
        return collected

    # ---- real-time commands
    def status(self) -> Status:
        """Query ``?`` and return the report; retried after a lost or damaged report.

        Replies to lines in flight that arrive meanwhile are accounted for. A damaged
        line is only retried when no line is in flight (else it may have been an ``ok``).
        """
        for attempt in range(self.status_retries + 1):
            self.transport.write(b"?")
            try:
                while not isinstance(reply := self._read_reply("status report"), Status):
                    pass
            except (StageTimeout, ProtocolError) as exc:
                if damage_of(exc) is None or self.in_flight or attempt == self.status_retries:
                    raise
                log.debug("%s: retrying status after %s", self.transport.name, exc)
                self.count_recovered("status", exc)
                continue
            if attempt and not self.in_flight:
                self.transport.discard_input(0.05)  # a late report of an earlier query
            return reply
        raise AssertionError("unreachable")

    def feed_hold(self) -> None:
        """``!``: decelerate to a stop (state ``Hold``)."""
        self.transport.write(b"!")

    def cycle_start(self) -> None:
        """``~``: resume after a feed hold."""
        self.transport.write(b"~")

    def soft_reset(self, timeout_s: float | None = None) -> Banner:
        """Ctrl-X: stop, clear buffers, wait for the banner (pushed alarms are recorded)."""
        self.transport.discard_input(0.0)
        self.transport.write(b"\x18")
        self.in_flight.clear()
        while True:
            line = self.transport.read_line(timeout_s or self.reply_timeout_s, "banner after reset")
            try:
                reply = parse_reply(line) if line else None
            except ProtocolError as exc:
                log.debug("%s: ignoring %s while resetting", self.transport.name, exc)
                continue
            if isinstance(reply, Alarm):
                self.last_alarm = reply.code
            elif isinstance(reply, Banner):
                return reply

    def unlock(self) -> list[Reply]:
        """``$X``: leave the alarm state."""
        return self.send("$X")

    def settings(self) -> dict[int, float]:
        """``$$``: the controller's settings, number → value."""
        return {r.number: r.value for r in self.send("$$") if isinstance(r, Setting)}

    def resync(self, quiet_s: float = 0.05) -> Status:
        """After a lost or damaged acknowledgement: forget lines in flight, drop stale
        input and confirm the controller answers (returns its status)."""
        self.in_flight.clear()
        self.transport.discard_input(quiet_s)
        return self.status()


def _check_line(line: str) -> None:
    if not isinstance(line, str) or not line.isascii() or not line.isprintable():
        raise ArgumentError("line", line, "one printable ASCII G-code line")
    if _REALTIME & set(line):
        raise ArgumentError("line", line, "no real-time characters ? ! ~ Ctrl-X inside a line")
    if len(line) > MAX_LINE_CHARS:
        raise ArgumentError("line", line, f"at most {MAX_LINE_CHARS} characters (Grbl's line buffer)")
