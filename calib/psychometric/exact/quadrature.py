"""Smooth distribution functions from densities known on uniform grids.

A marginal or conditional density known at the nodes of a uniform axis is refined
``REFINE`` times by a cubic spline through its logarithm (exact for a Gaussian, whose log
is a parabola) and integrated by the trapezoid rule on the fine grid. A quantity that
depends on several axes has its distribution function as a weighted sum of such 1-D
distribution functions evaluated at shifted arguments (see :mod:`feeler.calib.psychometric.exact.grid`); quantiles come
from a vectorised bracketing search on that sum.
"""
from __future__ import annotations

import numpy as np
from scipy.interpolate import CubicSpline

__all__ = ["FineCdf", "quantiles", "logsumexp", "REFINE"]

REFINE = 8          # fine nodes per grid cell
FLOOR = -60.0       # log-density floor relative to the largest value of each row


def logsumexp(a: np.ndarray, axis=None, keepdims: bool = False) -> np.ndarray:
    """log Σ exp(a) over ``axis`` (-inf for all -inf); scipy's has a large per-call cost."""
    top = np.max(a, axis=axis, keepdims=True)
    top = np.where(np.isfinite(top), top, 0.0)
    with np.errstate(divide="ignore"):
        out = np.log(np.sum(np.exp(a - top), axis=axis, keepdims=True)) + top
    return out if keepdims else np.squeeze(out, axis=axis) if axis is not None else out.reshape(())


class FineCdf:
    """Distribution functions of many rows of log-densities on one uniform axis.

    Args:
        nodes (ndarray[n]): uniform axis.
        log_density (ndarray[R, n]): unnormalised log-densities, one row each.
        refine (int): fine nodes per grid cell.
    """

    def __init__(self, nodes: np.ndarray, log_density: np.ndarray, refine: int = REFINE):
        ld = np.asarray(log_density, dtype=float)
        top = np.max(ld, axis=-1, keepdims=True)
        top = np.where(np.isfinite(top), top, 0.0)
        ld = np.maximum(ld - top, FLOOR)
        n = nodes.size
        self.x0, self.dx = float(nodes[0]), float(nodes[1] - nodes[0]) / refine
        fine = self.x0 + self.dx * np.arange((n - 1) * refine + 1)
        dens = np.exp(np.minimum(CubicSpline(nodes, ld, axis=-1)(fine), 0.5))
        cum = np.concatenate([np.zeros(ld.shape[:-1] + (1,)),
                              np.cumsum(0.5 * (dens[..., 1:] + dens[..., :-1]), axis=-1)], axis=-1)
        total = cum[..., -1:]
        self.cdf = cum / np.where(total > 0, total, 1.0)
        self.flat = self.cdf.reshape(-1)
        self.size = fine.size

    def __call__(self, y: np.ndarray) -> np.ndarray:
        """CDF of row r at ``y[r, t]``: ``y (R, T)`` for the R rows (flattened) → (R, T)."""
        pos = np.clip((np.asarray(y, dtype=float) - self.x0) * (1.0 / self.dx), 0.0, self.size - 1 - 1e-9)
        i0 = pos.astype(np.intp)
        frac = pos - i0
        i0 += (np.arange(i0.shape[0]) * self.size)[:, None]
        lo = self.flat[i0]
        return lo + frac * (self.flat[i0 + 1] - lo)


def quantiles(cdf, probs, lo: float, hi: float, *, points: int = 32, rounds: int = 3) -> np.ndarray:
    """Values where the monotone function ``cdf(t (T,)) -> (T,)`` crosses each of ``probs``.

    All brackets are searched together: [lo, hi] on ``points`` values each, then each
    bracketing interval again, ``rounds`` times, then linear interpolation (relative
    resolution ~``points ** -rounds``). A probability above cdf(hi) gives +inf, one at or
    below cdf(lo) gives lo.
    """
    probs = np.atleast_1d(np.asarray(probs, dtype=float))
    a, b = np.full(probs.size, float(lo)), np.full(probs.size, float(hi))
    top = float(cdf(np.array([float(hi)]))[0])
    fa, fb = np.zeros(probs.size), np.ones(probs.size)
    for _ in range(rounds):
        t = np.linspace(a, b, points, axis=1)                    # (P, points)
        f = cdf(t.ravel()).reshape(t.shape)
        i = np.array([np.searchsorted(fr, p, side="left") for fr, p in zip(f, probs)])
        i = np.clip(i, 1, points - 1)
        rows = np.arange(probs.size)
        a, b, fa, fb = t[rows, i - 1], t[rows, i], f[rows, i - 1], f[rows, i]
    frac = np.where(fb > fa, (probs - fa) / np.where(fb > fa, fb - fa, 1.0), 0.0)
    out = a + np.clip(frac, 0.0, 1.0) * (b - a)
    return np.where(probs > top, np.inf, out)
