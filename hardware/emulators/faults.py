"""Fault injection for the Grbl emulator: what goes wrong, when, parsed from a CLI spec.

A spec is ``KIND[:key=value,...]``, e.g. ``drop:reply=ok,nth=2`` (drop the second ``ok``),
``delay:reply=status,delay_s=1.5`` (hold the first status report 1.5 s),
``garble:reply=any,nth=none,p=0.1`` (corrupt each reply with probability 0.1),
``truncate:reply=status``, ``alarm:code=1,x_mm=5`` (a limit switch at x = 5 mm),
``alarm:code=1,after_s=2``, ``vanish:after_s=1``, ``vanish:reply=ok,nth=3``, or
``lose:nth=4`` (the fourth line the host sends is lost on the way: never received).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from feeler.errors import ArgumentError

__all__ = ["Fault", "FaultPlan", "parse_fault", "KINDS", "REPLY_KINDS"]

KINDS = ("delay", "drop", "garble", "truncate", "alarm", "vanish", "lose")
REPLY_KINDS = ("any", "ok", "error", "status", "alarm", "banner", "msg", "setting")
_AXES = ("x_mm", "y_mm", "z_mm")


@dataclass(frozen=True)
class Fault:
    """One injected fault.

    Attributes:
        kind (str): one of ``KINDS``.
        reply (str): which replies it hits (``REPLY_KINDS``), for reply faults.
        nth (int | None): hit the nth matching reply (1-based; for ``lose``: the nth line
            the host sends); ``None``: every match, each with probability ``p``.
        p (float): probability per match when ``nth`` is ``None``, in (0, 1].
        delay_s (float): how long a ``delay`` holds the reply, seconds, > 0.
        code (int): the ``ALARM:code`` an ``alarm`` raises, 1..10.
        x_mm, y_mm, z_mm (float | None): an ``alarm`` fires when that axis crosses it.
        after_s (float | None): ``alarm``/``vanish`` this long after the first byte in.
    """

    kind: str
    reply: str = "any"
    nth: int | None = 1
    p: float = 1.0
    delay_s: float = 0.5
    code: int = 1
    x_mm: float | None = None
    y_mm: float | None = None
    z_mm: float | None = None
    after_s: float | None = None

    def __post_init__(self):
        spec = f"{self.kind}:{self.reply}"
        if self.kind not in KINDS:
            raise ArgumentError("fault", self.kind, f"one of {', '.join(KINDS)}")
        if self.reply not in REPLY_KINDS:
            raise ArgumentError("fault reply", self.reply, f"one of {', '.join(REPLY_KINDS)}")
        if self.nth is not None and self.nth < 1:
            raise ArgumentError("fault nth", self.nth, "an integer >= 1 or none")
        if not 0 < self.p <= 1:
            raise ArgumentError("fault p", self.p, "a probability in (0, 1]")
        if not (self.delay_s > 0 and math.isfinite(self.delay_s)):
            raise ArgumentError("fault delay_s", self.delay_s, "a finite number of seconds > 0")
        if self.kind == "alarm" and not 1 <= self.code <= 10:
            raise ArgumentError("fault code", self.code, "a Grbl alarm code 1..10")
        if self.kind == "alarm" and self.after_s is None and not self.positions():
            raise ArgumentError("fault", spec, "an alarm needs after_s or one of x_mm, y_mm, z_mm")
        if self.after_s is not None and self.after_s < 0:
            raise ArgumentError("fault after_s", self.after_s, "seconds >= 0")

    def positions(self) -> dict[int, float]:
        """Axis index → coordinate (mm) at which an ``alarm`` fires."""
        return {i: getattr(self, a) for i, a in enumerate(_AXES) if getattr(self, a) is not None}

    @property
    def timed(self) -> bool:
        """Fires on the clock or position rather than on a reply."""
        return self.kind == "alarm" or (self.kind == "vanish" and self.after_s is not None)


def parse_fault(spec: str) -> Fault:
    """Parse ``KIND[:key=value,...]`` into a :class:`Fault` (``ArgumentError`` if bad)."""
    kind, _, rest = spec.partition(":")
    known = {f.name: f.type for f in fields(Fault) if f.name != "kind"}
    values: dict[str, object] = {}
    for item in filter(None, rest.split(",")):
        key, eq, text = item.partition("=")
        if not eq or key not in known:
            raise ArgumentError("--fault", spec, f"KIND[:key=value,...] with keys {', '.join(known)}")
        try:
            values[key] = _convert(key, text)
        except ValueError:
            raise ArgumentError("--fault", spec, f"{key} must be a number{_or_none(key)}") from None
    try:
        return Fault(kind.strip(), **values)
    except ArgumentError as exc:
        raise ArgumentError("--fault", spec, f"{exc.name} {exc.allowed}") from None


def _convert(key: str, text: str):
    if key == "reply":
        return text
    if text.lower() == "none" and key in ("nth", *_AXES, "after_s"):
        return None
    if key in ("nth", "code"):
        return int(text)
    return float(text)


def _or_none(key: str) -> str:
    return " or none" if key in ("nth", *_AXES, "after_s") else ""


class FaultPlan:
    """Decides, reply by reply, which fault (if any) strikes; seeded and deterministic."""

    def __init__(self, faults: tuple[Fault, ...], seed: int):
        self.reply_faults = [f for f in faults if not f.timed and f.kind != "lose"]
        self.timed_faults = [f for f in faults if f.timed]
        self.line_faults = [f for f in faults if f.kind == "lose"]
        self._lines = 0
        self._counts = [0] * len(self.reply_faults)
        self._rng = np.random.default_rng(seed)

    def on_reply(self, kind: str) -> Fault | None:
        """The fault hitting the next reply of ``kind`` (counting every matching fault)."""
        hit = None
        for i, fault in enumerate(self.reply_faults):
            if fault.reply not in ("any", kind):
                continue
            self._counts[i] += 1
            if fault.nth is not None:
                fires = self._counts[i] == fault.nth
            else:
                fires = bool(self._rng.random() < fault.p)
            hit = hit or (fault if fires else None)
        return hit

    def lose_line(self) -> bool:
        """Whether the next line from the host is lost on the way (counts it)."""
        self._lines += 1
        return any(self._lines == f.nth if f.nth is not None else bool(self._rng.random() < f.p)
                   for f in self.line_faults)

    def garble(self, line: bytes) -> bytes:
        """``line`` with one byte replaced by a non-ASCII byte (never a valid reply)."""
        i = int(self._rng.integers(0, max(len(line), 1)))
        bad = bytes([int(self._rng.integers(0x80, 0x100))])
        return line[:i] + bad + line[i + 1:]
