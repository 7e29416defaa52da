"""Grbl 1.1h's steps 3 and 4 for the emulator: check a parsed block, then list what runs.

:func:`interpret` returns the new parser state and the operations, in Grbl's order of
execution, as tuples the controller (:mod:`.grbl`) runs one after the other:

- ``("accessory",)``: spindle or coolant state changed (the next report shows ``Ov``/``A``);
- ``("dwell", seconds)``: wait for the planner to empty, then dwell;
- ``("offsets", coord_system, g92, tlo)``: wait for the planner, then new work offsets
  (the next report shows ``WCO``);
- ``("store", index, xyz)``: wait for the planner, then write coordinates 0-5 (G54-G59),
  6 (G28) or 7 (G30);
- ``("move", target_mm, feed_mm_min or None)``: plan a feed move (None: rapid);
- ``("jog", target_mm, feed_mm_min)``: a ``$J=`` jog;
- ``("pause",)``: M0, a feed hold once the planner is empty;
- ``("end", coord_system, g92, tlo)``: M2/M30: wait for the planner, reload G54, spindle
  and coolant off, ``[MSG:Pgm End]``.
"""
from __future__ import annotations

import math
from dataclasses import replace

from feeler.hardware.emulators.gcode import (MM_PER_INCH, N_COORD, GcodeError, Modal, ParserState,
                                             parse_block)

__all__ = ["interpret", "MAX_LINE_NUMBER"]

MAX_LINE_NUMBER = 10_000_000
_JOG_GROUPS = {"G3", "G6", "G0"}


def _targets(block, state, coord, xyz):
    """Where the axis words point, machine mm (Grbl: offsets, G53, distance mode)."""
    pos, out = state.position, []
    for i in range(3):
        if i not in xyz:
            out.append(pos[i])
        elif block.non_modal == 53:
            out.append(xyz[i])
        elif block.modal.distance == 0:
            out.append(xyz[i] + coord[i] + state.g92[i] + (state.tlo if i == 2 else 0.0))
        else:
            out.append(xyz[i] + pos[i])
    return tuple(out)


def _check(block, state: ParserState, stored, jog: bool):
    """Grbl's step 3; returns (words left, feed, speed, dwell, xyz mm, coord, store, g92, target, home)."""
    m, words, axes = block.modal, dict(block.words), block.axes
    if axes and not block.axis_command:
        block.axis_command = "motion"
    if words.get("N", 0) > MAX_LINE_NUMBER:
        raise GcodeError(27)
    scale = MM_PER_INCH if m.inches else 1.0
    if jog and "F" not in words:
        raise GcodeError(22)
    feed = words["F"] * scale if "F" in words else state.feed_mm_min
    speed = words.get("S", state.spindle_rpm)
    dwell = None
    if block.non_modal == 4:
        if "P" not in words:
            raise GcodeError(28)
        dwell = words.pop("P")
    xyz = {i: v * scale for i, v in axes.items()}
    if block.axis_command == "tlo" and m.tlo_dynamic and set(axes) != {2}:
        raise GcodeError(37)
    coord = state.coord_system if m.coord_select == state.modal.coord_select else stored[m.coord_select]
    pos, store, g92, target, home = state.position, None, state.g92, None, None
    if block.non_modal == 10:
        if not axes:
            raise GcodeError(26)
        if "P" not in words and "L" not in words:
            raise GcodeError(28)
        p, lword = math.trunc(words.get("P", 0)), words.get("L", 0)
        if p > N_COORD:
            raise GcodeError(29)
        if lword != 20 and (lword != 2 or "R" in words):
            raise GcodeError(20)
        words.pop("L", None), words.pop("P", None)
        index = p - 1 if p > 0 else m.coord_select
        values = list(stored[index])
        for i, v in xyz.items():
            values[i] = v if lword == 2 else pos[i] - state.g92[i] - v - (state.tlo if i == 2 else 0.0)
        store = (index, tuple(values))
    elif block.non_modal == 92:
        if not axes:
            raise GcodeError(26)
        g92 = tuple(pos[i] - coord[i] - xyz[i] - (state.tlo if i == 2 else 0.0) if i in xyz else state.g92[i]
                    for i in range(3))
    else:
        if block.axis_command != "tlo" and axes:
            target = _targets(block, state, coord, xyz)
        if block.non_modal in (28, 30):
            saved = stored[6 if block.non_modal == 28 else 7]
            home = tuple(saved[i] if (i in axes or not axes) else pos[i] for i in range(3))
            if not axes:
                block.axis_command = ""
        elif block.non_modal == 53 and m.motion not in (0, 1):
            raise GcodeError(30)
    if m.motion == 80:
        if axes:
            raise GcodeError(31)
    elif block.axis_command == "motion":
        if m.motion == 1 and feed == 0:
            raise GcodeError(22)
        if not axes:
            block.axis_command = ""
    for letter in ("N", "F") + (() if jog else ("S", "T")):
        words.pop(letter, None)
    if block.axis_command:
        for letter in "XYZ":
            words.pop(letter, None)
    if words:
        raise GcodeError(36)
    return feed, speed, dwell, xyz, coord, store, g92, target, home


def interpret(line: str, state: ParserState, stored, *, jog: bool = False) -> tuple[ParserState, list[tuple]]:
    """Check ``line`` (upper-cased, cleaned; ``$J=...`` when ``jog``) against ``state``.

    Args:
        stored (list of 8 xyz tuples): G54-G59, G28, G30 coordinates (Grbl's EEPROM), mm.
    Returns:
        (new parser state, operations): the offsets change only when their operation runs.
    Raises:
        GcodeError: the code Grbl answers.
    """
    block = parse_block(line, state.modal, jog)
    feed, speed, dwell, xyz, coord, store, g92, target, home = _check(block, state, stored, jog)
    if jog:
        if block.groups - _JOG_GROUPS or block.non_modal not in (0, 53):
            raise GcodeError(16)
        return state, [("jog", target or (0.0, 0.0, 0.0), feed)]
    m, old, ops = block.modal, state.modal, []
    new = replace(state, feed_mm_min=feed, tool=block.words.get("T", 0), modal=replace(m, program_flow=0))
    if speed != state.spindle_rpm:
        if old.spindle != 5:
            ops.append(("accessory",))
        new.spindle_rpm = speed
    if m.spindle != old.spindle or m.coolant != old.coolant:
        ops.append(("accessory",))
    if dwell is not None:
        ops.append(("dwell", dwell))
    coords, tlo = state.coord_system, state.tlo
    if block.axis_command == "tlo":
        value = xyz.get(2, 0.0) if m.tlo_dynamic else 0.0
        if value != tlo:
            tlo = value
            ops.append(("offsets", coords, state.g92, tlo))
    if m.coord_select != old.coord_select:
        coords = coord
        ops.append(("offsets", coords, state.g92, tlo))
    if store is not None:
        ops.append(("store", *store))
        if store[0] == m.coord_select:
            coords = store[1]
            ops.append(("offsets", coords, state.g92, tlo))
    if home is not None:
        if block.axis_command:
            ops.append(("move", target, None))
        ops.append(("move", home, None))
        new.position = home
    if block.non_modal in (38, 40):                        # G28.1, G30.1
        ops.append(("store", 6 if block.non_modal == 38 else 7, state.position))
    if block.non_modal in (92, 102):                       # G92, G92.1
        ops.append(("offsets", coords, g92 if block.non_modal == 92 else (0.0, 0.0, 0.0), tlo))
    if m.motion != 80 and block.axis_command == "motion":
        ops.append(("move", target, None if m.motion == 0 else feed))
        new.position = target
    if m.program_flow == 3:
        ops.append(("pause",))
    elif m.program_flow in (2, 30):
        new.modal = Modal(motion=1, inches=m.inches, tlo_dynamic=m.tlo_dynamic)
        ops.append(("end", stored[0], g92 if block.non_modal == 92 else state.g92, tlo))
    return new, ops
