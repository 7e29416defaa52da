"""A loaded scan plan turned into scans, stage moves and a sample schedule.

Scan ``scan_id = plate · scans_per_plate + repeat`` (the same numbering as ``feeler
simulate``). Each scan's moves, in order (stage coordinates, mm; feeds mm/min)::

    lift      z = surface + clearance                 at move_feed  (x, y unchanged)
    start     x = origin, y = plan y                  at move_feed
    lower     z = surface                             at press_feed
    press     z = surface − press                     at press_feed
    traverse  x = origin + traverse                   at 60 · speed
    lift      z = surface + clearance                 at move_feed

:func:`check_moves` validates every one of them against the stage's soft limits and feed
ceiling before anything moves, naming the plan key that put a move out of range.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from feeler.errors import SceneError

__all__ = ["ScanSpec", "scans_of", "sample_times_s", "moves_of", "check_moves"]


@dataclass(frozen=True)
class ScanSpec:
    """One scan of a plan: ids, its plate's label and start (stage x, mm)."""

    scan_id: int
    plate: int
    repeat: int
    step_mm: float
    origin_x_mm: float


def scans_of(plan) -> list[ScanSpec]:
    """Every scan of ``plan`` in campaign order (plate by plate)."""
    per = plan.repeats.scans_per_plate
    return [ScanSpec(plate * per + rep, plate, rep, float(h), float(x0))
            for plate, (h, x0) in enumerate(zip(plan.plates.heights_mm, plan.plates.origin_x_mm))
            for rep in range(per)]


def sample_times_s(plan) -> np.ndarray:
    """Scheduled sample times of one scan from the start of the traverse (s):
    ``k · sample_period_s`` for ``k = 0 … floor(traverse / (speed · period))``."""
    s = plan.scan
    n = int(math.floor(s.traverse_mm / (s.speed_mm_s * s.sample_period_s) + 1e-9)) + 1
    return np.arange(n) * s.sample_period_s


def moves_of(plan, scan: ScanSpec) -> list[tuple[str, tuple[float, float, float], float, str]]:
    """The moves of one scan as (plan key responsible, target (x, y, z) mm, feed mm/min,
    the axes that move: a string of x, y, z)."""
    p, s = plan.plates, plan.scan
    x0, x1 = scan.origin_x_mm, scan.origin_x_mm + s.traverse_mm
    up, surface, down = p.surface_z_mm + s.clearance_mm, p.surface_z_mm, p.surface_z_mm - s.press_mm
    return [("scan.clearance_mm", (x0, p.y_mm, up), s.move_feed_mm_min, "z"),
            (f"plates.origin_x_mm[{scan.plate}]", (x0, p.y_mm, up), s.move_feed_mm_min, "xy"),
            ("plates.surface_z_mm", (x0, p.y_mm, surface), s.press_feed_mm_min, "z"),
            ("scan.press_mm", (x0, p.y_mm, down), s.press_feed_mm_min, "z"),
            ("scan.traverse_mm", (x1, p.y_mm, down), s.speed_mm_s * 60.0, "x"),
            ("scan.clearance_mm", (x1, p.y_mm, up), s.move_feed_mm_min, "z")]


def check_moves(plan, plan_path: str | Path, limits, port: str) -> None:
    """Raise :class:`SceneError` (naming the plan file, the key, the value and the stage's
    range) for the first move beyond the soft limits or a feed above the ceiling."""
    feed_keys = {"scan.traverse_mm": "scan.speed_mm_s", "plates.surface_z_mm": "scan.press_feed_mm_min",
                 "scan.press_mm": "scan.press_feed_mm_min"}
    for scan in scans_of(plan):
        for key, target, feed, axes in moves_of(plan, scan):
            if feed > limits.max_feed_mm_min:
                fkey = feed_keys.get(key, "scan.move_feed_mm_min")
                raise SceneError(plan_path, fkey, f"feed {feed:g} mm/min is above the ceiling "
                                 f"{limits.max_feed_mm_min:g} mm/min of {port}")
            for axis, value in zip(("x_mm", "y_mm", "z_mm"), target):
                if axis[0] not in axes:
                    continue
                key = "plates.y_mm" if axis == "y_mm" else key
                lo, hi = getattr(limits, axis)
                if not lo <= value <= hi:
                    raise SceneError(plan_path, key, f"scan {scan.scan_id} moves {axis[0]} to {value:g} mm, "
                                     f"beyond the soft limits [{lo:g}, {hi:g}] mm of {port}")
