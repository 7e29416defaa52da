"""Device layer: a scanning stage driven by Grbl, with units in every name.

``Stage.open("/dev/ttyUSB0")`` (or the emulator's pty path, or any pyserial URL) resets
the controller, reads its settings for the soft limits and feed ceiling, and tracks the
commanded target. Moves are absolute G-code (``G90 G1 ... F...``), so a move whose
acknowledgement was lost or damaged is safely re-sent once. Targets beyond the soft
limits and non-positive feeds are refused before anything is sent.

A campaign drives it as: ``stage.move_to(...)``, ``stage.press(depth_mm, feed_mm_min)``,
then ``stage.traverse(dx_mm, speed_mm_s)`` (returns once planned) and
``for status in stage.track(): ...`` to sample the position while it moves.
"""
from __future__ import annotations

import logging
import math
import time
from typing import Iterator

from feeler.errors import ArgumentError
from feeler.hardware.stage.errors import ProtocolError, StageAlarm, StageTimeout
from feeler.hardware.stage.limits import AXES, StageGeometry, StageLimits
from feeler.hardware.stage.protocol import GrblProtocol
from feeler.hardware.stage.replies import Status
from feeler.hardware.stage.transport import Transport

__all__ = ["Stage"]

log = logging.getLogger("feeler.hardware.stage")
Vec = tuple[float, float, float]


class Stage:
    """A Grbl stage. Use :meth:`open`; close with :meth:`close` or a ``with`` block.

    Args:
        protocol: the Grbl conversation.
        limits (StageLimits): soft limits (mm) and feed ceiling (mm/min).
        geometry (StageGeometry): which axis scans and which presses, and the sign.
        poll_s (float): interval between status queries while waiting, seconds.
    """

    def __init__(self, protocol: GrblProtocol, limits: StageLimits,
                 geometry: StageGeometry = StageGeometry(), *, poll_s: float = 0.01):
        self.protocol, self.limits, self.geometry, self.poll_s = protocol, limits, geometry, poll_s
        self.port = protocol.transport.name
        self.target_mm: Vec = self.status().mpos_mm

    @classmethod
    def open(cls, port: str, *, limits: StageLimits | None = None,
             geometry: StageGeometry = StageGeometry(), baudrate: int = 115200,
             reply_timeout_s: float = 2.0, poll_s: float = 0.01, exclusive: bool = True) -> "Stage":
        """Open ``port``, soft-reset the controller and set millimetres and absolute mode.

        Raises:
            PortError: the port does not exist, is busy or is not permitted.
        """
        transport = Transport.open(port, baudrate=baudrate, exclusive=exclusive)
        try:
            protocol = GrblProtocol(transport, reply_timeout_s=reply_timeout_s)
            protocol.soft_reset()
            if limits is None:
                limits = StageLimits.from_settings(protocol.settings())
            stage = cls(protocol, limits, geometry, poll_s=poll_s)
            if stage.status().state != "Alarm":
                protocol.send("G21 G90")
            return stage
        except BaseException:
            transport.close()
            raise

    # ---- moves
    def move_to(self, *, x_mm: float | None = None, y_mm: float | None = None,
                z_mm: float | None = None, feed_mm_min: float) -> Vec:
        """Plan a straight move to the given machine coordinates (others unchanged).

        Returns once the controller has planned it (not finished: see :meth:`wait_idle`).
        Returns the new target (mm). Raises ``ArgumentError`` before sending for a target
        beyond the soft limits or a feed outside (0, max].
        """
        asked = {"x_mm": x_mm, "y_mm": y_mm, "z_mm": z_mm}
        target = tuple(self.target_mm[i] if asked[a] is None else float(asked[a])
                       for i, a in enumerate(AXES))
        self.limits.check(target, feed_mm_min, self.port)
        words = " ".join(f"{a[0].upper()}{v:.4f}" for a, v in zip(AXES, target)
                         if asked[a] is not None)
        if words:
            self._send_move(f"G90 G1 {words} F{feed_mm_min:.1f}")
        self.target_mm = target
        return target

    def press(self, depth_mm: float, feed_mm_min: float, *, wait_s: float | None = 30.0) -> Vec:
        """Move the press axis ``depth_mm`` (> 0) into the surface; wait until idle."""
        if not (math.isfinite(depth_mm) and depth_mm > 0):
            raise ArgumentError("depth_mm", depth_mm, "a press depth > 0 mm")
        target = self._offset(self.geometry.press_axis, self.geometry.press_sign * depth_mm,
                              feed_mm_min)
        if wait_s is not None:
            self.wait_idle(wait_s)
        return target

    def traverse(self, dx_mm: float, speed_mm_s: float) -> Vec:
        """Plan a move of ``dx_mm`` (≠ 0) along the scan axis at ``speed_mm_s`` (> 0)."""
        if not (math.isfinite(dx_mm) and dx_mm != 0):
            raise ArgumentError("dx_mm", dx_mm, "a finite, non-zero traverse in mm")
        if not (math.isfinite(speed_mm_s) and speed_mm_s > 0):
            raise ArgumentError("speed_mm_s", speed_mm_s, "a scan speed > 0 mm/s")
        return self._offset(self.geometry.scan_axis, dx_mm, speed_mm_s * 60.0)

    def _offset(self, axis: str, delta_mm: float, feed_mm_min: float) -> Vec:
        i = AXES.index(axis)
        return self.move_to(**{axis: self.target_mm[i] + delta_mm}, feed_mm_min=feed_mm_min)

    def _send_move(self, line: str) -> None:
        """Send an absolute move; re-send once if its acknowledgement was lost or damaged."""
        try:
            self.protocol.send(line)
        except (StageTimeout, ProtocolError) as exc:
            if isinstance(exc, ProtocolError) and exc.code is not None:
                raise
            log.warning("%s: %s; resynchronising and re-sending %r", self.port, exc, line)
            self.protocol.count_recovered("ok", exc)
            self.protocol.resync()
            self.protocol.send(line)

    # ---- state
    @property
    def recovered(self) -> dict[str, int]:
        """Damaged or lost replies recovered from since opening (a copy), e.g.
        ``{"status_malformed": 2, "ok_lost": 1}``: keys ``"<reply>_<damage>"``, see
        :attr:`GrblProtocol.recovered <feeler.hardware.stage.protocol.GrblProtocol>`."""
        return dict(self.protocol.recovered)

    def status(self) -> Status:
        """The controller's status report (position, state, feed)."""
        status = self.protocol.status()
        if status.mpos_mm is None:
            raise ProtocolError(None, b"status without MPos (set $10=1)")
        return status

    def position_mm(self) -> Vec:
        """Current machine position (x, y, z) in mm, as the controller reports it."""
        return self.status().mpos_mm

    def track(self, timeout_s: float = 60.0) -> Iterator[Status]:
        """Yield status reports every ``poll_s`` until the stage is idle (the last one).

        Raises:
            StageAlarm: the controller reports (or pushes) an alarm.
            StageTimeout: still moving after ``timeout_s``.
        """
        deadline = time.monotonic() + timeout_s
        while True:
            status = self.status()
            yield status
            if status.state == "Idle":
                return
            if status.state == "Alarm":
                raise StageAlarm(self.protocol.last_alarm or 0)
            if time.monotonic() > deadline:
                raise StageTimeout(f"idle state of {self.port} (last {status.state})", timeout_s)
            time.sleep(self.poll_s)

    def wait_idle(self, timeout_s: float = 60.0) -> Status:
        """Block until the stage is idle; return the final status (see :meth:`track`)."""
        for status in self.track(timeout_s):
            pass
        return status

    # ---- recovery and control
    def recover(self) -> Status:
        """After an alarm or a fault: soft reset, ``$X`` unlock, millimetres, absolute."""
        self.protocol.soft_reset()
        self.protocol.unlock()
        self.protocol.send("G21 G90")
        status = self.status()
        self.target_mm = status.mpos_mm
        return status

    def hold(self) -> None:
        """Feed hold: decelerate to a stop; :meth:`resume` continues."""
        self.protocol.feed_hold()

    def resume(self) -> None:
        self.protocol.cycle_start()

    def close(self) -> None:
        self.protocol.transport.close()

    def __enter__(self) -> "Stage":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
