"""What M1's verdict checks beyond sampling: design, units, prior–data conflict, fit.

Every function returns one-line problems naming the matrix; any problem fails the
verdict (:func:`feeler.calib.fit.make_result`). The regression is Y = X Bᵀ + E with
rows b_i of B per output axis (K for the inverse model, C for the forward one).

- design (:func:`design_problems`): directions of the design that carry no information
  (all-zero displacements: every direction), where B would be the prior's; rows that
  repeat an earlier row exactly (:func:`repeat_problems`: a file appended to itself);
- units (:mod:`.units`, re-exported here): the least-squares compliance against the nominal
  C₀ — a scale ~10³ off (µm for mm, mN for N), a smaller slip (kgf, lbf, cm, inches), forces
  and displacements swapped, axes exchanged, an axis of the opposite sign — and outputs
  scattering far beyond the noise prior's scale (both in another unit);
- prior–data conflict (:func:`conflict_problems`): the least-squares row b̂_i against
  its prior N(b0_i, s²I): under the model b̂_i ~ N(b0_i, s²I + σ̂_i²(XᵀX)⁻¹), so its
  Mahalanobis distance is χ²₃; a tail probability below 0.01/3 says prior and data
  disagree (the prior then drags the fit and inflates the noise, as it did on a
  near-singular sensor: σ_n 14× the truth);
- what the posterior pins (:func:`sign_problems`): a compliance on the sensor's own axis,
  C[i,i], whose 95 % interval holds 0 — the fit cannot tell its sign, so no force can be
  read from that axis (forces that do not follow the displacements: rows shuffled,
  columns mismatched, a contact that slips). The design and conflict checks do not see
  this: the design spans every direction and a prior wide enough for the nominal C₀
  also holds a row of K near 0;
- posterior predictive (:func:`ppc_problems`): replicated data from posterior draws,
  with two discrepancies per axis — lack of fit (replicated points: between-point over
  within-point scatter of the residuals) and the largest standardised residual
  (outliers, wrong noise law). Posterior predictive p < 0.01/6 fails. An axis whose
  least-squares residuals vanish (noise-free data: the matrix is pinned exactly) has
  nothing to check and is skipped: residuals below :data:`NOISE_FREE` of the outputs'
  scale, which is what a CSV's rounding leaves of exact data (replicated points rounded
  alike read as a 'lack of fit' of the rounding otherwise).
"""
from __future__ import annotations

import math

import numpy as np

from feeler.calib.diagnostics import repeated_rows
from feeler.calib.matrix.data import AXES, weak_directions
from feeler.calib.matrix.degenerate import NOISE_FREE, relative_residual
from feeler.calib.matrix.units import (MODERATE_SLIPS, UNIT_FACTOR, lstsq_rows, noise_unit_problems,
                                        span_unit_problems, unit_problems)

__all__ = ["design_problems", "repeat_problems", "unit_problems", "span_unit_problems", "noise_unit_problems",
           "conflict_problems",
           "sign_problems",
           "ppc_problems", "ALPHA", "UNIT_FACTOR", "NOISE_FREE", "MODERATE_SLIPS"]

ALPHA = 0.01


def design_problems(x: np.ndarray, *, matrix: str, what: str, unit: str) -> list[str]:
    """Unidentified directions of the design ``x (ndarray[n, 3])``."""
    if not np.any(x):
        return [f"{matrix}: the {what}s are all zero: the data pin no entry of {matrix} (its posterior is its prior)"]
    out = []
    for v in weak_directions(x, what=what, unit=unit, warn=False):
        coords = ", ".join(f"{a}={c:+.3f}" for a, c in zip(AXES, v))
        out.append(f"{matrix}: the data do not pin {matrix} along the {what} direction ({coords}) [{unit}]; "
                   f"there it is the prior's")
    return out


def repeat_problems(point_id: np.ndarray, u: np.ndarray, f: np.ndarray, *, matrix: str) -> list[str]:
    """Rows that repeat an earlier row exactly (its point, displacements and forces): a
    file appended to itself, whose copies would count as independent measurements."""
    _, point = np.unique(np.asarray(point_id).astype(str), return_inverse=True)      # ids may be text
    copies, earlier = repeated_rows(np.column_stack([np.ravel(point), np.asarray(u, float), np.asarray(f, float)]))
    if not copies.size:
        return []
    k = int(copies[0])
    return [f"{matrix}: {copies.size} of {len(earlier)} rows repeat an earlier row exactly (point, displacements and "
            f"forces; e.g. data row {k + 1} = data row {int(earlier[k]) + 1}): the file was probably appended to "
            f"itself, and its copies would count as new measurements; keep each measurement once"]




def conflict_problems(x: np.ndarray, y: np.ndarray, b0: np.ndarray, s: float, *, matrix: str, unit: str) -> list[str]:
    """Rows of B whose least-squares estimate is implausible under the prior."""
    n = x.shape[0]
    if n <= 3:
        return []
    b = lstsq_rows(x, y)
    gram_inv = np.linalg.pinv(x.T @ x)
    out = []
    for i in range(y.shape[1]):
        resid = y[:, i] - x @ b[i]
        s2 = float(resid @ resid) / (n - 3)
        cov = s ** 2 * np.eye(3) + s2 * gram_inv
        d = b[i] - b0[i]
        d2 = float(d @ np.linalg.solve(cov, d))
        p = _chi2_sf_3(d2)
        if p < ALPHA / y.shape[1]:
            out.append(f"{matrix}: row {i} by least squares {np.array2string(b[i], precision=3)} {unit} lies "
                       f"{np.sqrt(d2):.1f} prior sd from the prior's {np.array2string(b0[i], precision=3)} "
                       f"(prior-data conflict, p = {p:.1g}): the prior drags the fit; widen --rel-sd or check C0")
    return out


def sign_problems(c_draws: np.ndarray, c0: np.ndarray) -> list[str]:
    """One line when the 95 % interval of a diagonal compliance C[i,i] holds 0, from
    ``c_draws (ndarray[S, 3, 3])`` (mm/N; non-finite draws count as unknown) and the
    nominal ``c0``."""
    c = np.asarray(c_draws, float).reshape(-1, 3, 3)
    diag = np.diagonal(c, axis1=1, axis2=2)                                # (S, 3)
    finite = np.isfinite(diag).all(axis=1)
    if not finite.any():
        return [f"C: no draw of the compliance is finite (nominal diagonal {np.diag(c0).tolist()} mm/N): "
                f"the forces do not follow the displacements"]
    lo, hi = np.quantile(diag[finite], [0.025, 0.975], axis=0)
    bad = [i for i in range(3) if lo[i] <= 0 <= hi[i]]
    if not bad:
        return []
    spans = ", ".join(f"C[{i},{i}] [{lo[i]:.3g}, {hi[i]:.3g}] (nominal {c0[i, i]:.3g})" for i in bad)
    axes = ("axis " if len(bad) == 1 else "axes ") + ", ".join(AXES[i] for i in bad)
    what = "95 % interval" if len(bad) == 1 else "95 % intervals"
    return [f"C: the data do not pin the sign of the compliance on {axes}: {what} {spans} mm/N hold 0; "
            f"the forces there barely follow the displacements (rows shuffled, columns mismatched, or a contact "
            f"that slips?)"]


def _groups(x: np.ndarray) -> np.ndarray:
    _, inv = np.unique(np.round(x, 12), axis=0, return_inverse=True)
    return np.ravel(inv)


def ppc_problems(x: np.ndarray, y: np.ndarray, B: np.ndarray, sigma: np.ndarray, rng: np.random.Generator, *,
                 matrix: str, noise: str = "gaussian", nu: float = 4.0, n_draws: int = 400,
                 lack_of_fit: bool = True) -> list[str]:
    """Posterior predictive checks from draws ``B (ndarray[d, p, 3])``, ``sigma (ndarray[d, p])``.

    ``lack_of_fit`` False leaves out the replicated points' check: for copied rows, whose
    copies agree exactly, between over within says nothing about the model."""
    d = B.shape[0]
    pick = rng.choice(d, size=min(n_draws, d), replace=False)
    B, sigma = B[pick], sigma[pick]
    mu = np.einsum("nk,dpk->dnp", x, B)                                       # (d, n, p)
    eps = rng.standard_t(nu, size=mu.shape) if noise == "student" else rng.standard_normal(mu.shape)
    y_rep = mu + sigma[:, None, :] * eps
    g = _groups(x)
    onehot = np.eye(g.max() + 1)[g]
    counts = onehot.sum(axis=0)
    replicated = np.any(counts > 1) and counts.size > 3

    def between_within(yy):                                                     # (d, n, p) → (d, p)
        r = yy - mu
        means = np.einsum("dnp,ng->dgp", r, onehot) / counts[None, :, None]
        between = np.einsum("g,dgp->dp", counts, means ** 2)
        within = np.sum((r - np.einsum("ng,dgp->dnp", onehot, means)) ** 2, axis=1)
        return between / np.maximum(within, 1e-300)

    def extreme(yy):
        return np.max(np.abs(yy - mu) / sigma[:, None, :], axis=1)

    noisy = relative_residual(x, y) > NOISE_FREE
    out = []
    checks = [("lack of fit (between / within replicated points)", between_within)] if replicated and lack_of_fit \
        else []
    checks.append(("largest standardised residual", extreme))
    level = ALPHA / (len(checks) * y.shape[1])
    # the observed data's most extreme row per axis, at the posterior's median fit: where to look
    z_obs = np.median(np.abs(np.broadcast_to(y, y_rep.shape) - mu) / sigma[:, None, :], axis=0)   # (n, p)
    for name, stat in checks:
        p = np.mean(stat(y_rep) >= stat(np.broadcast_to(y, y_rep.shape)), axis=0)
        for i in np.flatnonzero((p < level) & noisy):
            where = ""
            if stat is extreme:
                k = int(np.argmax(z_obs[:, i]))
                where = f" (data row {k + 1}, {z_obs[k, i]:.1f} sd from the fit: a typo or a slipped contact?)"
            out.append(f"{matrix}: posterior predictive check of axis {AXES[i]}: {name}, p = {p[i]:.3g}{where}; "
                       f"the {noise} linear model does not describe these data")
    return out


def _chi2_sf_3(d2: float) -> float:
    """P(χ²₃ > d2), closed form (no SciPy import on the exact path: issue 18)."""
    r = math.sqrt(max(d2, 0.0))
    return math.erfc(r / math.sqrt(2.0)) + math.sqrt(2.0 / math.pi) * r * math.exp(-d2 / 2.0)
