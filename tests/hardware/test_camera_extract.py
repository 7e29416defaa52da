"""Area extraction: every reason a frame is rejected, and empty (dark) windows."""
import cv2
import numpy as np
import pytest

from feeler.hardware.camera import AreaExtractor
from feeler.models.optics import CameraParams, grid_layout, render_frames

LAYOUT = grid_layout(2, 2, width_px=320, height_px=240)
CAM = CameraParams()


@pytest.fixture(scope="module")
def frame():
    areas = np.full((1, 4, 4), 300.0)
    return render_frames(areas, LAYOUT, CAM, np.random.default_rng(3))[0]


def centre(e, k):
    cx, cy = LAYOUT.elements[e].feelers[k]
    return int(round(cx)), int(round(cy))


def test_clean_frame_is_accepted(frame):
    areas, problem = AreaExtractor(LAYOUT)(frame)
    assert problem is None and np.abs(areas / 300.0 - 1).max() < 0.01


def test_blob_outside_the_windows(frame):
    bad = frame.copy()
    cv2.circle(bad, (80, 60), 5, 200, -1)  # the middle of element 0, between its feelers
    assert AreaExtractor(LAYOUT)(bad)[1] == "a bright blob outside the feeler windows"


def test_two_blobs_in_one_window(frame):
    bad = frame.copy()
    x, y = centre(1, 2)
    cv2.circle(bad, (x + 16, y + 16), 3, 200, -1)
    areas, problem = AreaExtractor(LAYOUT)(bad)
    assert problem == "2 blobs in the window of element 1 feeler 2" and np.isnan(areas).all()


def test_disc_reaching_the_window_edge(frame):
    bad = frame.copy()
    x, y = centre(2, 0)
    cv2.circle(bad, (x, y), 21, 200, -1)
    assert AreaExtractor(LAYOUT)(bad)[1] == "a disc reaches the edge of its feeler window"


def test_saturated_window(frame):
    bad = frame.copy()
    x, y = centre(3, 3)
    bad[y, x] = 255
    assert AreaExtractor(LAYOUT)(bad)[1] == "saturated pixels in a feeler window"


def test_no_disc_interior_for_the_peak_level():
    tiny = render_frames(np.full((1, 4, 4), 30.0), LAYOUT, CAM, np.random.default_rng(4))[0]
    assert AreaExtractor(LAYOUT)(tiny)[1] == "no disc interior left to measure the peak level"
    # with known levels the same frame is measured (small discs, absolute error < 1 px²)
    areas, problem = AreaExtractor(LAYOUT, levels=(CAM.background_level, CAM.peak_level))(tiny)
    assert problem is None and np.abs(areas - 30.0).max() < 1.0


def test_dark_window_reads_zero_and_a_bright_one_is_rejected():
    areas = np.full((1, 4, 4), 300.0)
    areas[0, 1, 3] = 0.0
    dark = render_frames(areas, LAYOUT, CAM, np.random.default_rng(5))[0]
    found, problem = AreaExtractor(LAYOUT)(dark)
    assert problem is None and found[1, 3] == 0.0 and np.abs(found[0] / 300 - 1).max() < 0.01
    glow = dark.copy()
    x, y = centre(1, 3)
    w = LAYOUT.window_px
    glow[y - w + 2: y + w - 1, x - w + 2: x + w - 1] += 30  # diffuse light below the threshold
    assert AreaExtractor(LAYOUT)(glow)[1] == "no disc found in the bright window of element 1 feeler 3"
