"""Area extraction throughput on 640×480 frames of the 16-element sensor (issue 4 §7).

Goal ≥ 200 frames/s on one core. Reported as a ratio to ``cv2.threshold`` alone on the
same frames, timed in the same run: throughput(extract) / throughput(threshold); the
frames per second are attached to the benchmark's JSON (``extra_info``) for the record.
"""
from pathlib import Path

import cv2
import numpy as np
import pytest

from _ratios import best_seconds, record_ratio
from feeler.hardware.camera import AreaExtractor
from feeler.models.optics import CameraParams, load_layout, render_frames

LAYOUT = load_layout(Path(__file__).resolve().parents[1] / "datasets-synthetic" / "layouts" / "sensor-16.toml")


@pytest.fixture(scope="module")
def frames():
    rng = np.random.default_rng(0)
    return render_frames(rng.uniform(100.0, 900.0, (50, 16, 4)), LAYOUT, CameraParams(), rng)


@pytest.fixture(autouse=True)
def one_core():
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
    print(f"\narea extraction: {fps:.0f} frames/s on one core (goal >= 200); "
          f"cv2.threshold alone: {len(frames) / baseline:.0f} frames/s")
    record_ratio(benchmark, "throughput / cv2.threshold", baseline / benchmark.stats["min"],
                 f">= {200 * baseline / len(frames):.3f} (= 200 frames/s)")
