"""How the emulated Grbl 1.1h runs the lines it receives, one at a time (a mixin of
:class:`~feeler.hardware.emulators.grbl.GrblEmulator`).

A line is cleaned and either answered at once (an error, a ``$`` command) or turned into
operations (:mod:`.gcode_exec`) that run in order and may wait: a move for room in the
planner, a dwell, offset change, stored coordinate or program end for the planner to
empty, ``M0`` for a cycle start. The line is answered when its last operation is done.
Nothing runs while a completed feed hold (``Hold:0``) suspends the controller. Soft limits
(``$20=1``): a move beyond ``[-travel, 0]`` holds a running stage, then ``ALARM:2``; a
jog beyond them is ``error:15``.
"""
from __future__ import annotations

import logging
from collections import deque

from feeler.hardware.emulators.gcode import GcodeError, clean_line
from feeler.hardware.emulators.gcode_exec import interpret
from feeler.hardware.emulators.system import system_command

__all__ = ["LineRunner"]

log = logging.getLogger("feeler.hardware.emulators.grbl")
Vec = tuple[float, float, float]


class LineRunner:
    """Line execution of the emulator (uses its machine, parser, settings and replies)."""

    def _take_line(self, now: float) -> bool:
        if self.state == "Hold" and self.machine.hold == 0:
            return False              # a completed feed hold suspends the main program
        end = next((i for i, b in enumerate(self.rx) if b in (10, 13)), None)
        if end is None:
            return False
        raw = bytes(self.rx[:end])
        del self.rx[: end + 1]
        log.debug("line %r", raw)
        text, overflow = clean_line(raw)
        if overflow or not text:
            self.finish_line("error:11" if overflow else "ok", now)
        elif text[0] == "$":
            system_command(self, text, now)
        elif self.state in ("Alarm", "Jog"):
            self.finish_line("error:9", now)
        else:
            try:
                self.parser, ops = interpret(text, self.parser, self.stored)
            except GcodeError as exc:
                self.finish_line(f"error:{exc.code}", now)
            else:
                self.start_ops(ops, now)
        return True

    def start_ops(self, ops: list[tuple], now: float) -> None:
        """Run a line's operations (:mod:`.gcode_exec`); it is answered when they are done."""
        self.ops, self.in_process, self.reply = deque(ops), True, None
        self._run_ops(now)

    def _run_ops(self, now: float) -> bool:
        while self.ops:
            if not self._op(self.ops[0], now):
                return False
            self.ops.popleft()
        if self.in_process:
            self.finish_line(self.reply or "ok", now)
        return True

    def _op(self, op: tuple, now: float) -> bool:
        """Run one operation; False while it waits (planner full or busy, dwell, pause)."""
        kind, m, check = op[0], self.machine, self.state == "Check"
        if kind == "accessory":
            self.reporter.ovr_counter = 0
        elif kind in ("move", "jog"):
            return self._move(op[1], op[2], now, jog=kind == "jog")
        elif m.busy():
            return False              # everything else waits for the planner to empty
        elif kind == "dwell" and not check:
            self._dwell_until = self._dwell_until or now + op[1]
            if now < self._dwell_until:
                return False
            self._dwell_until = None
        elif kind == "offsets":
            self.parser.coord_system, self.parser.g92, self.parser.tlo = op[1], op[2], op[3]
            self.reporter.wco_counter = 0
        elif kind == "store":
            self.stored[op[1]] = tuple(op[2])
        elif kind == "pause" and not check:
            if self._pause != "done":
                if self._pause is None:
                    m.feed_hold(now)
                    self.state, self._pause = "Hold", "waiting"
                return False
            self._pause = None
        elif kind == "end":
            if not check:
                self.parser.coord_system, self.parser.g92, self.parser.tlo = op[1], op[2], op[3]
                self.reporter.wco_counter = self.reporter.ovr_counter = 0
            self._emit("msg", "[MSG:Pgm End]", now)
        return True

    def beyond_travel(self, target_mm: Vec) -> bool:
        """Outside Grbl's soft limits: a machine coordinate > 0 or < -travel."""
        return any(t > 0 or t < -self.settings[130 + i] for i, t in enumerate(target_mm))

    def _move(self, target: Vec, feed: float | None, now: float, jog: bool) -> bool:
        m = self.machine
        if self.settings[20] and self.beyond_travel(target):
            if jog:
                self.reply = "error:15"
                return True
            if not self._soft_limit:
                if m.queue and self.state in ("Run", "Hold"):
                    m.feed_hold(now)
                    self.state, self._soft_limit = "Hold", True
                else:
                    self._alarm(2, now)
            return False
        if self.state == "Check":
            return True
        if m.full():
            return False
        if m.plan(target, feed, self.settings, now) and self.state == "Idle":
            self.state = "Jog" if jog else "Run"
        if jog:
            self.parser.position = target
        return True
