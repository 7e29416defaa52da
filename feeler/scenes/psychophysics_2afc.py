"""Scene kind ``psychophysics-2afc``: synthetic human 2AFC step-height discrimination.

A subject touches a standard step (height ``design.standard_um`` at the condition's
standard speed) and a comparison step (one of ``design.comparisons_um`` at the
condition's comparison speed) and says which is higher. Each subject s and condition c
has a psychometric function (see :mod:`feeler.models.psychometric`) with

    PSE_sc = conditions[c].pse_um + N(0, subjects.pse_sd_um²),
    DT_sc  = conditions[c].dt_um · exp(N(0, subjects.log_dt_sd²)), clipped to
             subjects.dt_range_um (the published range, DESIGN §8),
    λ_s    ~ Uniform(subjects.lapse_range),

and ``n_trials`` trials per comparison level; with ``subjects.overdispersion_phi`` the
per-cell probability is first drawn from Beta(pφ, (1 − p)φ) (beta-binomial counts).
"""
from __future__ import annotations

from dataclasses import dataclass

from feeler.errors import SceneError
from feeler.scene import SEED_MAX, param

__all__ = ["Scene", "Head", "Design", "Condition", "Subjects"]


@dataclass(frozen=True)
class Head:
    kind: str = param(choices=("psychophysics-2afc",), doc="scene kind")
    description: str = param("", doc="free text; must say the data are synthetic")
    seed: int = param(0, lo=0, hi=SEED_MAX, doc="seed of the numpy Generator")


@dataclass(frozen=True)
class Design:
    standard_um: float = param(10.0, lo=0.0, hi=1000.0, lo_open=True, doc="standard step height, µm")
    comparisons_um: tuple[float, ...] = param((7.6, 8.4, 9.2, 10.0, 10.8, 11.6, 12.4), lo=0.0, hi=1000.0, min_len=2,
                                              doc="comparison step heights, µm, increasing")
    n_trials: int = param(20, lo=0, hi=100000, doc="trials per comparison level, subject and condition")
    n_subjects: int = param(6, lo=1, hi=1000, doc="number of synthetic subjects")


@dataclass(frozen=True)
class Condition:
    standard_speed_mm_s: float = param(lo=0.0, hi=1000.0, lo_open=True, doc="speed of the standard, mm/s")
    comparison_speed_mm_s: float = param(lo=0.0, hi=1000.0, lo_open=True, doc="speed of the comparisons, mm/s")
    pse_um: float = param(lo=0.0, hi=1000.0, lo_open=True, doc="population PSE, µm")
    dt_um: float = param(lo=0.0, hi=100.0, lo_open=True, doc="population difference threshold, µm")


@dataclass(frozen=True)
class Subjects:
    pse_sd_um: float = param(0.3, lo=0.0, hi=100.0, doc="between-subject sd of the PSE, µm")
    log_dt_sd: float = param(0.15, lo=0.0, hi=3.0, doc="between-subject sd of log DT")
    dt_range_um: tuple[float, ...] = param((0.95, 2.0), lo=0.0, hi=100.0, min_len=2,
                                           doc="[min, max] of a subject's DT, µm")
    lapse_range: tuple[float, ...] = param((0.0, 0.06), lo=0.0, hi=0.49, min_len=2,
                                           doc="[min, max] of a subject's lapse rate")
    overdispersion_phi: float | None = param(None, lo=0.0, lo_open=True, hi=1e9,
                                             doc="beta-binomial concentration; absent: binomial")


@dataclass(frozen=True)
class Scene:
    scene: Head
    design: Design
    conditions: tuple[Condition, ...] = param(min_len=1, doc="array of [[conditions]] tables")
    subjects: Subjects = Subjects()

    def check(self, path) -> None:
        """Cross-field rules: synthetic label, increasing levels, ranges, unique conditions."""
        if "synthetic" not in self.scene.description.lower():
            raise SceneError(path, "scene.description", "must say the data are synthetic")
        c = self.design.comparisons_um
        if any(b <= a for a, b in zip(c, c[1:])):
            raise SceneError(path, "design.comparisons_um", f"{list(c)} must be strictly increasing")
        for key in ("dt_range_um", "lapse_range"):
            rng = getattr(self.subjects, key)
            if len(rng) != 2 or rng[1] < rng[0]:
                raise SceneError(path, f"subjects.{key}", f"{list(rng)} must be [min, max] with min <= max")
        lo, hi = self.subjects.dt_range_um
        pairs = set()
        for i, cond in enumerate(self.conditions):
            if not lo <= cond.dt_um <= hi:
                raise SceneError(path, f"conditions[{i}].dt_um",
                                 f"{cond.dt_um} outside subjects.dt_range_um [{lo}, {hi}]")
            pair = (cond.standard_speed_mm_s, cond.comparison_speed_mm_s)
            if pair in pairs:
                raise SceneError(path, f"conditions[{i}]", f"speed pair {pair} (mm/s) appears twice")
            pairs.add(pair)
