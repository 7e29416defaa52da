"""Grbl's ``$`` system commands for the emulator: ``$ $$ $X $H $G $I $N=value``.

Called by :class:`~feeler.hardware.emulators.grbl.GrblEmulator` with a cleaned,
upper-cased line starting with ``$``; replies go through the emulator's ``_emit``.
Anything else (``$J=``, ``$#``, ``$N``, ``$C``, ``$SLP``) answers ``error:3``.
"""
from __future__ import annotations

import re

__all__ = ["system_command", "HELP"]

HELP = "[HLP:$$ $# $G $I $N $x=val $Nx=line $J=line $SLP $C $X $H ~ ! ? ctrl-x]"
_SETTING = re.compile(r"\$(\d+)=(.*)")
_NUMBER = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)")


def system_command(emu, text: str, now: float) -> bool:
    """Execute one ``$`` line on ``emu``; returns True (a line was consumed)."""
    busy = emu.state in ("Run", "Hold", "Home")
    if text == "$":
        return _ok(emu, now, HELP)
    if text == "$G":
        modal = emu._modal
        words = (f"G{modal.motion}", "G54", "G17", "G20" if modal.inches else "G21",
                 "G90" if modal.absolute else "G91", "G94", "M5", "M9", "T0",
                 f"F{modal.feed_mm_min:g}", "S0")
        return _ok(emu, now, "[GC:" + " ".join(words) + "]")
    if text == "$I":
        return _ok(emu, now, f"[VER:{emu.config.version}.20190825:]", "[OPT:V,15,128]")
    if busy:
        return emu._emit("error", "error:8", now)
    if text == "$$":
        emu_lines = [f"${k}={_format(v)}" for k, v in sorted(emu.settings.items())]
        for line in emu_lines:
            emu._emit("setting", line, now)
        return emu._emit("ok", "ok", now)
    if text == "$X":
        if emu.state == "Alarm":
            emu.state = "Idle"
            emu._emit("msg", "[MSG:Caution: Unlocked]", now)
        return emu._emit("ok", "ok", now)
    if text == "$H":
        emu.state, emu._block_t0 = "Home", now
        emu._plan_move((0.0, 0.0, 0.0), None)
        emu._sync = ("home", 0.0)
        return True
    match = _SETTING.fullmatch(text)
    if match is None or int(match.group(1)) not in emu.settings:
        return emu._emit("error", "error:3", now)
    if _NUMBER.fullmatch(match.group(2)) is None:
        return emu._emit("error", "error:2", now)
    value = float(match.group(2))
    if value < 0:
        return emu._emit("error", "error:4", now)
    number = int(match.group(1))
    emu.settings[number] = int(value) if isinstance(emu.settings[number], int) else value
    return emu._emit("ok", "ok", now)


def _ok(emu, now: float, *lines: str) -> bool:
    for line in lines:
        emu._emit("msg", line, now)
    return emu._emit("ok", "ok", now)


def _format(value: float) -> str:
    return f"{value:.3f}" if isinstance(value, float) else str(value)
