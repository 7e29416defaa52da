"""What M1's verdict checks beyond sampling: design, units, prior–data conflict, fit.

Every function returns one-line problems naming the matrix; any problem fails the
verdict (:func:`feeler.calib.fit.make_result`). The regression is Y = X Bᵀ + E with
rows b_i of B per output axis (K for the inverse model, C for the forward one).

- design (:func:`design_problems`): directions of the design that carry no information
  (all-zero displacements: every direction), where B would be the prior's; rows that
  repeat an earlier row exactly (:func:`repeat_problems`: a file appended to itself);
- units (:func:`unit_problems`): the least-squares compliance against the nominal C₀
  (a scale ~10³ off, forces and displacements swapped, axes exchanged, an axis of the
  opposite sign);
  a ratio beyond ×30 is no sensor tolerance but a unit (×10³: µm for mm, mN for N); a ratio
  within ×1.35 of a smaller slip's is named too (:data:`MODERATE_SLIPS`: kgf, lbf, cm, inches); with
  the compliance right, outputs scattering about the least-squares fit ×30 beyond the
  noise prior's scale are forces and displacements both in another unit
  (:func:`noise_unit_problems`: mN and µm leave the compliance as it was); a compliance
  near C0^-1 in size is a swap only when it has C0^-1's pattern (C0's: a softer sensor),
  and ×30 to ×170 a softer sensor before a unit; a design with unidentified directions
  gets the scale check along the directions it pins (:func:`span_unit_problems`);
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

__all__ = ["design_problems", "repeat_problems", "unit_problems", "span_unit_problems", "noise_unit_problems",
           "conflict_problems",
           "sign_problems",
           "ppc_problems", "ALPHA", "UNIT_FACTOR", "NOISE_FREE", "MODERATE_SLIPS"]

ALPHA = 0.01
UNIT_FACTOR = 30.0
GRAMS_FORCE_PER_N = 1000 / 9.80665      # a force gauge's gram-force, per newton
# The unit slips that move the compliance less than UNIT_FACTOR, as (data's / nominal compliance,
# what it says). Each is named when the ratio lies within a factor SLIP_WINDOW of it: 1.35, so a
# true compliance 35 % off the nominal still shows its slip, while every window lies beyond 3.3
# times the nominal or below 1/7.4 of it. A force gauge in kgf or lbf passed with verdict ok: the
# shipped prior on K (sd 0.5 max|K0| = 2.5 N/mm per entry) holds the kgf data's K within 1.8 sd.
MODERATE_SLIPS = ((9.80665, "forces probably in kgf (expected N; 1 kgf = 9.807 N)"),
                  (4.448222, "forces probably in lbf (expected N; 1 lbf = 4.448 N)"),
                  (0.1, "displacements probably in cm (expected mm), or forces 10 times too large"),
                  (1 / 25.4, "displacements probably in inches (expected mm; 1 in = 25.4 mm)"))
SLIP_WINDOW = 1.35


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


def _lstsq(x, y):
    coef, *_ = np.linalg.lstsq(x, y, rcond=None)                 # (3, p)
    return coef.T


def unit_problems(x: np.ndarray, y: np.ndarray, c0: np.ndarray, *, forward: bool) -> list[str]:
    """The data's compliance against the nominal one, by the Frobenius norm."""
    b = _lstsq(x, y)
    try:
        c = b if forward else np.linalg.inv(b)
    except np.linalg.LinAlgError:
        return []
    ratio = float(np.linalg.norm(c) / np.linalg.norm(c0))
    try:
        k0 = np.linalg.inv(c0)
    except np.linalg.LinAlgError:
        k0 = None
    slip = _slip(ratio)
    # C0 near 0.2 mm/N puts C0^-1 near C0 x 20 (and kgf's C0 x 9.8): a swap inverts the nominal's
    # pattern (the stiffest axis becomes the softest), a softer sensor or a unit slip keeps it;
    # an isotropic C0 has one pattern for both and cannot tell them apart
    unit = c / np.linalg.norm(c)
    to_c0 = to_k0 = 0.0
    if k0 is not None:
        to_c0, to_k0 = _rel(unit, c0 / np.linalg.norm(c0)), _rel(unit, k0 / np.linalg.norm(k0))
    if k0 is not None and _rel(c, k0) < 0.5 < _rel(c, c0) and not (slip is not None and to_c0 < to_k0):
        swap = (f"forces and displacements probably swapped (ux_mm, uy_mm, uz_mm are the displacements, fx_n, "
                f"fy_n, fz_n the forces)")
        if to_k0 < to_c0 - 0.05:
            return [f"C: the data's compliance {_flat(c)} mm/N matches the nominal stiffness C0^-1 {_flat(k0)} N/mm, "
                    f"not C0 {_flat(c0)}: {swap}"]
        softer = f"a sensor about {ratio:.2g}x softer than the prior's C0 {_flat(c0)} mm/N (check --c0 or the sensor)"
        if to_c0 < to_k0 - 0.05:
            return [f"C: the data's compliance {_flat(c)} mm/N is {ratio:.3g} times the nominal C0 and keeps its "
                    f"pattern (swapped columns would give C0^-1's, {_flat(k0)}): {softer}, or forces "
                    f"{ratio:.2g} times too small"]
        return [f"C: the data's compliance {_flat(c)} mm/N matches the nominal stiffness C0^-1 {_flat(k0)} N/mm "
                f"in size, and C0's pattern cannot tell a swap from a softer sensor: {swap}, or {softer}"]
    scale = _scale_line(ratio, slip, f"the data's compliance is {ratio:.3g} times the nominal C0")
    if scale:
        return [f"C: {scale}"]
    exchanged = _exchanged_axes(c, c0)
    if exchanged:
        return [exchanged]
    d, d0 = np.diag(c), np.diag(c0)
    flipped = [i for i in range(3) if d[i] * d0[i] < 0 and 0.2 < abs(d[i] / d0[i]) < 5.0]
    if flipped:
        return [f"C: the data's compliance on axis {'xyz'[i]} is {d[i]:.3g} mm/N against the nominal {d0[i]:.3g}: "
                f"u{'xyz'[i]}_mm or f{'xyz'[i]}_n probably has the opposite sign (the sensor's axis convention)"
                for i in flipped]
    return []


def _scale_line(ratio: float, slip: str | None, subject: str) -> str | None:
    """``subject``: the unit the compliance ``ratio`` (data's over nominal) points to, or None."""
    if ratio > UNIT_FACTOR:
        if ratio < np.sqrt(UNIT_FACTOR * 1e3):      # nearer, on a log scale, to x30 than to um's x1000
            return (f"{subject}: a sensor about {ratio:.2g}x softer than the prior's C0 (check --c0 or the sensor), "
                    f"or a unit (displacements in um or forces in kN would give about 1000x)")
        return f"{subject}: displacements probably in um (expected mm) or forces in kN (expected N)"
    if ratio < 1 / UNIT_FACTOR:
        # the nearer on a log scale of the two usual mistakes: ×1000 (mN, m) or ×102 (gram-force)
        if ratio > np.sqrt(1e-3 / GRAMS_FORCE_PER_N):
            return (f"{subject}: forces probably in gram-force (expected N; 1 N = {GRAMS_FORCE_PER_N:.4g} gf, "
                    f"a force gauge's usual unit)")
        return f"{subject}: forces probably in mN (expected N) or displacements in m (expected mm)"
    return f"{subject}: {slip}" if slip is not None else None


def _slip(ratio: float) -> str | None:
    return next((text for factor, text in MODERATE_SLIPS if abs(np.log(ratio / factor)) < np.log(SLIP_WINDOW)), None)


def span_unit_problems(x: np.ndarray, y: np.ndarray, c0: np.ndarray, *, forward: bool) -> list[str]:
    """:func:`unit_problems`' scale check for a design ``x`` that leaves directions
    unidentified (the full matrix, and so its pattern, is then unknown): the data's
    matrix along the directions the design pins against the nominal one along them,
    by the Frobenius norm. µm with only uy moved read 740x the nominal C[1,1] unnamed."""
    lam, vec = np.linalg.eigh(x.T @ x)
    keep = lam >= 1e-6 * max(float(lam[-1]), np.finfo(float).tiny)        # weak_directions' tolerance
    if not keep.any() or keep.all():
        return []
    v = vec[:, keep]                                                            # (3, r), largest entry > 0
    v = v * np.sign(v[np.argmax(np.abs(v), axis=0), np.arange(v.shape[1])])
    a, *_ = np.linalg.lstsq(x @ v, y, rcond=None)                               # y ≈ (x v) a: B v = aᵀ
    nominal = c0 @ v if forward else np.linalg.inv(c0) @ v
    data_norm, nominal_norm = float(np.linalg.norm(a)), float(np.linalg.norm(nominal))
    if data_norm == 0 or nominal_norm == 0:
        return []
    ratio = data_norm / nominal_norm if forward else nominal_norm / data_norm
    what, unit = ("force", "N") if forward else ("displacement", "mm")
    dirs = "; ".join("(" + ", ".join(f"{ax}={c:+.3f}" for ax, c in zip(AXES, col)) + ")" for col in v.T)
    plural = "s" if v.shape[1] > 1 else ""
    line = _scale_line(ratio, _slip(ratio), f"the data's compliance along the {what} direction{plural} the data pin, "
                                            f"{dirs} [{unit}], is {ratio:.3g} times the nominal C0's")
    return [f"C: {line}"] if line else []


def noise_unit_problems(x: np.ndarray, y: np.ndarray, sigma_scale: float, *, forward: bool) -> list[str]:
    """One line when the outputs ``y`` scatter about their least-squares fit on ``x`` (the
    median over axes of the residual sd) more than :data:`UNIT_FACTOR` times the
    half-normal noise prior's ``sigma_scale``: with the compliance as nominal, both
    columns are in another unit (µm and mN). [] with 3 rows or fewer."""
    n = x.shape[0]
    if n <= 3:
        return []
    resid = y - x @ _lstsq(x, y).T
    sd = float(np.median(np.sqrt(np.sum(resid ** 2, axis=0) / (n - 3))))
    ratio = sd / sigma_scale
    if not ratio > UNIT_FACTOR:        # far below is a quiet gauge as well as kN and m: not named
        return []
    what, unit = ("displacements", "mm") if forward else ("forces", "N")
    return [f"sigma: the {what} scatter {sd:.3g} {unit} about the least-squares fit, {ratio:.3g} times the noise "
            f"prior's scale {sigma_scale:g} {unit}, while their ratio, the compliance, is the nominal's: forces "
            f"probably in mN and displacements in um (expected N and mm)"]


def _exchanged_axes(c: np.ndarray, c0: np.ndarray) -> str | None:
    """A line when the data's compliance ``c`` matches the nominal ``c0`` with two or three
    axes exchanged (its rows: the displacement columns; its columns: the force columns)
    — within half of C0's norm while C0 itself is not — else None."""
    from itertools import permutations

    if _rel(c, c0) < 0.5:
        return None
    best = None
    for perm in permutations(range(3)):
        if perm == (0, 1, 2):
            continue
        p = np.eye(3)[list(perm)]
        for cand in (p @ c0, c0 @ p.T):          # displacement columns, or force columns, in another order
            err = _rel(c, cand)
            if err < 0.5 and (best is None or err < best[0]):
                best = (err, perm)
    if best is None:
        return None
    moved = [i for i in range(3) if best[1][i] != i]
    names = ["xyz"[i] for i in moved]
    axes = ", ".join(names[:-1]) + " and " + names[-1]
    u = ", ".join(f"u{'xyz'[i]}_mm" for i in moved)
    f = ", ".join(f"f{'xyz'[i]}_n" for i in moved)
    return (f"C: the data's compliance {_flat(c)} mm/N matches the nominal C0 {_flat(c0)} with axes {axes} "
            f"exchanged: the columns {u} (or {f}) are probably in the wrong order, or the sensor is mounted turned")


def _flat(m: np.ndarray) -> str:
    """A matrix on one line, rows separated by ';'."""
    return "[" + "; ".join(" ".join(f"{v:.3g}" for v in row) for row in np.atleast_2d(m)) + "]"


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


def conflict_problems(x: np.ndarray, y: np.ndarray, b0: np.ndarray, s: float, *, matrix: str, unit: str) -> list[str]:
    """Rows of B whose least-squares estimate is implausible under the prior."""
    n = x.shape[0]
    if n <= 3:
        return []
    b = _lstsq(x, y)
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
