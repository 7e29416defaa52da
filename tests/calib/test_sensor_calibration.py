"""sensor-calibration scene, campaign simulator and CSV reader."""
from __future__ import annotations

import json

import numpy as np
import pytest

from feeler.calib.matrix import read_calibration_csv
from feeler.errors import DataFileError, OverwriteError, SceneError
from feeler.scene import load_scene
from feeler.scenes.sensor_calibration import commanded_displacements
from feeler.simulate.calibration import draw_campaign, simulate_sensor_calibration

SHIPPED = "datasets-synthetic/sensor-calibration.toml"


def test_simulation_writes_the_three_files_and_is_deterministic(tmp_path):
    scene = load_scene(SHIPPED)
    paths = simulate_sensor_calibration(scene, tmp_path / "a")
    simulate_sensor_calibration(scene, tmp_path / "b", scene_path=SHIPPED)
    assert (tmp_path / "a" / "calibration.csv").read_bytes() == (tmp_path / "b" / "calibration.csv").read_bytes()
    header = paths["calibration"].read_text().splitlines()[0]
    assert header == "point_id,ux_mm,uy_mm,uz_mm,fx_n,fy_n,fz_n"
    data = read_calibration_csv(paths["calibration"])
    assert data.n == 39
    np.testing.assert_allclose(data.u_mm, commanded_displacements(scene.design), atol=1e-6)
    truth = json.loads(paths["truth"].read_text())
    np.testing.assert_allclose(truth["C_mm_per_n"], scene.sensor.c_mm_per_n)
    np.testing.assert_allclose(np.asarray(truth["C_mm_per_n"]) @ np.asarray(truth["K_n_per_mm"]), np.eye(3), atol=1e-12)
    assert load_scene(paths["scene"]) == scene                       # the rendered TOML reloads
    assert (tmp_path / "b" / "scene.toml").read_bytes() == open(SHIPPED, "rb").read()
    with pytest.raises(OverwriteError, match="calibration.csv"):
        simulate_sensor_calibration(scene, tmp_path / "a")


def test_forces_follow_the_true_stiffness():
    scene = load_scene(SHIPPED)
    u_cmd, u_true, f = draw_campaign(scene, np.random.default_rng(0))
    k = np.linalg.inv(np.asarray(scene.sensor.c_mm_per_n))
    resid = f - u_true @ k.T
    np.testing.assert_allclose(resid.std(axis=0), scene.noise.f_sd_n, rtol=0.35)
    assert np.abs(u_true - u_cmd).max() < 6 * scene.noise.stage_sd_mm


@pytest.mark.parametrize("old, new, match", [
    ("[0.018, 0.008, 0.280]]", "[0.018, 0.008]]", r"sensor.c_mm_per_n\[2\]: needs at least 3 items"),
    ("[0.018, 0.008, 0.280]]", "[0.018, 0.008, 0.280], [1.0, 1.0, 1.0]]", "sensor.c_mm_per_n: must be 3 rows of 3"),
    ("[0.0, 0.0, 0.25]]", "[0.25, 0.0, 0.0]]", "prior.c0_mm_per_n: must be invertible"),
    ("f_sd_n = [0.02, 0.02, 0.02]", "f_sd_n = [0.02, 0.02, 0.02, 0.02]", "noise.f_sd_n: needs exactly 3"),
    ("shear_offsets_mm = [-0.10, -0.05, 0.05, 0.10]", "shear_offsets_mm = [0.0]", "design.shear_offsets_mm: needs a non-zero"),
    ('kind = "gaussian"', 'kind = "laplace"', "noise.kind: 'laplace' is not allowed"),
])
def test_scene_errors_name_the_key(tmp_path, old, new, match):
    text = open(SHIPPED).read()
    assert old in text
    path = tmp_path / "s.toml"
    path.write_text(text.replace(old, new, 1))
    with pytest.raises(SceneError, match=match):
        load_scene(path)


@pytest.mark.parametrize("content, match", [
    ("point_id,ux_mm\n0,1\n", r"missing column\(s\) uy_mm"),
    ("point_id,ux_mm,uy_mm,uz_mm,fx_n,fy_n,fz_n\n" + "0,0,0.1,0,1,2,3\n" * 3 + "3,0,abc,0,1,2,3\n",
     "column uy_mm, row 4: 'abc' is not a finite number"),
    ("point_id,ux_mm,uy_mm,uz_mm,fx_n,fy_n,fz_n\n" + "0,0,0.1,0,1,2,3\n" * 3 + "3,0,0.1,0,1,2,\n",
     "column fz_n, row 4: an empty or NaN cell is not a finite number$"),
    ("point_id,ux_mm,uy_mm,uz_mm,fx_n,fy_n,fz_n\n" + "0,0,0.1,0,1,2,3\n" * 3 + "3,0,0.1,nan,1,2,3\n",
     "column uz_mm, row 4: an empty or NaN cell is not a finite number$"),      # pandas reads both as NaN
    ("point_id,ux_mm,uy_mm,uz_mm,fx_n,fy_n,fz_n\n" + "0,0,0.1,0,1,2,3\n" * 3 + "3,0,0.1,0,inf,2,3\n",
     "column fx_n, row 4: inf is not a finite number$"),
    ("point_id,ux_mm,uy_mm,uz_mm,fx_n,fy_n,fz_n\n" + "0,0,0.1,0,1,2,3\n" * 3 + "3,0,0.1,0,1e300,2,3\n",
     r"column fx_n, row 4: 1e\+300 lies beyond ±1e\+12 \(no displacement in mm or force in N comes near\)$"),
    ("point_id,ux_mm,uy_mm,uz_mm,fx_n,fy_n,fz_n\n" + "0,0,0.1,0,1,2,3\n" * 3, "3 points; a 3x3 matrix needs at least 4"),
    ("point_id,ux_mm,uy_mm,uz_mm,fx_n,fy_n,fz_n\n" + "0,0,0.1,0,0,0,0\n" * 4,
     "columns fx_n, fy_n, fz_n are 0 in every row: the force gauge read nothing"),
    ("point_id,ux_mm,uy_mm,uz_mm,fx_n,fy_n,fz_n\n" + "".join(f"{k},0.{k},0.1,0,1.{k},2,0\n" for k in range(5)),
     "column fz_n is 0 in every row: that axis of the force gauge read nothing"),
    ("", "empty: no header and no rows"),
])
def test_csv_errors_name_the_file(tmp_path, content, match):
    path = tmp_path / "calibration.csv"
    path.write_text(content)
    with pytest.raises(DataFileError, match=match):
        read_calibration_csv(path)


def test_a_decimal_comma_export_reads_as_the_comma_file(tmp_path):
    head = "point_id,ux_mm,uy_mm,uz_mm,fx_n,fy_n,fz_n"
    rows = [f"{k},0.{k},0.05{k},0,1.{k},2.5,3" for k in range(5)]
    plain, eu = tmp_path / "plain.csv", tmp_path / "eu.csv"
    plain.write_text("\n".join([head, *rows]) + "\n")
    eu.write_text("\n".join(ln.replace(",", ";").replace(".", ",") for ln in [head, *rows]) + "\n")
    a, b = read_calibration_csv(plain), read_calibration_csv(eu)
    for name in vars(a):
        np.testing.assert_array_equal(np.asarray(getattr(b, name)), np.asarray(getattr(a, name)), err_msg=name)



def test_missing_csv(tmp_path):
    with pytest.raises(DataFileError, match="no such calibration file"):
        read_calibration_csv(tmp_path / "nope.csv")


def test_a_file_without_point_ids_reads_and_its_copies_are_still_found(tmp_path):
    """A lab's force log has no point ids: each row is a measurement; rows copied whole
    (a file appended to itself) are still named, by their displacements and forces."""
    from feeler.calib.matrix.checks import repeat_problems

    head = "ux_mm,uy_mm,uz_mm,fx_n,fy_n,fz_n"
    rows = [f"0.{k},0.05{k},0,1.{k},2.5,3" for k in range(5)]
    (tmp_path / "with.csv").write_text("point_id," + head + "\n" + "\n".join(f"{k},{r}" for k, r in enumerate(rows)))
    (tmp_path / "without.csv").write_text(head + "\n" + "\n".join(rows + rows) + "\n")
    a, b = read_calibration_csv(tmp_path / "with.csv"), read_calibration_csv(tmp_path / "without.csv")
    np.testing.assert_array_equal(b.u_mm[:5], a.u_mm)
    np.testing.assert_array_equal(b.f_n[:5], a.f_n)
    assert set(b.point_id) == {""}
    said = repeat_problems(b.point_id, b.u_mm, b.f_n, matrix="K")
    assert len(said) == 1 and said[0].startswith("K: 5 of 10 rows repeat an earlier row exactly")
    assert repeat_problems(b.point_id[:5], b.u_mm[:5], b.f_n[:5], matrix="K") == []
