"""M3: the robot's discrimination of step heights from an M2 posterior (DESIGN §6).

Responses to any step height come from the forward model: the scene's scan chain
(surface → probe → sensor) simulates ``n_scans`` fresh touches of that height, and each
posterior draw θ_s = (a, τ, h) decodes them to peak pulse densities
z = max(a·P(τ) − h, 0). The 2AFC proportion correct of δ₁ < δ₂ under θ_s is
P(z₂ > z₁) + ½ P(z₂ = z₁) over all pairs of scans; its spread over draws is the
credible interval. Every height is simulated with the same root seed (common random
touches), so curves over Δδ are smooth; the reference scans use a different seed so
that the two intervals of a trial are independent touches.

Derived: the difference threshold Δδ₇₅ (the increment over ``reference_mm`` at 75 %
correct) and Weber fraction Δδ₇₅ / reference; the PSE between scan speeds (the step at
the test speed that is judged larger than the reference step at the reference speed
half of the time).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from feeler.calib.neuron.classify import fit_tables
from feeler.calib.neuron.model import peak_table
from feeler.calib.neuron.synth import FOUR_PLATES, scene_scans
from feeler.errors import ArgumentError

__all__ = ["Interval", "Discriminator", "Threshold"]


@dataclass(frozen=True)
class Interval:
    """Posterior mean, 95 % equal-tailed interval and the per-draw values."""
    mean: float
    lo95: float
    hi95: float
    draws: np.ndarray

    @classmethod
    def of(cls, values) -> "Interval":
        v = np.asarray(values, float)
        ok = v[np.isfinite(v)]
        if ok.size == 0:
            return cls(np.nan, np.nan, np.nan, v)
        lo, hi = np.quantile(ok, [0.025, 0.975])
        return cls(float(ok.mean()), float(lo), float(hi), v)


@dataclass(frozen=True)
class Threshold:
    """Difference threshold Δδ₇₅ (mm) and Weber fraction around ``reference_mm``;
    ``found`` is the fraction of draws whose curve reaches 75 % within the searched range."""
    reference_mm: float
    delta75_mm: Interval
    weber: Interval
    found: float


class Discriminator:
    """Decodes simulated scans with posterior draws.

    Args:
        result (FitResult): an M2 fit; scene_path: the robot-scan scene of the forward model;
        n_scans (int): touches simulated per height (the Monte-Carlo sd of a proportion
            correct near 0.5 is about √(2/(12·n_scans)), 0.02 at 400); n_draws (int): posterior draws used;
        seed (int): root seed of draws and touches.
    """

    def __init__(self, result, *, scene_path=FOUR_PLATES, n_scans: int = 400, n_draws: int = 200, seed: int = 0):
        if n_scans < 2 or n_draws < 2:
            raise ArgumentError("n_scans/n_draws", (n_scans, n_draws), "both >= 2")
        table, _, draws, attrs = fit_tables(result)
        self.log_tau, self.kernel = table.log_tau, str(attrs.get("kernel", "boxcar"))
        rng = np.random.default_rng(seed)
        pick = rng.choice(draws["a"].size, size=min(n_draws, draws["a"].size), replace=False)
        self.a, self.tau, self.h = (draws[k][pick] for k in ("a", "tau_s", "h"))
        self.scene_path, self.n_scans, self.seed = scene_path, int(n_scans), int(seed)

    def responses(self, height_mm: float, *, speed_mm_s: float | None = None, reference: bool = False) -> np.ndarray:
        """Peak z per draw and scan, ndarray[n_draws, n_scans], for one step height (mm)."""
        seed = self.seed + (1 if reference else 2)
        _, _, data = scene_scans(self.scene_path, seed=seed, per_plate=self.n_scans,
                                 heights_mm=(float(height_mm),), speed_mm_s=speed_mm_s)
        lt = self.log_tau
        tab = peak_table(data.strain, data.t_s, tau_lo_s=float(np.exp(lt[0])), tau_hi_s=float(np.exp(lt[-1])),
                         n_grid=lt.size, kernel=self.kernel)
        return np.maximum(self.a[:, None] * tab.at(self.tau) - self.h[:, None], 0.0)

    @staticmethod
    def proportion_correct(z_low: np.ndarray, z_high: np.ndarray) -> np.ndarray:
        """Per draw: P(z_high > z_low) + ½ P(tie) over all pairs, ndarray[n_draws]."""
        out = np.empty(z_low.shape[0])
        for s, (lo, hi) in enumerate(zip(z_low, z_high)):
            lo = np.sort(lo)
            below = np.searchsorted(lo, hi, side="left")            # lower responses under each higher one
            tied = np.searchsorted(lo, hi, side="right") - below
            out[s] = (below.sum() + 0.5 * tied.sum()) / (lo.size * hi.size)
        return out

    def pc(self, lower_mm: float, higher_mm: float) -> Interval:
        """2AFC proportion correct that ``higher_mm`` gives the larger response than ``lower_mm``."""
        return Interval.of(self.proportion_correct(self.responses(lower_mm, reference=True),
                                                   self.responses(higher_mm)))

    def threshold(self, reference_mm: float = 0.1, *, max_delta_mm: float | None = None, n_steps: int = 25) -> Threshold:
        """Δδ₇₅ around ``reference_mm`` (searched on ``n_steps`` increments up to
        ``max_delta_mm``, default a quarter of the reference)."""
        if not reference_mm > 0:
            raise ArgumentError("reference_mm", reference_mm, "> 0")
        top = 0.25 * reference_mm if max_delta_mm is None else max_delta_mm
        deltas = np.linspace(0.0, top, n_steps + 1)
        ref = self.responses(reference_mm, reference=True)
        curve = np.stack([self.proportion_correct(ref, self.responses(reference_mm + d)) for d in deltas], axis=1)
        d75 = _crossing(deltas, curve, 0.75)
        return Threshold(reference_mm=float(reference_mm), delta75_mm=Interval.of(d75),
                         weber=Interval.of(d75 / reference_mm), found=float(np.mean(np.isfinite(d75))))

    def pse(self, reference_mm: float, speed_ref_mm_s: float, speed_test_mm_s: float, *, span_mm: float | None = None,
            n_steps: int = 16) -> Interval:
        """Step at ``speed_test_mm_s`` judged larger than ``reference_mm`` at ``speed_ref_mm_s`` half the time (mm)."""
        span = reference_mm if span_mm is None else span_mm
        heights = np.linspace(max(reference_mm - span, 0.0), reference_mm + span, n_steps + 1)
        ref = self.responses(reference_mm, speed_mm_s=speed_ref_mm_s, reference=True)
        curve = np.stack([self.proportion_correct(ref, self.responses(x, speed_mm_s=speed_test_mm_s))
                          for x in heights], axis=1)
        return Interval.of(_crossing(heights, curve, 0.5))


def _crossing(x: np.ndarray, curve: np.ndarray, level: float) -> np.ndarray:
    """First upward crossing of ``level`` per row of ``curve (ndarray[n_draws, n_x])``, linear
    interpolation; NaN where the row starts above or never reaches ``level``."""
    out = np.full(curve.shape[0], np.nan)
    above = curve >= level
    for i, row in enumerate(curve):
        k = int(np.argmax(above[i]))
        if not above[i, k] or k == 0:
            continue
        y0, y1 = row[k - 1], row[k]
        out[i] = x[k - 1] + (level - y0) / (y1 - y0) * (x[k] - x[k - 1])
    return out
