"""Protocol layer: Grbl 1.1 line framing, replies, flow control, reset and unlock.

:class:`GrblProtocol` sends G-code lines with character-counting flow control (the sum of
the lengths of unacknowledged lines, ``\\n`` included, stays within the controller's
receive buffer, 127 of its 128 bytes), matches every ``ok``/``error:N`` to the oldest line
in flight, queries the status with ``?``, and turns controller status into exceptions in
exactly one place, :meth:`GrblProtocol._check`; the other real-time bytes, the reset and
the ``$`` queries are in :mod:`.commands`.

Waiting for an acknowledgement follows the planner (:mod:`.planner`): Grbl answers a move
once it is planned, so with the planner full an ``ok`` waits for the moves ahead of it; a
dwell is answered after it. The deadline for the oldest line is the reply timeout plus
``slack`` times the work the driver knows to be ahead of it (moves acknowledged and not
yet due to be done, its own dwell or homing); when it passes, a status query asks whether
the controller is still moving, and the wait goes on while it is. :meth:`send` never sends
a line twice; a lost reply is an error for the caller (the device layer decides, from the
stage's position, whether a move arrived). Only :meth:`~.commands.GrblCommands.ask` sends
again, and only a line that is safe to repeat (``$$``, ``$I``, ``G21 G90``).

Damaged or lost replies that the driver recovers from are counted in
:attr:`GrblProtocol.recovered`, keyed ``"<reply>_<damage>"`` (:func:`damage_of`).
"""
from __future__ import annotations

import logging
import time
from collections import Counter, deque
from dataclasses import dataclass

from feeler.errors import ArgumentError
from feeler.hardware.stage.commands import GrblCommands
from feeler.hardware.stage.errors import ProtocolError, StageAlarm, StageTimeout
from feeler.hardware.stage.planner import dwell_s
from feeler.hardware.stage.replies import Alarm, Banner, Error, Message, Ok, Reply, Status, parse_reply
from feeler.hardware.stage.transport import Transport

__all__ = ["GrblProtocol", "Sent", "RX_BUFFER_BYTES", "MAX_LINE_CHARS", "DAMAGES", "damage_of",
           "parse_reply", "moving", "MOVING"]

log = logging.getLogger("feeler.hardware.stage")

RX_BUFFER_BYTES = 128
MAX_LINE_CHARS = 78
_REALTIME = set("?!~\x18")
#: states in which the controller is working through its planner
MOVING = ("Run", "Jog", "Home")

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


@dataclass(frozen=True)
class Sent:
    """A line in flight: its own wait (a dwell, homing; s), the motion it queues (s), and
    whether status queries are answered while it runs (not during homing)."""

    line: str
    wait_s: float = 0.0
    motion_s: float = 0.0
    pollable: bool = True


class GrblProtocol(GrblCommands):
    """Grbl conversation over a :class:`Transport`.

    Args:
        transport: the byte layer.
        reply_timeout_s (float): deadline for a reply with nothing queued ahead, seconds.
        status_retries (int): extra ``?`` queries after a lost or damaged status report,
            each waiting twice as long as the one before (2: 7 reply timeouts in all).
        slack (float): how many times slower than its own clock the controller may run.
        rx_buffer_bytes (int): the controller's receive buffer (``$I`` reports it).

    Attributes:
        recovered (Counter[str]): damaged or lost replies recovered from so far.
        last_alarm (int | None): the last ``ALARM:N``; ``awaiting_reset`` (bool) is True
            from an alarm until the controller's next banner.
        wco_mm (tuple | None): the work coordinate offset last reported.
    """

    def __init__(self, transport: Transport, *, reply_timeout_s: float = 2.0, status_retries: int = 2,
                 slack: float = 4.0, rx_buffer_bytes: int = RX_BUFFER_BYTES):
        self.transport = transport
        self.reply_timeout_s, self.status_retries, self.slack = reply_timeout_s, status_retries, slack
        self.rx_buffer_bytes = rx_buffer_bytes
        self.in_flight: deque[Sent] = deque()
        self.messages: deque[Message] = deque(maxlen=64)
        self.last_alarm: int | None = None
        self.unparsed: bytes | None = None     # the last line during a reset that was no Grbl reply
        self.reset_wait_s = 0.0                # how long the last reset waited for a banner, s
        self.awaiting_reset = False
        self.wco_mm: tuple[float, float, float] | None = None
        self.recovered: Counter[str] = Counter()
        self.busy_until = 0.0                 # when the moves acknowledged so far are due done
        self._stray: list[Reply] = []         # replies read while waiting for a status report

    def count_recovered(self, reply: str, exc: Exception) -> None:
        """Count one damaged or lost ``reply`` (e.g. ``"ok"``) that is being recovered."""
        self.recovered[f"{reply}_{damage_of(exc)}"] += 1

    @property
    def in_flight_bytes(self) -> int:
        """Bytes of unacknowledged lines now in the controller's receive buffer."""
        return sum(len(s.line) + 1 for s in self.in_flight)

    # ---- the one place where controller status becomes an exception
    def _check(self, reply: Reply) -> Reply:
        """Account for ``reply``; raise for ``error:N`` and ``ALARM:N``."""
        if isinstance(reply, (Ok, Error)):
            sent = self.in_flight.popleft() if self.in_flight else None
            if sent is not None and sent.motion_s:
                self.busy_until = max(self.busy_until, time.monotonic()) + sent.motion_s
            if isinstance(reply, Error):
                raise ProtocolError(reply.code, f"error:{reply.code}".encode(), sent.line if sent else "")
        elif isinstance(reply, Alarm):
            self.last_alarm, self.awaiting_reset = reply.code, True
            self.in_flight.clear()  # the controller drops its buffers; a reset follows
            raise StageAlarm(reply.code)
        elif isinstance(reply, Banner):
            lost = self.in_flight.popleft().line if self.in_flight else ""
            self.in_flight.clear()
            self.awaiting_reset, self.wco_mm, self.busy_until = False, None, 0.0
            if lost:  # the controller reset itself and dropped the lines it had not answered
                raise ProtocolError(None, f"Grbl {reply.version} ['$' for help] (a reset)".encode(), lost)
        elif isinstance(reply, Message):
            self.messages.append(reply)
            log.info("%s: [%s:%s]", self.transport.name, reply.kind, reply.text)
        elif isinstance(reply, Status):
            wco = dict(reply.extra).get("WCO")
            if wco is not None:
                self.wco_mm = tuple(float(v) for v in wco.split(","))
            if reply.state == "Idle":
                self.busy_until = 0.0
        return reply

    def _read_reply(self, what: str, timeout_s: float | None = None) -> Reply:
        while True:
            line = self.transport.read_line(self.reply_timeout_s if timeout_s is None else timeout_s, what)
            if line:  # Grbl precedes its banner with an empty line
                return self._check(parse_reply(line))

    # ---- lines
    def send(self, line: str, *, wait: bool = True, wait_s: float | None = None, motion_s: float = 0.0,
             pollable: bool = True) -> list[Reply]:
        """Send one line; with ``wait``, return the replies up to and including its ``ok``.

        Args:
            wait_s (float): how long the line itself may take to be answered once the moves
                ahead are done (default: its dwell, if any), seconds on the controller's clock.
            motion_s (float): the motion it queues (its duration), seconds.
            pollable (bool): whether ``?`` is answered while it runs (False for ``$H``).
        Raises:
            ArgumentError: ``line`` is not one printable ASCII line of at most 78 chars.
            ProtocolError, StageAlarm, StageTimeout: see :meth:`_check` and :meth:`flush`.
        """
        _check_line(line)
        sent = Sent(line, dwell_s(line) if wait_s is None else wait_s, motion_s, pollable)
        collected = self._make_room(len(line) + 1)
        self.transport.write(line.encode("ascii") + b"\n")
        self.in_flight.append(sent)
        if wait:
            collected += self.flush()
        return collected

    def stream(self, lines) -> list[Reply]:
        """Send many lines, keeping the receive buffer full but never overfull."""
        collected: list[Reply] = []
        for line in lines:
            collected += self.send(line, wait=False)
        return collected + self.flush()

    def flush(self) -> list[Reply]:
        """Wait until every line in flight is acknowledged (see the module docstring)."""
        collected: list[Reply] = []
        while self.in_flight:
            collected += self._await_oldest()
        return collected

    def _make_room(self, nbytes: int) -> list[Reply]:
        collected: list[Reply] = []
        while self.in_flight and self.in_flight_bytes + nbytes > self.rx_buffer_bytes - 1:
            collected += self._await_oldest()
        return collected

    def _budget_s(self, sent: Sent) -> float:
        ahead = max(self.busy_until - time.monotonic(), 0.0)
        return self.reply_timeout_s + self.slack * (ahead + sent.wait_s)

    def _await_oldest(self) -> list[Reply]:
        """Read replies until the oldest line in flight is answered."""
        sent = self.in_flight[0]
        what = f"reply to {sent.line!r}"
        collected, deadline, idle_once = [], time.monotonic() + self._budget_s(sent), False
        while self.in_flight and self.in_flight[0] is sent:
            collected += self._take_stray()
            try:
                collected.append(self._read_reply(what, max(deadline - time.monotonic(), 0.001)))
                continue
            except StageTimeout as exc:
                if exc.partial or not sent.pollable:
                    raise
                timeout = exc
            status = self.status()                  # still working through the moves ahead?
            if not (self.in_flight and self.in_flight[0] is sent):
                break
            if not moving(status):
                if idle_once:
                    state = f"{status.state}:{status.substate}" if status.substate is not None else status.state
                    raise StageTimeout(f"{what} (controller {state})", timeout.timeout_s)
                idle_once = True                   # its own dwell may start only now
            deadline = time.monotonic() + self._budget_s(sent)
        return collected + self._take_stray()

    def _take_stray(self) -> list[Reply]:
        stray, self._stray = self._stray, []
        return stray

    # ---- real-time commands
    def status(self) -> Status:
        """Query ``?`` and return the report; retried after a lost or damaged report.

        Replies to lines in flight that arrive meanwhile are accounted for (and returned by
        the wait for them). A query that got nothing back is asked again; a damaged line only
        when no line is in flight (else it may have been an ``ok``). Each retry waits twice
        as long as the query before: a report lost on the line is asked for again after one
        reply timeout, as before, while a host or link that has slowed down (a loaded PC, a
        network serial bridge) gets 1 + 2 + 4 = 7 reply timeouts before the controller counts
        as silent, not 3 at one pace.
        """
        wait_s = self.reply_timeout_s
        for attempt in range(self.status_retries + 1):
            self.transport.write(b"?")
            try:
                while not isinstance(reply := self._read_reply("status report", wait_s), Status):
                    self._stray.append(reply)
            except (StageTimeout, ProtocolError) as exc:
                damage = damage_of(exc)
                if damage is None or (self.in_flight and damage != "lost"):
                    raise
                if attempt == self.status_retries:
                    if damage != "lost" or not attempt:
                        raise
                    waited_s = self.reply_timeout_s * (2 ** (attempt + 1) - 1)
                    raise StageTimeout(f"status report from {self.transport.name} in answer to {attempt + 1} "
                                       "queries", waited_s) from None
                log.debug("%s: retrying status after %s", self.transport.name, exc)
                self.count_recovered("status", exc)
                wait_s *= 2
                continue
            if attempt and not self.in_flight:
                self.transport.discard_input(0.05)  # a late report of an earlier query
            return reply
        raise AssertionError("unreachable")


def moving(status: Status) -> bool:
    """Whether the controller is executing motion (running, jogging, homing, decelerating)."""
    return status.state in MOVING or (status.state == "Hold" and status.substate == 1)


def _check_line(line: str) -> None:
    if not isinstance(line, str) or not line.isascii() or not line.isprintable():
        raise ArgumentError("line", line, "one printable ASCII G-code line")
    if _REALTIME & set(line):
        raise ArgumentError("line", line, "no real-time characters ? ! ~ Ctrl-X inside a line")
    if len(line) > MAX_LINE_CHARS:
        raise ArgumentError("line", line, f"at most {MAX_LINE_CHARS} characters (Grbl's line buffer)")
