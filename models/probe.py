"""Robot probe: the sensing element's tip rubbed over a plate by the stage (DESIGN §4).

The chain for one scan (one *touch*):

- stage motion x(t) = x0 + v·t sampled every ``dt_s`` (:class:`Motion`);
- the element's flat tip face (width ``pad_width_mm``) is pressed ``uy0_mm`` into the
  plate with a small tilt θ. On a linear (Winkler) rubber layer the contact pressure
  falls linearly from the low corner: uniform when θ = 0, a triangle ``uy0/tan θ`` long
  when the tilt lifts the far corner off. The tip's vertical displacement follows the
  pressure-weighted mean surface height under the face (:class:`Footprint`), computed
  exactly edge by edge — so the rise time of a step, hence the raw U̇_y peak, depends on
  the press U_y0 and the tilt of each touch, as the paper observes (§5.2);
- when sliding starts the stuck contact breaks away and the rubber partly unloads: U_y
  drops by ``breakaway_frac``·U_y0 with time constant ``breakaway_s`` (a transient at the
  start of every scan whose size follows U_y0 — the paper's remark that U̇_y "depends on
  the value of U_y0"; it is what the raw U̇_y peak sees on a fine step);
- stick–slip at a riser: on a fraction ``snap_prob`` of touches (drawn per touch) the
  face's leading corner catches on each rising edge, the rubber shears while the stage
  advances, and the tip snaps up onto the upper level when the face centre passes the
  edge — a jump of the full step within one frame instead of the ride over the face.
  A snapping touch's raw U̇_y peak is step/frame, several times the ride-over rate, so the
  raw peak of a fine step can exceed that of one twice as high (paper §5.2, Fig. 8); the
  total rise, hence a window sum over τ ≥ the ride time, is the same either way;
- U_y(t) = U_y0 + height(x(t)) − breakaway + drift·t (a linear creep per touch);
- U_x(t) = −``shear_per_normal``·U_y(t): kinetic friction drags the tip back in
  proportion to the normal load; U_z(t) = 0 (a straight step has no lateral cue).

Measurement noise belongs to the sensor (:mod:`feeler.models.sensor`). All random draws
of a touch come from the ``numpy.random.Generator`` passed to :func:`draw_touch`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from feeler.errors import ArgumentError
from feeler.models.surface import Profile

__all__ = ["Motion", "ProbeParams", "Touch", "Footprint", "draw_touch", "smoothed_height_mm",
           "tip_displacement", "samples_per_scan"]


def samples_per_scan(speed_mm_s: float, traverse_mm: float, dt_s: float) -> int:
    """Samples in one traverse, one every ``dt_s`` from its start: ``floor(traverse / (v·dt)) + 1``
    (the stage stops at the end; 1e-9 absorbs the rounding of the quotient). The one rule of
    a simulated scan (:attr:`Motion.n_samples`), a robot scene's frame count and an
    acquisition plan's samples (``sample_period_s`` for ``dt_s``)."""
    return int(math.floor(traverse_mm / (speed_mm_s * dt_s) + 1e-9)) + 1


@dataclass(frozen=True)
class Motion:
    """Stage motion: ``x0_mm + speed_mm_s·t`` for t = 0, dt_s, … over ``traverse_mm``."""

    speed_mm_s: float
    traverse_mm: float
    dt_s: float
    x0_mm: float = 0.0

    def __post_init__(self):
        for name in ("speed_mm_s", "traverse_mm", "dt_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ArgumentError(name, value, "a finite value > 0")

    @property
    def n_samples(self) -> int:
        """Samples in one traverse: floor(traverse / (v·dt)) + 1 (the stage stops at the end)."""
        return samples_per_scan(self.speed_mm_s, self.traverse_mm, self.dt_s)

    def times_s(self) -> np.ndarray:
        """Sample times, ndarray[n_samples] in s, starting at 0."""
        return np.arange(self.n_samples) * self.dt_s


@dataclass(frozen=True)
class ProbeParams:
    """How touches vary and how the tip couples to the plate (units in the names)."""

    pad_width_mm: float = 1.5
    uy0_mean_mm: float = 0.05
    uy0_sd_mm: float = 0.0
    tilt_sd_deg: float = 0.0
    x0_sd_mm: float = 0.0
    drift_sd_mm_s: float = 0.0
    shear_per_normal: float = 0.0
    breakaway_frac: float = 0.0
    breakaway_s: float = 0.2
    snap_prob: float = 0.0

    def __post_init__(self):
        if not (0.0 <= self.snap_prob <= 1.0):
            raise ArgumentError("snap_prob", self.snap_prob, "a probability in [0, 1]")
        for name in ("pad_width_mm", "uy0_sd_mm", "tilt_sd_deg", "x0_sd_mm", "drift_sd_mm_s",
                     "shear_per_normal", "breakaway_frac"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ArgumentError(name, value, "a finite value >= 0")
        for name in ("uy0_mean_mm", "breakaway_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ArgumentError(name, value, "a finite value > 0")


@dataclass(frozen=True)
class Touch:
    """The random state of one touch (recorded in ``truth.json``)."""

    uy0_mm: float
    tilt_deg: float
    x0_mm: float
    drift_mm_s: float
    snaps: bool = False


@dataclass(frozen=True)
class Footprint:
    """Contact pressure of a flat face ``width_mm`` wide, pressed ``press_mm``, tilted ``tilt_deg``.

    ``tilt_deg > 0`` lifts the leading (+x) corner, so contact concentrates at the
    trailing corner; ``width_mm = 0`` is a point contact (the profile itself).
    """

    width_mm: float
    press_mm: float
    tilt_deg: float = 0.0

    def cdf(self, r_mm) -> np.ndarray:
        """P(contact point ≤ r) for r measured from the face centre (ndarray[...], mm)."""
        r = np.asarray(r_mm, dtype=float)
        if self.width_mm == 0.0:
            return (r > 0).astype(float)
        if self.tilt_deg < 0:
            mirrored = Footprint(self.width_mm, self.press_mm, -self.tilt_deg)
            return 1.0 - mirrored.cdf(-r)
        grad = math.tan(math.radians(self.tilt_deg))
        length = self.width_mm if grad * self.width_mm <= self.press_mm else self.press_mm / grad
        s = np.clip(r + self.width_mm / 2, 0.0, length)
        area = self.press_mm * length - grad * length ** 2 / 2
        return np.where(s >= length, 1.0, (self.press_mm * s - grad * s ** 2 / 2) / area)  # exact 1 past the contact


def smoothed_height_mm(profile: Profile, x_mm, footprint: Footprint, *, snap: bool = False) -> np.ndarray:
    """Footprint-weighted mean height of ``profile`` under a face centred at ``x_mm`` (mm).

    ``snap``: rising edges are taken in one jump when the face centre passes them
    (stick–slip at the riser); falling edges are still smoothed by the footprint.
    """
    x = np.asarray(x_mm, dtype=float)
    h = np.full(x.shape, float(profile.base_mm))
    for edge, jump in zip(profile.edges_mm, profile.jumps_mm):
        h += jump * ((x >= edge) if snap and jump > 0 else (1.0 - footprint.cdf(edge - x)))
    return h


def draw_touch(params: ProbeParams, motion: Motion, rng: np.random.Generator) -> Touch:
    """Draw one touch: press U_y0 (normal, truncated to > 0), tilt, start offset, drift rate,
    and whether it snaps at a riser (probability ``snap_prob``; drawn last, so the other
    draws do not depend on it)."""
    uy0 = rng.normal(params.uy0_mean_mm, params.uy0_sd_mm)
    while uy0 <= 0:
        uy0 = rng.normal(params.uy0_mean_mm, params.uy0_sd_mm)
    tilt = rng.normal(0.0, params.tilt_sd_deg)
    x0 = motion.x0_mm + rng.normal(0.0, params.x0_sd_mm)
    drift = rng.normal(0.0, params.drift_sd_mm_s)
    snaps = bool(rng.random() < params.snap_prob)
    return Touch(uy0_mm=float(uy0), tilt_deg=float(tilt), x0_mm=float(x0), drift_mm_s=float(drift), snaps=snaps)


def tip_displacement(profile: Profile, motion: Motion, params: ProbeParams,
                     touch: Touch) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """True three-axis tip displacement of one scan.

    Returns:
        t_s (ndarray[n_time]): sample times in s.
        x_mm (ndarray[n_time]): stage position in plate coordinates, mm.
        u_mm (ndarray[n_time, 3]): (U_x, U_y, U_z) in mm, before measurement noise.
    """
    t = motion.times_s()
    x = touch.x0_mm + motion.speed_mm_s * t
    face = Footprint(params.pad_width_mm, touch.uy0_mm, touch.tilt_deg)
    release = params.breakaway_frac * touch.uy0_mm * -np.expm1(-t / params.breakaway_s)
    uy = touch.uy0_mm + smoothed_height_mm(profile, x, face, snap=touch.snaps) - release + touch.drift_mm_s * t
    ux = -params.shear_per_normal * uy  # friction drags the tip back against the motion (+x)
    return t, x, np.stack([ux, uy, np.zeros_like(uy)], axis=-1)
