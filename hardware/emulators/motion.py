"""Motion of the emulated stage: straight blocks with trapezoidal speed profiles.

A :class:`Block` moves from ``start_mm`` to ``end_mm`` along a straight line, starting at
speed ``v0_mm_s`` (0 for a planned move, > 0 for the deceleration of a feed hold),
accelerating at ``accel_mm_s2`` up to ``feed_mm_s`` and decelerating to rest at the end.
Unlike Grbl's planner, blocks do not blend at junctions: every block ends at rest, which
keeps the position at any time a closed-form function of the clock.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

__all__ = ["Block", "axis_limited"]

Vec = tuple[float, float, float]


def axis_limited(start_mm: Vec, end_mm: Vec, per_axis: Vec) -> float:
    """Largest path rate (or acceleration) keeping every axis within ``per_axis``.

    For a unit direction ``u`` the axis-``i`` component of a path rate ``r`` is
    ``r·|u_i|``, so the limit is ``min_i per_axis_i / |u_i|`` over moving axes
    (Grbl's ``limit_value_by_axis_maximum``). A zero-length move gets ``inf``.
    """
    delta = [e - s for s, e in zip(start_mm, end_mm)]
    length = math.sqrt(sum(d * d for d in delta))
    if length == 0.0:
        return math.inf
    return min(lim * length / abs(d) for d, lim in zip(delta, per_axis) if d != 0.0)


@dataclass(frozen=True)
class Block:
    """One straight move; times are seconds from the block's own start.

    Attributes:
        start_mm, end_mm (tuple[float, float, float]): machine coordinates, mm.
        feed_mm_s (float): cruise speed along the path, mm/s, > 0.
        accel_mm_s2 (float): acceleration and deceleration, mm/s², > 0.
        v0_mm_s (float): speed at the start, mm/s, with ``v0²/(2a) <= length``.
    """

    start_mm: Vec
    end_mm: Vec
    feed_mm_s: float
    accel_mm_s2: float
    v0_mm_s: float = 0.0
    length_mm: float = field(init=False)
    peak_mm_s: float = field(init=False)
    phases_s: tuple[float, float, float] = field(init=False)

    def __post_init__(self):
        length = math.dist(self.start_mm, self.end_mm)
        a, v0 = self.accel_mm_s2, self.v0_mm_s
        vmax = max(self.feed_mm_s, v0)
        if (2 * vmax**2 - v0**2) / (2 * a) <= length:
            peak = vmax
        else:
            peak = max(math.sqrt(max(2 * a * length + v0**2, 0.0) / 2), v0)
        d_acc = (peak**2 - v0**2) / (2 * a)
        d_dec = peak**2 / (2 * a)
        cruise = max(length - d_acc - d_dec, 0.0)
        phases = ((peak - v0) / a, cruise / peak if peak > 0 else 0.0, peak / a)
        object.__setattr__(self, "length_mm", length)
        object.__setattr__(self, "peak_mm_s", peak)
        object.__setattr__(self, "phases_s", phases if length > 0 else (0.0, 0.0, 0.0))

    @property
    def duration_s(self) -> float:
        t1, t2, t3 = self.phases_s
        return t1 + t2 + t3  # the same rounding as travelled() (sum() is compensated)

    def travelled(self, t_s: float) -> tuple[float, float]:
        """Path distance (mm) and speed (mm/s) at ``t_s`` seconds after the start."""
        a, v0, vp = self.accel_mm_s2, self.v0_mm_s, self.peak_mm_s
        t1, t2, t3 = self.phases_s
        if self.length_mm == 0.0 or t_s >= t1 + t2 + t3:
            return self.length_mm, 0.0
        t_s = max(t_s, 0.0)
        if t_s < t1:
            return v0 * t_s + 0.5 * a * t_s**2, v0 + a * t_s
        d1 = (vp**2 - v0**2) / (2 * a)
        if t_s < t1 + t2:
            return d1 + vp * (t_s - t1), vp
        tau = t_s - t1 - t2
        s = d1 + vp * t2 + vp * tau - 0.5 * a * tau**2
        return min(s, self.length_mm), max(vp - a * tau, 0.0)

    def point(self, distance_mm: float) -> Vec:
        """Machine coordinates ``distance_mm`` along the block from its start."""
        if self.length_mm == 0.0:
            return self.end_mm
        f = min(max(distance_mm / self.length_mm, 0.0), 1.0)
        return tuple(s + f * (e - s) for s, e in zip(self.start_mm, self.end_mm))

    def at(self, t_s: float) -> tuple[Vec, float]:
        """Position (mm) and speed (mm/s) at ``t_s`` seconds after the block's start."""
        s, v = self.travelled(t_s)
        return (self.end_mm if s >= self.length_mm else self.point(s)), v

    def stopping(self, t_s: float) -> tuple["Block", "Block"]:
        """Split at ``t_s`` for a feed hold: (deceleration to rest, remainder from rest)."""
        s, v = self.travelled(t_s)
        stop = min(s + v**2 / (2 * self.accel_mm_s2), self.length_mm)
        here, there = self.point(s), self.point(stop)
        decel = Block(here, there, max(v, 1e-9), self.accel_mm_s2, v0_mm_s=v)
        rest = Block(there, self.end_mm, self.feed_mm_s, self.accel_mm_s2)
        return decel, rest
