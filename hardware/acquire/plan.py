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
ceilings before anything moves, naming the plan key that put a move out of range.
Coordinates are the stage's machine coordinates: on a Grbl board, ``[-travel, 0]``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from feeler.errors import SceneError
from feeler.scenes.scan_plan import per_minute_hint, samples_per_scan

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
    return np.arange(samples_per_scan(s.speed_mm_s, s.traverse_mm, s.sample_period_s)) * s.sample_period_s


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


_FEED_KEYS = {"scan.traverse_mm": "scan.speed_mm_s", "plates.surface_z_mm": "scan.press_feed_mm_min",
              "scan.press_mm": "scan.press_feed_mm_min"}


def _feed_problem(plan, key: str, feed: float, ceiling: float, start, target, limits, port) -> tuple[str, str]:
    """The plan key behind a move's feed, and what is wrong with it."""
    length = math.dist(start, target)
    axis = min((i for i in range(3) if start[i] != target[i]),
               key=lambda i: limits.max_rate_mm_min[i] * length / abs(target[i] - start[i]))
    fkey = _FEED_KEYS.get(key, "scan.move_feed_mm_min")
    value = f"{plan.scan.speed_mm_s:g} mm/s ({feed:g} mm/min)" if fkey == "scan.speed_mm_s" else f"{feed:g} mm/min"
    return fkey, (f"{value} is above the ceiling of {ceiling:g} mm/min of {port} for this move "
                  f"(${110 + axis}, the {'xyz'[axis]} axis' maximum rate, is {limits.max_rate_mm_min[axis]:g} "
                  f"mm/min): lower {fkey} or raise ${110 + axis}"
                  + (_per_minute_hint(plan.scan, ceiling) if fkey == "scan.speed_mm_s" else ""))


def _per_minute_hint(scan, ceiling_mm_min: float) -> str:
    """The mm/min hint of a traverse too fast for the board, when the plan as written takes
    two samples a scan, the fewest a plan may have: a speed in mm/min that the stroke check
    let through (a 0.25 mm/s scan written 15) gives that; a plan of more samples is taken as
    meant in mm/s, too fast for the board."""
    if samples_per_scan(scan.speed_mm_s, scan.traverse_mm, scan.sample_period_s) > 2:
        return ""
    return per_minute_hint(scan, ceiling_mm_min)


def check_moves(plan, plan_path: str | Path, limits, port: str, start_mm=None) -> None:
    """Raise :class:`SceneError` (naming the plan file, the key, the value and the board's
    limit) for the first move beyond the soft limits (axes that move) or faster than the
    moving axes' maximum rates ``$110-$112`` (Grbl would silently run it slower).

    Args:
        limits (StageLimits): the stage's ranges and per-axis rates.
        start_mm (tuple | None): where the stage stands before the first move (None: not
            known; the feed of a move from an unknown position is not checked).
    """
    start = (math.nan,) * 3 if start_mm is None else tuple(float(v) for v in start_mm)   # nan: not known
    for scan in scans_of(plan):
        for key, target, feed, axes in moves_of(plan, scan):
            target = tuple(target[i] if "xyz"[i] in axes else start[i] for i in range(3))
            for i, axis in enumerate(("x_mm", "y_mm", "z_mm")):
                lo, hi = limits.range_of(axis)
                if not math.isnan(target[i]) and target[i] != start[i] and not lo <= target[i] <= hi:
                    where = "plates.y_mm" if axis == "y_mm" else key
                    if axis == "z_mm" and not lo <= plan.plates.surface_z_mm <= hi:
                        where = "plates.surface_z_mm"       # the plate itself is out of reach, not the clearance
                    raise SceneError(plan_path, where, f"scan {scan.scan_id} moves {axis[0]} to {target[i]:g} mm, "
                                     f"beyond the soft limits [{lo:g}, {hi:g}] mm of {port} ({limits.source})")
            known = not any(math.isnan(v) for v in start + target)
            ceiling = limits.feed_ceiling(start, target) if known else math.inf
            if feed > ceiling * (1 + 1e-9):
                raise SceneError(plan_path, *_feed_problem(plan, key, feed, ceiling, start, target, limits, port))
            start = target
