"""The commanded motion of a traverse, written independently of the emulator: a move from
rest to rest at speed v with acceleration a, and the check that recorded (t, x) lie on it.

A sample's position was read at some instant within its status query (``t_s`` ± half the
round trip ``status_rtt_s``), to within the position report's resolution ``q``; the
traverse started at an instant ``t0`` that the campaign does not observe. Every moving
sample bounds ``t0`` from both sides (the profile is strictly increasing there), samples
at rest before or after the move bound it from one side: the record is true exactly when
one ``t0`` satisfies them all.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["Trapezoid", "start_bounds"]


class Trapezoid:
    """x(τ) of a straight move of length L (mm) at speed v (mm/s), acceleration a (mm/s²)."""

    def __init__(self, length_mm: float, speed_mm_s: float, accel_mm_s2: float):
        self.length, self.a = length_mm, accel_mm_s2
        self.v = min(speed_mm_s, math.sqrt(length_mm * accel_mm_s2))      # reached, or a triangle
        self.t_acc = self.v / self.a
        self.d_acc = 0.5 * self.v * self.t_acc
        self.duration = self.length / self.v + self.t_acc

    def position_at(self, tau_s: float) -> float:
        """x (mm) at ``tau_s`` seconds after the start (0 before, L after)."""
        tau = min(max(tau_s, 0.0), self.duration)
        if tau <= self.t_acc:
            return 0.5 * self.a * tau * tau
        if tau <= self.duration - self.t_acc:
            return self.d_acc + self.v * (tau - self.t_acc)
        return self.length - 0.5 * self.a * (self.duration - tau) ** 2

    def time_at(self, x_mm: float) -> float:
        """τ at which the move passes ``x_mm`` (clipped to [0, L])."""
        x = min(max(x_mm, 0.0), self.length)
        if x <= self.d_acc:
            return math.sqrt(2 * x / self.a)
        if x <= self.length - self.d_acc:
            return self.t_acc + (x - self.d_acc) / self.v
        return self.duration - math.sqrt(2 * (self.length - x) / self.a)


def start_bounds(profile: Trapezoid, t_s, x_mm, rtt_s, q_mm: float) -> tuple[float, float]:
    """(lowest, highest) start instant t0 consistent with every sample; lowest > highest
    means no single motion explains the record."""
    lo, hi = -math.inf, math.inf
    for t, x, rtt in zip(np.asarray(t_s), np.asarray(x_mm), np.asarray(rtt_s)):
        early, late = t - rtt / 2, t + rtt / 2
        if x > q_mm:                           # it had passed x - q when read: started early enough
            hi = min(hi, late - profile.time_at(x - q_mm))
        if x < profile.length - q_mm:          # it had not passed x + q: started late enough
            lo = max(lo, early - profile.time_at(x + q_mm))
    return lo, hi
