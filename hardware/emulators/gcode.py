"""G-code of the emulated Grbl 1.1h: a block checked in Grbl's order, with Grbl's error codes.

:func:`parse_block` imports a cleaned, upper-cased line's words (Grbl's step 2: letters,
numbers, modal groups, repeats); :func:`~feeler.hardware.emulators.gcode_exec.interpret`
checks the block against the parser state and lists what the controller runs (steps 3
and 4). A failing line raises :class:`GcodeError` with the code Grbl sends. Positions are
machine coordinates in mm.

Supported as in Grbl: G0 G1 G4 G10 (L2, L20) G17-G19 G20 G21 G28 G30 (and .1) G40 G43.1 G49
G53 G54-G59 G61 G80 G90 G91 G91.1 G92 G92.1 G94, M0 M1 M2 M3 M4 M5 M8 M9 M30, words F I J K L
N P R S T X Y Z. Left out, and answered ``error:20`` as Grbl answers a command it cannot do:
arcs (G2 G3), probing (G38.x) and inverse-time feed (G93).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

from feeler.hardware.emulators.settings import read_float

__all__ = ["GcodeError", "Modal", "ParserState", "parse_block", "clean_line", "LEFT_OUT", "MM_PER_INCH"]

MM_PER_INCH = 25.4
N_COORD = 6
LEFT_OUT = {2: "G2", 3: "G3", 38: "G38.x", 93: "G93"}
_VALUE_LETTERS = "FIJKLNPRSTXYZ"


class GcodeError(Exception):
    """A line Grbl would reject with ``error:code``."""

    def __init__(self, code: int):
        self.code = code
        super().__init__(f"error:{code}")


@dataclass(frozen=True)
class Modal:
    """Modal groups: motion 0/1/80, plane 0-2 (G17-G19), distance 0/1 (G90/G91), inches,
    coord_select 0-5 (G54-G59), tlo_dynamic (G43.1), program_flow 0/3 (M0)/2/30,
    spindle 3/4/5, coolant 0/8."""

    motion: int = 0
    plane: int = 0
    distance: int = 0
    inches: bool = False
    coord_select: int = 0
    tlo_dynamic: bool = False
    program_flow: int = 0
    spindle: int = 5
    coolant: int = 0


@dataclass
class ParserState:
    """Grbl's ``gc_state``: modes, feed (mm/min), spindle speed, tool, the parser's position
    and the work offsets (active system, G92, tool length on Z), machine coordinates, mm."""

    modal: Modal = field(default_factory=Modal)
    feed_mm_min: float = 0.0
    spindle_rpm: float = 0.0
    tool: int = 0
    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    coord_system: tuple[float, float, float] = (0.0, 0.0, 0.0)
    g92: tuple[float, float, float] = (0.0, 0.0, 0.0)
    tlo: float = 0.0

    def wco(self) -> tuple[float, float, float]:
        """Work coordinate offset: machine − work position."""
        return tuple(c + o + (self.tlo if i == 2 else 0.0) for i, (c, o) in enumerate(zip(self.coord_system, self.g92)))


def clean_line(raw: bytes) -> tuple[str, bool]:
    """Grbl's serial filter: drop controls, blanks, '/', comments; upper-case. Returns the
    line and whether it overflowed the 80-byte line buffer."""
    out, paren, semicolon, overflow = [], False, False, False
    for c in raw:
        if paren or semicolon or overflow:
            paren = paren and c != ord(")")
            continue
        if c <= 32 or c == ord("/"):
            continue
        if c == ord("("):
            paren = True
        elif c == ord(";"):
            semicolon = True
        elif len(out) >= 79:
            overflow = True
        else:
            out.append(chr(c).upper() if ord("a") <= c <= ord("z") else chr(c))
    return "".join(out), overflow


def _round(x: float) -> int:
    return int(math.floor(abs(x) + 0.5)) * (1 if x >= 0 else -1)


@dataclass
class _Block:
    modal: Modal
    non_modal: int = 0
    axis_command: str = ""
    groups: set = field(default_factory=set)
    words: dict = field(default_factory=dict)
    axes: dict = field(default_factory=dict)


def _g_word(block: _Block, iv: int, mantissa: int) -> tuple[str, int]:
    """One G word (Grbl's STEP 2); returns the modal group and the mantissa left unused."""
    m = block.modal
    if iv in LEFT_OUT:
        raise GcodeError(20)
    if iv in (10, 28, 30, 92) and mantissa == 0:
        if block.axis_command:
            raise GcodeError(24)
        block.axis_command = "non_modal"
    if iv in (4, 10, 28, 30, 53, 92):
        block.non_modal = iv
        if iv in (28, 30, 92):
            if mantissa not in (0, 10):
                raise GcodeError(20)
            block.non_modal, mantissa = iv + mantissa, 0
        return "G0", mantissa
    if iv in (0, 1, 80):
        if iv != 80:
            if block.axis_command:
                raise GcodeError(24)
            block.axis_command = "motion"
        block.modal = replace(m, motion=iv)
        return "G1", mantissa
    if iv in (17, 18, 19):
        block.modal = replace(m, plane=iv - 17)
        return "G2", mantissa
    if iv in (90, 91):
        if mantissa == 0:
            block.modal = replace(m, distance=iv - 90)
            return "G3", 0
        if mantissa != 10 or iv == 90:
            raise GcodeError(20)
        return "G4", 0
    if iv == 94:
        return "G5", mantissa
    if iv in (20, 21):
        block.modal = replace(m, inches=iv == 20)
        return "G6", mantissa
    if iv == 40:
        return "G7", mantissa
    if iv in (43, 49):
        if block.axis_command:
            raise GcodeError(24)
        block.axis_command = "tlo"
        if iv == 43 and mantissa != 10:
            raise GcodeError(20)
        block.modal = replace(m, tlo_dynamic=iv == 43)
        return "G8", 0
    if 54 <= iv <= 59:
        block.modal = replace(m, coord_select=iv - 54)
        return "G12", mantissa
    if iv == 61:
        if mantissa != 0:
            raise GcodeError(20)
        return "G13", 0
    raise GcodeError(20)


def _m_word(block: _Block, iv: int) -> str:
    m = block.modal
    if iv in (0, 1, 2, 30):
        if iv != 1:
            block.modal = replace(m, program_flow=3 if iv == 0 else iv)
        return "M4"
    if iv in (3, 4, 5):
        block.modal = replace(m, spindle=iv)
        return "M7"
    if iv in (8, 9):
        block.modal = replace(m, coolant=8 if iv == 8 else 0)
        return "M8"
    raise GcodeError(20)


def parse_block(line: str, modal: Modal, jog: bool = False) -> _Block:
    """Grbl's STEP 2: import every word, checking letters, numbers, groups and repeats."""
    block = _Block(modal=replace(modal, motion=1) if jog else modal)
    i = 3 if jog else 0
    while i < len(line):
        letter = line[i]
        if not "A" <= letter <= "Z":
            raise GcodeError(1)
        value, i = read_float(line, i + 1)
        if value is None:
            raise GcodeError(2)
        iv = int(math.trunc(value)) % 256
        mantissa = _round(100 * (value - iv)) % 65536
        if letter == "G":
            group, mantissa = _g_word(block, iv, mantissa)
            if mantissa > 0:
                raise GcodeError(23)
        elif letter == "M":
            if mantissa > 0:
                raise GcodeError(23)
            group = _m_word(block, iv)
        else:
            if letter not in _VALUE_LETTERS:
                raise GcodeError(20)
            if letter == "T" and value > 255:
                raise GcodeError(38)
            if letter in block.words:
                raise GcodeError(25)
            if letter in "FNPTS" and value < 0:
                raise GcodeError(4)
            block.words[letter] = iv if letter in "LT" else (math.trunc(value) if letter == "N" else value)
            continue
        if group in block.groups:
            raise GcodeError(21)
        block.groups.add(group)
    block.axes = {"XYZ".index(a): block.words[a] for a in "XYZ" if a in block.words}
    return block
