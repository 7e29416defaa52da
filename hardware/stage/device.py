"""Device layer: a scanning stage driven by Grbl, with units in every name.

``Stage.open("/dev/ttyUSB0")`` (or the emulator's pty path, or any pyserial URL) resets
the controller, reads its settings (soft limits in Grbl's convention, per-axis feed
ceilings, steps per mm) and build options, refuses a locked board unless asked to home
(``$H``) or unlock (``$X``) it, and tracks the commanded target. Moves are absolute
machine coordinates (``G53 G1 ... F...``), whatever work offsets the board has; positions
are machine positions, from ``MPos`` or from ``WPos + WCO`` when ``$10`` reports work
positions. Targets beyond the soft limits (on the axes that move) and feeds above what
the moving axes allow are refused before anything is sent.

A lost or damaged reply to a set-up line that is safe to repeat (``$$``, ``$I``, ``$X``,
``G21 G90``) is answered by asking again (:meth:`GrblProtocol.ask`). A lost or damaged
acknowledgement of a move is never answered by sending the move again blindly: the stage is left to finish whatever it received, and the move is sent again
only when the stage stands idle where it was before it, with nothing pending — the one
case where the controller certainly did not receive it.

A campaign drives it as: ``stage.move_to(...)``, ``stage.press(depth_mm, feed_mm_min)``,
then ``stage.traverse(dx_mm, speed_mm_s)`` (returns once planned) and
``for status in stage.track(): ...`` to sample the position while it moves.
"""
from __future__ import annotations

import logging
import math
import re
import time

from feeler.errors import ArgumentError
from feeler.hardware.stage.errors import (PortError, ProtocolError, StageError, StageLocked, StageTimeout,
                                          shown_bytes)
from feeler.hardware.stage.limits import AXES, StageGeometry, StageLimits
from feeler.hardware.stage.planner import homing_s, move_duration_s
from feeler.hardware.stage.protocol import GrblProtocol, damage_of
from feeler.hardware.stage.replies import Status
from feeler.hardware.stage.tracking import StageTracking
from feeler.hardware.stage.transport import Transport

__all__ = ["Stage"]

log = logging.getLogger("feeler.hardware.stage")
Vec = tuple[float, float, float]


class Stage(StageTracking):
    """A Grbl stage. Use :meth:`open`; close with :meth:`close` or a ``with`` block.

    Args:
        protocol: the Grbl conversation.
        limits (StageLimits): soft limits (mm), feed ceilings (mm/min), accelerations.
        geometry (StageGeometry): which axis scans and which presses, and the sign.
        poll_s (float): interval between status queries while waiting, seconds.
        settings (dict[int, float]): the controller's ``$$`` (steps/mm, report units, homing).

    Attributes:
        target_mm (tuple[float, float, float]): the last commanded machine target, mm.
        locked (bool): the controller was in its alarm lock when last seen.
    """

    def __init__(self, protocol: GrblProtocol, limits: StageLimits, geometry: StageGeometry = StageGeometry(),
                 *, poll_s: float = 0.01, settings: dict[int, float] | None = None):
        self.protocol, self.limits, self.geometry, self.poll_s = protocol, limits, geometry, poll_s
        self.settings = dict(settings or {})
        self.port = protocol.transport.name
        status = self.status()
        self.target_mm: Vec = status.mpos_mm
        self.locked = status.state == "Alarm"
        self._held = False

    @classmethod
    def open(cls, port: str, *, limits: StageLimits | None = None, geometry: StageGeometry = StageGeometry(),
             baudrate: int = 115200, reply_timeout_s: float = 2.0, poll_s: float = 0.01, exclusive: bool = True,
             slack: float = 4.0, unlock: bool = False, home: bool = False, allow_locked: bool = False) -> "Stage":
        """Open ``port``, soft-reset the controller, read its settings, set millimetres.

        Args:
            unlock (bool): leave an alarm lock with ``$X`` (position not re-referenced).
            home (bool): run the homing cycle ``$H`` (needs ``$22=1``), locked or not.
            allow_locked (bool): return a locked stage instead of raising StageLocked.
            slack (float): how many times slower than its clock the controller may run.
        Raises:
            PortError: the port does not exist, is busy or is not permitted.
            StageLocked: the board is in its alarm lock and neither ``unlock`` nor ``home``.
            StageAlarm: homing failed (e.g. ``ALARM:8``, a switch that stays pressed).
        """
        transport = Transport.open(port, baudrate=baudrate, exclusive=exclusive)
        try:
            protocol = GrblProtocol(transport, reply_timeout_s=reply_timeout_s, slack=slack)
            protocol.hold_inherited_motion()        # an earlier process's moves still running: keep the position
            try:
                banner = protocol.soft_reset()
            except StageTimeout as exc:
                raise PortError(port, _no_banner(exc, protocol.unparsed, baudrate, protocol.reset_wait_s)) from None
            _check_version(port, banner.version)
            settings = protocol.settings()
            try:
                options = protocol.build_info().get("OPT", "").split(",")
            except ProtocolError as exc:          # a firmware without $I: Grbl's defaults then
                log.info("%s: no build options (%s)", port, exc)
                options = [""]
            if len(options) >= 3 and options[2].isdigit():
                protocol.rx_buffer_bytes = int(options[2])
            if limits is None:
                limits = StageLimits.from_settings(settings, origin_at_home="Z" in options[0])
            stage = cls(protocol, limits, geometry, poll_s=poll_s, settings=settings)
            if home:
                stage.home()
            elif stage.locked and unlock:
                stage.unlock()
            elif stage.locked and not allow_locked:
                raise StageLocked(port, protocol.last_alarm)
            if not stage.locked:
                protocol.ask("G21 G90")
            return stage
        except BaseException:
            transport.close()
            raise

    # ---- moves
    def move_to(self, *, x_mm: float | None = None, y_mm: float | None = None,
                z_mm: float | None = None, feed_mm_min: float) -> Vec:
        """Plan a straight move to the given machine coordinates (others unchanged).

        Returns the new target (mm) once the controller has planned it (not finished:
        see :meth:`wait_idle`). Raises ``ArgumentError`` before sending for a target beyond
        the soft limits or a feed that is not > 0 or above the moving axes' ``$11x``.
        """
        target, words = self._target(x_mm, y_mm, z_mm, feed_mm_min)
        if words:
            self._send_move(f"G53 G1 {words} F{feed_mm_min:.1f}", target, feed_mm_min)
        self.target_mm = target
        return target

    def jog_to(self, *, x_mm: float | None = None, y_mm: float | None = None,
               z_mm: float | None = None, feed_mm_min: float) -> Vec:
        """Jog (``$J=G53 ...``) to machine coordinates: state ``Jog``, stopped by
        :meth:`jog_cancel`; checked like :meth:`move_to`. Returns the target once planned."""
        target, words = self._target(x_mm, y_mm, z_mm, feed_mm_min)
        if words:
            self.protocol.send(f"$J=G53 {words} F{feed_mm_min:.1f}", motion_s=self._duration(target, feed_mm_min))
        self.target_mm = target
        return target

    def jog_cancel(self) -> Status:
        """Stop a jog (0x85): the stage decelerates and drops the jog moves still queued."""
        self.protocol.jog_cancel()
        status = self.wait_idle(at_target=False)
        self.target_mm = status.mpos_mm
        return status

    def press(self, depth_mm: float, feed_mm_min: float, *, wait: bool = True) -> Vec:
        """Move the press axis ``depth_mm`` (> 0) into the surface; wait until idle."""
        if not (math.isfinite(depth_mm) and depth_mm > 0):
            raise ArgumentError("depth_mm", depth_mm, "a press depth > 0 mm")
        target = self._offset(self.geometry.press_axis, self.geometry.press_sign * depth_mm, feed_mm_min)
        if wait:
            self.wait_idle()
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

    def _target(self, x_mm, y_mm, z_mm, feed_mm_min) -> tuple[Vec, str]:
        asked = {"x_mm": x_mm, "y_mm": y_mm, "z_mm": z_mm}
        target = tuple(self.target_mm[i] if asked[a] is None else float(asked[a]) for i, a in enumerate(AXES))
        self.limits.check(self.target_mm, target, feed_mm_min, self.port)
        words = " ".join(f"{a[0].upper()}{v:.4f}" for a, v in zip(AXES, target) if asked[a] is not None)
        return target, words

    def _duration(self, target: Vec, feed_mm_min: float) -> float:
        return move_duration_s(self.target_mm, target, feed_mm_min, self.limits.max_rate_mm_min,
                               self.limits.accel_mm_s2)

    def _send_move(self, line: str, target: Vec, feed_mm_min: float) -> None:
        """Send an absolute move; after a lost or damaged reply, send it again only if the
        stage certainly did not receive it (idle where it stood before, nothing pending)."""
        before = self.target_mm
        duration = self._duration(target, feed_mm_min)
        try:
            self.protocol.send(line, motion_s=duration)
            return
        except StageError as exc:
            if damage_of(exc) is None:
                raise
            log.warning("%s: %s; waiting for the stage to settle before deciding on %r", self.port, exc, line)
            self.protocol.count_recovered("ok", exc)
        self.protocol.resync()
        self.target_mm = target
        final = self.wait_idle(at_target=False)
        if self.at(final.mpos_mm, target):
            return                                       # it arrived; only its reply was lost
        time.sleep(max(self.protocol.reply_timeout_s / 4, self.poll_s))
        again = self.status()
        if again.state == "Idle" and self.at(again.mpos_mm, before) and self.at(final.mpos_mm, before):
            log.warning("%s: the stage never received %r; sending it again", self.port, line)
            self.protocol.send(line, motion_s=duration)
            return
        self.target_mm = again.mpos_mm
        raise StageError(f"{self.port}: after a lost reply to {line!r} the stage stands at {again.mpos_mm} "
                         f"({again.state}), neither where it was ({before}) nor at the target ({target})")

    # ---- homing, unlocking, recovery
    def home(self) -> Status:
        """``$H``: the homing cycle (minutes on a large machine; no reports meanwhile)."""
        self.protocol.send("$H", wait_s=homing_s(self.settings), pollable=False)
        status = self.status()
        self.locked, self.target_mm = status.state == "Alarm", status.mpos_mm
        return status

    def unlock(self) -> None:
        """``$X``: leave the alarm lock without homing (the position is not re-referenced)."""
        self.protocol.unlock()
        self.locked = False

    def recover(self) -> Status:
        """After an alarm or a fault: reset (waiting out Grbl's 0.5 s alarm report and
        ``[MSG:Reset to continue]``), ``$X`` unlock, millimetres, absolute mode."""
        p = self.protocol
        if not (p.awaiting_reset and p.last_alarm not in (1, 2) and self._await_banner()):
            p.soft_reset()
        p.transport.discard_input(0.05)
        if self.status().state == "Alarm":
            self.unlock()
        p.ask("G21 G90")
        status = self.status()
        self.target_mm, self.locked = status.mpos_mm, False
        return status

    def _await_banner(self) -> bool:
        """Wait for the reset Grbl does by itself after a non-critical alarm."""
        deadline = time.monotonic() + self.protocol.reply_timeout_s + self.protocol.slack * 0.5
        while self.protocol.awaiting_reset:
            try:
                self.protocol._read_reply("banner after the alarm", max(deadline - time.monotonic(), 0.001))
            except StageTimeout:
                return False
            except StageError:
                continue
        return True

    def hold(self) -> None:
        """Feed hold: decelerate to a stop (``Hold:1``, then ``Hold:0``); :meth:`resume`."""
        self.protocol.feed_hold()
        self._held = True

    def resume(self) -> Status:
        """Cycle start once the hold is complete: Grbl ignores ``~`` until then (``Hold:1``,
        or a ``!`` it has not yet acted on). Returns the first status after the hold."""
        last = None
        stalled_at = time.monotonic() + self.stall_s
        while True:                                       # wait for Hold:0, while the stage slows
            status = self.status()
            if status.state == "Hold" and status.substate == 0 or not self._held and status.state != "Hold":
                break
            if status.mpos_mm != last:
                last, stalled_at = status.mpos_mm, time.monotonic() + self.stall_s
            elif time.monotonic() > stalled_at:
                raise StageTimeout(f"hold of {self.port} to complete (still {status.state})", self.stall_s)
            time.sleep(self.poll_s)
        self._held = False
        for _ in range(5):
            if status.state != "Hold":
                return status
            self.protocol.cycle_start()
            time.sleep(self.poll_s)
            status = self.status()
        raise StageTimeout(f"resume of {self.port} (still {status.state}:{status.substate})", self.stall_s)

    def close(self) -> None:
        self.protocol.transport.close()

    def __enter__(self) -> "Stage":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _check_version(port: str, version: str) -> None:
    """PortError for a board older than Grbl 1.1, whose replies this driver cannot read
    (0.9 answers ``$$`` with ``$0=10 (step pulse, usec)``, errors in words, and status as
    ``<Idle,MPos:...,WPos:...>``): said after the reset, before any command is sent, instead of
    "malformed reply"."""
    match = re.match(r"(\d+)\.(\d+)", version)
    if match and (int(match.group(1)), int(match.group(2))) < (1, 1):
        raise PortError(port, f"the board runs Grbl {version}, and feeler speaks Grbl 1.1 (its status reports, "
                              f"error codes and settings replies changed in 1.1): flash Grbl 1.1h "
                              f"(github.com/gnea/grbl) onto the board")


def _no_banner(exc: StageTimeout, unparsed: bytes | None, baudrate: int, waited_s: float) -> str:
    """What a port that never sent Grbl's banner after a reset (waiting ``waited_s``) most
    likely is."""
    heard = exc.partial or unparsed or b""
    text = heard.decode("ascii", "replace")
    if not heard:
        guess = "nothing came back: is this the board's port, and is the board powered?"
    elif sum(ch.isprintable() or ch in "\r\n" for ch in text) < 0.8 * len(text):
        guess = (f"bytes that are not text came back ({shown_bytes(heard)}): the board talks at another baud "
                 f"rate than {baudrate}" + ("" if baudrate == 115200 else " (Grbl 1.1's is 115200)") + "?")
    else:
        guess = f"it answered {shown_bytes(heard)}, not Grbl's banner: is this a Grbl 1.1 board?"
    return f"no Grbl banner within {waited_s:.3g} s of a reset (Ctrl-X); {guess}"
