"""The two kinds of forced-choice task M4 fits, as one psychometric function with lapses.

- **comparison** (the 2AFC "which step is higher" design of the shipped data): the
  response counted is "comparison judged higher", P = λ/2 + (1 − λ)·Φ((x − PSE)/σ);
- **nAFC proportion correct** (psignifit's kind of data, e.g. which of n plates has the
  step): the response counted is "correct", P = γ + (1 − γ)(1 − λ)·Φ((x − m)/σ) with
  the guess rate γ = 1/n.

In both a lapse (probability λ) is a trial on which the observer guesses: "higher" with
probability ½ in the comparison design, the right plate with probability 1/n in nAFC.
Both are P = base(λ) + scale(λ)·Φ(z), z = (x − m)/σ, with

    comparison: base = λ/2, scale = 1 − λ;      nAFC: base = γ, scale = (1 − γ)(1 − λ),

and 1 − P = rest(λ) + scale(λ)·Φ(−z), rest = 1 − base − scale (λ/2, resp. λ(1 − γ)).
In psignifit's terms the comparison design is "equal asymptote" with its λ = λ/2 here,
and nAFC has its λ = λ(1 − γ) here. ``m`` is the PSE of the comparison design and
psignifit's "threshold" (unscaled ½) in nAFC.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import ndtr, ndtri

__all__ = ["Task", "COMPARISON"]


@dataclass(frozen=True)
class Task:
    """Which psychometric function: ``n_alternatives`` None (comparison) or n ≥ 2 (nAFC)."""
    n_alternatives: int | None = None

    def __post_init__(self):
        from feeler.errors import ArgumentError
        n = self.n_alternatives
        if n is not None and (not isinstance(n, (int, np.integer)) or isinstance(n, bool) or n < 2):
            raise ArgumentError("nafc", n, "number of alternatives must be an integer >= 2")

    @property
    def is_nafc(self) -> bool:
        return self.n_alternatives is not None

    @property
    def guess(self) -> float:
        """γ: P at x → −∞ without lapses (0 comparison, 1/n nAFC)."""
        return 0.0 if self.n_alternatives is None else 1.0 / self.n_alternatives

    @property
    def name(self) -> str:
        return ("comparison (P comparison judged higher)" if self.n_alternatives is None
                else f"{self.n_alternatives}AFC (P correct, guess 1/{self.n_alternatives})")

    @property
    def label(self) -> str:
        """Short label for tables: ``comparison`` or ``4AFC``."""
        return "comparison" if self.n_alternatives is None else f"{self.n_alternatives}AFC"

    @property
    def response(self) -> str:
        return "comparison judged higher" if self.n_alternatives is None else "correct"

    @property
    def default_pc(self) -> float:
        """0.75 (the DT convention) for comparison; halfway from guess to 1 for nAFC."""
        return 0.75 if self.n_alternatives is None else 0.5 * (1.0 + self.guess)

    def check_pc(self, pc, name: str = "pc") -> float:
        """``pc`` as a float when P can reach it, else :class:`~feeler.errors.ArgumentError`.

        P runs from ``base`` to ``base + scale``: above the guess rate γ (0 for the
        comparison design, 1/n in nAFC, where P stays however small the stimulus) and
        below 1 (a lapse-free ceiling). A proportion at or below γ is never a threshold,
        whatever the data: refused before any work. How close to 1 the curve gets depends on
        the fitted lapse, so that side is the verdict's (``threshold_unreached``)."""
        from feeler.errors import ArgumentError
        ok = isinstance(pc, (int, float, np.floating)) and not isinstance(pc, bool) and np.isfinite(pc)
        if ok and self.guess < float(pc) < 1.0:
            return float(pc)
        if self.n_alternatives is None:
            raise ArgumentError(name, pc, "proportion must be in (0, 1)")
        n = self.n_alternatives
        raise ArgumentError(name, pc, f"proportion correct must be in (1/{n}, 1) = ({self.guess:.4g}, 1): "
                                      f"{n}AFC guessing alone gives 1/{n}, so P never falls to it")

    def ceiling(self, lapse):
        """base + scale: the largest P at lapse ``lapse`` (1 − λ/2, resp. 1 − λ(1 − γ))."""
        base, scale, _ = self.base_scale_rest(lapse)
        return base + scale

    @property
    def ceiling_text(self) -> str:
        """The ceiling as a formula, for messages."""
        return "1 − λ/2" if self.n_alternatives is None else f"1 − λ·(1 − 1/{self.n_alternatives})"

    def base_scale_rest(self, lapse):
        """(base, scale, rest) arrays for lapse rates ``lapse (...)`` in [0, 0.5)."""
        lapse = np.asarray(lapse, dtype=float)
        if self.n_alternatives is None:
            return lapse / 2.0, 1.0 - lapse, lapse / 2.0
        g = self.guess
        return np.full_like(lapse, g), (1.0 - g) * (1.0 - lapse), lapse * (1.0 - g)

    def p(self, x, m, sigma, lapse):
        """P(response counted) at ``x``; every argument broadcasts (µm, µm, µm, 1)."""
        base, scale, _ = self.base_scale_rest(lapse)
        return base + scale * ndtr((np.asarray(x, float) - m) / sigma)

    def log_pq(self, z, lapse):
        """(log P, log(1 − P)) at standardised ``z``, exact in the tails (log space)."""
        from scipy.special import log_ndtr
        base, scale, rest = self.base_scale_rest(lapse)
        with np.errstate(divide="ignore"):          # λ = 0: log 0 = -inf is intended
            lb, ls, lr = np.log(base), np.log(scale), np.log(rest)
        return np.logaddexp(lb, ls + log_ndtr(z)), np.logaddexp(lr, ls + log_ndtr(-z))

    def z_at(self, pc, lapse):
        """Φ⁻¹ of the unscaled level that gives P = ``pc``; NaN where P never reaches it."""
        base, scale, _ = self.base_scale_rest(lapse)
        u = (pc - base) / scale
        with np.errstate(invalid="ignore"):
            return np.where((u > 0) & (u < 1), ndtri(np.clip(u, 1e-300, 1 - 1e-16)), np.nan)

    def x_at(self, pc, m, sigma, lapse):
        """Stimulus (µm) where P = ``pc``: m + σ·z_at(pc, λ); NaN where not reached."""
        return m + sigma * self.z_at(pc, lapse)

    def slope_at(self, pc, sigma, lapse):
        """dP/dx (per µm) at the point where P = ``pc``; NaN where not reached."""
        _, scale, _ = self.base_scale_rest(lapse)
        z = self.z_at(pc, lapse)
        return scale * np.exp(-0.5 * z * z) / (np.sqrt(2 * np.pi) * sigma)

    def dt(self, sigma, lapse):
        """Difference threshold (comparison design): distance from the PSE to P = 0.75.
        NaN for nAFC (no PSE there; use the threshold at ``pc``)."""
        if self.n_alternatives is not None:
            return np.full(np.broadcast(sigma, lapse).shape, np.nan)
        return sigma * self.z_at(0.75, lapse)


COMPARISON = Task()
