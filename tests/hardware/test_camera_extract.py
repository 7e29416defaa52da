"""Area extraction: every reason a frame is rejected, and empty (dark) windows."""
import cv2
import numpy as np
import pytest

from feeler.hardware.camera import AreaExtractor
from feeler.hardware.camera.extract import _masked_mean
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


@pytest.mark.parametrize("blur_sd_px", [0.8, 1.125, 1.2, 2.0])   # 1.125: depth 5.0, a tie at an integer distance
def test_interior_and_levels_equal_the_distance_transform_and_masked_means(blur_sd_px):
    """The extractor's disc interior (an erosion by the Euclidean disc) is exactly the set
    of pixels whose precise distance transform reaches the depth, and its masked means
    equal ``cv2.mean`` — on discs of many sizes, with noise, and on random masks."""
    rng = np.random.default_rng(11)
    ex = AreaExtractor(LAYOUT, blur_sd_px=blur_sd_px)
    cam = CameraParams(blur_sd_px=blur_sd_px)
    for area in (40.0, 150.0, 300.0, 600.0):
        f = render_frames(np.full((1, 4, 4), area), LAYOUT, cam, rng)[0]
        _, binary = cv2.threshold(f, 0, 255, cv2.THRESH_BINARY | cv2.THRESH_OTSU)
        depth = cv2.distanceTransform(binary, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
        ours = cv2.erode(binary, ex._interior_disc) > 0
        np.testing.assert_array_equal(ours, depth >= ex._depth_px)
        mask = np.where(rng.random(f.shape) < 0.3, 255, 0).astype(np.uint8)
        assert _masked_mean(f, mask, cv2.countNonZero(mask)) == pytest.approx(cv2.mean(f, mask=mask)[0], rel=1e-12)
        assert _masked_mean(f, ex._outside, ex._n_outside) == pytest.approx(cv2.mean(f, mask=ex._outside)[0],
                                                                            rel=1e-12)


def test_integral_in_int32_is_exact_up_to_a_saturated_full_frame():
    """The window sums' integral images are int32: exact while 255 × the pixel count fits,
    checked on the worst case (a white 640×480 frame) against float64."""
    from feeler.hardware.camera.extract import _integral

    rng = np.random.default_rng(5)
    for img in (np.full((480, 640), 255, np.uint8), rng.integers(0, 256, (480, 640), dtype=np.uint8)):
        work = np.empty((481, 641), np.int32)
        ours = _integral(img, work)
        assert ours.dtype == np.int32 and np.shares_memory(ours, work)
        np.testing.assert_array_equal(ours, cv2.integral(img, sdepth=cv2.CV_64F))


def test_one_extractor_shared_by_threads_gives_every_frame_its_own_result():
    """The extractor keeps its work images per thread: four threads reading the same
    frames in different orders (rejected frames among them) each get exactly the result a
    fresh extractor gives that frame alone."""
    from concurrent.futures import ThreadPoolExecutor

    rng = np.random.default_rng(8)
    frames = list(render_frames(rng.uniform(120.0, 500.0, (12, 4, 4)), LAYOUT, CAM, rng))
    bad = frames[3].copy()
    x, y = centre(0, 0)
    bad[y - 2: y + 3, x - 40: x - 35] = 250                               # a blob between the windows
    frames.append(bad)
    alone = [AreaExtractor(LAYOUT)(f) for f in frames]
    assert alone[-1][1] is not None and all(p is None for _, p in alone[:-1])
    shared = AreaExtractor(LAYOUT)

    def read_all(order):
        return order, [shared(frames[i]) for i in order]

    orders = [rng.permutation(len(frames)) for _ in range(4)]
    with ThreadPoolExecutor(4) as pool:
        for order, results in pool.map(read_all, orders * 3):
            for i, (areas, problem) in zip(order, results):
                assert problem == alone[i][1]
                np.testing.assert_array_equal(areas, alone[i][0])
