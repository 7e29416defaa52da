"""Approximate M4 backend: per-observer mode + Laplace (Gaussian) approximation.

Each subject (and the pooled observer ``all``) is fitted alone in the unconstrained
coordinates of :mod:`feeler.calib.psychometric.model.observer`; the mode comes from :func:`feeler.calib.psychometric.exact.grid.observer_mode` (polished
by Newton steps to :data:`~feeler.calib.psychometric.model.mode.MODE_XTOL`), the covariance from the inverse of the
central-difference Hessian there, and the draws from N(mode, H⁻¹) with the caller's
generator (independent draws, so R-hat and ESS pass naturally).

The approximation is symmetric in log σ and logit λ: with few trials it cuts the skewed
tails of the DT and the threshold (the fit compares its bounds with the exact grid and
warns when they disagree). Draws go through the Cholesky factor of the covariance: unlike
eigenvectors (whose signs are arbitrary and flip with rounding) it is unique, so the same
generator state gives the same draws whatever the likelihood's summation order.
"""
from __future__ import annotations

import numpy as np

from feeler.calib.psychometric.exact.grid import observer_mode
from feeler.calib.psychometric.model.mode import MODE_XTOL, gradient, hessian, newton_polish
from feeler.calib.psychometric.model.observer import Observer

__all__ = ["laplace_observer", "hessian", "gradient", "newton_polish", "MODE_XTOL"]


def laplace_observer(obs: Observer, *, rng: np.random.Generator, n: int) -> tuple[dict, list[str]]:
    """Fit one observer; returns (draws, problems).

    Returns:
        draws: ``pse``, ``sigma`` (n, n_cond), ``lapse`` (n, n_lapse) and ``phi`` (n,)
        with overdispersion.
        problems: one line per optimiser or Hessian failure (empty when fine).
    """
    label = obs.cells.subjects[0]
    mode, h, msg = observer_mode(obs)
    problems = [f"subject {label}: {msg}"] if msg else []
    prec = -h
    evals, evecs = np.linalg.eigh(0.5 * (prec + prec.T))
    if not np.all(evals > 0):
        problems.append(f"subject {label}: Laplace Hessian not positive definite "
                        f"(smallest eigenvalue {evals.min():.3g}); covariance clipped")
        evals = np.maximum(evals, 1e-6)
    cov = (evecs / evals) @ evecs.T
    scale = np.linalg.cholesky(0.5 * (cov + cov.T))
    theta = mode + rng.standard_normal((n, mode.size)) @ scale.T
    out = obs.unpack(theta)
    return {k: v for k, v in out.items() if v is not None}, problems
