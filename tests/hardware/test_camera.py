"""The camera reading chain: sources, area extraction accuracy, bad frames, bad input."""
import logging
import os
import warnings
from pathlib import Path

import cv2
import numpy as np
import pytest

from feeler.errors import ArgumentError, DataFileError
from feeler.hardware.camera import AreaExtractor, FrameReader, open_source, read_source, write_video
from feeler.hardware.camera.source import LossyVideoWarning, lossy_codec
from feeler.models.optics import CameraParams, OpticsParams, load_layout, render_frames

ROOT = Path(__file__).resolve().parents[2]
LAYOUT = load_layout(ROOT / "datasets-synthetic" / "layouts" / "sensor-16.toml")
CAM = CameraParams()
P = OpticsParams()


@pytest.fixture(scope="module")
def rendered():
    """12 frames of the 16-element sensor with areas over the working range 100–900 px²."""
    rng = np.random.default_rng(2024)
    areas = rng.uniform(100.0, 900.0, (12, 16, 4))
    return areas, render_frames(areas, LAYOUT, CAM, rng)


@pytest.mark.slow
@pytest.mark.parametrize("levels", [None, (CAM.background_level, CAM.peak_level)])
def test_areas_within_one_percent_of_rendered_truth(levels):
    # 12 frames (768 areas) in `make test`; FEELER_FULL=1: 300 frames (19 200 areas)
    n_frames = 300 if os.environ.get("FEELER_FULL") == "1" else 12
    rng = np.random.default_rng(2025)
    areas = rng.uniform(100.0, 900.0, (n_frames, 16, 4))
    frames = render_frames(areas, LAYOUT, CAM, rng)
    extract = AreaExtractor(LAYOUT, blur_sd_px=CAM.blur_sd_px, levels=levels)
    found = []
    for frame in frames:
        got, problem = extract(frame)
        assert problem is None
        found.append(got)
    rel = np.array(found) / areas - 1
    print(f"{areas.size} areas, levels={levels}: max |rel err| {np.abs(rel).max():.4f}, mean {rel.mean():+.5f}")
    assert np.abs(rel).max() < 0.01
    assert abs(rel.mean()) < 0.001  # no bias beyond 0.1 %: sub-pixel sum keeps the blur tails


def test_video_round_trip_is_lossless(tmp_path, rendered):
    areas, frames = rendered
    path = write_video(frames, tmp_path / "scan.avi", fps=25)
    cap = cv2.VideoCapture(str(path))
    ok, first = cap.read()
    cap.release()
    assert ok and np.array_equal(cv2.cvtColor(first, cv2.COLOR_BGR2GRAY), frames[0])
    reading = read_source(path, LAYOUT, P)
    extract = AreaExtractor(LAYOUT)
    expected = np.array([extract(f)[0] for f in frames])
    assert reading.bad == () and reading.n_frames == 12
    np.testing.assert_array_equal(reading.index, np.arange(12))
    np.testing.assert_array_equal(reading.areas_px2, expected)
    np.testing.assert_allclose(reading.u_mm, reading.force_n @ P.c_matrix.T)


def test_image_sequence_with_a_corrupt_file(tmp_path, rendered, caplog):
    _, frames = rendered
    pattern = str(tmp_path / "frames" / "%05d.png")
    write_video(frames[:5], pattern)
    assert open_source(pattern).isOpened()
    (tmp_path / "frames" / "00002.png").write_bytes(b"\x89PNG broken")
    with caplog.at_level(logging.WARNING):
        reading = read_source(pattern, LAYOUT, P)
    assert reading.n_frames == 5 and [i for i, _ in reading.bad] == [2]
    np.testing.assert_array_equal(reading.index, [0, 1, 3, 4])
    assert "frame 2 rejected: cannot be decoded" in caplog.text


def test_truncated_video_keeps_readable_frames_and_counts_the_rest(tmp_path, rendered, caplog):
    areas, frames = rendered
    path = write_video(frames, tmp_path / "scan.avi")
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with caplog.at_level(logging.WARNING):
        reading = read_source(path, LAYOUT, P)
    n_good = len(reading.index)
    assert 0 < n_good < 12 and reading.n_frames == 12 and len(reading.bad) == 12 - n_good
    assert all("truncated" in reason for _, reason in reading.bad)
    assert np.abs(reading.areas_px2 / areas[reading.index] - 1).max() < 0.01
    assert f"{12 - n_good} of 12 frames bad" in caplog.text


@pytest.mark.parametrize("n_bytes, reason", [(16, "identical to the previous frame"), (3000, "truncated")])
def test_corrupt_video_frames_are_rejected_not_used(tmp_path, rendered, n_bytes, reason, capfd):
    # 16 garbled bytes: FFmpeg conceals the slice from the previous frame and reports success;
    # 3000: the decoder gives up. Either way no corrupted frame may reach the areas.
    areas, frames = rendered
    path = write_video(frames, tmp_path / "scan.avi")
    data = bytearray(path.read_bytes())
    start = len(data) // 2
    data[start: start + n_bytes] = np.random.default_rng(5).integers(0, 256, n_bytes, dtype=np.uint8).tobytes()
    path.write_bytes(bytes(data))
    reading = read_source(path, LAYOUT, P)
    assert len(reading.bad) >= 1 and reading.n_frames == 12
    assert len(reading.index) + len(reading.bad) == 12
    assert all(reason in why for _, why in reading.bad)
    assert np.abs(reading.areas_px2 / areas[reading.index] - 1).max() < 0.01
    # libav's own lines ('[ffv1 @ 0x55...] slice CRC mismatch') stay off the terminal: the
    # bad frames are feeler's to name (file descriptors: libav writes to fd 2 itself)
    assert " @ 0x" not in capfd.readouterr().err


def test_frozen_tiles(tmp_path, rendered):
    frames = rendered[1]
    pattern = str(tmp_path / "seq" / "%05d.png")
    write_video(np.stack([frames[0], frames[0], frames[1]]), pattern)
    reader = FrameReader(pattern)
    assert [i for i, _ in reader] == [0, 2] and "column 0, row 0 is identical" in reader.bad[0][1]
    assert [i for i, _ in FrameReader(pattern, reject_frozen=False)] == [0, 1, 2]
    black = str(tmp_path / "black" / "%05d.png")
    write_video(np.zeros((3, 32, 48), np.uint8), black)  # uniform tiles may repeat
    assert [i for i, _ in FrameReader(black)] == [0, 1, 2]


def _encode(frames, path, fourcc):
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*fourcc), 10.0, frames.shape[2:0:-1], isColor=False)
    assert writer.isOpened(), fourcc
    for frame in frames:
        writer.write(frame)
    writer.release()
    return path


@pytest.fixture(scope="module")
def still_scan():
    """A scan as a camera sees it: 4 elements pressed slowly, 12 unchanged, shot noise on all."""
    rng = np.random.default_rng(5)
    areas = np.repeat(rng.uniform(200.0, 800.0, (1, 16, 4)), 12, axis=0)
    areas[:, :4] += np.linspace(0.0, 150.0, 12)[:, None, None]
    return areas, render_frames(areas, LAYOUT, CAM, rng)


@pytest.mark.parametrize("fourcc, suffix", [("mp4v", ".mp4"), ("MJPG", ".avi"), ("XVID", ".avi")])
def test_a_lossy_video_is_read_whole_with_one_warning(tmp_path, still_scan, fourcc, suffix):
    """A lossy encoder repeats the unchanged elements' tiles exactly: 10-11 of these 12 frames
    were rejected as frozen ('decoder concealment or a stuck camera'). A lossy source is
    read with that check off and says so in one warning; FFV1 keeps the check."""
    areas, frames = still_scan
    path = _encode(frames, tmp_path / f"scan{suffix}", fourcc)
    with pytest.warns(LossyVideoWarning, match=r"scan\.\w+: recorded in a lossy codec \(\w+\)") as seen:
        reading = read_source(path, LAYOUT, P)
    assert len(seen) == 1 and reading.bad == () and reading.n_frames == 12
    assert np.abs(reading.areas_px2 / areas - 1).max() < 0.05       # the frames' content, with its compression error
    with pytest.warns(LossyVideoWarning):
        assert [i for i, _ in FrameReader(path)] == list(range(12))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        lossless = FrameReader(write_video(np.stack([frames[0], frames[0], frames[1]]), tmp_path / "ffv1.avi"))
        assert lossless.codec is None and [i for i, _ in lossless] == [0, 2]


def test_jpeg_images_are_lossy_png_images_are_not(tmp_path, still_scan):
    frames = still_scan[1][:3]
    jpeg, png = str(tmp_path / "j" / "%03d.jpg"), str(tmp_path / "p" / "%03d.png")
    write_video(frames, jpeg)
    write_video(frames, png)
    with pytest.warns(LossyVideoWarning, match="JPG images"):
        assert FrameReader(jpeg).codec == "JPG images"
    assert lossy_codec(png) is None


def test_source_errors_name_the_source(tmp_path):
    with pytest.raises(DataFileError, match=r"^camera 97: no camera device"):
        open_source(97)
    with pytest.raises(DataFileError, match="no such video file"):
        open_source(tmp_path / "absent.avi")
    junk = tmp_path / "junk.avi"
    junk.write_bytes(np.random.default_rng(0).integers(0, 256, 5000, dtype=np.uint8).tobytes())
    with pytest.raises(DataFileError, match="junk.avi: cannot be opened"):
        open_source(junk)
    with pytest.raises(DataFileError, match="no files matching"):
        open_source(str(tmp_path / "none" / "%05d.png"))
    with pytest.raises(DataFileError, match="no files matching"):
        FrameReader(str(tmp_path / "none" / "%05d.png"))


def test_frames_of_the_wrong_size(tmp_path, rendered):
    _, frames = rendered
    small = write_video(frames[:3, :240, :320].copy(), tmp_path / "small.avi")
    with pytest.raises(DataFileError, match=r"small.avi: frames are 320×240 px, the layout needs 640×480"):
        read_source(small, LAYOUT, P)
    pattern = str(tmp_path / "seq" / "%05d.png")
    write_video(frames[:3], pattern)
    cv2.imwrite(pattern % 1, frames[1, :100, :100])
    reader = FrameReader(pattern, size=(640, 480))
    assert [i for i, _ in reader] == [0, 2]
    assert reader.bad == [(1, "size 100×100 px instead of 640×480")]


def test_write_video_bad_input(tmp_path):
    with pytest.raises(ArgumentError, match="uint8"):
        write_video(np.zeros((2, 8, 8)), tmp_path / "x.avi")
    with pytest.raises(ArgumentError, match=r"\.avi or \.mkv"):
        write_video(np.zeros((2, 8, 8), np.uint8), tmp_path / "x.mp4")
    with pytest.raises(DataFileError, match="cannot write image"):
        write_video(np.zeros((1, 8, 8), np.uint8), str(tmp_path / "x" / "%05d.nosuchext"))


def test_read_source_rejects_a_bad_matrix(tmp_path, rendered):
    path = write_video(rendered[1][:2], tmp_path / "two.avi")
    with pytest.raises(ArgumentError, match="3×3"):
        read_source(path, LAYOUT, P, c_mm_per_n=np.eye(2))
    reading = read_source(path, LAYOUT, P, c_mm_per_n=2 * np.eye(3), max_frames=1)
    assert len(reading.index) == 1
    np.testing.assert_allclose(reading.u_mm, 2 * reading.force_n)
