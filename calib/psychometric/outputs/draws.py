"""Summaries of one table row from posterior draws (the Laplace and NUTS backends).

The same quantities as :func:`feeler.calib.psychometric.exact.stats.grid_row_stats` (mean, median, 95 %
equal-tailed bounds of pse, sigma, dt, threshold and slope at ``pc``, lapse), computed on
the draws: a draw whose lapse never lets P reach ``pc`` has the threshold +inf (and no
slope); its share is ``unreached``.
"""
from __future__ import annotations

import numpy as np

from feeler.calib.psychometric.model.task import Task

__all__ = ["draw_row_stats", "inf_quantiles"]


def inf_quantiles(x: np.ndarray, probs=(0.025, 0.5, 0.975)) -> np.ndarray:
    """Linear-interpolation quantiles of ``x (N,)`` where +inf may occur (it sorts last;
    a quantile reaching into the +inf draws is +inf)."""
    x = np.sort(np.asarray(x, dtype=float).ravel())
    pos = np.asarray(probs) * (x.size - 1)
    lo = np.floor(pos).astype(int)
    hi = np.minimum(lo + 1, x.size - 1)
    frac = pos - lo
    with np.errstate(invalid="ignore"):
        out = np.where(frac == 0, x[lo], x[lo] + frac * (x[hi] - x[lo]))
    return np.where(np.isinf(x[hi]) | np.isinf(x[lo]), np.inf, out)


def _summary(x: np.ndarray) -> dict:
    q = inf_quantiles(x)
    mean = float(np.mean(x)) if np.all(np.isfinite(x)) else np.nan
    return {"mean": mean, "lb": float(q[0]), "median": float(q[1]), "ub": float(q[2])}


def draw_row_stats(task: Task, pse, sigma, lapse, pc: float) -> dict[str, dict]:
    """Row summaries from draws ``pse, sigma, lapse (N,)`` (µm, µm, 1)."""
    pse, sigma, lapse = (np.asarray(v, dtype=float).ravel() for v in (pse, sigma, lapse))
    thr = task.x_at(pc, pse, sigma, lapse)
    unreached = float(np.mean(~np.isfinite(thr)))
    slope = task.slope_at(pc, sigma, lapse)
    out = {"pse": _summary(pse), "sigma": _summary(sigma), "lapse": _summary(lapse),
           "threshold": _summary(np.where(np.isfinite(thr), thr, np.inf)) | {"unreached": unreached},
           "slope": _summary(np.where(np.isfinite(slope), slope, np.inf)) | {"unreached": unreached}}
    if unreached:
        out["slope"]["mean"] = np.nan
    out["dt"] = _summary(task.dt(sigma, lapse)) if not task.is_nafc else \
        {"mean": np.nan, "lb": np.nan, "median": np.nan, "ub": np.nan}
    return out
