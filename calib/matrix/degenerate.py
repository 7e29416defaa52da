"""Data M1 can fit but that pin nothing: noise-free outputs, copied rows, dead or joined outputs.

Both are checked before any sampling (:func:`feeler.calib.matrix.fit.fit_matrix`):

- noise-free (:func:`noise_free_problems`): outputs that lie on a linear function of the
  inputs to rounding level leave the noise sd σ nothing to estimate; its posterior
  collapses onto the rounding (1e-16 N for exact floats) and every interval is
  zero-width, while NUTS and emcee cannot sample a σ → 0 funnel at all (they failed on
  R-hat, ESS and divergences, never naming the cause). Data simulated without noise, or
  a force column computed from the other columns, look like this;
- copied rows (:func:`copy_problems`): at least half of the rows repeat an earlier row's
  displacements and forces exactly, whatever their point ids: a file appended to itself
  with its ids renumbered. No two real readings of a noisy gauge agree in all three
  forces; a quantised gauge can repeat the odd row, never half of them;
- dead or joined forces (:func:`output_problems`, the inverse models): a force column that
  never changes, or two that move together (|correlation| > :data:`JOINED`): a channel not read, or one
  copied or wired into another. The least-squares matrix is then singular and its inverse
  huge, which the unit check read as a unit slip (an audit: fz a copy of fx read as
  "compliance 2.72e+04 times nominal: displacements probably in um").
"""
from __future__ import annotations

import numpy as np

from feeler.calib.diagnostics import repeated_rows
from feeler.calib.matrix.data import F_COLUMNS, U_COLUMNS

__all__ = ["NOISE_FREE", "JOINED", "relative_residual", "noise_free_problems", "copy_problems", "output_problems"]

# Least-squares residual RMS over the output RMS below which an axis is noise-free. Exact
# forces leave 1e-16 as floats, 0.6-1.6e-9 as `feeler simulate` writes them and 0.7-1.0e-6
# at 6 significant digits; no measurement comes near: the stage's ~1 um on displacements of
# at most 0.2 mm alone leaves ~5e-3, and the shipped campaign's 0.02 N noise 0.02-0.14. 1e-5
# lies a decade above the coarsest rounding and two and more below any real campaign.
NOISE_FREE = 1e-5
# |correlation| between two output columns above which they are one signal. The shipped
# campaign's force columns correlate at most 0.17 over 20 seeds (its design moves one axis at a time); a
# design along one diagonal that moves two axes together in a fixed ratio is a design
# problem (design_problems names it on the inputs) before it is this one.
JOINED = 0.9999


def relative_residual(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Least-squares residual RMS of ``y (ndarray[n, p])`` on ``x (ndarray[n, 3])`` over
    the output RMS, per output axis: ndarray[p] (0 where the outputs are all 0)."""
    coef, *_ = np.linalg.lstsq(x, y, rcond=None)
    resid = y - x @ coef
    scale = np.maximum(np.sqrt(np.mean(y ** 2, axis=0)), np.finfo(float).tiny)
    return np.sqrt(np.mean(resid ** 2, axis=0)) / scale


def noise_free_problems(x: np.ndarray, y: np.ndarray, *, forward: bool) -> list[str]:
    """One line naming the output axes whose residuals about the least-squares fit are
    below :data:`NOISE_FREE` of their scale; [] when the design leaves no residual to
    judge (no more distinct input rows than its rank: one point copied down the file
    fits exactly whatever its noise, and :func:`copy_problems` names it)."""
    if not np.any(x) or np.unique(x, axis=0).shape[0] <= np.linalg.matrix_rank(x):
        return []
    rel = relative_residual(x, y)
    quiet = np.flatnonzero(rel < NOISE_FREE)
    if not quiet.size:
        return []
    sigma, cols, what, of = (("sigma_mm", U_COLUMNS, "displacements", "forces") if forward
                             else ("sigma_n", F_COLUMNS, "forces", "displacements"))
    names = ", ".join(f"{sigma}[{i}]" for i in quiet)
    columns = ", ".join(cols[i] for i in quiet)
    return [f"{names}: noise-free: the residuals of {columns} about their least-squares fit on the {of} are at "
            f"rounding level ({float(rel[quiet].max()):.1g} of the {what}' scale; a measurement leaves 1e-3 or "
            f"more): the noise {sigma} cannot be pinned and the intervals would be zero-width; data simulated "
            f"without noise, or a column computed from the others?"]


def copy_problems(u: np.ndarray, f: np.ndarray, *, matrix: str) -> list[str]:
    """One line when at least half of the rows (and 3) repeat an earlier row's
    displacements ``u (ndarray[n, 3])`` and forces ``f (ndarray[n, 3])`` exactly."""
    rows = np.column_stack([np.asarray(u, float), np.asarray(f, float)])
    copies, earlier = repeated_rows(rows)
    n = len(earlier)
    if copies.size < max(3, n / 2):
        return []
    firsts, counts = np.unique(earlier, return_counts=True)
    tail = ("the file was probably appended to itself (its point ids renumbered), and its copies would count as "
            "new measurements; keep each measurement once")
    if firsts.size == 1:
        return [f"{matrix}: all {n} rows hold the same displacements and forces (those of data row 1): one reading "
                f"copied down the file, or a gauge and a stage that were not read?"]
    if np.all(counts == counts[0]):
        k = int(counts[0])
        again = np.flatnonzero(earlier == earlier[0])[:3] + 1
        return [f"{matrix}: every row appears {k} times (displacements and forces; e.g. data rows "
                f"{', '.join(map(str, again))}{', ...' if k > 3 else ''} are one row): {tail}"]
    k = int(copies[0])
    return [f"{matrix}: {copies.size} of {n} rows repeat an earlier row's displacements and forces exactly (e.g. "
            f"data row {k + 1} = data row {int(earlier[k]) + 1}): {tail}"]


def output_problems(f: np.ndarray) -> list[str]:
    """Lines for the measured force columns of ``f (ndarray[n, 3])`` (the inverse models'
    outputs; in the forward model they are its inputs, which :func:`.checks.design_problems`
    judges) that never change, or that move together."""
    f = np.asarray(f, float)
    if f.shape[0] < 3:
        return []
    spread = np.std(f, axis=0)
    dead = spread <= 1e-12 * max(float(np.max(np.abs(f))), np.finfo(float).tiny)
    out = [f"{F_COLUMNS[i]}: the same value ({f[0, i]:.6g}) in all {f.shape[0]} rows: a force channel that was not "
           f"read? The matrix cannot be found along it" for i in np.flatnonzero(dead)]
    live = np.flatnonzero(~dead)
    for a, b in ((live[i], live[j]) for i in range(live.size) for j in range(i + 1, live.size)):
        r = float(np.corrcoef(f[:, a], f[:, b])[0, 1])
        if abs(r) > JOINED:
            out.append(f"{F_COLUMNS[a]}, {F_COLUMNS[b]}: the two forces move together (correlation {r:.6f}) though "
                       f"the design moves its axes apart: one channel copied or wired into the other? The matrix "
                       f"cannot tell their axes apart")
    return out
