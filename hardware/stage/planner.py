"""How long the controller may take: estimates the driver's deadlines follow.

Grbl acknowledges a move once it is planned, a dwell once it has waited, and ``$H`` once
homing is over; an acknowledgement can therefore wait for every move queued ahead of it.
These are upper bounds on Grbl's own clock: a move from rest to rest (Grbl blends the
junctions, so it is never slower), a dwell's ``P`` seconds, a homing cycle that searches
the whole travel. A controller can run slower than its clock (grbl-sim on a loaded host
does); the protocol multiplies them by a slack and extends a wait while the controller
shows progress.
"""
from __future__ import annotations

import math
import re

from feeler.hardware.stage.limits import axis_limited

__all__ = ["move_duration_s", "dwell_s", "homing_s", "HOMING_SEARCH_SCALE"]

#: Grbl searches 1.5 × the travel for a switch, and 5 × the pull-off to locate it again
HOMING_SEARCH_SCALE, HOMING_LOCATE_SCALE = 1.5, 5.0
_DWELL = re.compile(r"G0*4(?![0-9.])")
_P = re.compile(r"P([+-]?(?:\d+\.?\d*|\.\d+))")


def move_duration_s(start_mm, end_mm, feed_mm_min: float | None, rates_mm_min, accels_mm_s2) -> float:
    """Seconds for a straight move from rest to rest (``feed_mm_min`` None: a rapid).

    With path length L, speed v (the feed, clipped by every moving axis' rate) and
    acceleration a (likewise clipped): L/v + v/a when the move reaches v, else 2·√(L/a).
    """
    length = math.dist(start_mm, end_mm)
    if length == 0.0:
        return 0.0
    rate = axis_limited(start_mm, end_mm, rates_mm_min)
    v = (rate if feed_mm_min is None else min(rate, feed_mm_min)) / 60.0
    a = axis_limited(start_mm, end_mm, accels_mm_s2)
    return length / v + v / a if length >= v * v / a else 2.0 * math.sqrt(length / a)


def dwell_s(line: str) -> float:
    """Seconds a line dwells (``G4 P<s>``), 0 for any other line."""
    text = line.upper().replace(" ", "")
    if not _DWELL.search(text):
        return 0.0
    match = _P.search(text)
    return max(float(match.group(1)), 0.0) if match else 0.0


def homing_s(settings: dict[int, float]) -> float:
    """Upper bound on a homing cycle (``$H``): Z, then X and Y, each searching the whole
    travel at the seek rate ``$25``, locating at ``$24``, pulling off ``$27`` twice."""
    seek, feed, pull = settings[25] / 60.0, settings[24] / 60.0, settings[27]
    debounce = settings[26] / 1000.0
    cycle = [HOMING_SEARCH_SCALE * max(settings[130 + i] for i in axes) / seek
             + HOMING_LOCATE_SCALE * pull / feed + 2 * pull / seek + 2 * debounce for axes in ((2,), (0, 1))]
    return sum(cycle)
