"""Area extraction of small discs (down to the optics' rest area) and its bias.

``exact_frames`` renders discs with exact pixel coverage (each pixel's area inside the
circle, to 0.02 px² per disc, by sub-column integration independent of the renderer's
analytic coverage) at arbitrary sub-pixel positions, so the interior is at the peak level
AND the light integrates to the area: the ground truth for the estimator's bias.
``render_frames`` now draws the same exact coverage, so its frames are read unbiased too.
"""
import numpy as np
import pytest
from scipy.ndimage import gaussian_filter

from feeler.hardware.camera import AreaExtractor
from feeler.models.optics import CameraParams, OpticsParams, grid_layout, render_frames
from feeler.models.optics.render import disc_coverage

LAYOUT = grid_layout(2, 2, width_px=320, height_px=240)
CAM = CameraParams()
REST = OpticsParams().rest_area_px2


def disc_cover(r_px: float, dx: np.ndarray, dy: np.ndarray, columns: int = 64) -> np.ndarray:
    """Fraction of each unit pixel square (centre ``dx, dy`` px from the disc's centre)
    inside the disc: exact in y (the chord's extent), ``columns`` midpoints in x."""
    x = dx[..., None] + (np.arange(columns) + 0.5) / columns - 0.5
    half = np.sqrt(np.clip(r_px ** 2 - x ** 2, 0.0, None))
    y0, y1 = dy[..., None] - 0.5, dy[..., None] + 0.5
    return np.clip(np.minimum(y1, half) - np.maximum(y0, -half), 0.0, 1.0).mean(axis=-1)


def exact_frames(areas_px2: np.ndarray, rng: np.random.Generator | None, shift_px=None) -> np.ndarray:
    """Frames (n, H, W) uint8 like ``render_frames`` but with exact coverage; ``shift_px``
    (n, 16, 2) moves each disc off its feeler centre (sub-pixel positions)."""
    n, w = len(areas_px2), LAYOUT.window_px
    offsets = np.arange(-w, w + 1, dtype=float)
    out = np.empty((n, LAYOUT.height_px, LAYOUT.width_px), np.uint8)
    for i in range(n):
        cover = np.zeros((LAYOUT.height_px, LAYOUT.width_px))
        for j, (cx, cy) in enumerate(LAYOUT.centres_px.reshape(-1, 2)):
            ix, iy = int(round(cx)), int(round(cy))
            if shift_px is not None:
                cx, cy = cx + shift_px[i, j, 0], cy + shift_px[i, j, 1]
            dx, dy = offsets[None, :] + ix - cx, offsets[:, None] + iy - cy
            cover[iy - w: iy + w + 1, ix - w: ix + w + 1] += disc_cover(np.sqrt(areas_px2[i].flat[j] / np.pi),
                                                                        *np.broadcast_arrays(dx, dy))
        level = CAM.background_level + (CAM.peak_level - CAM.background_level) * gaussian_filter(
            cover, CAM.blur_sd_px, mode="constant", truncate=4.0)
        if rng is not None:
            level = rng.poisson(level * CAM.photons_per_level) / CAM.photons_per_level
        out[i] = np.clip(np.rint(level), 0, 255)
    return out


def test_exact_cover_integrates_to_the_disc_area():
    """Cross-checks of the reference renderer: a pixel cut through its centre by a huge disc is
    half covered, and discs anywhere integrate to π r² within 0.02 px²."""
    assert disc_cover(1e4, np.array(1e4), np.array(0.0)) == pytest.approx(0.5, abs=1e-4)   # ~straight edge
    assert disc_cover(10.0, np.array(0.0), np.array(0.0)) == 1.0
    offsets = np.arange(-20, 21, dtype=float)
    for area, (sx, sy) in [(150.0, (0.5, 0.5)), (150.0, (0.13, 0.41)), (300.0, (0.0, 0.0)), (95.0, (0.3, 0.9))]:
        dx, dy = np.meshgrid(offsets - sx, offsets - sy)
        assert disc_cover(np.sqrt(area / np.pi), dx, dy).sum() == pytest.approx(area, abs=0.02)


@pytest.mark.parametrize("area_px2", [REST, 250.0])
def test_small_discs_down_to_the_rest_area_within_1_percent(area_px2):
    """Every disc at the optics' rest area (150 px², blur 1.2 px): measured, within 1 %."""
    frames = render_frames(np.full((4, 4, 4), area_px2), LAYOUT, CAM, np.random.default_rng(11))
    extract = AreaExtractor(LAYOUT, blur_sd_px=CAM.blur_sd_px)
    for frame in frames:
        areas, problem = extract(frame)
        assert problem is None and np.abs(areas / area_px2 - 1).max() < 0.01


def test_discs_below_the_interior_depth_are_still_rejected():
    frame = render_frames(np.full((1, 4, 4), 85.0), LAYOUT, CAM, np.random.default_rng(12))[0]
    areas, problem = AreaExtractor(LAYOUT)(frame)
    assert problem == "no disc interior left to measure the peak level" and np.isnan(areas).all()


@pytest.mark.parametrize("area_px2", [REST, 300.0])
def test_estimator_is_unbiased_on_exactly_rendered_discs(area_px2):
    """Mean error over 16 × 12 discs at random sub-pixel positions: |bias| < 0.1 px²
    (its standard error is ≈ 0.02 px²; the noise of one area is ≈ 0.2 px²)."""
    rng = np.random.default_rng(13)
    shift = rng.uniform(-0.5, 0.5, (12, 16, 2))
    frames = exact_frames(np.full((12, 4, 4), area_px2), rng, shift)
    extract = AreaExtractor(LAYOUT)
    errors = np.array([extract(f)[0] - area_px2 for f in frames])
    assert not np.isnan(errors).any()
    assert abs(errors.mean()) < 0.1 and 0.1 < errors.std() < 0.5


def test_project_frames_are_read_without_bias():
    """``render_frames`` draws exact pixel coverage (interior at the full peak level, light
    = A), so on the project's own frames the estimator is unbiased too: |mean| < 0.1 px²
    over 16 × 8 discs (standard error ≈ 0.02 px²). The former linear anti-aliasing,
    re-scaled to A, dimmed the interior and read +0.4 px² at 150 and +1.1 px² at 300."""
    extract = AreaExtractor(LAYOUT)
    for area in (REST, 300.0):
        frames = render_frames(np.full((8, 4, 4), area), LAYOUT, CAM, np.random.default_rng(14))
        errors = np.array([extract(f)[0] for f in frames]) - area
        assert not np.isnan(errors).any() and abs(errors.mean()) < 0.1


def test_reference_and_renderer_coverage_agree():
    """The renderer's analytic coverage equals this file's sub-column reference per pixel."""
    edges = np.arange(-15.5, 16.0)
    for area, (sx, sy) in [(REST, (0.13, 0.41)), (300.0, (-0.5, 0.2))]:
        r = np.sqrt(area / np.pi)
        ref = disc_cover(r, *np.meshgrid(edges[:-1] + 0.5 - sx, edges[:-1] + 0.5 - sy), columns=1024)
        assert np.abs(disc_coverage(np.array([r]), edges - sx, edges - sy)[0] - ref).max() < 1e-4
