"""Grbl's real-time commands, soft reset and ``$`` queries, for :class:`~.protocol.GrblProtocol`.

``!`` feed hold, ``~`` cycle start, 0x85 jog cancel, Ctrl-X soft reset (outlasting the
0.5 s after a hard or soft limit alarm during which Grbl ignores it), ``$X``, ``$$``,
``$I``, the resynchronisation after a lost reply, and :meth:`GrblCommands.ask`: a line that
is safe to repeat (:func:`idempotent`) sent again when its reply is lost or damaged. A
mixin: it uses the protocol's transport, reply reader and state.
"""
from __future__ import annotations

import logging
import re
import time

from feeler.errors import ArgumentError
from feeler.hardware.stage.errors import ProtocolError, StageError, StageTimeout
from feeler.hardware.stage.replies import Alarm, Banner, Message, Reply, Setting, Status, parse_reply

__all__ = ["GrblCommands", "JOG_CANCEL", "idempotent", "ASK_TRIES"]

log = logging.getLogger("feeler.hardware.stage")
JOG_CANCEL = b"\x85"
#: how often :meth:`GrblCommands.ask` sends a line whose reply keeps being lost
ASK_TRIES = 3
#: Grbl's read-only ``$`` queries (settings, build info, parser state, offsets) and ``$X``,
#: which has no effect outside the alarm lock (gnea/grbl system.c: "Otherwise, no effect")
_REPEATABLE_SYSTEM = ("$$", "$I", "$G", "$#", "$X")
#: G-code words that only set a modal state (plane, units, distance mode, feed mode): the
#: same state however often the line runs
_MODAL_WORD = re.compile(r"G(17|18|19|20|21|90|91|94)(?!\d|\.)")


def idempotent(line: str) -> bool:
    """Whether ``line`` leaves the controller in the same state however often it runs: a
    read-only ``$`` query, ``$X``, or a line of modal G-code words only (``G21 G90``); never a
    move, a dwell, a setting (``$N=v``) or homing."""
    text = line.strip().upper()
    if text in _REPEATABLE_SYSTEM:
        return True
    words = text.split()
    return bool(words) and all(_MODAL_WORD.fullmatch(w) for w in words)


class GrblCommands:
    """Real-time bytes, reset and ``$`` queries of a Grbl conversation (a mixin)."""

    def feed_hold(self) -> None:
        """``!``: decelerate to a stop (state ``Hold:1``, then ``Hold:0``)."""
        self.transport.write(b"!")

    def cycle_start(self) -> None:
        """``~``: resume after a completed feed hold (ignored while ``Hold:1``)."""
        self.transport.write(b"~")

    def jog_cancel(self) -> None:
        """0x85: stop a jog (decelerate, drop the jog moves queued)."""
        self.transport.write(JOG_CANCEL)

    def hold_inherited_motion(self, *, ask_s: float = 0.3, hold_s: float = 10.0) -> Status | None:
        """Before the reset that opens a conversation: a board still running the moves of a
        process that was killed (``kill -9`` during a traverse: its planner runs on) is
        feed-held, and this waits for the hold to complete (``Hold:0``). Grbl keeps its
        position through a reset in a completed hold, while a reset in motion raises
        ``ALARM:3`` (position lost): ``acquire --resume`` straight after a ``kill -9``
        reset the still-moving real firmware and then refused it as locked (an outside
        test on grbl-sim). Returns the last status, or None when no report came within
        ``ask_s`` (a board that is booting, or not a Grbl: the reset then goes ahead as
        before)."""
        status = self._status_now(ask_s)
        # protocol.moving() but homing, which a feed hold does not stop
        if status is None or not (status.state in ("Run", "Jog") or (status.state == "Hold" and status.substate == 1)):
            return status
        log.info("%s: the board is still moving (%s): feed hold before the reset", self.transport.name, status.state)
        self.transport.write(b"!")
        deadline = time.monotonic() + hold_s * self.slack
        while time.monotonic() < deadline:
            time.sleep(0.02)
            status = self._status_now(ask_s) or status
            if status.state == "Idle" or (status.state == "Hold" and status.substate == 0):
                break
        return status

    def _status_now(self, timeout_s: float) -> Status | None:
        """One ``?`` answered within ``timeout_s``, other lines (an earlier process's ``ok``,
        a banner, noise) skipped; None when no report came."""
        self.transport.write(b"?")
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            try:
                line = self.transport.read_line(max(deadline - time.monotonic(), 0.001), "status report")
                reply = parse_reply(line) if line else None
            except (StageTimeout, ProtocolError):
                continue
            if isinstance(reply, Status):
                return reply
        return None

    def soft_reset(self, timeout_s: float | None = None) -> Banner:
        """Ctrl-X: stop, clear buffers, wait for the banner (pushed alarms are recorded).

        After a hard or soft limit Grbl discards a Ctrl-X that arrives before it prints
        ``[MSG:Reset to continue]`` (0.5 s after the alarm); the reset is sent again then.
        """
        timeout_s = timeout_s or self.reply_timeout_s + self.slack * 0.5
        self.transport.discard_input(0.0)
        self.transport.write(b"\x18")
        self.in_flight.clear()
        deadline = time.monotonic() + timeout_s
        self.unparsed, self.reset_wait_s = None, timeout_s
        while True:
            line = self.transport.read_line(max(deadline - time.monotonic(), 0.001), "banner after reset")
            try:
                reply = parse_reply(line) if line else None
            except ProtocolError as exc:
                log.debug("%s: ignoring %s while resetting", self.transport.name, exc)
                self.unparsed = line                # named if no banner ever comes (not a Grbl board?)
                continue
            if isinstance(reply, Alarm):
                self.last_alarm = reply.code
            elif isinstance(reply, Message) and reply.text == "Reset to continue":
                self.transport.write(b"\x18")
                deadline = time.monotonic() + timeout_s
            elif isinstance(reply, Banner):
                self._check(reply)
                return self._settle(reply)

    def _settle(self, banner: Banner) -> Banner:
        """Read on for a quiet spell after a banner: one from power-up (a board that resets
        when its port opens) may be followed by the one of our own reset."""
        while True:
            try:
                line = self.transport.read_line(self.reply_timeout_s / 4, "quiet after the banner")
            except StageTimeout:
                return banner
            try:
                reply = parse_reply(line) if line else None
            except ProtocolError:
                continue
            if isinstance(reply, Banner):
                banner = reply
            elif isinstance(reply, Message):
                self.messages.append(reply)

    def ask(self, line: str, tries: int = ASK_TRIES) -> list[Reply]:
        """Send a line that is safe to repeat (:func:`idempotent`) and return its replies; when
        its reply is lost or damaged (no ``ok`` before the deadline, with the controller idle; a
        garbled or cut line), resynchronise and send it again, ``tries`` times in all. Each
        retry is logged and counted in :attr:`recovered` as the lost reply to a move is.

        A lost reply is not a lost line: the controller may well have run it. Sending again
        is therefore only for lines whose second run changes nothing (``$$``, ``$I``, ``G21
        G90``); a move's lost reply is the device layer's business (it looks where the stage
        stands). A real answer (``error:N``, ``ALARM:N``) is raised at once.

        Raises:
            ArgumentError: ``line`` is not safe to repeat.
            StageTimeout, ProtocolError: still lost or damaged at the last try; an ``error:N``.
        """
        if not idempotent(line):
            raise ArgumentError("line", line, "a line that is safe to send twice ($$, $I, $G, $#, $X, or modal "
                                "G20/G21/G90/G91/G17-19/G94 words only)")
        from feeler.hardware.stage.protocol import damage_of

        for attempt in range(1, tries + 1):
            try:
                return self.send(line)
            except StageError as exc:
                if damage_of(exc) is None or attempt == tries:
                    raise
                log.warning("%s: %s; %r is safe to repeat: sending it again (try %d of %d)",
                            self.transport.name, exc, line, attempt + 1, tries)
                self.count_recovered("ok", exc)
                self.resync()
        raise AssertionError("unreachable")

    def unlock(self) -> list[Reply]:
        """``$X``: leave the alarm state (sent again if its reply is lost: see :meth:`ask`)."""
        return self.ask("$X")

    def settings(self) -> dict[int, float]:
        """``$$``: the controller's settings, number → value (asked again after a lost reply)."""
        return {r.number: r.value for r in self.ask("$$") if isinstance(r, Setting)}

    def build_info(self) -> dict[str, str]:
        """``$I``: ``{"VER": "1.1h.20190830:", "OPT": "V,15,128"}`` (asked again after a lost reply)."""
        return {r.kind: r.text for r in self.ask("$I") if isinstance(r, Message)}

    def resync(self, quiet_s: float = 0.05) -> Status:
        """After a lost or damaged acknowledgement: forget lines in flight, drop stale
        input and confirm the controller answers (returns its status)."""
        self.in_flight.clear()
        self._stray.clear()
        self.transport.discard_input(quiet_s)
        return self.status()
