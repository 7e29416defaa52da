"""The emulated stage's motion: a planner of straight blocks, feed hold, jog cancel, steps.

Targets are rounded to whole motor steps as Grbl rounds them (``lround(mm · $100)``), and
positions are reported in whole steps. Blocks follow trapezoidal profiles from rest to
rest (:class:`~feeler.hardware.emulators.motion.Block`); Grbl's planner blends junctions
instead, so a chain of short moves takes longer here, but every block ends where the
firmware's does and the position at any time is a closed-form function of the clock.
"""
from __future__ import annotations

import math
from collections import deque

from feeler.hardware.emulators.motion import Block, axis_limited

__all__ = ["Machine", "lround"]

Vec = tuple[float, float, float]
MINIMUM_FEED_MM_MIN = 1.0


def lround(x: float) -> int:
    """C's ``lround``: nearest integer, halves away from zero."""
    return int(math.floor(abs(x) + 0.5)) * (1 if x >= 0 else -1)


class Machine:
    """Planned blocks and where the stage is.

    Attributes:
        pos (tuple[float, float, float]): machine position now, mm.
        queue (deque[Block]): planned blocks, the one executing first.
        hold (int | None): None, 1 while decelerating into a feed hold, 0 once stopped.
        cancelling (bool): a jog cancel is decelerating (the rest is dropped at the stop).
    """

    def __init__(self, pos: Vec, blocks: int):
        self.pos, self.blocks = tuple(float(v) for v in pos), blocks
        self.queue: deque[Block] = deque()
        self.t0 = 0.0
        self.hold: int | None = None
        self.cancelling = False
        self.target_steps: tuple[int, ...] | None = None

    # ---- planning
    def full(self) -> bool:
        return len(self.queue) >= self.blocks

    def busy(self) -> bool:
        """Blocks planned or executing (Grbl's buffer synchronisation waits for this)."""
        return bool(self.queue)

    def plan(self, target_mm: Vec, feed_mm_min: float | None, settings: dict, now: float) -> bool:
        """Append a block to ``target_mm`` (rounded to steps); False for a zero-length move."""
        spm = [settings[100 + i] for i in range(3)]
        start_steps = self.target_steps or tuple(lround(p * s) for p, s in zip(self.pos, spm))
        steps = tuple(lround(t * s) for t, s in zip(target_mm, spm))
        if steps == start_steps:
            return False
        start = tuple(n / s for n, s in zip(start_steps, spm))
        end = tuple(n / s for n, s in zip(steps, spm))
        rate = axis_limited(start, end, tuple(settings[110 + i] for i in range(3)))
        if feed_mm_min is not None:
            rate = max(min(rate, feed_mm_min), MINIMUM_FEED_MM_MIN)
        accel = axis_limited(start, end, tuple(settings[120 + i] for i in range(3)))
        if not self.queue:
            self.t0 = now
        self.queue.append(Block(start, end, rate / 60.0, accel))
        self.target_steps = steps
        return True

    # ---- time
    def advance(self, now: float) -> bool:
        """Move the clock to ``now``; True when motion stopped during this call."""
        if not self.queue or self.hold == 0:
            return False
        while self.queue and now - self.t0 >= self.queue[0].duration_s:
            self.t0 += self.queue[0].duration_s
            self.pos = self.queue.popleft().end_mm
            if self.hold == 1 or self.cancelling:
                self.hold = 0 if self.hold == 1 else None
                if self.cancelling:
                    self.queue.clear()
                    self.cancelling, self.target_steps = False, None
                return True
        if self.queue:
            self.pos = self.queue[0].at(now - self.t0)[0]
            return False
        self.target_steps = None
        return True

    def speed_mm_min(self, now: float) -> float:
        if not self.queue or self.hold == 0:
            return 0.0
        return self.queue[0].at(now - self.t0)[1] * 60.0

    def reported(self, settings: dict) -> Vec:
        """The position in whole steps, mm (what Grbl reports)."""
        return tuple(lround(p * settings[100 + i]) / settings[100 + i] for i, p in enumerate(self.pos))

    # ---- interruptions
    def decelerate(self, now: float) -> None:
        """Split the executing block: a deceleration to rest now, the remainder after it."""
        decel, rest = self.queue[0].stopping(now - self.t0)
        self.queue[0] = rest
        self.queue.appendleft(decel)
        self.t0 = now

    def feed_hold(self, now: float) -> None:
        if self.hold is not None:
            return
        if self.queue:
            self.advance(now)
            if self.queue:
                self.decelerate(now)
                self.hold = 1
                return
        self.hold = 0

    def resume(self, now: float) -> None:
        self.hold, self.t0 = None, now

    def cancel(self, now: float) -> None:
        """Jog cancel: decelerate to rest and drop everything planned after."""
        if self.queue and not self.cancelling:
            self.advance(now)
            if self.queue:
                self.decelerate(now)
                self.cancelling = True

    def stop(self) -> None:
        """Stop dead (reset, alarm): nothing planned any more; the position is kept."""
        self.queue.clear()
        self.hold, self.cancelling, self.target_steps = None, False, None
