"""Rendered camera frames: exact disc coverage, conserved light, disc placement, shot-noise
statistics, validation."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from feeler.errors import ArgumentError
from feeler.models.optics import CameraParams, grid_layout, render_frames
from feeler.models.optics.render import disc_coverage

LAYOUT = grid_layout(2, 2, width_px=320, height_px=240)
CAM = CameraParams()


def windows(frame, layout=LAYOUT):
    w = layout.window_px
    for e, element in enumerate(layout.elements):
        for k, (cx, cy) in enumerate(element.feelers):
            ix, iy = int(round(cx)), int(round(cy))
            yield e, k, cx, cy, frame[iy - w: iy + w + 1, ix - w: ix + w + 1].astype(float), ix, iy


def sampled_coverage(r, x_edges, y_edges, columns=4096):
    """Independent reference: exact chord extent in y, ``columns`` midpoints per pixel in x."""
    x = (x_edges[:-1, None] + (np.arange(columns) + 0.5) / columns * np.diff(x_edges)[:, None]).ravel()
    half = np.sqrt(np.clip(r * r - x * x, 0.0, None))
    rows = np.clip(np.minimum(y_edges[1:, None], half) - np.maximum(y_edges[:-1, None], -half), 0.0, None)
    return rows.reshape(len(y_edges) - 1, -1, columns).mean(axis=-1) * np.diff(x_edges)


def test_coverage_exact_cases():
    unit = np.array([-0.5, 0.5])
    assert disc_coverage(np.array([0.0, 0.71, 10.0]), unit, unit)[:, 0, 0] == pytest.approx([0.0, 1.0, 1.0])
    # a disc of radius 1 about a pixel corner: a quarter disc in each of the 4 pixels
    assert disc_coverage(np.array([1.0]), np.array([-1.0, 0.0, 1.0]), np.array([-1.0, 0.0, 1.0]))[0] \
        == pytest.approx(np.full((2, 2), np.pi / 4), abs=1e-14)
    # inscribed disc of a pixel: π/4; a pixel cut through its centre by a huge disc: ½ − 1/(24 r)
    assert disc_coverage(np.array([0.5]), unit, unit)[0, 0, 0] == pytest.approx(np.pi / 4, abs=1e-14)
    r = 1e4
    half = disc_coverage(np.array([r]), unit + r, unit)[0, 0, 0]
    assert half == pytest.approx(0.5 - 1 / (24 * r), abs=1e-9)


def test_coverage_matches_sampled_integration_pixel_by_pixel():
    edges = np.arange(-12.5, 13.0)
    for r, (sx, sy) in [(np.sqrt(150 / np.pi), (0.13, -0.41)), (7.5, (0.5, 0.0)), (3.2, (-0.27, 0.33))]:
        exact = disc_coverage(np.array([r]), edges - sx, edges - sy)[0]
        assert np.abs(exact - sampled_coverage(r, edges - sx, edges - sy)).max() < 1e-4


@settings(max_examples=60, deadline=None)
@given(st.floats(0.0, 900.0), st.floats(-0.5, 0.5), st.floats(-0.5, 0.5))
def test_coverage_is_a_fraction_summing_to_the_disc_area(area, sx, sy):
    edges = np.arange(-18.5, 19.0)
    cover = disc_coverage(np.array([np.sqrt(area / np.pi)]), edges - sx, edges - sy)[0]
    assert cover.min() >= -1e-12 and cover.max() <= 1 + 1e-12
    assert cover.sum() == pytest.approx(area, abs=1e-9)


def test_sharp_disc_interior_is_at_the_full_peak_level():
    """Exact coverage: no dimming of the interior (the light is not re-scaled to the area)."""
    sharp = CameraParams(blur_sd_px=0.0, photons_per_level=np.inf)
    for area in (150.0, 300.0):
        frame = render_frames(np.full((1, 4, 4), area), LAYOUT, sharp, None)[0].astype(float)
        for *_, patch, _, _ in windows(frame):
            assert patch.max() == sharp.peak_level and (patch == sharp.peak_level).sum() > 0.7 * area
            light = (patch - sharp.background_level).sum() / (sharp.peak_level - sharp.background_level)
            assert abs(light - area) < 0.3


def test_noise_free_frame_carries_each_area_as_light():
    areas = np.random.default_rng(0).uniform(30.0, 900.0, (3, 4, 4))
    frames = render_frames(areas, LAYOUT, CAM, None)
    assert frames.dtype == np.uint8 and frames.shape == (3, 240, 320)
    for n in range(3):
        for e, k, *_, patch, _, _ in windows(frames[n]):
            light = (patch - CAM.background_level).sum() / (CAM.peak_level - CAM.background_level)
            # only 8-bit rounding of the blurred rim remains (≤ 0.1 % of the area here)
            assert abs(light - areas[n, e, k]) < 0.3 + 1e-3 * areas[n, e, k]


def test_disc_is_centred_on_its_feeler_with_the_right_radius():
    areas = np.full((1, 4, 4), 400.0)
    sharp = CameraParams(blur_sd_px=0.0, photons_per_level=np.inf)
    frame = render_frames(areas, LAYOUT, sharp, None)[0]
    for e, k, cx, cy, patch, ix, iy in windows(frame):
        light = patch - CAM.background_level
        ys, xs = np.mgrid[: patch.shape[0], : patch.shape[1]]
        w = LAYOUT.window_px
        assert abs((light * xs).sum() / light.sum() + ix - w - cx) < 0.02
        assert abs((light * ys).sum() / light.sum() + iy - w - cy) < 0.02
        inside = patch > 0.5 * (CAM.background_level + CAM.peak_level)
        assert abs(inside.sum() - 400.0) < 0.05 * 400.0  # ≈ π r² counted in whole pixels


def test_shot_noise_is_poisson_in_photons():
    rng = np.random.default_rng(1)
    frames = render_frames(np.zeros((4, 4, 4)), LAYOUT, CAM, rng).astype(float)
    # photons ~ Poisson(bg·g): level variance bg/g, plus uniform 8-bit rounding 1/12
    assert abs(frames.mean() - CAM.background_level) < 0.01
    expected = CAM.background_level / CAM.photons_per_level + 1 / 12
    assert abs(frames.var() / expected - 1) < 0.02
    again = render_frames(np.zeros((4, 4, 4)), LAYOUT, CAM, np.random.default_rng(1))
    np.testing.assert_array_equal(again, frames.astype(np.uint8))


def test_render_validation():
    with pytest.raises(ArgumentError, match=r"shape \(n_frames, 4, 4\)"):
        render_frames(np.zeros((2, 3, 4)), LAYOUT, CAM, None)
    with pytest.raises(ArgumentError, match="finite areas"):
        render_frames(np.full((1, 4, 4), -1.0), LAYOUT, CAM, None)
    with pytest.raises(ArgumentError, match="inside the ±24 px feeler window"):
        render_frames(np.full((1, 4, 4), 1500.0), LAYOUT, CAM, None)


@pytest.mark.parametrize("kwargs, match", [
    (dict(background_level=210.0), "background_level < peak_level"),
    (dict(peak_level=255.0), "peak_level ≤ 250"),
    (dict(blur_sd_px=-1.0), "blur_sd_px"),
    (dict(photons_per_level=0.0), "photons_per_level"),
])
def test_camera_params_validation(kwargs, match):
    with pytest.raises(ArgumentError, match=match):
        CameraParams(**kwargs)
