"""The optical element's force law: contact areas of the conical feelers ↔ force ↔ displacement.

One sensing element is a columnar feeler standing on a 2×2 array of conical feelers. The
conical feelers sit on the diagonals of the element, indexed in this fixed order::

    index   0        1        2        3
    corner  (+x,+z)  (+x,−z)  (−x,+z)  (−x,−z)

so that every feeler belongs to one x side and one z side. With signs ``s_x = (+1, +1,
−1, −1)`` and ``s_z = (+1, −1, +1, −1)`` the area-sum / area-difference law (DESIGN §4) is

    F_y = (ΣA − 4·A_rest) / g_y
    F_x = (s_x · A) / g_x          (area at +x minus area at −x)
    F_z = (s_z · A) / g_z          (area at +z minus area at −z)

with ``A_rest`` the area of each feeler at zero force and ``g_*`` gains in px² per newton.
The forward map used by the simulators, ``areas_from_force``, is the minimum-norm solution
``A_i = A_rest + (g_y F_y + s_x,i g_x F_x + s_z,i g_z F_z) / 4``; its fourth ("twist")
combination ``A₀ − A₁ − A₂ + A₃`` is zero, and ``force_from_areas`` ignores it, so noise
in that direction never reaches the force. ``force_from_areas(areas_from_force(F)) == F``
to float rounding.

Displacement and force are tied by the force→displacement matrix C (mm per N):
``U = C F`` and ``F = C⁻¹ U``; vectors are ordered (x, y, z) everywhere.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from feeler.errors import ArgumentError

__all__ = [
    "SIGN_X", "SIGN_Z", "OpticsParams",
    "areas_from_force", "force_from_areas", "force_from_displacement",
    "displacement_from_force",
]

SIGN_X = np.array([1.0, 1.0, -1.0, -1.0])  # +x feelers are 0 and 1
SIGN_Z = np.array([1.0, -1.0, 1.0, -1.0])  # +z feelers are 0 and 2

_NOMINAL_C = ((1.0, 0.0, 0.02), (0.05, 0.5, 0.05), (0.02, 0.0, 1.0))


@dataclass(frozen=True)
class OpticsParams:
    """Parameters of one optical three-axis element and of its area measurement.

    Attributes:
        c_mm_per_n (tuple[3][3]): force→displacement matrix C, U = C F (mm per N);
            row i is the displacement axis, column j the force axis, order (x, y, z).
        rest_area_px2 (float): contact area of each conical feeler at zero force (px²), > 0.
        gain_y_px2_per_n (float): change of the summed area per newton of F_y (px²/N), > 0.
        gain_x_px2_per_n (float): (area at +x) − (area at −x) per newton of F_x (px²/N), > 0.
        gain_z_px2_per_n (float): (area at +z) − (area at −z) per newton of F_z (px²/N), > 0.
        area_sd_px2 (float): white noise on each measured area, `areas` fidelity (px²), ≥ 0;
            the default 0.25 is the error of the `images` level's sub-pixel areas at
            200–400 px² with the default camera (measured: sd 0.18–0.30 px² over 100–600 px²).
        area_step_px2 (float): quantisation step of a measured area (px²; 1 = whole
            pixels, as a plain thresholded pixel count gives; 0 = none), ≥ 0.
    """

    c_mm_per_n: tuple = _NOMINAL_C
    rest_area_px2: float = 150.0
    gain_y_px2_per_n: float = 800.0
    gain_x_px2_per_n: float = 400.0
    gain_z_px2_per_n: float = 400.0
    area_sd_px2: float = 0.25
    area_step_px2: float = 1.0

    def __post_init__(self):
        c = np.asarray(self.c_mm_per_n, dtype=float)
        if c.shape != (3, 3) or not np.all(np.isfinite(c)):
            raise ArgumentError("c_mm_per_n", self.c_mm_per_n, "a finite 3×3 matrix (mm/N)")
        if np.linalg.cond(c) > 1e8:
            raise ArgumentError("c_mm_per_n", self.c_mm_per_n,
                                "an invertible matrix (condition number ≤ 1e8)")
        object.__setattr__(self, "c_mm_per_n", tuple(tuple(float(v) for v in row) for row in c))
        for name in ("rest_area_px2", "gain_y_px2_per_n", "gain_x_px2_per_n", "gain_z_px2_per_n"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ArgumentError(name, value, "a finite number > 0")
        for name in ("area_sd_px2", "area_step_px2"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ArgumentError(name, value, "a finite number ≥ 0")

    @property
    def c_matrix(self) -> np.ndarray:
        """C as a (3, 3) array (mm/N)."""
        return np.array(self.c_mm_per_n)

    @property
    def area_matrix(self) -> np.ndarray:
        """G (4, 3) with A − A_rest = G F (px² per N)."""
        gains = np.array([self.gain_x_px2_per_n, self.gain_y_px2_per_n, self.gain_z_px2_per_n])
        cols = np.stack([SIGN_X, np.ones(4), SIGN_Z], axis=1)  # (4, 3): x, y, z
        return cols * gains / 4.0


def areas_from_force(f_n: np.ndarray, params: OpticsParams) -> np.ndarray:
    """Contact areas of the four conical feelers under force ``f_n``.

    Args:
        f_n (ndarray[..., 3]): force on the element (N), order (x, y, z).
        params (OpticsParams): the element.

    Returns:
        ndarray[..., 4]: areas (px²), feeler order (+x+z, +x−z, −x+z, −x−z).

    Raises:
        ArgumentError: a force that would need a negative contact area (outside the
            element's measuring range), or a force array whose last axis is not 3.
    """
    f_n = _last_axis(f_n, 3, "f_n")
    areas = params.rest_area_px2 + f_n @ params.area_matrix.T
    if np.any(areas < 0):
        worst = f_n.reshape(-1, 3)[np.argmin(areas.reshape(-1, 4).min(axis=1))]
        raise ArgumentError("f_n", tuple(worst.round(6)),
                            "a force inside the measuring range (every contact area ≥ 0)")
    return areas


def force_from_areas(areas_px2: np.ndarray, params: OpticsParams) -> np.ndarray:
    """Force from the four contact areas by the area-sum / area-difference law.

    Args:
        areas_px2 (ndarray[..., 4]): areas (px²), feeler order (+x+z, +x−z, −x+z, −x−z).

    Returns:
        ndarray[..., 3]: force (N), order (x, y, z).
    """
    a = _last_axis(areas_px2, 4, "areas_px2")
    fx = a @ SIGN_X / params.gain_x_px2_per_n
    fy = (a.sum(axis=-1) - 4.0 * params.rest_area_px2) / params.gain_y_px2_per_n
    fz = a @ SIGN_Z / params.gain_z_px2_per_n
    return np.stack([fx, fy, fz], axis=-1)


def force_from_displacement(u_mm: np.ndarray, c_mm_per_n: np.ndarray) -> np.ndarray:
    """F = C⁻¹ U for ``u_mm`` (..., 3) in mm and C (3, 3) in mm/N; returns N."""
    u = _last_axis(u_mm, 3, "u_mm")
    return np.linalg.solve(np.asarray(c_mm_per_n, float), u.reshape(-1, 3).T).T.reshape(u.shape)


def displacement_from_force(f_n: np.ndarray, c_mm_per_n: np.ndarray) -> np.ndarray:
    """U = C F for ``f_n`` (..., 3) in N and C (3, 3) in mm/N; returns mm."""
    return _last_axis(f_n, 3, "f_n") @ np.asarray(c_mm_per_n, float).T


def _last_axis(x, n: int, name: str) -> np.ndarray:
    arr = np.asarray(x, dtype=float)
    if arr.ndim == 0 or arr.shape[-1] != n:
        raise ArgumentError(name, f"array of shape {arr.shape}", f"an array of shape (..., {n})")
    return arr
