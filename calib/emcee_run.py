"""Run an emcee ensemble until its chains pass the verdict's diagnostics, or up to a cap.

The verdict (DESIGN §6) asks every stored emcee chain to be at least 50 integrated
autocorrelation times long, and, as for every backend, R-hat ≤ 1.01 and bulk ESS ≥ 400
with the walkers as chains. Walkers of an ensemble are correlated, and R-hat over 32 of
them needs more than 50 τ_int to settle (the shipped M1 data gave R-hat 1.015–1.026 at
50 τ). :func:`run_until_converged` runs the sampler in chunks that grow geometrically
and, after each, discards the first quarter as burn-in and checks the rest, parameter by
parameter, against those three rules with a margin (60 τ_int, R-hat ≤ 1.005, ESS ≥ 480),
so that the verdict's own estimates on the same draws agree. It stops when they pass or
at ``max_steps``; then the returned note says so and the verdict fails on the short chain.
A fixed ``steps`` runs exactly that many.

The steps kept after a converged run are thinned to every ⌊τ_int/4⌋-th. Neighbouring steps of
a chain with τ_int of 160 steps say nearly the same thing, and keeping all of them made the
shipped M1 posterior 289 MB (1.6 million draws) and its summary a minute's work. Thinned by a
quarter of τ_int, a chain's own τ_int falls by the same factor to within a few per cent (an
AR(1) chain with τ_int = 160 thinned by 40: 4.1 against 4), so it keeps its length in τ_int,
its ESS and R-hat inside the margins above. A run stopped at its cap is not thinned.

Progress: emcee's bar on a terminal (sized for a pseudo-terminal that reports no size),
otherwise a line per chunk (steps so far, longest τ_int, elapsed time); none with
``progress=False``.
"""
from __future__ import annotations

import logging
import sys
import time

import numpy as np

from feeler.calib.progress import bar_width, duration, show_progress

__all__ = ["run_until_converged", "autocorr_times", "converged", "MAX_STEPS", "TIMES"]

MAX_STEPS = 200_000
TIMES = 50.0


def autocorr_times(chain: np.ndarray) -> np.ndarray:
    """Integrated autocorrelation time (steps) per parameter of ``chain (ndarray[steps, walkers, dim])``."""
    from emcee.autocorr import integrated_time

    log = logging.getLogger("emcee")
    level = log.level
    log.setLevel(logging.ERROR)
    try:
        return np.asarray(integrated_time(chain, quiet=True), float)
    finally:
        log.setLevel(level)


def converged(chain: np.ndarray, *, times: float = TIMES) -> tuple[bool, float]:
    """(passes with margin, longest τ_int) for ``chain (ndarray[steps, walkers, dim])``."""
    from feeler.calib import convergence as C

    tau = autocorr_times(chain)
    if not np.all(np.isfinite(tau)):
        return False, float("inf")
    x = np.transpose(chain, (1, 0, 2))                                     # (walker, step, dim)
    with np.errstate(invalid="ignore", divide="ignore"):
        rhat = np.array([C.rhat(x[..., j]) for j in range(x.shape[-1])])
        ess = np.array([C.ess_bulk(x[..., j]) for j in range(x.shape[-1])])
    ok = (chain.shape[0] >= 1.2 * times * tau.max() and np.all(rhat <= 1.005) and np.all(ess >= 480))
    return bool(ok), float(tau.max())


def run_until_converged(sampler, p0: np.ndarray, *, steps: int | None = None, max_steps: int = MAX_STEPS,
                        times: float = TIMES, chunk: int = 2000, progress: bool | None = None):
    """Run ``sampler`` from ``p0``; returns (burn-in steps to discard, notes, thinning: keep
    every how many-th step after the burn-in; 1 for a fixed ``steps`` or a run at its cap).

    Args:
        steps (int | None): run exactly this many steps; None: until converged or ``max_steps``.
    """
    bar = {"progress": show_progress(progress), "progress_kwargs": bar_width()}
    lines = progress is None and not bar["progress"]
    start = time.monotonic()
    if steps is not None:
        if lines:
            print(f"emcee: {int(steps)} steps per walker ...", file=sys.stderr, flush=True)
        sampler.run_mcmc(p0, int(steps), **bar)
        return int(steps) // 4, [], 1
    state, done, tau = p0, 0, float("inf")
    while done < max_steps:
        n = min(chunk if done == 0 else max(chunk, done // 2), max_steps - done)
        state = sampler.run_mcmc(state, n, **bar)
        done += n
        ok, tau = converged(sampler.get_chain(discard=done // 4), times=times)
        if lines:
            print(f"emcee: {done} steps per walker, {duration(time.monotonic() - start)}, longest tau "
                  f"{tau:.0f} steps: {'converged' if ok else f'not yet converged, continuing (cap {max_steps})'}",
                  file=sys.stderr, flush=True)
        if ok:
            thin = max(1, int(tau // 4))
            _summarising(sampler, len(range(done // 4 + thin - 1, done, thin)), progress)    # as get_chain keeps
            return done // 4, [], thin
    _summarising(sampler, done - done // 4, progress)
    note = (f"emcee: stopped at its cap of {max_steps} steps per walker before the chains passed their "
            f"diagnostics ({times:.0f} autocorrelation times, R-hat, ESS; longest tau = {tau:.0f} steps) - use the "
            f"exact backend or nuts")
    return done // 4, [note], 1


def _summarising(sampler, kept: int, progress: bool | None) -> None:
    """The stage after the sampler: the fit turns every kept step of every walker into its
    posterior and checks it (predictive check, R-hat, ESS), which took a minute of silence
    after "converged" on the shipped M1 data (an outside audit)."""
    if progress is not False:
        walkers = sampler.nwalkers
        print(f"emcee: summarising the last {kept} steps of its {walkers} walkers ({kept * walkers:,} draws: "
              f"posterior, predictive check, R-hat, ESS) ...", file=sys.stderr, flush=True)
