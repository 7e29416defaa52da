"""Where a stage is, and waiting for it: machine positions and waits that follow the motion.

Grbl reports either machine positions (``MPos``, ``$10`` bit 0 set) or work positions
(``WPos``) with the work coordinate offset ``WCO`` only on some reports (the first after a
reset or an offset change, then every 10th idle, 30th busy); the machine position is
``WPos + WCO`` with the last offset seen. ``$13=1`` reports inches.

A wait has no fixed deadline: it ends when the stage is idle at its target, and fails
when the stage shows no motion for :attr:`StageTracking.stall_s` (a loaded host running
the firmware slows it several times; a halted controller does not move at all), or after
an explicit ``timeout_s``.
"""
from __future__ import annotations

import time
from dataclasses import replace
from typing import Iterator

from feeler.hardware.stage.errors import ProtocolError, StageAlarm, StageTimeout
from feeler.hardware.stage.replies import Status

__all__ = ["StageTracking", "machine_status", "WCO_QUERIES"]

#: Grbl sends WCO at least every 30th report
WCO_QUERIES = 31
MM_PER_INCH = 25.4


def machine_status(status: Status, wco_mm, scale: float = 1.0) -> Status:
    """``status`` with machine (and work) positions filled in from ``wco_mm``, all × ``scale``."""
    mpos, wpos = status.mpos_mm, status.wpos_mm
    if mpos is None:
        mpos = tuple(w + o for w, o in zip(wpos, wco_mm))
    elif wpos is None and wco_mm is not None:
        wpos = tuple(m - o for m, o in zip(mpos, wco_mm))
    if scale != 1.0:
        mpos = tuple(v * scale for v in mpos)
        wpos = None if wpos is None else tuple(v * scale for v in wpos)
    return replace(status, mpos_mm=mpos, wpos_mm=wpos, feed_mm_min=status.feed_mm_min * scale)


class StageTracking:
    """Position queries and waits of :class:`~feeler.hardware.stage.device.Stage`."""

    @property
    def stall_s(self) -> float:
        """How long a wait tolerates no motion at all, seconds."""
        return 2.0 * self.protocol.reply_timeout_s + self.protocol.slack * 0.5

    @property
    def recovered(self) -> dict[str, int]:
        """Damaged or lost replies recovered from since opening (a copy), e.g.
        ``{"status_malformed": 2, "ok_lost": 1}``: keys ``"<reply>_<damage>"``, see
        :attr:`GrblProtocol.recovered <feeler.hardware.stage.protocol.GrblProtocol>`."""
        return dict(self.protocol.recovered)

    def status(self) -> Status:
        """The controller's status report, positions in machine millimetres."""
        p = self.protocol
        status = p.status()
        for _ in range(WCO_QUERIES):
            if status.mpos_mm is not None or p.wco_mm is not None:
                return machine_status(status, p.wco_mm, MM_PER_INCH if self.settings.get(13) else 1.0)
            status = p.status()
        raise ProtocolError(None, b"WPos without WCO", f"{WCO_QUERIES} status queries")

    def position_mm(self) -> tuple[float, float, float]:
        """Current machine position (x, y, z) in mm, as the controller reports it."""
        return self.status().mpos_mm

    def at(self, position_mm, target_mm) -> bool:
        """Whether a reported position is the target, to half a motor step (and the
        report's 0.001 mm)."""
        steps = [self.settings.get(100 + i, 1000.0) for i in range(3)]
        return all(abs(p - t) <= 0.5 / s + 0.0006 for p, t, s in zip(position_mm, target_mm, steps))

    def track(self, timeout_s: float | None = None, *, at_target: bool = True) -> Iterator[Status]:
        """Yield status reports every ``poll_s`` until the stage is idle (the last one).

        Args:
            timeout_s (float | None): an overall limit, seconds (None: none; a stall of
                :attr:`stall_s` without motion fails anyway).
            at_target (bool): idle counts only at the commanded target (a report can come
                in before a move just planned has started).
        Raises:
            StageAlarm: the controller reports (or pushes) an alarm.
            StageTimeout: no motion for :attr:`stall_s`, or ``timeout_s`` passed.
        """
        start = last_move = time.monotonic()
        last_pos = None
        while True:
            status = self.status()
            yield status
            now = time.monotonic()
            if status.state == "Alarm":
                raise StageAlarm(self.protocol.last_alarm or 0)
            if status.mpos_mm != last_pos:
                last_pos, last_move = status.mpos_mm, now
            stalled = now - last_move > self.stall_s
            if status.state == "Idle" and (not at_target or self.at(status.mpos_mm, self.target_mm)):
                return
            if stalled:
                where = "" if status.state != "Idle" else f" at {status.mpos_mm}, short of its target {self.target_mm}"
                raise StageTimeout(f"motion of {self.port}: none for {self.stall_s:g} s (last {status.state}"
                                   f"{'' if status.substate is None else ':%d' % status.substate}{where})", self.stall_s)
            if timeout_s is not None and now - start > timeout_s:
                raise StageTimeout(f"idle state of {self.port} (last {status.state})", timeout_s)
            time.sleep(self.poll_s)

    def wait_idle(self, timeout_s: float | None = None, *, at_target: bool = True) -> Status:
        """Block until the stage is idle; return the final status (see :meth:`track`)."""
        for status in self.track(timeout_s, at_target=at_target):
            pass
        return status
