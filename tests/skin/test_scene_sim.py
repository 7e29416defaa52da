"""finger-steps scene validation, the simulator's files, and the CLI."""
import csv
import json
from pathlib import Path

import numpy as np
import pytest

from feeler.cli import main
from feeler.errors import OverwriteError, SceneError
from feeler.scene import load_scene
from feeler.simulate.finger import mesh_spec_of, simulate_finger_steps, skin_params_of

SHIPPED = Path(__file__).resolve().parents[2] / "datasets-synthetic" / "finger-steps.toml"
TINY = """
[scene]
kind = "finger-steps"
[loading]
speeds_mm_s = [20.0, 40.0]
travel_step_mm = 0.05
[steps]
heights_um = [5.0, 15.0]
[model]
level = "l0"
"""


def _scene(tmp_path, text=TINY, name="s.toml"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_shipped_scene_loads_with_the_papers_values():
    scene = load_scene(SHIPPED)
    params = skin_params_of(scene)
    assert params.e_mpa == (0.14, 0.034, 0.080) and params.nu == 0.45
    assert params.prony_ratio == 0.5 and params.prony_tau_s == 0.0129
    assert scene.steps.heights_um == (5.0, 7.5, 10.0, 12.5, 15.0)
    assert scene.loading.speeds_mm_s == (20.0, 40.0)
    assert min(scene.neuron.tau_sweep_s) == 0.01 and max(scene.neuron.tau_sweep_s) == 0.3
    mesh_spec_of(scene).check(params)


@pytest.mark.parametrize("extra, key", [
    ("[skin]\ne_mpa = [0.1, 0.1]", "skin.e_mpa"),
    ("[skin]\nthickness_mm = [0.4]", "skin.thickness_mm"),
    ("[skin]\ncorpuscle_depth_mm = 3.0", "skin.corpuscle_depth_mm"),
    ("[mesh]\nh_corpuscle_mm = 0.05", "mesh.h_corpuscle_mm"),
    ("[model]\nlevel = \"l9\"", "model.level"),
])
def test_bad_scenes_name_the_key(tmp_path, extra, key):
    text = "[scene]\nkind = \"finger-steps\"\n" + extra
    with pytest.raises(SceneError, match=key.replace(".", r"\.")):
        load_scene(_scene(tmp_path, text))


def test_simulator_writes_long_csv_and_truth(tmp_path):
    scene_path = _scene(tmp_path)
    files = simulate_finger_steps(load_scene(scene_path), tmp_path / "out", scene_path=scene_path)
    with open(files["strain.csv"]) as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0]) == ["step_um", "speed_mm_s", "t_s", "x_mm", "eps_y"]
    combos = {(float(r["step_um"]), float(r["speed_mm_s"])) for r in rows}
    assert combos == {(5.0, 20.0), (5.0, 40.0), (15.0, 20.0), (15.0, 40.0)}
    x = np.array([float(r["x_mm"]) for r in rows if r["step_um"] == "15" and r["speed_mm_s"] == "40"])
    assert x[0] == 0 and x[-1] == pytest.approx(10.0) and np.all(np.diff(x) >= 0)
    truth = json.loads(files["truth.json"].read_text())
    assert truth["level"] == "l0" and len(truth["runs"]) == 4
    big = [r["peak_step_eps"] for r in truth["runs"] if r["step_um"] == 15.0]
    small = [r["peak_step_eps"] for r in truth["runs"] if r["step_um"] == 5.0]
    np.testing.assert_allclose(big, 3 * np.array(small), rtol=1e-9)     # L0 is linear in height
    assert (tmp_path / "out" / "scene.toml").read_bytes() == scene_path.read_bytes()
    with pytest.raises(OverwriteError):
        simulate_finger_steps(load_scene(scene_path), tmp_path / "out")


def test_cli_figures_writes_all_files(tmp_path, capsys):
    scene_path = _scene(tmp_path)
    assert main(["skin", "figures", str(scene_path), "--out", str(tmp_path / "f")]) == 0
    for name in ("fig3_strain.png", "fig4_pulse_density.png", "fig5_peak_vs_height.png",
                 "fig6_accepted.png", "fig5_peaks.csv", "fig6_accepted.csv", "figures.json"):
        assert (tmp_path / "f" / name).stat().st_size > 0
    out, err = capsys.readouterr()
    assert "R²" in out
    lines = err.splitlines()                             # off a terminal: a line per stage and per skin run
    head = "skin runs (l0, height x speed): "
    runs = [ln for ln in lines if ln.startswith(head)]
    assert [ln[len(head):].split(",")[0] for ln in runs] == [f"{i}/4 done" for i in range(1, 5)]
    assert lines.index(runs[-1]) < lines.index("Figs 4-6: pulse densities and accepted heights over the tau sweep ...") \
        < lines.index(f"plotting Figs 3-6 into {tmp_path / 'f'} ...")
    assert main(["skin", "figures", str(scene_path), "--out", str(tmp_path / "f2"), "--no-progress"]) == 0
    assert capsys.readouterr().err == ""
    assert main(["skin", "figures", str(scene_path), "--out", str(tmp_path / "f")]) == 2


def test_cli_figures_rejects_other_scene_kinds(tmp_path, capsys):
    other = Path(__file__).resolve().parents[2] / "datasets-synthetic" / "psychophysics-2afc.toml"
    assert main(["skin", "figures", str(other), "--out", str(tmp_path / "g")]) == 2
    assert "finger-steps" in capsys.readouterr().err


def test_simulators_registry_entry_point(tmp_path):
    from feeler.simulate.finger import simulate_finger_scene
    scene_path = _scene(tmp_path)
    simulate_finger_scene(load_scene(scene_path), scene_path, tmp_path / "r", False)
    assert {p.name for p in (tmp_path / "r").iterdir()} == {"strain.csv", "truth.json", "scene.toml"}
