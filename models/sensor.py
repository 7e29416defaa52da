"""The sensor interface: what the three-axis optical sensor reports for a true tip displacement.

``observe(u_true_mm, fidelity=..., params=..., rng=...)`` returns the measured U with the
same shape ``(..., n_time, 3)`` (axes U_x, U_y, U_z in mm). Fidelity levels (DESIGN §4):

- ``"displacement"``: U plus white Gaussian noise per axis (:class:`DisplacementNoise`);
- ``"areas"`` and ``"images"``: contact areas / rendered camera frames inverted back to U.
  They plug into :data:`FIDELITIES` (``register_fidelity``) from ``models/optics`` and
  ``hardware``; until then asking for them raises :class:`~feeler.errors.ArgumentError`.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from feeler.errors import ArgumentError

__all__ = ["DisplacementNoise", "observe", "register_fidelity", "FIDELITIES"]


@dataclass(frozen=True)
class DisplacementNoise:
    """White measurement noise of the displacement output, one sd per axis (mm)."""

    ux_sd_mm: float = 0.004
    uy_sd_mm: float = 0.004
    uz_sd_mm: float = 0.004

    def __post_init__(self):
        for name in ("ux_sd_mm", "uy_sd_mm", "uz_sd_mm"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ArgumentError(name, value, "a finite noise sd >= 0 mm")


def _observe_displacement(u_true_mm: np.ndarray, params: DisplacementNoise,
                          rng: np.random.Generator) -> np.ndarray:
    sd = np.array([params.ux_sd_mm, params.uy_sd_mm, params.uz_sd_mm])
    return u_true_mm + sd * rng.standard_normal(u_true_mm.shape)


#: fidelity name -> ``func(u_true_mm, params, rng) -> u_measured_mm`` (None: not available yet)
FIDELITIES: dict[str, Callable[[np.ndarray, Any, np.random.Generator], np.ndarray] | None] = {
    "displacement": _observe_displacement,
    "areas": None,
    "images": None,
}


def register_fidelity(name: str, func: Callable[[np.ndarray, Any, np.random.Generator], np.ndarray]) -> None:
    """Plug in a fidelity level (``func(u_true_mm, params, rng) -> u_measured_mm``)."""
    FIDELITIES[name] = func


def observe(u_true_mm, *, fidelity: str, params: Any, rng: np.random.Generator) -> np.ndarray:
    """Measured displacement for the true one.

    Args:
        u_true_mm (ndarray[..., n_time, 3]): true (U_x, U_y, U_z) in mm.
        fidelity (str): a key of :data:`FIDELITIES`.
        params: the fidelity's parameters (:class:`DisplacementNoise` for ``"displacement"``).
        rng (numpy.random.Generator): the only source of randomness.

    Returns:
        ndarray[..., n_time, 3] float64: measured U in mm.

    Raises:
        ArgumentError: unknown or not yet available fidelity, or a wrongly shaped ``u_true_mm``.
    """
    u = np.asarray(u_true_mm, dtype=float)
    if u.ndim < 2 or u.shape[-1] != 3:
        raise ArgumentError("u_true_mm", u.shape, "an array of shape (..., n_time, 3)")
    if fidelity not in FIDELITIES:
        raise ArgumentError("fidelity", fidelity, f"one of {', '.join(FIDELITIES)}")
    func = FIDELITIES[fidelity]
    if func is None:
        ready = ", ".join(k for k, f in FIDELITIES.items() if f is not None)
        raise ArgumentError("fidelity", fidelity, f"not available in this installation yet; available: {ready}")
    return func(u, params, rng)
