"""Plate profiles as piecewise-constant height functions of the scan coordinate x.

Every profile the robot scenes use — a single step up or down, a staircase of equal
steps, a square-wave grating — is a base height plus a finite list of edges, each a jump
of the height at one position. Keeping the edges explicit lets the probe smooth the
profile with its footprint exactly (a sum of the footprint's CDF over the edges), with no
grid whose spacing could change the answer.

Coordinates (DESIGN §3): x along the scan in mm, heights along y (the surface normal) in
mm, positive upwards (towards the sensor).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from feeler.errors import ArgumentError

__all__ = ["Profile", "step", "staircase", "grating"]


@dataclass(frozen=True)
class Profile:
    """A plate profile: ``base_mm`` plus a jump ``jumps_mm[i]`` at every ``edges_mm[i]``.

    Attributes:
        edges_mm (tuple[float, ...]): edge positions along x in mm, strictly increasing.
        jumps_mm (tuple[float, ...]): height change at each edge in mm (> 0 step up,
            < 0 step down); same length as ``edges_mm``.
        base_mm (float): height left of the first edge in mm.
    """

    edges_mm: tuple[float, ...]
    jumps_mm: tuple[float, ...]
    base_mm: float = 0.0

    def __post_init__(self):
        edges = np.asarray(self.edges_mm, dtype=float)
        jumps = np.asarray(self.jumps_mm, dtype=float)
        if edges.ndim != 1 or jumps.shape != edges.shape:
            raise ArgumentError("jumps_mm", self.jumps_mm, f"one jump per edge ({edges.size} edges)")
        if not (np.all(np.isfinite(edges)) and np.all(np.isfinite(jumps)) and math.isfinite(self.base_mm)):
            raise ArgumentError("edges_mm", self.edges_mm, "finite edges, jumps and base_mm")
        if np.any(np.diff(edges) <= 0):
            raise ArgumentError("edges_mm", self.edges_mm, "strictly increasing positions in mm")

    def height_mm(self, x_mm) -> np.ndarray:
        """Height at ``x_mm`` (ndarray[...] in mm); an edge belongs to its right side."""
        x = np.asarray(x_mm, dtype=float)
        h = np.full(x.shape, float(self.base_mm))
        for edge, jump in zip(self.edges_mm, self.jumps_mm):
            h += jump * (x >= edge)
        return h

    @property
    def total_rise_mm(self) -> float:
        """Height right of the last edge minus ``base_mm`` (mm)."""
        return float(sum(self.jumps_mm))


def step(position_mm: float, height_mm: float) -> Profile:
    """One step of ``height_mm`` (negative: step down) at ``position_mm``."""
    return Profile((float(position_mm),), (float(height_mm),))


def staircase(start_mm: float, spacing_mm: float, height_mm: float, n_steps: int) -> Profile:
    """``n_steps`` equal steps of ``height_mm`` every ``spacing_mm`` from ``start_mm``."""
    if n_steps < 1:
        raise ArgumentError("n_steps", n_steps, "an integer >= 1")
    if not spacing_mm > 0:
        raise ArgumentError("spacing_mm", spacing_mm, "a spacing > 0 mm")
    edges = tuple(start_mm + i * spacing_mm for i in range(n_steps))
    return Profile(edges, (float(height_mm),) * n_steps)


def grating(start_mm: float, period_mm: float, depth_mm: float, n_periods: int,
            duty: float = 0.5) -> Profile:
    """A square-wave grating: ``n_periods`` ridges of ``depth_mm``, each ``duty·period_mm`` wide.

    The plate is at 0 outside the grating; each period starts with a rise of ``depth_mm``
    and falls back after ``duty * period_mm``.
    """
    if n_periods < 1:
        raise ArgumentError("n_periods", n_periods, "an integer >= 1")
    if not period_mm > 0:
        raise ArgumentError("period_mm", period_mm, "a period > 0 mm")
    if not 0 < duty < 1:
        raise ArgumentError("duty", duty, "a fraction strictly between 0 and 1")
    edges, jumps = [], []
    for i in range(n_periods):
        left = start_mm + i * period_mm
        edges += [left, left + duty * period_mm]
        jumps += [float(depth_mm), -float(depth_mm)]
    return Profile(tuple(edges), tuple(jumps))
