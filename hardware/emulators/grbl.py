"""A Grbl 1.1h controller, emulated: the byte-level state machine of one stage board.

:class:`GrblEmulator` is driven by a clock: ``receive(data, now)`` takes the bytes the
host wrote, ``tick(now)`` advances motion and runs buffered lines, and ``pop_output(now)``
returns the bytes due to the host. :mod:`.pty_server` serves it on a pseudo-terminal.

It is held to the real firmware (recorded exchanges in ``tests/hardware/data``): a
128-byte receive buffer (bytes beyond it are lost); lines run one at a time, and a line
is answered when it has run — a move once planned (15 blocks ahead), a dwell, offset
change or program end once the planner is empty; nothing runs while a feed hold is
complete (``Hold:0``) until ``~``; real-time ``?`` ``!`` ``~`` Ctrl-X and jog cancel 0x85;
``$`` commands (:mod:`.system`); G-code with Grbl's codes (:mod:`.gcode`); soft limits
with ``$20=1`` on ``[-travel, 0]`` (a planned move: feed hold, then ``ALARM:2``; a jog:
``error:15``); with ``$22=1`` it powers up locked. After ``ALARM:N`` it is silent for
0.5 s; hard and soft limits (1, 2) then print ``[MSG:Reset to continue]`` and ignore
everything but a Ctrl-X (one sent before the message is discarded; ``?`` is not
answered); other alarms from a reset or homing reset by themselves. A reset answers the
line that was running with a stale ``ok`` before the banner. Homing ($H) succeeds
(the board's switches at the positive end of travel) and leaves the stage at ``-$27``.
Faults from :mod:`.faults` are injected on top.
"""
from __future__ import annotations

import logging
from collections import deque

from feeler.hardware.emulators.config import GrblConfig
from feeler.hardware.emulators.faults import Fault, FaultPlan
from feeler.hardware.emulators.gcode import ParserState
from feeler.hardware.emulators.lines import LineRunner
from feeler.hardware.emulators.machine import Machine
from feeler.hardware.emulators.reports import Reporter
from feeler.hardware.emulators.settings import store_setting

__all__ = ["GrblConfig", "GrblEmulator", "RESET", "REALTIME", "JOG_CANCEL"]

log = logging.getLogger("feeler.hardware.emulators.grbl")

RESET, JOG_CANCEL = 0x18, 0x85
REALTIME = {ord("?"), ord("!"), ord("~"), RESET, JOG_CANCEL}
ALARM_SILENCE_S = 0.5
CRITICAL = (1, 2)
Vec = tuple[float, float, float]


class GrblEmulator(LineRunner):
    """Grbl 1.1h state machine (see the module docstring); ``faults`` from :mod:`.faults`."""

    def __init__(self, config: GrblConfig = GrblConfig(), faults: tuple[Fault, ...] = (), seed: int = 0):
        self.config, self.settings = config, config.table()
        self.plan = FaultPlan(tuple(faults), seed)
        self.machine = Machine(config.start_mm, config.planner_blocks)
        self.stored: list[Vec] = [(0.0, 0.0, 0.0)] * 8
        self.state = "Alarm" if self.settings[22] else "Idle"
        self.vanished, self.lost_bytes = False, 0
        self._out: deque[tuple[float, bytes]] = deque()
        self._last_release, self._first_byte_s = 0.0, None
        self._fired: set[int] = set()
        self._prev_pos = self.machine.pos
        self._losing: bool | None = None   # None: at a line start; True: inside a lost line
        self._restart()
        self._banner(0.0)

    # ---- host -> emulator
    def receive(self, data: bytes, now: float) -> None:
        """Take bytes written by the host: real-time bytes act at once, others are buffered."""
        if data and self._first_byte_s is None:
            self._first_byte_s = now
        for byte in data:
            if byte in REALTIME:
                self.tick(now)
                self._realtime(byte, now)
            elif byte >= 0x80:
                continue              # overrides and safety door: left out (no reply exists)
            else:
                if self._losing is None and self.plan.line_faults:
                    self._losing = self.plan.lose_line()     # a line lost on the wire?
                end = byte in (10, 13)
                if not self._losing:
                    if len(self.rx) < self.config.rx_buffer_bytes - 1:
                        self.rx.append(byte)
                    else:
                        self.lost_bytes += 1
                self._losing = None if end else bool(self._losing)

    def _realtime(self, byte: int, now: float) -> None:
        m = self.machine
        if byte == ord("?"):
            if self.lock is None:
                self._emit("status", self.status_line(now), now)
        elif byte == RESET:
            self._ctrl_x(now)
        elif byte == JOG_CANCEL:
            if self.state == "Jog":
                m.cancel(now)
        elif byte == ord("!"):
            if self.state == "Jog":
                m.cancel(now)
            elif self.state in ("Run", "Idle"):
                m.feed_hold(now)
                self.state = "Hold"
        elif self.state == "Hold" and m.hold == 0:
            if self._pause == "waiting":
                self._pause = "done"
            if m.queue:
                m.resume(now)
                self.state = "Run"
            else:
                m.hold, self.state = None, "Idle"

    def _ctrl_x(self, now: float) -> None:
        if self.lock == "critical":
            self.reset(now)
        elif isinstance(self.lock, tuple) and self.lock[0] == "home":
            self._alarm(6, now)       # homing fail: reset during the cycle
        elif self.lock is not None:
            return                    # in an alarm's silence: discarded (or a reset is due)
        elif self.state in ("Run", "Jog", "Home") or (self.state == "Hold" and self.machine.hold == 1):
            self._alarm(6 if self.state == "Home" else 3, now)
        else:
            self.reset(now)

    # ---- resets and alarms
    def _restart(self) -> None:
        """What a reset reinitialises: buffers, parser, report counters."""
        self.rx = bytearray()
        self.ops: deque[tuple] = deque()
        self.in_process, self.reply = False, None
        self.lock: object = None
        self.parser = ParserState(position=self.machine.reported(self.settings), coord_system=self.stored[0])
        self.reporter = Reporter()
        self._dwell_until, self._pause, self._soft_limit = None, None, False

    def _banner(self, now: float) -> None:
        self._emit("banner", f"\r\nGrbl {self.config.version} ['$' for help]", now)
        if self.state == "Alarm":
            self._emit("msg", "[MSG:'$H'|'$X' to unlock]", now)

    def reset(self, now: float) -> None:
        """Soft reset: a stale ``ok`` for the line running, then the banner."""
        if self.in_process:
            self._emit("ok", "ok", now)
        self.machine.stop()
        self.state = "Alarm" if self.state == "Alarm" else "Idle"
        self._restart()
        self._banner(now)

    def _alarm(self, code: int, now: float) -> None:
        """Stop dead, lock, push ``ALARM:code``; then 0.5 s of silence (see :meth:`tick`)."""
        self.machine.stop()
        self.state = "Alarm"
        self._emit("alarm", f"ALARM:{code}", now)
        self.lock = ("silent", now + ALARM_SILENCE_S, code)

    def _unlock_after_silence(self, now: float) -> None:
        _, until, code = self.lock
        if now < until:
            return
        if code in CRITICAL:
            self.lock = "critical"
            self._emit("msg", "[MSG:Reset to continue]", now)
        elif code in (4, 5):
            self.lock = None
        else:
            self.lock = None
            self.reset(now)

    def home(self, now: float) -> None:
        """``$H``: seek the switches (Z, then X and Y) and pull off to ``-$27``."""
        s, pos = self.settings, self.machine.pos
        seek, feed, pull = s[25] / 60.0, s[24] / 60.0, s[27]
        duration = sum(max(abs(pos[i]) for i in axes) / seek + pull / seek + 2 * pull / feed + 2 * s[26] / 1000.0
                       for axes in ((2,), (0, 1)))
        self.state, self.in_process = "Home", True
        self.lock = ("home", now + duration)

    def _homed(self, now: float) -> None:
        if now < self.lock[1]:
            return
        s = self.settings
        self.machine.pos = tuple(-s[27] if not (int(s[23]) >> i) & 1 else -s[130 + i] + s[27] for i in range(3))
        self.parser.position = self.machine.reported(s)
        self.lock, self.state = None, "Idle"
        self.finish_line("ok", now)

    # ---- time
    def tick(self, now: float) -> None:
        """Advance motion to ``now``, fire timed faults, run buffered lines."""
        if self.machine.advance(now):
            self._stopped(now)
        self._timed_faults(now)
        if isinstance(self.lock, tuple):
            (self._homed if self.lock[0] == "home" else self._unlock_after_silence)(now)
        while self.lock is None and (self._run_ops(now) if self.in_process else self._take_line(now)):
            pass

    def _stopped(self, now: float) -> None:
        m = self.machine
        if self._soft_limit:
            self._soft_limit = False
            self._alarm(2, now)
        elif self.state in ("Run", "Jog") and not m.queue:
            if self.state == "Jog":
                self.parser.position = m.reported(self.settings)
            self.state = "Idle"

    def _timed_faults(self, now: float) -> None:
        pos = self.machine.pos
        for i, fault in enumerate(self.plan.timed_faults):
            if i in self._fired or self._first_byte_s is None:
                continue
            due = fault.after_s is not None and now - self._first_byte_s >= fault.after_s
            reached = [(a, mm) for a, mm in fault.positions().items()
                       if (self._prev_pos[a] - mm) * (pos[a] - mm) <= 0 and self._prev_pos[a] != pos[a]]
            if due or reached:
                self._fired.add(i)
                if reached:           # a switch at a position: stop exactly there, whatever the tick
                    a, mm = reached[0]
                    f = (mm - self._prev_pos[a]) / (pos[a] - self._prev_pos[a])
                    self.machine.pos = tuple(b + f * (p - b) for b, p in zip(self._prev_pos, pos))
                if fault.kind == "vanish":
                    self.vanished = True
                else:
                    self._alarm(fault.code, now)
        self._prev_pos = self.machine.pos

    # ---- emulator -> host
    def finish_line(self, reply: str, now: float) -> None:
        """Answer the line that ran (``ok`` or ``error:N``)."""
        self.in_process = False
        self._emit("ok" if reply == "ok" else "error", reply, now)

    def say(self, now: float, *lines: str) -> int:
        """Print ``lines`` (settings or messages); returns 0 (the line's ``ok`` follows)."""
        for line in lines:
            self._emit("setting" if line.startswith("$") else "msg", line, now)
        return 0

    def store_setting(self, number: int, value: float) -> int:
        code = store_setting(self.settings, number, value)
        if code == 0 and number == 13:
            self.reporter.wco_counter = 0
        return code

    def status_line(self, now: float) -> str:
        m, p = self.machine, self.parser
        state = f"Hold:{m.hold if m.hold is not None else 0}" if self.state == "Hold" else self.state
        spindle = p.spindle_rpm if p.modal.spindle != 5 else 0.0
        accessory = ("S" if p.modal.spindle == 3 else "C") * (spindle > 0) + "F" * bool(p.modal.coolant)
        return self.reporter.status(state, self.settings, m.reported(self.settings), p.wco(), m.speed_mm_min(now),
                                    spindle, accessory, (self.config.planner_blocks - len(m.queue),
                                                         self.config.rx_buffer_bytes - len(self.rx)))

    def _emit(self, kind: str, text: str, now: float) -> None:
        """Queue one reply line, passing it through the fault plan."""
        line = text.encode("ascii") + b"\r\n"
        fault = self.plan.on_reply(kind)
        delay = 0.0
        if fault is not None:
            log.debug("fault %s on %r", fault.kind, line)
            if fault.kind in ("drop", "vanish"):
                self.vanished = self.vanished or fault.kind == "vanish"
                return
            if fault.kind == "garble":
                line = self.plan.garble(line[:-2]) + b"\r\n"
            elif fault.kind == "truncate":
                line = line[: max(len(line) // 2 - 1, 1)]
            elif fault.kind == "delay":
                delay = fault.delay_s
        self._last_release = max(now + delay, self._last_release)
        self._out.append((self._last_release, line))

    def pop_output(self, now: float) -> bytes:
        """Bytes due to the host by ``now`` (in order; a delayed reply holds back the rest)."""
        out = bytearray()
        while self._out and self._out[0][0] <= now:
            out += self._out.popleft()[1]
        return bytes(out)

    def next_due_s(self, now: float) -> float:
        """Seconds until something needs a tick (small while moving or waiting)."""
        if self.machine.queue or self.lock is not None or self.in_process or self.plan.timed_faults:
            return 0.002
        if self._out:
            return max(self._out[0][0] - now, 0.0)
        return 0.05
