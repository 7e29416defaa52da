"""Priors of M1, stated in words for the output.

The prior is a matrix-normal distribution on the matrix that is regressed:

- ``direction="inverse"`` (default) and ``"eiv"``: the stiffness K = C⁻¹ (N/mm),
  K ~ MN(K₀ = C₀⁻¹, s_K I₃, s_K I₃), i.e. independent entries N(K₀[j,k], s_K²) with
  s_K = ``rel_sd`` · max|K₀|;
- ``direction="forward"``: the compliance C (mm/N), C ~ MN(C₀, s_C I₃, s_C I₃),
  s_C = ``rel_sd`` · max|C₀|.

``MN(M, r I, c I)`` has vec-covariance (c I) ⊗ (r I) = r c I₉: with a single scale the
matrix-normal prior is exactly "independent entries with sd s = √(r c)". Noise sds per
axis have half-normal priors with the stated scales.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from feeler.errors import ArgumentError

__all__ = ["MatrixPrior", "RegressionPrior"]


@dataclass(frozen=True)
class MatrixPrior:
    """Prior knowledge about a sensor element.

    Attributes:
        c0_mm_per_n (tuple[tuple[float, float, float], ...]): nominal compliance C₀
            (3×3, mm/N), invertible.
        rel_sd (float): prior sd of every entry relative to the largest |entry| of the
            regressed matrix, > 0 (0.5: ±50 %).
        sigma_f_scale_n (float): half-normal scale of the force noise sd per axis, N, > 0.
        sigma_u_scale_mm (float): half-normal scale of the displacement noise sd per
            axis (forward model), mm, > 0.
    """
    c0_mm_per_n: tuple
    rel_sd: float = 0.5
    sigma_f_scale_n: float = 0.1
    sigma_u_scale_mm: float = 0.01

    def __post_init__(self):
        c0 = np.asarray(self.c0_mm_per_n, dtype=float)
        if c0.shape != (3, 3) or not np.all(np.isfinite(c0)):
            raise ArgumentError("c0_mm_per_n", self.c0_mm_per_n, "must be a finite 3x3 matrix (mm/N)")
        if np.linalg.cond(c0) > 1e8:
            raise ArgumentError("c0_mm_per_n", self.c0_mm_per_n, "must be invertible (condition number <= 1e8)")
        for name in ("rel_sd", "sigma_f_scale_n", "sigma_u_scale_mm"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and np.isfinite(v) and v > 0):
                raise ArgumentError(name, v, "must be a finite number > 0")

    @property
    def c0(self) -> np.ndarray:
        return np.asarray(self.c0_mm_per_n, dtype=float)

    def for_direction(self, direction: str) -> "RegressionPrior":
        """The prior of the regressed matrix B (rows = output axes) and noise."""
        if direction == "forward":
            b0, sigma_scale, unit, name = self.c0, self.sigma_u_scale_mm, "mm", "C"
        else:
            b0, sigma_scale, unit, name = np.linalg.inv(self.c0), self.sigma_f_scale_n, "N", "K"
        sd = self.rel_sd * float(np.max(np.abs(b0)))
        return RegressionPrior(b0=b0, sd=sd, sigma_scale=sigma_scale, matrix=name, noise_unit=unit)


@dataclass(frozen=True)
class RegressionPrior:
    """B ~ independent N(b0, sd²) entries (= MN(b0, sd I, sd I)); σ_i ~ HalfNormal(sigma_scale)."""
    b0: np.ndarray
    sd: float
    sigma_scale: float
    matrix: str
    noise_unit: str

    def stated(self) -> dict:
        unit = "mm/N" if self.matrix == "C" else "N/mm"
        b0 = np.array2string(self.b0, precision=4, separator=", ").replace("\n", "")
        return {self.matrix: f"matrix-normal MN({self.matrix}0, {self.sd:.4g} I3, {self.sd:.4g} I3) "
                             f"= independent Normal(mean {self.matrix}0[i,j], sd {self.sd:.4g} {unit}) "
                             f"per entry, {self.matrix}0 = {b0} {unit}"
                             + (" (K0 = C0^-1, C0 the nominal compliance)" if self.matrix == "K" else ""),
                "sigma": f"HalfNormal(scale {self.sigma_scale:g} {self.noise_unit}) per axis"}
