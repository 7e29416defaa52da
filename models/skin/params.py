"""Parameters of the finger-skin models: one frozen dataclass shared by L0, L1 and L2.

Units are in the field names (mm, MPa, s). Coordinates follow the paper: x along the
scan, y the surface normal pointing into the skin; depths are measured from the skin
surface. The defaults are the paper's §4 values; the geometry the paper does not give
(finger radius, layer thicknesses) is chosen in ``datasets-synthetic/finger-steps.toml``
with its reasoning.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from feeler.errors import ArgumentError

__all__ = ["SkinParams", "StepProfile"]


def _positive(name: str, value: float) -> None:
    if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
        raise ArgumentError(name, value, "must be a finite number > 0")


@dataclass(frozen=True)
class SkinParams:
    """Material, geometry and loading of the finger model (paper §4).

    Attributes:
        e_mpa (tuple[float, float, float]): instantaneous Young's moduli of epidermis,
            dermis and hypodermis in MPa.
        nu (float): Poisson's ratio of all layers, in [0, 0.5).
        prony_ratio (float): first-order Prony ratio g1 in [0, 1): the fraction of the
            instantaneous modulus that relaxes (long-term modulus = (1 - g1) E).
        prony_tau_s (float): Prony relaxation time in seconds, > 0.
        radius_mm (float): radius of the half-cylinder finger in mm.
        thickness_mm (tuple[float, float]): epidermis and dermis thicknesses in mm; the
            hypodermis fills the rest of the radius.
        press_mm (float): press depth of the finger onto the surface in mm.
        press_s (float): duration of the press ramp in seconds.
        hold_s (float): hold time after the press in seconds.
        slide_mm (float): slide distance in mm (the finger moves in +x).
        corpuscle_width_mm, corpuscle_height_mm (float): the corpuscle element (x × y).
        corpuscle_depth_mm (float): depth of the element's centre below the surface.
        l0_gain (float): layering gain applied to the half-space step response (L0).
        l0_base (float): pressed-state strain added by L0 (base shift), reached at the
            end of the press ramp.
    """

    e_mpa: tuple[float, float, float] = (0.14, 0.034, 0.080)
    nu: float = 0.45
    prony_ratio: float = 0.5
    prony_tau_s: float = 0.0129
    radius_mm: float = 8.0
    thickness_mm: tuple[float, float] = (0.45, 1.55)
    press_mm: float = 1.0
    press_s: float = 0.1
    hold_s: float = 1.0
    slide_mm: float = 10.0
    corpuscle_width_mm: float = 0.040
    corpuscle_height_mm: float = 0.050
    corpuscle_depth_mm: float = 0.5
    l0_gain: float = 1.0
    l0_base: float = 0.0

    def __post_init__(self):
        if len(self.e_mpa) != 3:
            raise ArgumentError("e_mpa", self.e_mpa, "needs 3 moduli (epidermis, dermis, hypodermis)")
        for e in self.e_mpa:
            _positive("e_mpa", e)
        if not (0.0 <= self.nu < 0.5):
            raise ArgumentError("nu", self.nu, "Poisson's ratio must be in [0, 0.5)")
        if not (0.0 <= self.prony_ratio < 1.0):
            raise ArgumentError("prony_ratio", self.prony_ratio, "must be in [0, 1)")
        if len(self.thickness_mm) != 2:
            raise ArgumentError("thickness_mm", self.thickness_mm, "needs 2 thicknesses (epidermis, dermis)")
        for name in ("prony_tau_s", "radius_mm", "press_mm", "press_s", "slide_mm",
                     "corpuscle_width_mm", "corpuscle_height_mm", "corpuscle_depth_mm"):
            _positive(name, getattr(self, name))
        for t in self.thickness_mm:
            _positive("thickness_mm", t)
        if not (math.isfinite(self.hold_s) and self.hold_s >= 0):
            raise ArgumentError("hold_s", self.hold_s, "must be a finite number >= 0")
        if sum(self.thickness_mm) >= 0.5 * self.radius_mm:
            raise ArgumentError("thickness_mm", self.thickness_mm,
                                f"epidermis + dermis must be < half the radius {self.radius_mm} mm")
        top = self.corpuscle_depth_mm - self.corpuscle_height_mm / 2
        if top <= 0 or self.corpuscle_depth_mm + self.corpuscle_height_mm / 2 >= sum(self.thickness_mm):
            raise ArgumentError("corpuscle_depth_mm", self.corpuscle_depth_mm,
                                "the corpuscle element must lie inside the skin, above the hypodermis")
        if self.press_mm >= 0.5 * self.radius_mm:
            raise ArgumentError("press_mm", self.press_mm, f"must be < half the radius {self.radius_mm} mm")
        if not (math.isfinite(self.l0_gain) and math.isfinite(self.l0_base)):
            raise ArgumentError("l0_gain", (self.l0_gain, self.l0_base), "L0 constants must be finite")

    @property
    def relaxed_fraction(self) -> float:
        """Long-term over instantaneous modulus, 1 - g1."""
        return 1.0 - self.prony_ratio


@dataclass(frozen=True)
class StepProfile:
    """A single step on a flat rigid plate (the surface the finger slides on).

    Attributes:
        height_um (float): step height in µm; > 0 is a step up in +x, < 0 a step down.
        position_mm (float): x of the step's centre on the plate in mm; the finger's
            corpuscle starts above x = 0 and slides to x = slide_mm.
        edge_um (float): width of the linear ramp that rounds the step's edge in µm
            (0 = sharp). A real edge is never sharp; at 0.5 mm depth a 50 µm ramp is
            indistinguishable from a sharp step (tested), while FEM needs it to converge.
    """

    height_um: float
    position_mm: float = 5.0
    edge_um: float = 50.0

    def __post_init__(self):
        if not math.isfinite(self.height_um) or abs(self.height_um) > 1000:
            raise ArgumentError("height_um", self.height_um, "must be finite, |height| <= 1000 µm")
        if not math.isfinite(self.position_mm):
            raise ArgumentError("position_mm", self.position_mm, "must be finite")
        if not (math.isfinite(self.edge_um) and self.edge_um >= 0):
            raise ArgumentError("edge_um", self.edge_um, "must be finite and >= 0")

    def height_mm(self, x_mm):
        """Plate height in mm at plate positions ``x_mm`` (ndarray[...], mm)."""
        x = np.asarray(x_mm, dtype=float) - self.position_mm
        h = self.height_um * 1e-3
        if self.edge_um == 0:
            return np.where(x > 0, h, np.where(x < 0, 0.0, h / 2))
        return h * np.clip(x / (self.edge_um * 1e-3) + 0.5, 0.0, 1.0)

    def second_integral_mm3(self, x_mm):
        """∫∫ height dx dx (mm³) from −∞, at plate positions ``x_mm`` (ndarray[...])."""
        e = self.edge_um * 1e-3
        r = np.maximum(np.asarray(x_mm, dtype=float) - self.position_mm + e / 2, 0.0)
        h = self.height_um * 1e-3
        if e == 0:
            return h * r * r / 2
        return h * np.where(r <= e, r ** 3 / (6 * e), r * r / 2 - e * r / 2 + e * e / 6)

    def hat_average_mm(self, x_mm, travel_mm=0.0):
        """Plate height averaged over the P1 hat function of each node (the weighted gap).

        Args:
            x_mm (ndarray[n]): node positions in the finger frame, increasing, n >= 2.
            travel_mm (float | ndarray[...]): finger travel; a node at x sits above
                plate x + travel.
        Returns:
            ndarray[..., n]: ∫ φ_i height / ∫ φ_i in mm; the end nodes use a mirrored hat.
        """
        x_nodes = np.asarray(x_mm, dtype=float)
        a = np.diff(x_nodes, prepend=2 * x_nodes[0] - x_nodes[1])
        b = np.diff(x_nodes, append=2 * x_nodes[-1] - x_nodes[-2])
        x = x_nodes + np.asarray(travel_mm, dtype=float)[..., None]
        i2 = self.second_integral_mm3
        mid = i2(x)
        return 2.0 / (a + b) * ((i2(x + b) - mid) / b - (mid - i2(x - a)) / a)
