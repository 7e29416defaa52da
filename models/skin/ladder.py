"""The ladder study: mesh convergence of L2, and the trade between L0, L1 and L2.

Every figure here is measured in the run that reports it: seconds per slide (the
one-off setup — mesh, assembly, factorisation, compliance, adjoint — reported apart),
and the error of the peak strain rate against L2 on the finest (converged) mesh.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from feeler.models.skin.fem import finger_fem
from feeler.models.skin.history import strain_history
from feeler.models.skin.l0 import fit_l0
from feeler.models.skin.l1 import influence
from feeler.models.skin.loading import loading_history
from feeler.models.skin.mesh import MeshSpec
from feeler.models.skin.params import SkinParams, StepProfile

__all__ = ["SlideSummary", "ConvergenceRow", "TradeRow", "summarise", "convergence_study",
           "converged_change", "trade_table"]


@dataclass(frozen=True)
class SlideSummary:
    """Peaks of one slide: pressed strain, largest |Δε_y| of the step response, largest |ε̇_y| (1/s)."""

    pressed_eps: float
    peak_step_eps: float
    peak_rate_per_s: float


@dataclass(frozen=True)
class ConvergenceRow:
    factor: float
    n_nodes: int
    h_contact_mm: float
    setup_s: float
    slide_s: float
    summary: SlideSummary


@dataclass(frozen=True)
class TradeRow:
    level: str
    mesh: str
    setup_s: float
    seconds_per_slide: float
    peak_rate_per_s: float
    rate_error: float        # relative to converged L2


def summarise(t_s: np.ndarray, eps: np.ndarray, slide_start: int) -> SlideSummary:
    """Peaks of the slide part of a strain history (samples from ``slide_start`` on)."""
    t, e = t_s[slide_start:], eps[slide_start:]
    rate = np.diff(e) / np.diff(t)
    return SlideSummary(float(e[0]), float(np.max(np.abs(e - e[0]))), float(np.max(np.abs(rate))))


def _timed(fn, repeats: int = 1):
    best, out = np.inf, None
    for _ in range(repeats):
        start = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - start)
    return out, best


def convergence_study(params: SkinParams, profile: StepProfile, speed_mm_s: float, *,
                      base: MeshSpec, factors, dt_s: float | None = None,
                      progress: bool | None = False) -> list[ConvergenceRow]:
    """L2 on ``base.refined(f)`` for each factor f (coarse to fine); ``progress`` as in
    :func:`feeler.calib.progress.progress` (None: a bar on a terminal, a line per mesh otherwise)."""
    from feeler.calib.progress import progress as bar

    slide_start = loading_history(params, speed_mm_s, dt_s).slide_start
    rows = []
    for f in bar(list(factors), desc="L2 meshes", enabled=progress, lines=True):
        spec = base.refined(f)
        fem, setup = _timed(lambda: (finger_fem(params, spec), influence(params, spec))[0])
        (t, e), slide = _timed(lambda: strain_history(profile, speed_mm_s, level="l2", params=params,
                                                      dt_s=dt_s, mesh=spec))
        rows.append(ConvergenceRow(f, fem.mesh.n_nodes, spec.h_contact_mm, setup, slide,
                                   summarise(t, e, slide_start)))
    return rows


def converged_change(rows: list[ConvergenceRow]) -> dict[str, float]:
    """Relative changes between the two finest meshes of the study."""
    a, b = rows[-2].summary, rows[-1].summary
    return {name: abs(getattr(b, name) - getattr(a, name)) / abs(getattr(b, name))
            for name in ("pressed_eps", "peak_step_eps", "peak_rate_per_s")}


def trade_table(params: SkinParams, profile: StepProfile, speed_mm_s: float, *,
                meshes: dict[str, MeshSpec], reference: str, setup_s: dict[str, float],
                dt_s: float | None = None, repeats: int = 5) -> tuple[list[TradeRow], SkinParams]:
    """Seconds per slide and peak-rate error against L2 on ``meshes[reference]``.

    Returns the rows and ``params`` with the L0 gain and base shift fitted to the
    reference L2 run (its "l0-fitted" row is therefore an in-sample fit).

    Args:
        meshes: named mesh specs; L2 and L1 run on each.
        reference: the name of the converged mesh.
        setup_s: one-off setup time per mesh name (from the convergence study).
        repeats: timing repeats for L0 and L1 (best of), L2 runs once.
    """
    load = loading_history(params, speed_mm_s, dt_s)
    rows, ref_rate, ref_run = [], None, None
    for name in [reference] + [m for m in meshes if m != reference]:
        spec = meshes[name]
        for level, reps in (("l2", 1), ("l1", repeats)):
            (t, e), secs = _timed(lambda: strain_history(profile, speed_mm_s, level=level, params=params,
                                                         dt_s=dt_s, mesh=spec), reps)
            rate = summarise(t, e, load.slide_start).peak_rate_per_s
            if ref_rate is None:
                ref_rate, ref_run = rate, e
            rows.append(TradeRow(level, name, setup_s.get(name, float("nan")), secs, rate,
                                 abs(rate - ref_rate) / ref_rate))
    sl = slice(load.slide_start, None)
    fitted = fit_l0(profile, ref_run[sl], load.travel_mm[sl], params=params)
    for label, p in (("l0", params), ("l0-fitted", fitted)):
        (t, e), secs = _timed(lambda: strain_history(profile, speed_mm_s, level="l0", params=p, dt_s=dt_s),
                              repeats * 4)
        rate = summarise(t, e, load.slide_start).peak_rate_per_s
        rows.append(TradeRow(label, "closed form", 0.0, secs, rate, abs(rate - ref_rate) / ref_rate))
    return rows, fitted
