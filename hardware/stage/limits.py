"""Soft limits, feed ceiling and axis roles of a stage, as frozen dataclasses."""
from __future__ import annotations

import math
from dataclasses import dataclass

from feeler.errors import ArgumentError

__all__ = ["AXES", "StageLimits", "StageGeometry"]

AXES = ("x_mm", "y_mm", "z_mm")


@dataclass(frozen=True)
class StageLimits:
    """Where the stage may go and how fast.

    Attributes:
        x_mm, y_mm, z_mm (tuple[float, float]): allowed machine range per axis, mm.
        max_feed_mm_min (float): highest feed accepted, mm/min.
    """

    x_mm: tuple[float, float] = (0.0, 200.0)
    y_mm: tuple[float, float] = (0.0, 200.0)
    z_mm: tuple[float, float] = (0.0, 50.0)
    max_feed_mm_min: float = 3000.0

    @classmethod
    def from_settings(cls, settings: dict[int, float]) -> "StageLimits":
        """From Grbl's ``$$``: travel ``$130-132`` as ``[0, travel]``, feed ``min($110-112)``.

        Grbl places soft limits at ``[-travel, 0]`` unless built with the origin forced at
        the home position; pass explicit limits for such machines.
        """
        try:
            travel = [settings[130 + i] for i in range(3)]
            rate = min(settings[110 + i] for i in range(3))
        except KeyError as exc:
            raise ArgumentError("settings", sorted(settings), f"Grbl settings including ${exc}") from None
        return cls(*((0.0, t) for t in travel), max_feed_mm_min=rate)

    def check(self, target_mm: tuple[float, float, float], feed_mm_min: float, port: str) -> None:
        """Raise ``ArgumentError`` naming the axis, value and range, or a bad feed."""
        if not (math.isfinite(feed_mm_min) and 0 < feed_mm_min <= self.max_feed_mm_min):
            raise ArgumentError("feed_mm_min", feed_mm_min,
                                f"> 0 and <= {self.max_feed_mm_min:g} mm/min on {port}")
        for axis, value in zip(AXES, target_mm):
            lo, hi = getattr(self, axis)
            if not (math.isfinite(value) and lo <= value <= hi):
                raise ArgumentError(axis, value, f"within the soft limits [{lo:g}, {hi:g}] mm of {port}")


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
