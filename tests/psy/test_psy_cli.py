"""`feeler fit psychophysics` and `feeler fit finger-route` end to end (fast settings)."""
import json
from pathlib import Path

import pandas as pd
import pytest

from feeler.calib.psychometric.fit import THRESHOLD_COLUMNS
from feeler.cli import main
from feeler.scene import load_scene
from feeler.simulate.psychophysics import simulate_psychophysics

SCENE_PATH = Path(__file__).parents[2] / "datasets-synthetic" / "psychophysics-2afc.toml"


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    out = tmp_path_factory.mktemp("sim")
    return simulate_psychophysics(load_scene(SCENE_PATH), out)["trials"]


def test_fit_psychophysics_laplace_writes_labelled_thresholds(data, tmp_path, capsys):
    code = main(["fit", "psychophysics", str(data), "--backend", "laplace", "--draws", "300",
                 "--out", str(tmp_path)])
    text = capsys.readouterr().out
    assert code == 0 and text.startswith("DATA: SYNTHETIC")
    table = pd.read_csv(tmp_path / "thresholds.csv", comment="#")
    assert tuple(table.columns) == THRESHOLD_COLUMNS
    assert set(table.subject) == {f"S{i}" for i in range(1, 7)} | {"all"}
    assert "synthetic" in (tmp_path / "thresholds.csv").read_text().splitlines()[0].lower()
    for name in ("posterior.nc", "summary.csv", "verdict.json"):
        assert (tmp_path / name).is_file()
    from feeler.calib.fit import load
    assert "SYNTHETIC" in load(tmp_path).posterior["posterior"].attrs["data_comments"]
    assert main(["fit", "psychophysics", str(data), "--backend", "laplace", "--draws", "300",
                 "--out", str(tmp_path)]) == 2          # refuses to overwrite without --force
    assert "--force" in capsys.readouterr().err


def test_fit_finger_route_reports_tau_beside_the_paper(data, tmp_path, capsys):
    code = main(["fit", "finger-route", str(data), "--n-tau", "61", "--draws", "300",
                 "--check-level", "l0", "--out", str(tmp_path)])
    text = capsys.readouterr().out
    assert code == 0 and "P(tau <= 300 ms | data)" in text and "paper:" in text
    report = json.loads((tmp_path / "tau_report.json").read_text())
    assert report["synthetic_data"] is True and report["check"]["max_abs_dp"] == 0.0
    assert report["tau_eti95_s"][0] < report["tau_mean_s"] < report["tau_eti95_s"][1]


@pytest.mark.parametrize("argv, match", [
    (["fit", "psychophysics", "MISSING.csv"], "no such file"),
    (["fit", "finger-route", "MISSING.csv"], "no such file"),
])
def test_bad_input_is_one_line_exit_2(argv, match, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert match in err and err.count("\n") == 1


def test_bad_grid_size_and_missing_target(data, capsys):
    assert main(["fit", "finger-route", str(data), "--n-tau", "1"]) == 2
    assert "--n-tau" in capsys.readouterr().err
    assert main(["fit"]) == 2
