"""The G-code subset of the emulated Grbl 1.1, with Grbl's own error codes.

Supported: G0 G1 (motion), G4 P<s> (dwell), G90 G91 (distance mode), G20 G21 (units),
G17 G54 G94 (accepted, no effect), M2 M5 M30 M9 (accepted), words N F P X Y Z.
Anything else is ``error:20``; a failing line raises :class:`GcodeError` with the code
Grbl would send (see ``feeler.hardware.stage.errors.GRBL_ERRORS``).
"""
from __future__ import annotations

import re
from dataclasses import dataclass, replace

__all__ = ["GcodeError", "Modal", "Action", "clean_line", "parse_words", "interpret"]

_NUMBER = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)")
_MOTION, _DISTANCE, _UNITS = {0, 1}, {90, 91}, {20, 21}
_NO_EFFECT_G, _NO_EFFECT_M = {17, 54, 94}, {2, 5, 9, 30}
_AXES = "XYZ"


class GcodeError(Exception):
    """A line Grbl would reject with ``error:code``."""

    def __init__(self, code: int):
        self.code = code
        super().__init__(f"error:{code}")


@dataclass(frozen=True)
class Modal:
    """Modal state after a reset: G0, G90, G21 and an undefined feed rate."""

    motion: int = 0
    absolute: bool = True
    inches: bool = False
    feed_mm_min: float = 0.0


@dataclass(frozen=True)
class Action:
    """What a line asks for: ``kind`` is ``"none"``, ``"move"`` or ``"dwell"``."""

    kind: str
    modal: Modal
    target_mm: tuple[float, float, float] | None = None
    rapid: bool = False
    dwell_s: float = 0.0


def clean_line(raw: str) -> str:
    """Grbl's pre-processing: drop blanks and comments, upper-case the rest."""
    out, in_paren = [], False
    for ch in raw:
        if in_paren:
            in_paren = ch != ")"
        elif ch == "(":
            in_paren = True
        elif ch == ";":
            break
        elif ch not in " \t%":
            out.append(ch.upper())
    return "".join(out)


def parse_words(line: str) -> list[tuple[str, float]]:
    """Split a cleaned line into (letter, value) words (errors 1 and 2)."""
    words, i = [], 0
    while i < len(line):
        letter = line[i]
        if not ("A" <= letter <= "Z"):
            raise GcodeError(1)
        match = _NUMBER.match(line, i + 1)
        if match is None:
            raise GcodeError(2)
        words.append((letter, float(match.group())))
        i = match.end()
    return words


def interpret(words: list[tuple[str, float]], modal: Modal, position_mm) -> Action:
    """Apply one block's words to ``modal`` at machine position ``position_mm``."""
    seen: dict[str, float] = {}
    groups: dict[str, int] = {}
    for letter, value in words:
        if letter in "GM":
            if value != int(value):
                raise GcodeError(20)
            code = int(value)
            group = _group(letter, code)
            if group in groups:
                raise GcodeError(21)
            groups[group] = code
        elif letter in "NFPXYZ":
            if letter in seen:
                raise GcodeError(25)
            seen[letter] = value
        else:
            raise GcodeError(20)
    if seen.get("N", 0) < 0 or seen.get("N", 0) > 9999999:
        raise GcodeError(27)
    for letter in "FP":
        if seen.get(letter, 0.0) < 0:
            raise GcodeError(4)
    if "motion" in groups:
        modal = replace(modal, motion=groups["motion"])
    if "distance" in groups:
        modal = replace(modal, absolute=groups["distance"] == 90)
    if "units" in groups:
        modal = replace(modal, inches=groups["units"] == 20)
    scale = 25.4 if modal.inches else 1.0
    if "F" in seen:
        modal = replace(modal, feed_mm_min=seen["F"] * scale)
    if groups.get("dwell") == 4:
        if "P" not in seen:
            raise GcodeError(28)
        if any(a in seen for a in _AXES):
            raise GcodeError(31)
        return Action("dwell", modal, dwell_s=seen["P"])
    if "P" in seen:
        raise GcodeError(36)
    if not any(a in seen for a in _AXES):
        return Action("none", modal)
    if modal.motion == 1 and modal.feed_mm_min <= 0:
        raise GcodeError(22)
    target = tuple(
        (seen[a] * scale if modal.absolute else p + seen[a] * scale) if a in seen else p
        for a, p in zip(_AXES, position_mm))
    return Action("move", modal, target_mm=target, rapid=modal.motion == 0)


def _group(letter: str, code: int) -> str:
    if letter == "M":
        if code not in _NO_EFFECT_M:
            raise GcodeError(20)
        return "mcode"
    if code in _MOTION:
        return "motion"
    if code in _DISTANCE:
        return "distance"
    if code in _UNITS:
        return "units"
    if code == 4:
        return "dwell"
    if code in _NO_EFFECT_G:
        return f"g{code}"
    raise GcodeError(20)
