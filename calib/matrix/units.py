"""M1's unit checks: the data's compliance against the nominal C₀ (part of the verdict's checks,
:mod:`.checks`, which re-exports them).

- :func:`unit_problems`: the least-squares compliance against C₀ — a scale ~10³ off, forces
  and displacements swapped, axes exchanged, an axis of the opposite sign. A ratio beyond ×30
  (:data:`UNIT_FACTOR`) is no sensor tolerance but a unit (×10³: µm for mm, mN for N); a ratio
  within ×1.35 of a smaller slip's is named too (:data:`MODERATE_SLIPS`: kgf, lbf, cm, inches);
  a compliance near C0^-1 in size is a swap only when it has C0^-1's pattern (C0's: a softer
  sensor), and ×30 to ×170 a softer sensor before a unit;
- :func:`span_unit_problems`: the scale check along the directions a design pins, when it
  leaves some unidentified;
- :func:`noise_unit_problems`: with the compliance right, outputs scattering about the
  least-squares fit ×30 beyond the noise prior's scale are forces and displacements both in
  another unit (mN and µm leave the compliance as it was).
"""
from __future__ import annotations

import numpy as np

from feeler.calib.matrix.data import AXES

__all__ = ["unit_problems", "span_unit_problems", "noise_unit_problems", "lstsq_rows", "UNIT_FACTOR",
           "MODERATE_SLIPS"]

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
#: share of the outputs' variance a least-squares fit must explain before its scale is read as a unit
MIN_EXPLAINED = 0.5


def lstsq_rows(x, y):
    """The least-squares B of Y = X Bᵀ, one row per output axis."""
    coef, *_ = np.linalg.lstsq(x, y, rcond=None)                 # (3, p)
    return coef.T


def unit_problems(x: np.ndarray, y: np.ndarray, c0: np.ndarray, *, forward: bool) -> list[str]:
    """The data's compliance against the nominal one, by the Frobenius norm; nothing when
    the outputs barely follow the inputs (a least-squares fit explains under
    :data:`MIN_EXPLAINED` of their variance): rows whose forces do not belong to their
    displacements give a compliance of any scale, and shuffled rows were named "forces
    probably in kgf" (an outside audit; the pairing check names them)."""
    b = lstsq_rows(x, y)
    spread = float(np.sum((y - y.mean(axis=0)) ** 2))
    if spread > 0 and 1.0 - float(np.sum((y - x @ b.T) ** 2)) / spread < MIN_EXPLAINED:
        return []
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
    return f"{subject}: {slip}, or a nominal C0 that far off (check --c0)" if slip is not None else None


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
    resid = y - x @ lstsq_rows(x, y).T
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
