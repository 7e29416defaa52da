"""four-plates and sensor-calibration at the optical fidelities: the [optics] table, the
simulated datasets, and the M1 / M2 fits on them (small sizes)."""
from __future__ import annotations

import logging
import re
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from feeler.datasets import read_scans
from feeler.errors import SceneError
from feeler.scene import load_scene
from feeler.simulate import run_simulation

SHIPPED = Path(__file__).parents[1] / "datasets-synthetic"
FOUR_IMAGES = SHIPPED / "four-plates-images.toml"
CAL_IMAGES = SHIPPED / "sensor-calibration-images.toml"


def variant(src: Path, tmp_path: Path, name: str = "scene.toml", copy_layouts: bool = True, **replace) -> Path:
    text = src.read_text()
    for old, new in replace.items():
        assert old in text, old
        text = text.replace(old, new)
    if copy_layouts:
        (tmp_path / "layouts").mkdir(exist_ok=True)
        (tmp_path / "layouts" / "sensor-16.toml").write_bytes((SHIPPED / "layouts" / "sensor-16.toml").read_bytes())
    path = tmp_path / name
    path.write_text(text)
    return path


@pytest.mark.parametrize("src, replace, key", [
    (FOUR_IMAGES, {'fidelity = "images"': 'fidelity = "displacement"'}, "optics: only used when sensor.fidelity"),
    (CAL_IMAGES, {'fidelity = "images"': 'fidelity = "displacement"'}, "optics: only used when sensor.fidelity"),
    (FOUR_IMAGES, {'layout = "layouts/sensor-16.toml"': 'c_mm_per_n = [[1.0, 0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]]'},
     "optics.c_mm_per_n: must be 3 rows of 3"),
    (FOUR_IMAGES, {'layout = "layouts/sensor-16.toml"': 'c_mm_per_n = [[1.0, 0.0], [0.0, 1.0], [0.0, 0.0]]'},
     "optics.c_mm_per_n[0]: needs at least 3 items"),
    (CAL_IMAGES, {'layout = "layouts/sensor-16.toml"': 'c_mm_per_n = [[1, 2, 3], [2, 4, 6], [0, 0, 1]]'},
     "optics.c_mm_per_n: must be invertible"),
    (FOUR_IMAGES, {"rest_area_px2 = 150.0": "rest_area_px2 = 0.0"}, "optics.rest_area_px2"),
    (CAL_IMAGES, {'fidelity = "images"': 'fidelity = "camera"'}, "sensor.fidelity"),
])
def test_optics_table_is_validated(tmp_path, src, replace, key):
    with pytest.raises(SceneError, match=re.escape(key)):
        load_scene(variant(src, tmp_path, **replace))


def test_missing_layout_file_names_the_key(tmp_path):
    path = variant(CAL_IMAGES, tmp_path, copy_layouts=False)
    with pytest.raises(SceneError, match=r"optics\.layout: 'layouts/sensor-16\.toml': no such layout file"):
        run_simulation(path, tmp_path / "run")


def test_images_calibration_reads_forces_close_to_the_truth_and_video_changes_nothing(tmp_path):
    import json

    mem = run_simulation(CAL_IMAGES, tmp_path / "mem")
    vid = run_simulation(variant(CAL_IMAGES, tmp_path, **{"photons_per_level = 40.0":
                                                          "photons_per_level = 40.0\nvideo = true"}), tmp_path / "vid")
    assert (vid / "sensor.avi").stat().st_size > 0 and not (mem / "sensor.avi").exists()
    a, b = pd.read_csv(mem / "calibration.csv"), pd.read_csv(vid / "calibration.csv")
    pd.testing.assert_frame_equal(a, b)                           # lossless video: same frames, same areas
    truth = json.loads((mem / "truth.json").read_text())
    f_true = np.asarray(truth["u_true_mm"]) @ np.asarray(truth["K_n_per_mm"]).T
    err = a[["fx_n", "fy_n", "fz_n"]].to_numpy() - f_true
    assert np.abs(err).max() < 0.02 and np.abs(err).max() > 0    # the reader's error, well below f_sd_n


def test_m1_fit_on_the_images_calibration_recovers_c(tmp_path):
    from feeler.calib.matrix import MatrixPrior, fit_matrix, read_calibration_csv

    run = run_simulation(CAL_IMAGES, tmp_path / "run")
    scene = load_scene(CAL_IMAGES)
    prior = MatrixPrior(c0_mm_per_n=scene.prior.c0_mm_per_n, rel_sd=scene.prior.rel_sd,
                        sigma_f_scale_n=scene.prior.sigma_f_scale_n)
    result = fit_matrix(read_calibration_csv(run / "calibration.csv"), prior, backend="exact",
                        rng=np.random.default_rng(1), chains=2, draws=500)
    c_mean = result.posterior["posterior"]["C"].mean(("chain", "draw")).values
    np.testing.assert_allclose(c_mean, scene.sensor.c_mm_per_n, atol=0.004)
    assert result.verdict.ok


def test_four_plates_at_images_is_a_dataset_and_m2_fits_it(tmp_path):
    from feeler.calib.neuron import data_from_scans, fit_neuron

    small = variant(FOUR_IMAGES, tmp_path, **{"scans_per_plate = 8": "scans_per_plate = 4"})
    disp = variant(FOUR_IMAGES, tmp_path, "disp.toml", **{"scans_per_plate = 8": "scans_per_plate = 4",
                                                         'fidelity = "images"': 'fidelity = "displacement"'})
    disp.write_text(disp.read_text()[: disp.read_text().index("[optics]")])
    img, ref = read_scans(run_simulation(small, tmp_path / "img")), read_scans(run_simulation(disp, tmp_path / "disp"))
    np.testing.assert_array_equal(img.t_s, ref.t_s)
    np.testing.assert_array_equal(img.x_mm, ref.x_mm)                  # same touches, same seed
    d = img.uy_mm - ref.uy_mm                                          # images noise vs 2 um displacement noise
    assert abs(d.mean()) < 0.002 and 0.001 < d.std() < 0.004
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = fit_neuron(data_from_scans(img, length_mm=3.0), backend="grid", chains=2, draws=200)
    attrs = result.posterior["posterior"].attrs
    assert attrs["ppc_coverage90"] >= 0.8 and np.isfinite(result.summary["mean"]).all()


def test_areas_fidelity_needs_no_opencv_and_reads_close_to_the_truth(tmp_path):
    import subprocess
    import sys

    scene = variant(FOUR_IMAGES, tmp_path, **{'fidelity = "images"': 'fidelity = "areas"',
                                              "scans_per_plate = 8": "scans_per_plate = 2"})
    code = ("import sys; from feeler.simulate import run_simulation; "
            f"run_simulation({str(scene)!r}, {str(tmp_path / 'run')!r}); "
            "print(sorted(m for m in ('cv2', 'pymc') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
    disp = variant(FOUR_IMAGES, tmp_path, "disp.toml", **{'fidelity = "images"': 'fidelity = "displacement"',
                                                         "scans_per_plate = 8": "scans_per_plate = 2"})
    disp.write_text(disp.read_text()[: disp.read_text().index("[optics]")])
    a, d = read_scans(tmp_path / "run"), read_scans(run_simulation(disp, tmp_path / "disp"))
    np.testing.assert_array_equal(a.x_mm, d.x_mm)
    assert 0.001 < np.std(a.uy_mm - d.uy_mm) < 0.004 and not np.array_equal(a.uy_mm, d.uy_mm)


# --- scenes whose rendered frames the camera could not read: refused at load, naming the key ---

FOUR_OPTICS = {"blur": "blur_sd_px = 1.2", "rest": "rest_area_px2 = 150.0", "photons": "photons_per_level = 40.0",
               "press": "uy0_mean_mm = 0.05", "heights": "heights_mm = [0.0, 0.05, 0.1, 0.2]"}
CAL_DESIGN = {"presses": "normal_presses_mm = [0.05, 0.10, 0.15, 0.20, 0.25]",
              "offsets": "shear_offsets_mm = [-0.10, -0.05, 0.05, 0.10]", "preload": "shear_preload_mm = 0.15",
              "blur": "blur_sd_px = 1.2", "rest": "rest_area_px2 = 150.0"}
_LIMIT = re.compile(r"(?:at most|at least|up to ±?)\s*([0-9.]+)")


@pytest.mark.parametrize("src, old, value, key, fmt", [
    # the audit's scenes: each used to fail after rendering on areas_px2 (or 82 frame warnings)
    (FOUR_IMAGES, FOUR_OPTICS["blur"], "10.0", "optics.blur_sd_px", "blur_sd_px = {}"),
    (FOUR_IMAGES, FOUR_OPTICS["rest"], "9000.0", "optics.rest_area_px2", "rest_area_px2 = {}"),
    (FOUR_IMAGES, FOUR_OPTICS["press"], "3.0", "probe.uy0_mean_mm", "uy0_mean_mm = {}"),
    (FOUR_IMAGES, FOUR_OPTICS["heights"], "[0.0, 2.0, 4.0, 5.0]", "surface.heights_mm", "heights_mm = [0.0, {}]"),
    (FOUR_IMAGES, FOUR_OPTICS["rest"], "1.0", "optics.rest_area_px2", "rest_area_px2 = {}"),
    (FOUR_IMAGES, FOUR_OPTICS["photons"], "0.001", "optics.photons_per_level", "photons_per_level = {}"),
    (FOUR_IMAGES, FOUR_OPTICS["photons"], "1.5", "optics.photons_per_level", "photons_per_level = {}"),
    (CAL_IMAGES, CAL_DESIGN["presses"], "[0.05, 0.10, 0.15, 0.20, 2.0]", "design.normal_presses_mm",
     "normal_presses_mm = [{}]"),
    (CAL_IMAGES, CAL_DESIGN["offsets"], "[-2.0, -0.05, 0.05, 2.0]", "design.shear_offsets_mm",
     "shear_offsets_mm = [-{0}, {0}]"),
    (CAL_IMAGES, CAL_DESIGN["preload"], "1.5", "design.shear_preload_mm", "shear_preload_mm = {}"),
    (CAL_IMAGES, CAL_DESIGN["blur"], "10.0", "optics.blur_sd_px", "blur_sd_px = {}"),
    (CAL_IMAGES, CAL_DESIGN["rest"], "900.0", "optics.rest_area_px2", "rest_area_px2 = {}"),
    (CAL_IMAGES, CAL_DESIGN["rest"], "20.0", "optics.rest_area_px2", "rest_area_px2 = {}"),
])
def test_unreadable_frames_are_refused_at_load_naming_the_key_and_a_limit_that_loads(tmp_path, src, old, value,
                                                                                    key, fmt):
    name = old.split(" = ")[0]
    with pytest.raises(SceneError) as refused:
        load_scene(variant(src, tmp_path, **{old: f"{name} = {value}"}))
    message = str(refused.value)
    assert f": {key}: " in message and "\n" not in message and "areas_px2" not in message, message
    limit = _LIMIT.findall(message)[-1].rstrip(".")
    load_scene(variant(src, tmp_path, "fixed.toml", **{old: fmt.format(limit)}))     # the limit named holds


def test_shipped_images_scenes_and_their_nominal_optics_load():
    for path in (FOUR_IMAGES, CAL_IMAGES):
        assert load_scene(path).optics.blur_sd_px == 1.2


def test_a_refused_simulate_is_one_line_exit_2_and_leaves_no_directory(tmp_path, capsys):
    from feeler.cli import main

    scene = variant(FOUR_IMAGES, tmp_path, **{FOUR_OPTICS["blur"]: "blur_sd_px = 10.0"})
    assert main(["simulate", str(scene), "--out", str(tmp_path / "run"), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "optics.blur_sd_px: 10: " in err[0] and "at most" in err[0], err
    assert not (tmp_path / "run").exists()


def _past_the_load_checks(monkeypatch):
    import feeler.scenes._frames as frames

    monkeypatch.setattr(frames, "check_frames", lambda *args, **kw: None)
    monkeypatch.setattr(frames, "check_photons", lambda *args, **kw: None)


@pytest.mark.parametrize("old, new, key, cause, advice", [
    (FOUR_OPTICS["photons"], "photons_per_level = 0.001", "optics.photons_per_level", "shot noise",
     "raise photons_per_level"),
    (FOUR_OPTICS["rest"], "rest_area_px2 = 1.0", "optics.rest_area_px2", "too small for the blur",
     "raise rest_area_px2"),
])
def test_frames_rejected_at_run_time_are_one_line_naming_what_is_at_fault(tmp_path, monkeypatch, caplog,
                                                                          old, new, key, cause, advice):
    _past_the_load_checks(monkeypatch)
    scene = variant(FOUR_IMAGES, tmp_path, **{old: new, "scans_per_plate = 8": "scans_per_plate = 1"})
    with pytest.raises(SceneError) as refused:
        run_simulation(scene, tmp_path / "run", progress=False)
    message = str(refused.value)
    assert f": {key}: " in message and cause in message and advice in message, message
    assert "see the log" not in message and "lower blur_sd_px or the noise" not in message
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]      # per-frame lines: -v only
    assert not (tmp_path / "run").exists()


def test_frames_rejected_in_a_video_keep_their_lines_at_info(tmp_path, monkeypatch, caplog):
    _past_the_load_checks(monkeypatch)
    caplog.set_level(logging.INFO)
    scene = variant(FOUR_IMAGES, tmp_path, **{FOUR_OPTICS["photons"]: "photons_per_level = 0.001\nvideo = true",
                                              "scans_per_plate = 8": "scans_per_plate = 1", "video = false": ""})
    with pytest.raises(SceneError, match=r"optics\.photons_per_level: 0\.001: shot noise"):
        run_simulation(scene, tmp_path / "run", progress=False)
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING]
    assert any("frame 0 rejected" in r.getMessage() and r.levelno == logging.INFO for r in caplog.records)
    assert not (tmp_path / "run").exists()


def test_a_blur_refusal_names_both_limits_it_quotes(tmp_path):
    """The message explained the blur's reach past the largest disc but quoted the lighter
    limit of the lightest touch's interior (1.43 px where the reach alone allows 3.25 px)."""
    with pytest.raises(SceneError) as refused:
        load_scene(variant(FOUR_IMAGES, tmp_path, **{FOUR_OPTICS["blur"]: "blur_sd_px = 10.0"}))
    found = re.search(r"inside their windows with a blur up to ([0-9.]+) px and their brightness readable at the "
                      r"lightest touch up to ([0-9.]+) px: at most ([0-9.]+) px$", str(refused.value))
    assert found, str(refused.value)
    inside, readable, most = map(float, found.groups())
    assert most == min(inside, readable)
    for blur in (inside, readable):                 # each limit holds for the condition it names alone
        if blur > most:
            with pytest.raises(SceneError) as other:
                load_scene(variant(FOUR_IMAGES, tmp_path, f"b{blur}.toml",
                                   **{FOUR_OPTICS["blur"]: f"blur_sd_px = {blur}"}))
            why = str(other.value).split(";")[0]     # refused for the other condition, not the one it names
            assert ("the reader measures the discs' brightness" in why) == (blur == inside), why
