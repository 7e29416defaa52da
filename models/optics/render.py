"""Camera frames of an element array: bright discs of the feelers' contact areas.

Each conical feeler in contact scatters the light of the light-guide plate, so the camera
sees a bright disc of the contact area on a dark background. A frame is rendered as

    I = background + (peak − background) · (coverage ⊛ Gaussian(blur_sd_px))

where ``coverage`` is the exact pixel coverage of the disc of radius √(A/π) about the
feeler centre: each pixel holds the area of its unit square inside the circle (analytic
circle–square intersection), so the disc's interior is at the full peak level and its
light integrates to exactly A px² (the "rendered truth": Σ(I − background) /
(peak − background) = A before noise, because the blur conserves the integral). Shot
noise is Poisson in photons (``photons_per_level`` photons per grey level), then the
frame is rounded and clipped to 8 bits.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter

from feeler.errors import ArgumentError

from .layout import Layout

__all__ = ["CameraParams", "render_frames", "blur_margin_px", "disc_coverage"]


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
    patches = []  # (rows slice, cols slice, light (n, 2h+1, 2h+1)) per feeler
    for e, element in enumerate(layout.elements):
        for k, (cx, cy) in enumerate(element.feelers):
            ix, iy = int(round(cx)), int(round(cy))
            # half-size h of the patch: the discs (≤ r_max + ½ px from the centre pixel) plus
            # their blur (the Gaussian's reach ≤ blur_margin_px); zero light beyond it
            h = min(w, int(np.ceil(radius[:, e, k].max(initial=0.0) + 0.5)) + blur_margin_px(camera))
            edges = np.arange(-h - 0.5, h + 1.0)  # pixel borders about the centre pixel
            light = disc_coverage(radius[:, e, k], edges + ix - cx, edges + iy - cy)
            if camera.blur_sd_px > 0:
                light = gaussian_filter(light, sigma=camera.blur_sd_px, axes=(1, 2), mode="constant",
                                        truncate=4.0)
            patches.append((slice(iy - h, iy + h + 1), slice(ix - h, ix + h + 1), light))
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


def disc_coverage(radius_px: np.ndarray, x_edges_px: np.ndarray, y_edges_px: np.ndarray) -> np.ndarray:
    """Exact area of discs inside every pixel of a grid (analytic circle–rectangle areas).

    Args:
        radius_px (ndarray[n]): disc radii (px), ≥ 0; the discs are centred at the origin.
        x_edges_px (ndarray[P+1]): increasing column borders (px) relative to the centre.
        y_edges_px (ndarray[Q+1]): increasing row borders (px) relative to the centre.

    Returns:
        ndarray[n, Q, P]: area (px²) of each disc inside each cell; for unit pixels the
        fraction covered, summing to π r² (to rounding) when the grid holds the disc.

    With S(X, Y) the signed area of the disc inside [0, X] × [0, Y] (odd in X and in Y by
    the disc's symmetry), a cell's area is S(x₁, y₁) − S(x₀, y₁) − S(x₁, y₀) + S(x₀, y₀).
    For X, Y ≥ 0, clipped to the radius (X' = min(X, r), Y' = min(Y, r)), the chord
    reaches Y' up to x_c = √(r² − Y'²), so S = min(X', x_c)·Y' + max(0, G(X') − G(x_c))
    with G(x) = ∫₀ˣ √(r² − u²) du increasing. G is taken up to a constant as
    (x·h − r²·atan2(h, x)) / 2, h = √((r − x)(r + x)) (h(x_c) = Y' exactly): no
    cancellation near the rim. Only G and √ of the borders (1-D) are evaluated; the
    2-D part is minima, products and sums.
    """
    r = np.asarray(radius_px, dtype=float)[:, None, None]
    xb = np.asarray(x_edges_px, dtype=float)[None, None, :]
    yb = np.asarray(y_edges_px, dtype=float)[None, :, None]
    x_clip, y_clip = np.minimum(np.abs(xb), r), np.minimum(np.abs(yb), r)     # (n,1,P+1), (n,Q+1,1)
    x_height = np.sqrt((r - x_clip) * (r + x_clip))                            # h(X')
    x_chord = np.sqrt((r - y_clip) * (r + y_clip))                             # x_c per row border
    g_x = 0.5 * (x_clip * x_height - r * r * np.arctan2(x_height, x_clip))
    g_chord = 0.5 * (x_chord * y_clip - r * r * np.arctan2(y_clip, x_chord))
    beyond = g_x - g_chord                                                     # (n, Q+1, P+1)
    np.maximum(beyond, 0.0, out=beyond)
    quadrant = np.minimum(x_clip, x_chord)
    quadrant *= y_clip
    quadrant += beyond
    quadrant *= np.sign(yb) * np.sign(xb)
    return quadrant[:, 1:, 1:] - quadrant[:, 1:, :-1] - quadrant[:, :-1, 1:] + quadrant[:, :-1, :-1]
