"""`feeler calibrate sensor` and `feeler validate sbc` end to end (exact backend, small)."""
from __future__ import annotations

import json

import pandas as pd
import pytest

from feeler.cli import main
from feeler.scene import load_scene
from feeler.simulate.calibration import simulate_sensor_calibration

SHIPPED = "datasets-synthetic/sensor-calibration.toml"


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    out = tmp_path_factory.mktemp("campaign")
    simulate_sensor_calibration(load_scene(SHIPPED), out, scene_path=SHIPPED)
    return out


def test_calibrate_sensor_prints_table_and_writes_fit(dataset, tmp_path, capsys):
    rc = main(["calibrate", "sensor", str(dataset), "--out", str(tmp_path), "--predict", "0", "1", "0",
               "--no-progress"])
    out = capsys.readouterr().out
    assert rc == 0
    assert "C[1,1]" in out and "cond_C" in out and "verdict: ok" in out
    assert "predicted U for F = [0.0, 1.0, 0.0] N (90 %)" in out
    assert json.loads((tmp_path / "verdict.json").read_text()) == {"ok": True, "problems": []}
    summary = pd.read_csv(tmp_path / "summary.csv").set_index("name")
    truth = load_scene(SHIPPED).sensor.c_mm_per_n
    assert summary.loc["C[1,1]", "eti95_lb"] <= truth[1][1] <= summary.loc["C[1,1]", "eti95_ub"]
    assert main(["calibrate", "sensor", str(dataset), "--out", str(tmp_path)]) == 2   # no --force


def test_failed_verdict_gives_exit_1(dataset, capsys):
    rc = main(["calibrate", "sensor", str(dataset), "--backend", "emcee", "--draws", "60",
               "--tune", "10", "--no-progress"])
    out = capsys.readouterr().out
    assert rc == 1 and "verdict: FAILED" in out and "autocorrelation times" in out


@pytest.mark.parametrize("argv, message", [
    (["calibrate", "sensor", "nowhere.txt"], "nowhere.txt: not a dataset directory"),
    (["calibrate", "sensor", "DATA", "--backend", "exact", "--noise", "student"], "exact needs noise=gaussian"),
    (["calibrate", "sensor", "DATA", "--rel-sd", "-1"], "rel_sd=-1.0: must be a finite number > 0"),
])
def test_bad_input_is_one_line_exit_2(dataset, capsys, argv, message):
    argv = [str(dataset) if a == "DATA" else a for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


def test_csv_without_scene_needs_c0(dataset, tmp_path, capsys):
    csv = tmp_path / "points.csv"
    csv.write_text((dataset / "calibration.csv").read_text())
    assert main(["calibrate", "sensor", str(csv)]) == 2
    assert "--c0" in capsys.readouterr().err
    assert main(["calibrate", "sensor", str(csv), "--c0", "0.25", "0", "0", "0", "0.2", "0", "0", "0", "0.25"]) == 0


def test_calibrate_without_target_prints_help(capsys):
    assert main(["calibrate"]) == 2
    assert "sensor" in capsys.readouterr().out


def test_validate_sbc_matrix(tmp_path, capsys):
    rc = main(["validate", "sbc", "--model", "matrix", "--n", "20", "--scheduler", "serial",
               "--out", str(tmp_path)])
    out = capsys.readouterr().out
    assert rc == 0 and "SBC ok" in out
    ranks = pd.read_csv(tmp_path / "ranks.csv")
    assert ranks.shape == (20, 23) and ranks.drop(columns="dataset").to_numpy().max() <= 99
    assert set(pd.read_csv(tmp_path / "sbc.csv").columns) == {"name", "chi2_p", "ecdf_p"}
