"""The `images` fidelity end to end: U → frames → (video) → OpenCV → U, against `displacement`."""
import logging
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from feeler.errors import ArgumentError
from feeler.models.optics import (CameraParams, OpticsParams, areas_from_force, force_from_areas,
                                  force_from_displacement, load_layout, observe_areas)
from feeler.models.sensor import FIDELITIES, DisplacementNoise, observe
from feeler.simulate.images import (FramesRejected, ImagesFidelity, frames_from_displacement, observe_images,
                                    register_optical_fidelities, rejection_cause)

LAYOUT = load_layout(Path(__file__).resolve().parents[1] / "datasets-synthetic" / "layouts" / "sensor-16.toml")
P = OpticsParams()


def scans(n_scans=20, n_time=24, seed=0):
    """Plate-scan-like tip displacements (mm): a press of 0.2–0.5 mm, a 0.1 mm step half way,
    a small shear along the scan and a lateral wobble."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 1.0, n_time)
    u = np.empty((n_scans, n_time, 3))
    u[..., 1] = rng.uniform(0.2, 0.5, (n_scans, 1)) + 0.1 * (t > 0.5)
    u[..., 0] = 0.03 + 0.01 * np.sin(6 * t)
    u[..., 2] = 0.01 * np.cos(4 * t) * rng.uniform(-1, 1, (n_scans, 1))
    return u


def test_images_error_against_truth_and_the_displacement_level(capsys):
    u = scans()
    images = observe_images(u, params=P, layout=LAYOUT, rng=np.random.default_rng(1))
    areas = observe_areas(u, params=P, rng=np.random.default_rng(2))
    plain = observe(u, fidelity="displacement", params=DisplacementNoise(), rng=np.random.default_rng(3))
    rms = {name: np.sqrt(((m - u) ** 2).mean(axis=(0, 1))) * 1e3
           for name, m in (("images", images), ("areas", areas), ("displacement", plain))}
    with capsys.disabled():
        for name, value in rms.items():
            print(f"\n{name:>12}: rms error (Ux, Uy, Uz) = {np.round(value, 2)} µm", end="")
        print()
    # Bound: the camera guarantees areas within 1 % of the truth; propagated worst case,
    # |δU| ≤ |C| |K| (0.01 A) per sample, with K = ∂F/∂A. The measured error must lie inside.
    k = (force_from_areas(np.eye(4), P) - force_from_areas(np.zeros(4), P)).T  # (3, 4)
    a_true = areas_from_force(force_from_displacement(u, P.c_matrix), P)
    bound = (0.01 * a_true) @ np.abs(np.abs(P.c_matrix) @ np.abs(k)).T
    assert not np.isnan(images).any()
    assert np.all(np.abs(images - u) <= bound)
    # and it is a real measurement: not exact, not biased beyond 2 µm on U_y
    assert 0.1 < rms["images"][1] < 5.0 and abs((images - u)[..., 1].mean()) < 2e-3


def test_video_route_equals_in_memory_route(tmp_path):
    u = scans(n_scans=5, n_time=6)
    direct = observe_images(u, params=P, layout=LAYOUT, rng=np.random.default_rng(4))
    for name in ("u.avi", "seq/%05d.png"):
        via = observe_images(u, params=P, layout=LAYOUT, rng=np.random.default_rng(4),
                             video_path=tmp_path / name)
        np.testing.assert_array_equal(via, direct)


def test_packing_puts_series_on_elements_and_rest_elsewhere():
    u = scans(n_scans=18, n_time=3)  # 2 frame groups: 16 + 2 series, 14 elements at rest
    frames = frames_from_displacement(u, params=P, layout=LAYOUT, rng=np.random.default_rng(5))
    assert frames.shape == (6, 480, 640) and frames.dtype == np.uint8
    noise_free = CameraParams(photons_per_level=np.inf)
    out = observe_images(u[:, :1], params=P, layout=LAYOUT, rng=None, camera=noise_free)
    assert out.shape == (18, 1, 3) and np.abs(out - u[:, :1]).max() < 3e-3


def test_noise_free_static_video_is_not_taken_for_frozen(tmp_path):
    u = np.tile([0.01, 0.3, 0.0], (2, 4, 1))  # identical frames: legitimate without shot noise
    out = observe_images(u, params=P, layout=LAYOUT, rng=None, video_path=tmp_path / "still.avi",
                         camera=CameraParams(photons_per_level=np.inf))
    assert not np.isnan(out).any() and np.abs(out - u).max() < 3e-3


def test_bad_frames_become_nan_never_values(caplog):
    caplog.set_level(logging.INFO, logger="feeler.simulate.images")
    glare = CameraParams(peak_level=250.0, photons_per_level=0.5)  # shot noise saturates 8 bits
    out = observe_images(scans(n_scans=3, n_time=2), params=P, layout=LAYOUT,
                         rng=np.random.default_rng(6), camera=glare)
    assert out.shape == (3, 2, 3) and np.isnan(out).all()
    assert "rendered frame 1 rejected: saturated pixels" in caplog.text
    # a line per frame is detail for -v (INFO), never a warning on stderr
    assert [r.levelno for r in caplog.records] == [logging.INFO, logging.INFO]


def test_strict_reading_raises_with_every_reason_and_the_series_it_cost():
    glare = CameraParams(peak_level=250.0, photons_per_level=0.5)
    u = scans(n_scans=18, n_time=2)                 # two frame groups: series 0-15, then 16-17
    with pytest.raises(FramesRejected) as rejected:
        observe_images(u, params=P, layout=LAYOUT, rng=np.random.default_rng(6), camera=glare, strict=True)
    exc = rejected.value
    assert exc.n_frames == 4 and [i for i, _ in exc.problems] == [0, 1, 2, 3]
    assert exc.cause == "noise" and exc.series.tolist() == list(range(18))
    fine = observe_images(u, params=P, layout=LAYOUT, rng=np.random.default_rng(6), strict=True)
    assert not np.isnan(fine).any()


@pytest.mark.parametrize("reasons, cause", [
    (["a bright blob outside the feeler windows"] * 3 + ["no disc interior left to measure the peak level"], "noise"),
    (["saturated pixels in a feeler window", "2 blobs in the window of element 0 feeler 1"], "noise"),
    (["no disc interior left to measure the peak level"] * 2 + ["no disc found in the bright window of element 3 "
                                                               "feeler 0", "saturated pixels in a feeler window"],
     "small discs"),
    (["a disc reaches the edge of its feeler window"], "large discs"),
    (["cannot be decoded", "missing: the video ends after 3 of 5 frames"], "other"),
    ([], "other"),
])
def test_rejection_cause_follows_the_majority_of_reasons(reasons, cause):
    assert rejection_cause(reasons) == cause


def test_bad_displacements():
    with pytest.raises(ArgumentError, match="n_time, 3"):
        observe_images(np.zeros((4, 2)), params=P, layout=LAYOUT, rng=np.random.default_rng(0))
    with pytest.raises(ArgumentError, match="finite"):
        observe_images(np.full((1, 2, 3), np.inf), params=P, layout=LAYOUT, rng=np.random.default_rng(0))
    with pytest.raises(ArgumentError, match="measuring range"):
        observe_images(np.tile([0.0, -1.0, 0.0], (1, 2, 1)), params=P, layout=LAYOUT,
                       rng=np.random.default_rng(0))


def test_registration_into_the_sensor_interface(monkeypatch):
    monkeypatch.setitem(FIDELITIES, "areas", None)
    monkeypatch.setitem(FIDELITIES, "images", None)
    register_optical_fidelities()
    u = scans(n_scans=2, n_time=2)
    got = observe(u, fidelity="images", params=ImagesFidelity(P, LAYOUT), rng=np.random.default_rng(7))
    np.testing.assert_array_equal(got, observe_images(u, params=P, layout=LAYOUT, rng=np.random.default_rng(7)))
    got = observe(u, fidelity="areas", params=P, rng=np.random.default_rng(8))
    np.testing.assert_array_equal(got, observe_areas(u, params=P, rng=np.random.default_rng(8)))


def test_registering_stays_light():
    code = ("import sys; from feeler.simulate.images import register_optical_fidelities; "
            "register_optical_fidelities(); print('cv2' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
