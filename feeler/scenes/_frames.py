"""Will the camera read a scene's frames? Its contact discs against the reader's limits, at load.

At ``sensor.fidelity = "images"`` every conical feeler is rendered as a bright disc of its
contact area, blurred by ``optics.blur_sd_px`` σ, and read back by
:class:`feeler.hardware.camera.AreaExtractor`. The discs' areas are linear in the tip
displacement (area law, :mod:`feeler.models.optics.law`), so a scene's largest and
smallest discs follow from its extreme presses and steps before anything is rendered.
Limits (``w`` the layout's ``window_px``):

- largest: a disc plus its blur's reach (⌈4σ⌉ + 1 px) must lie inside its ±w px window,
  A ≤ π (w − ⌈4σ⌉ − 1)² (what :func:`~feeler.models.optics.render_frames` refuses);
- interior: the reader measures the peak level on pixels 4σ + ½ px inside a disc, so the
  largest disc of every frame needs A ≥ π (4σ + 1)² (measured on the 16-element layout:
  frames read from 26, 96 and 243–252 px² at σ = 0.5, 1.2 and 2 px);
- smallest: a disc below about π (σ + 1.6)² px² thresholds to a speck and its window is
  rejected, or read as empty (measured: from 8, 11, 19 and 26 px² at σ = 0.5, 1.2, 2, 2.5);
- shot noise: one saturated pixel rejects its frame, so the Poisson photon counts of the
  discs' pixels at the peak level may reach 255 grey levels in at most one of the scene's
  frames in a hundred (expected; ``photons_per_level`` 1.5: 2 of 82 frames of
  four-plates-images rejected).

Each refusal names the key most likely at fault: the blur or the rest area when they
depart from the optics' nominal values and the nominal value would fit, otherwise the
scene's press or steps (:func:`check_frames` takes the scene kind's own ``growth`` rule).
Frames rejected at run time all the same are summed up in one line naming the key their
reasons point to (:func:`rejection_error`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from feeler.errors import SceneError

__all__ = ["DiscLimits", "scene_layout", "contact_areas", "check_frames", "check_photons", "saturated_frames",
           "rejection_error", "round_down"]

_SATURATED_FRAMES = 0.01  # expected rendered frames with a saturated pixel, at most


@dataclass(frozen=True)
class DiscLimits:
    """Contact-disc areas (px²) the reader takes, for a window half-size and a blur.

    Attributes:
        largest_px2 (float): disc + blur inside the window, π (w − ⌈4σ⌉ − 1)² (0 if none fits).
        interior_px2 (float): the largest disc of a frame must reach π (4σ + 1)².
        smallest_px2 (float): every disc must reach π (σ + 1.6)².
        reach_px (int): the blur's reach past a disc's edge, ⌈4σ⌉ + 1 px.
    """

    largest_px2: float
    interior_px2: float
    smallest_px2: float
    reach_px: int

    @classmethod
    def of(cls, window_px: int, blur_sd_px: float) -> DiscLimits:
        reach = int(math.ceil(4.0 * blur_sd_px)) + 1     # render.blur_margin_px
        free = max(0.0, window_px - reach)
        return cls(math.pi * free ** 2, math.pi * (4.0 * blur_sd_px + 1.0) ** 2,
                   math.pi * (blur_sd_px + 1.6) ** 2, reach)


def round_down(x: float, digits: int = 3) -> float:
    """``x`` > 0 cut (not rounded) to ``digits`` significant digits: a limit quoted in a
    message that still holds; 0 for x ≤ 0."""
    if x <= 0:
        return 0.0
    scale = 10.0 ** (digits - 1 - math.floor(math.log10(x)))
    return math.floor(x * scale) / scale


def scene_layout(optics, scene_path):
    """The camera :class:`~feeler.models.optics.Layout` of an ``[optics]`` table (its
    ``layout`` file relative to the scene file, or the default 4×4 grid).

    Raises:
        SceneError: ``optics.layout`` names no file.
    """
    from feeler.models.optics import grid_layout, load_layout

    if optics is None or not optics.layout:
        return grid_layout()
    path = Path(scene_path).parent / optics.layout if scene_path is not None else Path(optics.layout)
    if not path.is_file():
        raise SceneError(scene_path, "optics.layout", f"{optics.layout!r}: no such layout file ({path})")
    return load_layout(path)


def contact_areas(optics, u_mm: np.ndarray, c_mm_per_n) -> np.ndarray:
    """Areas (px²) of the four feelers, ndarray[n, 4], at tip displacements ``u_mm``
    (n, 3) mm through compliance ``c_mm_per_n`` (mm/N); negative where the law leaves its range."""
    from feeler.scenes._optics import optics_params

    params = optics_params(optics, c_mm_per_n)
    force = np.linalg.solve(np.asarray(c_mm_per_n, float), np.asarray(u_mm, float).T).T
    return params.rest_area_px2 + force @ params.area_matrix.T


def check_frames(optics, path, areas: np.ndarray, growth: Callable[..., SceneError], layout,
                 shrink: Callable[..., SceneError] | None = None) -> None:
    """Refuse a scene whose rendered discs the reader could not take (module docstring).

    Args:
        optics (Optics): the scene's ``[optics]`` table (not None).
        path: the scene file, for the message.
        areas (ndarray[n, 4]): feeler areas (px²) at the scene's extreme points, n ≥ 1.
        growth: ``growth(peak_px2, budget_px2, limits, where)`` → the SceneError naming
            the scene's own key (press, steps, design) when the discs outgrow the window
            from the nominal rest area and blur; ``budget_px2`` is what the window leaves
            above the rest area, ``where`` names the windows for the message.
        layout (Layout): the camera layout.
        shrink: ``shrink(least_px2, limits, where)`` → the SceneError naming the scene's
            key that shrinks a disc below the smallest readable one from a rest area that
            is readable; None: the rest area is named.

    Raises:
        SceneError: naming ``optics.blur_sd_px``, ``optics.rest_area_px2`` or growth's key.
    """
    from feeler.scenes._optics import Optics

    nominal, w = Optics(), layout.window_px
    blur, rest = optics.blur_sd_px, optics.rest_area_px2
    lim = DiscLimits.of(w, blur)
    where = f"the ±{w} px feeler windows of layout {layout.name or 'grid'!r}"
    peak = float(areas.max())
    weakest = float(areas.max(axis=1).min())
    r_peak, r_weak = math.sqrt(peak / math.pi), math.sqrt(max(weakest, 0.0) / math.pi)
    # the largest blur both limits allow: the reach ⌈4σ⌉ + 1 beside the largest disc, and
    # an interior 4σ + ½ px deep (π (4σ + 1)²) in the largest disc of the lightest touch
    blur_inside = math.floor(math.floor(w - 1 - r_peak) / 4.0 * 100) / 100
    blur_readable = math.floor((r_weak - 1.0) / 4.0 * 100) / 100
    blur_most = min(blur_inside, blur_readable)
    blur_limits = (f"the discs stay inside their windows with a blur up to {blur_inside:g} px and their brightness "
                   f"readable at the lightest touch up to {blur_readable:g} px: at most {blur_most:g} px")
    if peak > lim.largest_px2:
        if blur > nominal.blur_sd_px and peak <= DiscLimits.of(w, nominal.blur_sd_px).largest_px2:
            raise SceneError(path, "optics.blur_sd_px",
                             f"{blur:g}: the blur reaches {lim.reach_px} px past a disc's edge, and with the "
                             f"scene's largest contact disc ({peak:.0f} px², radius {r_peak:.1f} px) it leaves "
                             f"{where}; {blur_limits}")
        grown = peak - rest
        if rest > nominal.rest_area_px2 and grown + nominal.rest_area_px2 <= lim.largest_px2:
            raise SceneError(path, "optics.rest_area_px2",
                             f"{rest:g}: the scene's contact discs reach {peak:.0f} px², but with the blur's "
                             f"{lim.reach_px} px only {lim.largest_px2:.0f} px² fit {where}; at most "
                             f"{math.floor(lim.largest_px2 - grown):d} px² leaves room for the {grown:.0f} px² "
                             f"the scene's hardest press adds")
        raise growth(peak, lim.largest_px2 - rest, lim, where)
    if weakest < lim.interior_px2:
        if blur > nominal.blur_sd_px and weakest >= DiscLimits.of(w, nominal.blur_sd_px).interior_px2:
            raise SceneError(path, "optics.blur_sd_px",
                             f"{blur:g}: the reader measures the discs' brightness 4σ + ½ px inside their edge, "
                             f"and at the scene's lightest touch the largest disc ({weakest:.0f} px²) has no "
                             f"such pixel (it needs {lim.interior_px2:.0f} px²); {blur_limits}")
        raise SceneError(path, "optics.rest_area_px2",
                         f"{rest:g}: at the scene's lightest touch the largest contact disc is "
                         f"{max(weakest, 0.0):.0f} px², "
                         f"below the {lim.interior_px2:.0f} px² (π (4σ + 1)², blur {blur:g} px) the frame "
                         f"reader needs to measure the discs' brightness; at least "
                         f"{math.ceil(rest + lim.interior_px2 - weakest):d} px²")
    least = min(float(areas.min()), rest)          # elements without a series rest at zero force
    if least < lim.smallest_px2 and shrink is not None and rest >= lim.smallest_px2:
        raise shrink(least, lim, where)
    if least < lim.smallest_px2:
        raise SceneError(path, "optics.rest_area_px2",
                         f"{rest:g}: the scene's smallest contact disc is {max(least, 0.0):.0f} px², below the "
                         f"{lim.smallest_px2:.0f} px² (π (σ + 1.6)², blur {blur:g} px) the frame reader "
                         f"tells from shot-noise specks; at least {math.ceil(rest + lim.smallest_px2 - least):d} px²")


def saturated_frames(photons_per_level: float, n_frames: int, disc_px: float) -> float:
    """Expected frames with a saturated pixel: ``n_frames`` frames of ``disc_px`` pixels at
    the peak level (:class:`~feeler.models.optics.CameraParams`), each saturating when its
    Poisson photon count reaches 254.5 grey levels (it rounds to 255)."""
    from scipy.special import pdtrc

    from feeler.models.optics import CameraParams

    if not math.isfinite(photons_per_level):
        return 0.0
    peak = CameraParams().peak_level
    at_least = math.ceil(254.5 * photons_per_level)
    return n_frames * disc_px * float(pdtrc(at_least - 1, peak * photons_per_level))   # P(count ≥ at_least)


def check_photons(optics, path, n_frames: int, n_elements: int) -> None:
    """Refuse a shot noise that would saturate a disc's pixel in one of the scene's frames in
    a hundred or more (module docstring): the discs' pixels counted as 4 ``rest_area_px2``
    per element of ``n_elements``, over ``n_frames`` rendered frames (measured: 2 and 1 of
    82 frames rejected at 1.5 and 1.69 photons per level, 2.4 and 0.5 expected).

    Raises:
        SceneError: ``optics.photons_per_level`` below the bound, which it names.
    """
    disc_px = 4 * n_elements * optics.rest_area_px2
    expected = saturated_frames(optics.photons_per_level, n_frames, disc_px)
    if expected <= _SATURATED_FRAMES:
        return
    lo, hi = 1e-3, 1e6                                        # bisect the least count that passes
    for _ in range(60):
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if saturated_frames(mid, n_frames, disc_px) > _SATURATED_FRAMES else (lo, mid)
    least = math.ceil(hi * 100) / 100
    while saturated_frames(least, n_frames, disc_px) > _SATURATED_FRAMES:   # the count steps with ⌈254.5·p⌉
        least = round(least + 0.01, 2)
    raise SceneError(path, "optics.photons_per_level",
                     f"{optics.photons_per_level:g}: the shot noise would saturate a pixel of the contact discs "
                     f"in {min(expected, n_frames):.2g} of the scene's {n_frames} rendered frames, and a saturated "
                     f"pixel rejects its frame; at least {least:g} photons per grey level")


def rejection_error(exc, optics, path, unit: str) -> SceneError:
    """The scene's one-line error for rendered frames the reader rejected at run time
    (:class:`~feeler.simulate.images.FramesRejected` ``exc``; ``unit`` names a series:
    "scan", "point"), naming the key its reasons point to (:func:`~feeler.simulate.images.rejection_cause`)."""
    from feeler.scenes._optics import Optics

    optics, nominal = optics or Optics(), Optics()
    first, reason = exc.problems[0]
    lost = (f"the frame reader rejected {len(exc.problems)} of {exc.n_frames} rendered frames "
            f"({exc.series.size} {unit}s, first: {unit} {exc.series[0]}; frame {first}: {reason}; "
            f"-v lists every frame)")
    blur_at_fault = optics.blur_sd_px > nominal.blur_sd_px
    if exc.cause == "noise":
        return SceneError(path, "optics.photons_per_level",
                          f"{optics.photons_per_level:g}: shot noise: {lost}; raise photons_per_level")
    if exc.cause == "small discs":
        key, value, advice = (("blur_sd_px", optics.blur_sd_px, "lower blur_sd_px") if blur_at_fault else
                              ("rest_area_px2", optics.rest_area_px2, "raise rest_area_px2"))
        return SceneError(path, f"optics.{key}", f"{value:g}: contact discs too small for the blur: {lost}; {advice}")
    if exc.cause == "large discs":
        key, value = ("blur_sd_px", optics.blur_sd_px) if blur_at_fault else ("rest_area_px2", optics.rest_area_px2)
        return SceneError(path, f"optics.{key}", f"{value:g}: contact discs with their blur reach their windows' "
                                                 f"edges: {lost}; lower {key} or the press")
    return SceneError(path, "optics", lost)
