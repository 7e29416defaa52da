"""Area extraction throughput on 640×480 frames of the 16-element sensor (issue 4 §7).

Goal ≥ 200 frames/s on one core. Reported as a ratio to ``cv2.threshold`` alone on the
same frames, timed in the same run: throughput(extract) / throughput(threshold), as a
median with its spread idle and with two busy loops (``_ratios``), the best-of ratio
beside it; frames per second (median) go to the benchmark's JSON (``extra_info``).

OpenCV's own threads (issue 18 §3): :func:`test_opencv_threads_under_load` times the
extractor with OpenCV's default thread count against one thread, interleaved, idle
and loaded (goal ≤ 2 under load: no thread cliff on the camera path).
"""
from pathlib import Path

import cv2
import numpy as np
import pytest

from _ratios import LOADS, Timed, best_seconds, busy_loops, record_median_ratio, record_ratio
from feeler.hardware.camera import AreaExtractor
from feeler.models.optics import CameraParams, load_layout, render_frames

LAYOUT = load_layout(Path(__file__).resolve().parents[1] / "datasets-synthetic" / "layouts" / "sensor-16.toml")


@pytest.fixture(scope="module")
def frames():
    rng = np.random.default_rng(0)
    return render_frames(rng.uniform(100.0, 900.0, (50, 16, 4)), LAYOUT, CameraParams(), rng)


@pytest.fixture(scope="module")
def default_threads():
    return cv2.getNumThreads()


@pytest.fixture(autouse=True)
def one_core(default_threads):
    before = cv2.getNumThreads()
    cv2.setNumThreads(1)
    yield
    cv2.setNumThreads(before)


def test_extraction_vs_threshold(benchmark, frames):
    extract = AreaExtractor(LAYOUT)

    def extract_all():
        for frame in frames:
            extract(frame)

    def threshold_all():
        for frame in frames:
            cv2.threshold(frame, 0, 255, cv2.THRESH_BINARY | cv2.THRESH_OTSU)

    baseline = best_seconds(threshold_all, repeat=10)
    benchmark.pedantic(extract_all, rounds=5, iterations=1)
    fps = len(frames) / benchmark.stats["min"]
    benchmark.extra_info["frames_per_s"] = fps
    print(f"\narea extraction: {fps:.0f} frames/s on one core (goal >= 200, best of 5); "
          f"cv2.threshold alone: {len(frames) / baseline:.0f} frames/s")
    goal = f">= {200 * baseline / len(frames):.3f} (= 200 frames/s)"
    record_ratio(benchmark, "throughput / cv2.threshold", baseline / benchmark.stats["min"], goal)
    for load, n in LOADS.items():
        with busy_loops(n):
            timed = Timed.interleaved(extract_all, threshold_all, rounds=8)
        record_median_ratio(benchmark, "throughput / cv2.threshold", timed, goal, load=load)
        benchmark.extra_info[f"frames_per_s [{load}]: median"] = len(frames) / float(np.median(timed.call))


def test_opencv_threads_under_load(benchmark, frames, default_threads):
    """The extractor with OpenCV's default threads against one thread (goal ≤ 2 loaded)."""
    extract = AreaExtractor(LAYOUT)

    def with_threads(k):
        def run():
            cv2.setNumThreads(k)
            for frame in frames[:20]:
                extract(frame)
        return run

    default, one = with_threads(default_threads), with_threads(1)
    benchmark.extra_info["opencv_default_threads"] = default_threads
    benchmark.pedantic(default, rounds=3, iterations=1)
    for load, n in LOADS.items():
        with busy_loops(n):
            t = Timed.rotated({"default": default, "one": one}, 10)
        record_median_ratio(benchmark, f"time with OpenCV's {default_threads} threads / one thread",
                            Timed(call=t["default"], base=t["one"]), "<= 2" if n or load != "idle" else "informational",
                            load=load, invert=True)
