"""The loading history shared by every level: press, hold, slide.

The finger is pressed ``press_mm`` onto the plate in ``press_s`` (linear ramp), held
``hold_s``, then slid ``slide_mm`` in +x at constant speed. All levels return their
strain on the same time grid, built here.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from feeler.errors import ArgumentError
from feeler.models.skin.params import SkinParams

__all__ = ["Loading", "loading_history", "check_speed"]

N_PRESS = 20   # time steps of the press ramp
N_HOLD = 40    # time steps of the hold, geometrically growing (resolve the Prony transient)
MAX_SLIDE_STEPS = 2_000_000


@dataclass(frozen=True)
class Loading:
    """Time grid and imposed motion.

    Attributes:
        t_s (ndarray[n_time]): times in seconds, strictly increasing, t_s[0] = 0.
        press_mm (ndarray[n_time]): press depth of the plate into the finger, mm.
        travel_mm (ndarray[n_time]): finger travel along the plate, mm (0 before the slide).
        slide_start (int): index of the first sample of the slide (the end of the hold).
    """

    t_s: np.ndarray
    press_mm: np.ndarray
    travel_mm: np.ndarray
    slide_start: int


def check_speed(speed_mm_s: float) -> float:
    """Validate a sliding speed in mm/s (finite, > 0)."""
    if not (isinstance(speed_mm_s, (int, float, np.floating)) and math.isfinite(speed_mm_s)
            and speed_mm_s > 0):
        raise ArgumentError("speed_mm_s", speed_mm_s, "must be a finite number > 0 mm/s")
    return float(speed_mm_s)


def loading_history(params: SkinParams, speed_mm_s: float, dt_s: float | None = None) -> Loading:
    """Build the press–hold–slide grid.

    Args:
        params: the skin model's parameters (press, hold, slide).
        speed_mm_s (float): sliding speed in mm/s, > 0.
        dt_s (float | None): time step of the slide in seconds; None → 10 µm of travel
            per step.
    """
    speed = check_speed(speed_mm_s)
    dt = 0.010 / speed if dt_s is None else dt_s
    if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0):
        raise ArgumentError("dt_s", dt_s, "must be a finite number > 0 s")
    slide_s = params.slide_mm / speed
    n_slide = max(1, math.ceil(slide_s / dt - 1e-9))
    if n_slide > MAX_SLIDE_STEPS:
        raise ArgumentError("dt_s", dt_s, f"gives {n_slide} slide steps; at most {MAX_SLIDE_STEPS}")
    t_press = np.linspace(0.0, params.press_s, N_PRESS + 1)
    if params.hold_s > 0:
        first = min(params.press_s / N_PRESS, params.hold_s / N_HOLD)
        grow = np.geomspace(first, params.hold_s + first, N_HOLD) - first
        t_hold = params.press_s + grow[1:] * (params.hold_s / grow[-1])
    else:
        t_hold = np.empty(0)
    t0 = params.press_s + params.hold_s
    t_slide = t0 + np.linspace(0.0, slide_s, n_slide + 1)[1:]
    t = np.concatenate([t_press, t_hold, t_slide])
    press = np.minimum(t / params.press_s, 1.0) * params.press_mm
    travel = np.clip((t - t0) * speed, 0.0, params.slide_mm)
    return Loading(t_s=t, press_mm=press, travel_mm=travel, slide_start=len(t_press) + len(t_hold) - 1)
