"""Grbl 1.1h's ``$`` system commands for the emulator, with Grbl's state rules and codes.

``$`` ``$$`` ``$#`` ``$G`` ``$I`` ``$N`` ``$C`` ``$X`` ``$H`` ``$J=`` ``$RST=$|#|*`` and
``$N=value``, as ``system_execute_line`` runs them: ``$$`` refused (``error:8``) while
running or held, ``$#`` ``$H`` ``$I`` ``$N`` ``$RST`` and settings only when idle or in
alarm, ``$C`` only when idle, ``$X`` always ``ok``, ``$J=`` when idle or jogging. Left out
and answered ``error:3``, as Grbl answers a statement it cannot run: ``$SLP`` (sleep),
``$Nn=line`` (startup lines) and ``$I=text`` (build info).
"""
from __future__ import annotations

from feeler.hardware.emulators.config import GrblConfig
from feeler.hardware.emulators.gcode import GcodeError
from feeler.hardware.emulators.gcode_exec import interpret
from feeler.hardware.emulators.reports import gcode_modes, ngc_parameters
from feeler.hardware.emulators.settings import read_float, settings_lines, store_setting

__all__ = ["system_command", "HELP"]

HELP = "[HLP:$$ $# $G $I $N $x=val $Nx=line $J=line $SLP $C $X $H ~ ! ? ctrl-x]"


def system_command(emu, text: str, now: float) -> None:
    """Run one cleaned ``$`` line on ``emu`` (a :class:`~feeler.hardware.emulators.GrblEmulator`)."""
    code = _run(emu, text, now)
    if code is not None:
        emu.finish_line("ok" if code == 0 else f"error:{code}", now)


def _run(emu, text: str, now: float) -> int | None:
    """The status code to answer, or None when the command answers later (jog, homing)."""
    state, key = emu.state, text[1:2]
    if key == "":
        return emu.say(now, HELP)
    if key == "J":
        if state not in ("Idle", "Jog"):
            return 8
        if text[2:3] != "=":
            return 3
        try:
            _, ops = interpret(text, emu.parser, emu.stored, jog=True)
        except GcodeError as exc:
            return exc.code
        emu.start_ops(ops, now)
        return None
    if key in "$GCX":
        if len(text) != 2:
            return 3
        if key == "$":
            return 8 if state in ("Run", "Hold") else emu.say(now, *settings_lines(emu.settings))
        if key == "G":
            return emu.say(now, gcode_modes(emu.parser, bool(emu.settings[13])))
        if key == "C":
            return _check_mode(emu, now)
        if state == "Alarm":
            emu.state = "Idle"
            emu.say(now, "[MSG:Caution: Unlocked]")
        return 0
    if state not in ("Idle", "Alarm"):
        return 8
    if key == "#":
        return 3 if len(text) != 2 else emu.say(now, *ngc_parameters(emu.stored, emu.parser, bool(emu.settings[13])))
    if key == "H":
        if not emu.settings[22]:
            return 5
        if len(text) != 2:
            return 3
        emu.home(now)
        return None
    if key == "I":
        return 3 if len(text) != 2 else emu.say(
            now, f"[VER:{emu.config.version}.{emu.config.build}:]",
            f"[OPT:V,{emu.config.planner_blocks},{emu.config.rx_buffer_bytes}]")
    if key == "R":
        return _restore(emu, text, now)
    if key == "N" and len(text) == 2:
        return emu.say(now, "$N0=", "$N1=")
    if key in "NS":
        return 3                                   # startup lines, sleep: left out
    parameter, i = read_float(text, 1)
    if parameter is None:
        return 2
    if text[i:i + 1] != "=":
        return 3
    value, j = read_float(text, i + 1)
    if value is None:
        return 2
    if j != len(text) or parameter > 255:
        return 3
    return emu.store_setting(int(parameter), value)


def _check_mode(emu, now: float) -> int | None:
    """``$C``: toggle check mode (idle only); leaving it resets the controller."""
    if emu.state == "Check":
        emu.say(now, "[MSG:Disabled]")
        emu.finish_line("ok", now)
        emu.reset(now)
        return None
    if emu.state != "Idle":
        return 8
    emu.state = "Check"
    return emu.say(now, "[MSG:Enabled]")


def _restore(emu, text: str, now: float) -> int | None:
    """``$RST=$`` (settings), ``$RST=#`` (coordinates), ``$RST=*`` (both), then a reset."""
    if len(text) != 6 or text[:5] != "$RST=" or text[5] not in "$#*":
        return 3
    if text[5] in "$*":
        emu.settings.clear()
        emu.settings.update(GrblConfig().table())          # the firmware's own defaults
    if text[5] in "#*":
        emu.stored[:] = [(0.0, 0.0, 0.0)] * 8
    emu.say(now, "[MSG:Restoring defaults]")
    emu.finish_line("ok", now)
    emu.reset(now)
    return None
