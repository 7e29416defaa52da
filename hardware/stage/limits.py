"""Soft limits, feed ceilings and axis roles of a stage, as frozen dataclasses.

Grbl 1.1 places machine positions in ``[-travel, 0]`` per axis (``$130-$132``): homing
ends at the switches' end of travel, which is machine 0 (less the pull-off ``$27``), and
the work area lies below it; soft limits (``$20=1``) reject targets outside. Only a
firmware built with ``HOMING_FORCE_SET_ORIGIN`` (``Z`` among ``$I``'s options) homes to 0
and, for axes homing towards negative (``$23``), uses ``[0, travel]``. A machine whose
coordinates follow another convention sets its limits explicitly.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from feeler.errors import ArgumentError

__all__ = ["AXES", "StageLimits", "StageGeometry", "axis_limited"]

AXES = ("x_mm", "y_mm", "z_mm")
Vec = tuple[float, float, float]


def axis_limited(start_mm: Vec, end_mm: Vec, per_axis: Vec) -> float:
    """Largest path rate (or acceleration) keeping every moving axis within ``per_axis``
    (Grbl limits the path by ``min_i per_axis_i / |u_i|``); ``inf`` for no motion."""
    delta = [e - s for s, e in zip(start_mm, end_mm)]
    length = math.sqrt(sum(d * d for d in delta))
    if length == 0.0:
        return math.inf
    return min(lim * length / abs(d) for d, lim in zip(delta, per_axis) if d != 0.0)


@dataclass(frozen=True)
class StageLimits:
    """Where the stage may go and how fast.

    Attributes:
        x_mm, y_mm, z_mm (tuple[float, float]): allowed machine range per axis, mm.
        max_rate_mm_min (tuple[float, float, float]): per-axis ceiling ``$110-$112``, mm/min.
        accel_mm_s2 (tuple[float, float, float]): per-axis acceleration ``$120-$122``, mm/s².
        source (str): where the ranges come from (for messages), e.g. ``"$130-$132"``.
    """

    x_mm: tuple[float, float] = (-200.0, 0.0)
    y_mm: tuple[float, float] = (-200.0, 0.0)
    z_mm: tuple[float, float] = (-200.0, 0.0)
    max_rate_mm_min: Vec = (500.0, 500.0, 500.0)
    accel_mm_s2: Vec = (10.0, 10.0, 10.0)
    source: str = "Grbl's [-$130..$132, 0]"

    def __post_init__(self):
        for axis in AXES:
            lo, hi = getattr(self, axis)
            if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
                raise ArgumentError(axis, (lo, hi), "a soft-limit range [lo, hi] mm with lo <= hi")
        for name in ("max_rate_mm_min", "accel_mm_s2"):
            if not all(math.isfinite(v) and v > 0 for v in getattr(self, name)):
                raise ArgumentError(name, getattr(self, name), "three numbers > 0")

    @classmethod
    def from_settings(cls, settings: dict[int, float], *, origin_at_home: bool = False) -> "StageLimits":
        """From Grbl's ``$$``: ranges ``[-travel, 0]`` (``origin_at_home``: a firmware with
        HOMING_FORCE_SET_ORIGIN, where axes homing negative use ``[0, travel]``)."""
        try:
            travel = [settings[130 + i] for i in range(3)]
            rates = tuple(float(settings[110 + i]) for i in range(3))
            accels = tuple(float(settings[120 + i]) for i in range(3))
        except KeyError as exc:
            raise ArgumentError("settings", sorted(settings), f"Grbl settings including ${exc}") from None
        mask = int(settings.get(23, 0))
        ranges = [(0.0, t) if origin_at_home and (mask >> i) & 1 else (-t, 0.0) for i, t in enumerate(travel)]
        return cls(*ranges, max_rate_mm_min=rates, accel_mm_s2=accels,
                   source="HOMING_FORCE_SET_ORIGIN" if origin_at_home else "Grbl's [-$130..$132, 0]")

    def range_of(self, axis: str) -> tuple[float, float]:
        return getattr(self, axis)

    def feed_ceiling(self, start_mm: Vec, end_mm: Vec) -> float:
        """Highest feed (mm/min) of a straight move that no moving axis' ``$11x`` clips."""
        return axis_limited(start_mm, end_mm, self.max_rate_mm_min)

    def check(self, start_mm: Vec, target_mm: Vec, feed_mm_min: float, port: str) -> None:
        """Raise ``ArgumentError`` naming the axis, value and range (only axes that move are
        checked), or a feed that is not > 0 or above what the moving axes allow."""
        if not (math.isfinite(feed_mm_min) and feed_mm_min > 0):
            raise ArgumentError("feed_mm_min", feed_mm_min, f"a feed > 0 mm/min on {port}")
        for i, (axis, start, value) in enumerate(zip(AXES, start_mm, target_mm)):
            if not math.isfinite(value):
                raise ArgumentError(axis, value, f"a finite machine coordinate on {port}")
            lo, hi = self.range_of(axis)
            if value != start and not lo <= value <= hi:
                raise ArgumentError(axis, value, f"within the soft limits [{lo:g}, {hi:g}] mm of {port} ({self.source})")
        ceiling = self.feed_ceiling(start_mm, target_mm)
        if feed_mm_min > ceiling * (1 + 1e-9):
            axis = next(i for i in range(3) if start_mm[i] != target_mm[i]
                        and self.max_rate_mm_min[i] * math.dist(start_mm, target_mm) / abs(target_mm[i] - start_mm[i])
                        <= ceiling * (1 + 1e-12))
            raise ArgumentError("feed_mm_min", feed_mm_min,
                                f"<= {ceiling:g} mm/min for this move on {port} (${110 + axis}, the "
                                f"{'xyz'[axis]} axis' maximum rate, is {self.max_rate_mm_min[axis]:g} mm/min)")


@dataclass(frozen=True)
class StageGeometry:
    """Axis roles: the scan runs along ``scan_axis``; a press moves ``press_axis`` by
    ``press_sign`` × depth (−1: a downward Z presses into the surface)."""

    scan_axis: str = "x_mm"
    press_axis: str = "z_mm"
    press_sign: int = -1

    def __post_init__(self):
        for name in ("scan_axis", "press_axis"):
            if getattr(self, name) not in AXES:
                raise ArgumentError(name, getattr(self, name), f"one of {', '.join(AXES)}")
        if self.press_sign not in (-1, 1):
            raise ArgumentError("press_sign", self.press_sign, "-1 or +1")
