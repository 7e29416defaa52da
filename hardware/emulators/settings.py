"""Grbl 1.1h's settings for the emulator: ``$N=value`` with Grbl's checks, ``$$`` lines,
and the number format of every report (:func:`grbl_float`).
"""
from __future__ import annotations

from feeler.hardware.emulators.config import GRBL_DEFAULTS, INTEGER_SETTINGS

__all__ = ["grbl_float", "store_setting", "settings_lines", "read_float", "AXIS_SETTINGS"]

#: per-axis settings: steps/mm, max rate, acceleration, travel (X, Y, Z each)
AXIS_SETTINGS = tuple(base + i for base in (100, 110, 120, 130) for i in range(3))


def grbl_float(value: float, decimals: int) -> str:
    """``value`` as Grbl's ``printFloat`` writes it: sign first, then rounded half up."""
    sign = "-" if value < 0 else ""
    digits = str(int(abs(value) * 10 ** decimals + 0.5)).rjust(decimals + 1, "0")
    return sign + (digits[:-decimals] + "." + digits[-decimals:] if decimals else digits)


def read_float(text: str, i: int) -> tuple[float | None, int]:
    """Grbl's ``read_float`` at ``text[i]``: an optional sign, digits with at most one point.

    Returns (value, index after it), or (None, i) when no digit was read.
    """
    j = i
    if j < len(text) and text[j] in "+-":
        j += 1
    digits, point = 0, False
    while j < len(text) and (text[j].isdigit() or (text[j] == "." and not point)):
        digits += text[j].isdigit()
        point = point or text[j] == "."
        j += 1
    if not digits:
        return None, i
    number = text[i:j]
    return float(number.rstrip(".") if number.endswith(".") else number), j


def store_setting(table: dict[int, float], number: int, value: float) -> int:
    """Store ``$number=value`` in ``table`` as Grbl does; returns the status code (0: ok).

    Errors: 4 negative value, 6 step pulse < 3 µs, 10 soft limits without homing, 3 no such
    setting. ``$22=0`` also clears ``$20`` (soft limits need homing).
    """
    if value < 0:
        return 4
    if number >= 100:
        if number not in AXIS_SETTINGS:
            return 3
        table[number] = float(value)
        return 0
    if number not in GRBL_DEFAULTS:
        return 3
    whole = int(value) & 0xFF
    if number == 0 and whole < 3:
        return 6
    if number in (4, 5, 6, 13, 20, 21, 22, 32):
        whole = int(bool(whole))
    if number == 20 and whole and not table[22]:
        return 10
    if number == 22 and not whole:
        table[20] = 0
    table[number] = whole if number in INTEGER_SETTINGS else float(value)
    return 0


def settings_lines(table: dict[int, float]) -> list[str]:
    """The lines of ``$$``, in Grbl's order and number format."""
    out = []
    for number in sorted(table):
        value = table[number]
        if number in INTEGER_SETTINGS:
            out.append(f"${number}={int(value)}")
        else:
            out.append(f"${number}={grbl_float(value, 0 if number in (30, 31) else 3)}")
    return out
