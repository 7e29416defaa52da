"""feeler simulate: determinism from the seed, order independence, files, --force, CLI
exit codes with one-line errors, and no OpenCV/PyMC at displacement fidelity."""
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from feeler.cli import main
from feeler.datasets import read_scans
from feeler.errors import OverwriteError
from feeler.scene import load_scene
from feeler.simulate import CSV_COLUMNS, run_simulation, simulate_scans

SHIPPED = Path(__file__).resolve().parents[1] / "datasets-synthetic" / "four-plates.toml"


def small_scene(tmp_path, name="small.toml", **swap):
    text = SHIPPED.read_text(encoding="utf-8").replace("scans_per_plate = 24", "scans_per_plate = 3")
    for old, new in swap.items():
        text = text.replace(old, new)
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_same_seed_gives_identical_bytes_and_another_seed_differs(tmp_path):
    scene = small_scene(tmp_path)
    a, b = run_simulation(scene, tmp_path / "a"), run_simulation(scene, tmp_path / "b")
    for name in ("scans.csv", "truth.json", "scene.toml"):
        assert (a / name).read_bytes() == (b / name).read_bytes()
    assert (a / "scene.toml").read_bytes() == scene.read_bytes()
    other = small_scene(tmp_path, "other.toml", **{"seed = 20040501": "seed = 7"})
    c = run_simulation(other, tmp_path / "c")
    assert (c / "scans.csv").read_bytes() != (a / "scans.csv").read_bytes()


def test_files_hold_the_columns_and_every_true_parameter(tmp_path):
    out = run_simulation(small_scene(tmp_path), tmp_path / "run")
    header = (out / "scans.csv").read_text().splitlines()[0].split(",")
    assert tuple(header) == CSV_COLUMNS
    truth = json.loads((out / "truth.json").read_text())
    assert len(truth["touches"]) == 12
    assert set(truth["touches"][0]) == {"scan_id", "plate", "step_mm", "uy0_mm", "tilt_deg", "x0_mm", "drift_mm_s", "snaps"}
    assert truth["scene"]["noise"]["uy_sd_mm"] == 0.001
    scans = read_scans(out)
    assert scans.uy_mm.shape == (12, truth["n_time"])
    np.testing.assert_array_equal(scans.step_mm, np.repeat([0.0, 0.05, 0.1, 0.2], 3))
    # the file holds the simulated numbers to 9 significant digits, and U_y starts at the drawn press
    uy0 = np.array([t["uy0_mm"] for t in truth["touches"]])
    assert np.all(np.abs(scans.uy_mm[:, 0] - uy0) < 5 * 0.002)


def test_a_scan_does_not_depend_on_the_others(tmp_path):
    full = load_scene(small_scene(tmp_path))
    fewer = load_scene(small_scene(tmp_path, "fewer.toml", **{"[0.0, 0.05, 0.1, 0.2]": "[0.0, 0.05]"}))
    a, touches_a = simulate_scans(full)
    b, touches_b = simulate_scans(fewer)
    np.testing.assert_array_equal(a.uy_mm[:6], b.uy_mm)
    assert touches_a[:6] == touches_b


def test_force_is_needed_to_overwrite(tmp_path):
    scene = small_scene(tmp_path)
    run_simulation(scene, tmp_path / "run")
    with pytest.raises(OverwriteError):
        run_simulation(scene, tmp_path / "run")
    run_simulation(scene, tmp_path / "run", force=True)


def test_features_output(tmp_path):
    out = run_simulation(small_scene(tmp_path, **{'outputs = ["scans"]': 'outputs = ["scans", "features"]'}),
                         tmp_path / "run")
    lines = (out / "features.csv").read_text().splitlines()
    assert lines[0] == "scan_id,plate,step_mm,peak_z,jump_uy_mm,peak_rate_uy_mm_s" and len(lines) == 13


def test_cli_exit_codes_and_one_line_errors(tmp_path, capsys):
    scene = small_scene(tmp_path)
    assert main(["simulate", str(scene), "--out", str(tmp_path / "run")]) == 0
    capsys.readouterr()
    optics_at_displacement = small_scene(tmp_path, "optics.toml")
    optics_at_displacement.write_text(optics_at_displacement.read_text()
                                      + '\n[optics]\nlayout = "layouts/sensor-16.toml"\n')
    cases = [
        ["simulate", str(scene), "--out", str(tmp_path / "run")],                  # exists, no --force
        ["simulate", str(tmp_path / "nope.toml"), "--out", str(tmp_path / "x")],   # missing scene
        ["simulate", str(optics_at_displacement), "--out", str(tmp_path / "y")],
    ]
    expected = ["--force", "no such scene file", "optics: only used when sensor.fidelity"]
    for argv, words in zip(cases, expected):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert len([ln for ln in err.splitlines() if ln.startswith("feeler:")]) == 1 and words in err
    assert main(["simulate", str(scene), "--out", str(tmp_path / "run"), "--force"]) == 0


def test_displacement_fidelity_imports_neither_opencv_nor_pymc(tmp_path):
    scene = small_scene(tmp_path)
    code = ("import sys; from feeler.cli import main; "
            f"rc = main(['simulate', {str(scene)!r}, '--out', {str(tmp_path / 'run')!r}]); "
            "print(rc, 'cv2' in sys.modules, 'pymc' in sys.modules, 'weasyprint' in sys.modules)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.stdout.split()[-4:] == ["0", "False", "False", "False"], done.stderr
