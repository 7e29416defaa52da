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


@pytest.mark.parametrize("extra, key, words", [
    ("[steps]\nposition_mm = 20.0", "steps.position_mm", "must lie inside the slide"),   # beyond a 10 mm slide
    ("[steps]\nposition_mm = 0.0", "steps.position_mm", "must lie inside the slide"),    # its edge starts at -0.025
    ("[loading]\nslide_mm = 4.0", "steps.position_mm", "loading.slide_mm = 4 mm"),       # the step at 5 mm
    ("[steps]\nheights_um = [10.0]", "steps.heights_um", "at least 2 distinct heights"),
    ("[steps]\nheights_um = [10.0, 10.0]", "steps.heights_um", "at least 2 distinct heights"),
    ("[steps]\nheights_um = [500.0, 750.0, 1000.0]", "steps.heights_um", "a tenth of the press depth"),
    ("[loading]\npress_mm = 0.1", "steps.heights_um", "15 µm: at most 10 µm"),           # the paper's steps
])
def test_scenes_whose_figures_would_be_meaningless_are_refused_at_load(tmp_path, extra, key, words):
    """A step beyond the slide gave slope -2.5e-17, R² = -inf and conversion 4e17 with exit 0;
    one height R² = -inf (and "r2": -Infinity in figures.json); steps of 500-1000 µm under a
    1 mm press ran the linear models far outside what they describe."""
    with pytest.raises(SceneError, match=key.replace(".", r"\.")) as err:
        load_scene(_scene(tmp_path, "[scene]\nkind = \"finger-steps\"\n" + extra))
    assert words in str(err.value) and "\n" not in str(err.value)


def test_steps_up_to_a_tenth_of_the_press_and_inside_the_slide_load(tmp_path):
    scene = load_scene(_scene(tmp_path, "[scene]\nkind = \"finger-steps\"\n[steps]\nheights_um = [5.0, 100.0]\n"
                                        "position_mm = 9.9\nedge_um = 0.0\n"))
    assert scene.steps.heights_um == (5.0, 100.0)


def test_a_threshold_no_peak_reaches_is_one_line_exit_2(tmp_path, capsys):
    """All peaks zero divided by zero: 'feeler: warning: divide by zero' and non-finite numbers."""
    path = _scene(tmp_path, TINY + "[neuron]\nh = 1000.0\n")
    assert main(["skin", "figures", str(path), "--out", str(tmp_path / "f"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("feeler: error: argument neuron.h=1000.0: ") and "warning" not in err


def test_figures_json_holds_no_non_finite_number(tmp_path):
    from feeler.skin.figures import _line_fit
    from feeler.skin.study import _finite_or_null

    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("error")                   # no raw 'invalid value' or 'poorly conditioned'
        flat = _line_fit(20.0, np.array([5.0, 15.0]), np.array([0.5, 0.5]))
    assert np.isnan(flat.r2) and flat.slope_per_um == pytest.approx(0.0, abs=1e-12)
    assert _finite_or_null({"r2": [flat.r2, 1.0, np.inf], "k": np.array([-np.inf, 2.0])}) == \
        {"r2": [None, 1.0, None], "k": [None, 2.0]}
    out = tmp_path / "f"
    assert main(["skin", "figures", str(_scene(tmp_path)), "--out", str(out), "--no-progress"]) == 0

    def refuse(name):
        raise AssertionError(f"{name} in figures.json")
    json.loads((out / "figures.json").read_text(), parse_constant=refuse)
