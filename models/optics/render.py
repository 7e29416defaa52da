"""Camera frames of an element array: bright discs of the feelers' contact areas.

Each conical feeler in contact scatters the light of the light-guide plate, so the camera
sees a bright disc of the contact area on a dark background. A frame is rendered as

    I = background + (peak − background) · (coverage ⊛ Gaussian(blur_sd_px))

where ``coverage`` is the anti-aliased disc of radius √(A/π) about the feeler centre,
scaled so that it integrates to exactly A px² (the "rendered truth": Σ(I − background)
/ (peak − background) = A before noise, because the blur conserves the integral). Shot
noise is Poisson in photons (``photons_per_level`` photons per grey level), then the
frame is rounded and clipped to 8 bits.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter

from feeler.errors import ArgumentError

from .layout import Layout

__all__ = ["CameraParams", "render_frames", "blur_margin_px"]


@dataclass(frozen=True)
class CameraParams:
    """The camera's view of the light-guide plate.

    Attributes:
        background_level (float): grey level of the plate without contact, 0 ≤ · < peak.
        peak_level (float): grey level inside a contact disc, < 255 (no saturation).
        blur_sd_px (float): standard deviation of the Gaussian blur (px), ≥ 0.
        photons_per_level (float): photons (photo-electrons) per grey level for the shot
            noise, > 0; the default 40 is a 10 000 e⁻ full well spread over 255 levels, as
            in common 8-bit machine-vision CMOS cameras; ``inf`` renders without noise
            (then only 8-bit rounding remains).
    """

    background_level: float = 20.0
    peak_level: float = 200.0
    blur_sd_px: float = 1.2
    photons_per_level: float = 40.0

    def __post_init__(self):
        if not (0 <= self.background_level < self.peak_level <= 250):
            raise ArgumentError("background_level, peak_level",
                                (self.background_level, self.peak_level),
                                "0 ≤ background_level < peak_level ≤ 250 (8-bit, unsaturated)")
        if not (np.isfinite(self.blur_sd_px) and 0 <= self.blur_sd_px <= 10):
            raise ArgumentError("blur_sd_px", self.blur_sd_px, "a number in [0, 10] px")
        if not self.photons_per_level > 0:
            raise ArgumentError("photons_per_level", self.photons_per_level, "a number > 0 (or inf)")


def blur_margin_px(camera: CameraParams) -> int:
    """Pixels beyond a disc's edge that still carry its blurred light (4 σ + 1)."""
    return int(np.ceil(4.0 * camera.blur_sd_px)) + 1


def render_frames(areas_px2: np.ndarray, layout: Layout, camera: CameraParams,
                  rng: np.random.Generator | None) -> np.ndarray:
    """Render camera frames of an element array.

    Args:
        areas_px2 (ndarray[n_frames, n_elements, 4]): contact area of every feeler (px²),
            feeler order (+x+z, +x−z, −x+z, −x−z).
        layout (Layout): frame size, element regions and feeler centres.
        camera (CameraParams): levels, blur and shot noise.
        rng (numpy.random.Generator | None): source of the shot noise; ``None`` renders
            the noise-free frame (rounded to 8 bits).

    Returns:
        ndarray[n_frames, height_px, width_px] of uint8.

    Raises:
        ArgumentError: wrong shape, a negative or non-finite area, or a disc (with its
            blur) that does not fit inside its feeler's window.
    """
    areas = np.asarray(areas_px2, dtype=float)
    n_el = len(layout.elements)
    if areas.ndim != 3 or areas.shape[1:] != (n_el, 4):
        raise ArgumentError("areas_px2", f"array of shape {areas.shape}",
                            f"shape (n_frames, {n_el}, 4) for layout {layout.name!r}")
    if not np.all(np.isfinite(areas)) or np.any(areas < 0):
        raise ArgumentError("areas_px2", float(np.nanmin(areas)), "finite areas ≥ 0 px²")
    w = layout.window_px
    radius = np.sqrt(areas / np.pi)
    limit = w - blur_margin_px(camera)
    if radius.max(initial=0.0) > limit:
        raise ArgumentError("areas_px2", float(areas.max()),
                            f"areas ≤ {np.pi * limit ** 2:.0f} px² (disc + blur inside the "
                            f"±{w} px feeler window)")
    n = areas.shape[0]
    offsets = np.arange(-w, w + 1, dtype=float)
    patches = []  # (rows slice, cols slice, light (n, P, P)) per feeler
    for e, element in enumerate(layout.elements):
        for k, (cx, cy) in enumerate(element.feelers):
            ix, iy = int(round(cx)), int(round(cy))
            dist = np.hypot(offsets[None, :] + ix - cx, offsets[:, None] + iy - cy)
            light = _disc_patch(radius[:, e, k], areas[:, e, k], dist, camera.blur_sd_px)
            patches.append((slice(iy - w, iy + w + 1), slice(ix - w, ix + w + 1), light))
    noisy = rng is not None and np.isfinite(camera.photons_per_level)
    gain = camera.photons_per_level if noisy else 1.0
    contrast = (camera.peak_level - camera.background_level) * gain
    out = np.empty((n, layout.height_px, layout.width_px), dtype=np.uint8)
    level = np.empty((layout.height_px, layout.width_px))
    for i in range(n):  # one frame at a time keeps the working set in cache
        level.fill(camera.background_level * gain)
        for rows, cols, light in patches:
            level[rows, cols] += contrast * light[i]
        counts = rng.poisson(level) / gain if noisy else level
        out[i] = np.clip(np.rint(counts), 0, 255)
    return out


def _disc_patch(radius: np.ndarray, area: np.ndarray, dist: np.ndarray, blur_sd_px: float) -> np.ndarray:
    """Blurred unit-intensity discs (n, P, P) integrating to ``area`` each."""
    cover = np.clip(radius[:, None, None] - dist[None] + 0.5, 0.0, 1.0)
    total = cover.sum(axis=(1, 2))
    scale = np.divide(area, total, out=np.zeros_like(area), where=total > 0)
    cover *= scale[:, None, None]
    if blur_sd_px > 0:
        cover = gaussian_filter(cover, sigma=blur_sd_px, axes=(1, 2), mode="constant", truncate=4.0)
    return cover
