"""A Grbl 1.1 controller, emulated: the byte-level state machine of one stage.

:class:`GrblEmulator` is driven by a clock: ``receive(data, now)`` takes the bytes the
host wrote, ``tick(now)`` advances motion and executes buffered lines, and
``pop_output(now)`` returns the bytes due to the host. :mod:`.pty_server` serves it on a
pseudo-terminal. Behaviour follows Grbl 1.1h: a 128-byte receive buffer (bytes beyond it
are lost), a 15-block planner (a motion line is acknowledged when planned), real-time
``?`` ``!`` ``~`` and Ctrl-X, ``$$ $X $H $G $I $N=value``, soft limits → ``ALARM:2``
(critical: reset to continue), G-code errors with Grbl's codes (:mod:`.gcode`). Motion
blocks follow trapezoidal speed profiles (:mod:`.motion`); faults from :mod:`.faults`.
"""
from __future__ import annotations

import logging
from collections import deque
from feeler.hardware.emulators.config import GrblConfig
from feeler.hardware.emulators.faults import Fault, FaultPlan
from feeler.hardware.emulators.gcode import GcodeError, Modal, clean_line, interpret, parse_words
from feeler.hardware.emulators.motion import Block, axis_limited
from feeler.hardware.emulators.system import system_command

__all__ = ["GrblConfig", "GrblEmulator", "RESET", "REALTIME"]

log = logging.getLogger("feeler.hardware.emulators.grbl")

RESET = 0x18
REALTIME = {ord("?"), ord("!"), ord("~"), RESET}
Vec = tuple[float, float, float]


class GrblEmulator:
    """Grbl 1.1 state machine (see the module docstring); ``faults`` from :mod:`.faults`."""

    LINE_BYTES = 80

    def __init__(self, config: GrblConfig = GrblConfig(), faults: tuple[Fault, ...] = (),
                 seed: int = 0):
        self.config, self.settings = config, config.settings()
        self.plan = FaultPlan(tuple(faults), seed)
        self.pos: Vec = tuple(float(v) for v in config.start_mm)
        self._prev_pos = self.pos
        self.state, self.hold_phase, self.critical = "Idle", 0, False
        self.vanished = False
        self.lost_bytes = 0
        self._out: deque[tuple[float, bytes]] = deque()
        self._last_release = 0.0
        self._first_byte_s: float | None = None
        self._fired: set[int] = set()
        self._status_count = 0
        self._reset_state(now=0.0)
        self._emit("banner", f"\r\nGrbl {config.version} ['$' for help]", now=0.0)

    # ---- host → emulator
    def receive(self, data: bytes, now: float) -> None:
        """Take bytes written by the host: real-time bytes act at once, others are buffered."""
        if data and self._first_byte_s is None:
            self._first_byte_s = now
        for byte in data:
            if byte in REALTIME:
                self._realtime(byte, now)
            elif byte >= 0x80:
                continue  # Grbl's extended real-time commands (overrides): ignored here
            elif len(self._rx) < self.config.rx_buffer_bytes - 1:
                self._rx.append(byte)
            else:
                self.lost_bytes += 1

    def _realtime(self, byte: int, now: float) -> None:
        self.tick(now)
        if byte == ord("?"):
            self._emit("status", self.status_line(now), now)
        elif byte == ord("!") and self.state == "Run":
            decel, rest = self._queue[0].stopping(now - self._block_t0)
            self._queue[0] = rest
            self._queue.appendleft(decel)
            self._block_t0, self.state, self.hold_phase = now, "Hold", 1
        elif byte == ord("~") and self.state == "Hold" and self.hold_phase == 0:
            self.state, self._block_t0 = "Run", now
        elif byte == RESET:
            self._soft_reset(now)

    def _soft_reset(self, now: float) -> None:
        if self.moving:
            self._alarm(3, now)
        self._reset_state(now)
        self._emit("banner", f"\r\nGrbl {self.config.version} ['$' for help]", now)
        if self.state == "Alarm":
            self._emit("msg", "[MSG:'$H'|'$X' to unlock]", now)

    def _reset_state(self, now: float) -> None:
        self._rx = bytearray()
        self._queue: deque[Block] = deque()
        self._block_t0 = now
        self._sync: tuple[str, float] | None = None
        self._modal = Modal()
        self.critical = False
        if self.state != "Alarm":
            self.state = "Idle"

    @property
    def moving(self) -> bool:
        """Motion in progress (running, homing, or decelerating into a hold)."""
        return self.state in ("Run", "Home") or (self.state == "Hold" and self.hold_phase == 1)

    # ---- time
    def tick(self, now: float) -> None:
        """Advance motion to ``now``, fire timed faults, execute buffered lines."""
        self._advance(now)
        self._timed_faults(now)
        while not self.critical and self._sync is None and self._execute_next_line(now):
            self._advance(now)
        self._finish_sync(now)

    def _advance(self, now: float) -> None:
        if self.moving:
            while self._queue and now - self._block_t0 >= self._queue[0].duration_s:
                self._block_t0 += self._queue[0].duration_s
                self.pos = self._queue.popleft().end_mm
                if self.state == "Hold":
                    self.hold_phase = 0
                    return
            if self._queue:
                self.pos = self._queue[0].at(now - self._block_t0)[0]
            elif self.state in ("Run", "Home"):
                self.state = "Idle"
        elif self.state == "Idle" and self._queue:
            self.state, self._block_t0 = "Run", now

    def _speed_mm_min(self, now: float) -> float:
        return self._queue[0].at(now - self._block_t0)[1] * 60.0 if self.moving and self._queue else 0.0

    def _timed_faults(self, now: float) -> None:
        for i, fault in enumerate(self.plan.timed_faults):
            if i in self._fired or self._first_byte_s is None:
                continue
            due = fault.after_s is not None and now - self._first_byte_s >= fault.after_s
            reached = [(axis, mm) for axis, mm in fault.positions().items() if self._crossed(axis, mm)]
            if due or reached:
                self._fired.add(i)
                if reached:  # a switch at a position: stop exactly there, whatever the tick
                    axis, mm = reached[0]
                    f = (mm - self._prev_pos[axis]) / (self.pos[axis] - self._prev_pos[axis])
                    self.pos = tuple(b + f * (p - b) for b, p in zip(self._prev_pos, self.pos))
                if fault.kind == "vanish":
                    self.vanished = True
                else:
                    self._alarm(fault.code, now)
        self._prev_pos = self.pos

    def _crossed(self, axis: int, mm: float) -> bool:
        before = self._prev_pos[axis]
        return (before - mm) * (self.pos[axis] - mm) <= 0 and before != self.pos[axis]

    def _alarm(self, code: int, now: float) -> None:
        """Stop dead, lock, and push ``ALARM:code`` (hard and soft limits are critical)."""
        self._queue.clear()
        self._sync = None
        self.state, self.hold_phase = "Alarm", 0
        self._emit("alarm", f"ALARM:{code}", now)
        if code in (1, 2):
            self.critical = True
            self._emit("msg", "[MSG:Reset to continue]", now)

    # ---- lines
    def _execute_next_line(self, now: float) -> bool:
        end = next((i for i, b in enumerate(self._rx) if b in (10, 13)), None)
        if end is None or len(self._queue) >= self.config.planner_blocks:
            return False
        raw = self._rx[:end].decode("latin-1")
        del self._rx[: end + 1]
        log.debug("line %r", raw)
        text = clean_line(raw)
        if len(text) >= self.LINE_BYTES - 1:
            return self._emit("error", "error:11", now)
        if text.startswith("$"):
            return system_command(self, text, now)
        if text and self.state == "Alarm":
            return self._emit("error", "error:9", now)
        try:
            action = interpret(parse_words(text), self._modal, self._plan_end())
        except GcodeError as exc:
            return self._emit("error", f"error:{exc.code}", now)
        self._modal = action.modal
        if action.kind == "dwell":
            self._sync = ("dwell", action.dwell_s)
            return True
        if action.kind == "move":
            if not self.within_travel(action.target_mm):
                self._alarm(2, now)
                return True
            self._plan_move(action.target_mm, None if action.rapid else action.modal.feed_mm_min)
        return self._emit("ok", "ok", now)

    def _plan_end(self) -> Vec:
        return self._queue[-1].end_mm if self._queue else self.pos

    def within_travel(self, target_mm: Vec) -> bool:
        """Whether ``target_mm`` lies inside the soft limits ``[0, $130..132]``."""
        travel = [self.settings[130 + i] for i in range(3)]
        return all(-1e-9 <= t <= lim + 1e-9 for t, lim in zip(target_mm, travel))

    def _plan_move(self, target_mm: Vec, feed_mm_min: float | None) -> None:
        start = self._plan_end()
        rates = tuple(self.settings[110 + i] for i in range(3))
        accels = tuple(self.settings[120 + i] for i in range(3))
        rate = axis_limited(start, target_mm, rates)
        if feed_mm_min is not None:
            rate = min(rate, feed_mm_min)
        if rate == float("inf"):
            return  # zero-length move: nothing to plan
        self._queue.append(Block(start, tuple(target_mm), rate / 60.0,
                                 axis_limited(start, target_mm, accels)))

    def _finish_sync(self, now: float) -> None:
        if self._sync is None or self._queue or self.state not in ("Idle", "Home"):
            return
        what, value = self._sync
        if what == "dwell":
            self._sync = ("until", now + value)
        elif what == "until" and now >= value:
            self._sync = None
            self._emit("ok", "ok", now)
        elif what == "home":
            self._sync, self.state = None, "Idle"
            self._emit("ok", "ok", now)

    # ---- emulator → host
    def status_line(self, now: float) -> str:
        self._status_count += 1
        state = f"Hold:{self.hold_phase}" if self.state == "Hold" else self.state
        x, y, z = self.pos
        extra = ""
        if self._status_count % 10 == 1:
            extra = "|WCO:0.000,0.000,0.000"
        elif self._status_count % 10 == 2:
            extra = "|Ov:100,100,100"
        return f"<{state}|MPos:{x:.3f},{y:.3f},{z:.3f}|FS:{self._speed_mm_min(now):.0f},0{extra}>"

    def _emit(self, kind: str, text: str, now: float) -> bool:
        """Queue one reply line, passing it through the fault plan; returns True."""
        line = text.encode("ascii") + b"\r\n"
        fault = self.plan.on_reply(kind)
        delay = 0.0
        if fault is not None:
            log.debug("fault %s on %r", fault.kind, line)
            if fault.kind == "drop":
                return True
            if fault.kind == "vanish":
                self.vanished = True
                return True
            if fault.kind == "garble":
                line = self.plan.garble(line[:-2]) + b"\r\n"
            elif fault.kind == "truncate":
                line = line[: max(len(line) // 2 - 1, 1)]
            elif fault.kind == "delay":
                delay = fault.delay_s
        release = max(now + delay, self._last_release)
        self._last_release = release
        self._out.append((release, line))
        return True

    def pop_output(self, now: float) -> bytes:
        """Bytes due to the host by ``now`` (in order; a delayed reply holds back the rest)."""
        out = bytearray()
        while self._out and self._out[0][0] <= now:
            out += self._out.popleft()[1]
        return bytes(out)

    def next_due_s(self, now: float) -> float:
        """Seconds until something needs a tick (small while moving)."""
        if self.state in ("Run", "Home", "Hold") or self._sync or self.plan.timed_faults:
            return 0.002
        if self._out:
            return max(self._out[0][0] - now, 0.0)
        return 0.05
