"""Rendered camera frames: conserved light, disc placement, shot-noise statistics, validation."""
import numpy as np
import pytest

from feeler.errors import ArgumentError
from feeler.models.optics import CameraParams, grid_layout, render_frames

LAYOUT = grid_layout(2, 2, width_px=320, height_px=240)
CAM = CameraParams()


def windows(frame, layout=LAYOUT):
    w = layout.window_px
    for e, element in enumerate(layout.elements):
        for k, (cx, cy) in enumerate(element.feelers):
            ix, iy = int(round(cx)), int(round(cy))
            yield e, k, cx, cy, frame[iy - w: iy + w + 1, ix - w: ix + w + 1].astype(float), ix, iy


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
