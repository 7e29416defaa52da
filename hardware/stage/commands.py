"""Grbl's real-time commands, soft reset and ``$`` queries, for :class:`~.protocol.GrblProtocol`.

``!`` feed hold, ``~`` cycle start, 0x85 jog cancel, Ctrl-X soft reset (outlasting the
0.5 s after a hard or soft limit alarm during which Grbl ignores it), ``$X``, ``$$``,
``$I``, and the resynchronisation after a lost reply. A mixin: it uses the protocol's
transport, reply reader and state.
"""
from __future__ import annotations

import logging
import time

from feeler.hardware.stage.errors import ProtocolError, StageTimeout
from feeler.hardware.stage.replies import Alarm, Banner, Message, Reply, Setting, Status, parse_reply

__all__ = ["GrblCommands", "JOG_CANCEL"]

log = logging.getLogger("feeler.hardware.stage")
JOG_CANCEL = b"\x85"


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

    def unlock(self) -> list[Reply]:
        """``$X``: leave the alarm state."""
        return self.send("$X")

    def settings(self) -> dict[int, float]:
        """``$$``: the controller's settings, number → value."""
        return {r.number: r.value for r in self.send("$$") if isinstance(r, Setting)}

    def build_info(self) -> dict[str, str]:
        """``$I``: ``{"VER": "1.1h.20190830:", "OPT": "V,15,128"}``."""
        return {r.kind: r.text for r in self.send("$I") if isinstance(r, Message)}

    def resync(self, quiet_s: float = 0.05) -> Status:
        """After a lost or damaged acknowledgement: forget lines in flight, drop stale
        input and confirm the controller answers (returns its status)."""
        self.in_flight.clear()
        self._stray.clear()
        self.transport.discard_input(quiet_s)
        return self.status()
