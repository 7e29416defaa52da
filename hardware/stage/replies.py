"""Grbl 1.1 reply lines as typed records: ``parse_reply(line) -> Reply``.

Every line a Grbl controller sends is one of: ``ok``, ``error:N``, ``ALARM:N``, a status
report ``<State|MPos:x,y,z|FS:f,s|...>``, a bracketed feedback message ``[KIND:text]``,
a setting ``$N=value`` or the welcome banner ``Grbl 1.1h ['$' for help]``. Anything else
(bad bytes, bad numbers, an unknown state) is a :class:`ProtocolError` with ``code=None``;
``parse_reply`` never raises anything else, whatever the bytes.
"""
from __future__ import annotations

import re
from dataclasses import dataclass

from feeler.hardware.stage.errors import ProtocolError

__all__ = ["Ok", "Error", "Alarm", "Status", "Message", "Setting", "Banner", "Reply",
           "parse_reply", "STATES"]

STATES = ("Idle", "Run", "Hold", "Jog", "Alarm", "Door", "Check", "Home", "Sleep")

_CODE = re.compile(r"(error|ALARM):(\d{1,3})")
_BANNER = re.compile(r"Grbl (\S{1,20}) \['\$' for help\]")
_SETTING = re.compile(r"\$(\d{1,3})=(-?\d{1,9}(?:\.\d{1,6})?)")
_MESSAGE = re.compile(r"\[([A-Z][A-Za-z0-9]{0,9}):([ -~]*)\]")
_STATE = re.compile(r"(" + "|".join(STATES) + r")(?::(\d))?")
_FLOAT = r"-?\d{1,7}(?:\.\d{1,6})?"
_VEC3 = re.compile(rf"({_FLOAT}),({_FLOAT}),({_FLOAT})")
_FIELD = re.compile(r"([A-Za-z]{1,4}):([ -{}~]*)")  # any printable except '|'
_NUMBERS = re.compile(rf"{_FLOAT}(?:,{_FLOAT})*")


@dataclass(frozen=True)
class Ok:
    """``ok``: the oldest unacknowledged line was executed (or planned)."""


@dataclass(frozen=True)
class Error:
    """``error:code``: the oldest unacknowledged line was rejected."""
    code: int


@dataclass(frozen=True)
class Alarm:
    """``ALARM:code`` pushed by the controller; motion stopped."""
    code: int


@dataclass(frozen=True)
class Status:
    """A status report.

    Attributes:
        state (str): one of ``STATES``; ``substate`` (int | None) e.g. 0/1 of ``Hold:0``.
        mpos_mm (tuple[float, float, float] | None): machine position, mm.
        wpos_mm (tuple[float, float, float] | None): work position, mm (if reported).
        feed_mm_min (float): current feed rate, mm/min; ``spindle_rpm`` (float).
        extra (tuple[tuple[str, str], ...]): other fields (``Bf``, ``Ov``, ``WCO``...).
    """
    state: str
    substate: int | None
    mpos_mm: tuple[float, float, float] | None
    wpos_mm: tuple[float, float, float] | None
    feed_mm_min: float
    spindle_rpm: float
    extra: tuple[tuple[str, str], ...] = ()


@dataclass(frozen=True)
class Message:
    """A bracketed feedback line ``[kind:text]`` (``MSG``, ``GC``, ``VER``, ``OPT``, ...)."""
    kind: str
    text: str


@dataclass(frozen=True)
class Setting:
    """One line of ``$$``: setting ``number`` has ``value``."""
    number: int
    value: float


@dataclass(frozen=True)
class Banner:
    """The welcome banner after power-up or soft reset; ``version`` e.g. ``"1.1h"``."""
    version: str


Reply = Ok | Error | Alarm | Status | Message | Setting | Banner


def parse_reply(line: bytes) -> Reply:
    """Parse one line (without its ``\\r\\n``) or raise ``ProtocolError(None, line)``."""
    try:
        text = line.decode("ascii")
    except UnicodeDecodeError:
        raise ProtocolError(None, line) from None
    if text == "ok":
        return Ok()
    if match := _CODE.fullmatch(text):
        kind, code = match.groups()
        return Error(int(code)) if kind == "error" else Alarm(int(code))
    if text.startswith("<") and text.endswith(">"):
        return _status(text[1:-1], line)
    if match := _MESSAGE.fullmatch(text):
        return Message(*match.groups())
    if match := _SETTING.fullmatch(text):
        return Setting(int(match.group(1)), float(match.group(2)))
    if match := _BANNER.fullmatch(text):
        return Banner(match.group(1))
    raise ProtocolError(None, line)


def _status(body: str, line: bytes) -> Status:
    state, *fields = body.split("|")
    match = _STATE.fullmatch(state)
    if match is None:
        raise ProtocolError(None, line)
    values: dict[str, str] = {}
    for item in fields:
        field = _FIELD.fullmatch(item)
        if field is None or field.group(1) in values:
            raise ProtocolError(None, line)
        values[field.group(1)] = field.group(2)
    vectors = {}
    for key in ("MPos", "WPos"):
        if key in values:
            vec = _VEC3.fullmatch(values.pop(key))
            if vec is None:
                raise ProtocolError(None, line)
            vectors[key] = tuple(float(v) for v in vec.groups())
    if not vectors:
        raise ProtocolError(None, line)
    feed, spindle = _rates(values, line)
    substate = int(match.group(2)) if match.group(2) is not None else None
    return Status(match.group(1), substate, vectors.get("MPos"), vectors.get("WPos"),
                  feed, spindle, tuple(values.items()))


def _rates(values: dict[str, str], line: bytes) -> tuple[float, float]:
    """Feed and spindle from ``FS:f,s`` or ``F:f`` (removed from ``values``)."""
    if "FS" in values:
        text, count = values.pop("FS"), 2
    elif "F" in values:
        text, count = values.pop("F"), 1
    else:
        return 0.0, 0.0
    if _NUMBERS.fullmatch(text) is None or len(parts := text.split(",")) != count:
        raise ProtocolError(None, line)
    return float(parts[0]), float(parts[1]) if count == 2 else 0.0
