"""`feeler calibrate sensor` and `feeler validate sbc` end to end (exact backend, small)."""
from __future__ import annotations

import json
import re
import shutil

import numpy as np
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
    assert "predicted U for F = [0.0, 1.0, 0.0] N (median [90 % interval])" in out
    assert json.loads((tmp_path / "verdict.json").read_text()) == {"ok": True, "problems": []}
    summary = pd.read_csv(tmp_path / "summary.csv").set_index("name")
    truth = load_scene(SHIPPED).sensor.c_mm_per_n
    assert summary.loc["C[1,1]", "eti95_lb"] <= truth[1][1] <= summary.loc["C[1,1]", "eti95_ub"]
    assert main(["calibrate", "sensor", str(dataset), "--out", str(tmp_path)]) == 2   # no --force


def test_predict_prints_the_median_inside_its_interval_on_a_near_singular_design(dataset, tmp_path, capsys):
    """Displacements whose z barely differs from x: a few draws of C = K^-1 are huge, and the
    predictive mean lies outside its own interval (an audit: uz 0.8524 [-0.7633, 0.2348]; here
    ux 3.72 [-0.23, 0.78]); the median is printed, inside it."""
    from feeler.calib.fit import load
    from feeler.calib.matrix import predict_u

    rng = np.random.default_rng(0)
    cal = pd.read_csv(dataset / "calibration.csv")
    u = cal[["ux_mm", "uy_mm", "uz_mm"]].to_numpy().copy()
    u[:, 2] = u[:, 0] + rng.normal(0, 1e-4, len(u))
    k = np.linalg.inv(np.array([[0.300, 0.012, 0.020], [0.015, 0.150, 0.010], [0.018, 0.008, 0.280]]))
    cal[["ux_mm", "uy_mm", "uz_mm"]] = u
    cal[["fx_n", "fy_n", "fz_n"]] = u @ k.T + rng.normal(0, 0.02, u.shape)
    (tmp_path / "data").mkdir()
    cal.to_csv(tmp_path / "data" / "calibration.csv", index=False)
    shutil.copy(dataset / "scene.toml", tmp_path / "data" / "scene.toml")
    main(["calibrate", "sensor", str(tmp_path / "data"), "--out", str(tmp_path / "fit"), "--predict", "0.5", "1",
          "-0.5", "--no-progress"])
    line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("predicted U"))
    cells = re.findall(r"u([xyz]) (\S+) \[(\S+), (\S+)\]", line)
    assert len(cells) == 3, line
    for axis, m, lo, hi in cells:
        assert float(lo) <= float(m) <= float(hi), line
    p = predict_u(load(tmp_path / "fit"), [0.5, 1.0, -0.5], rng=np.random.default_rng(0))
    assert np.any((p["mean_mm"] < p["lb_mm"]) | (p["mean_mm"] > p["ub_mm"]))       # the case this is about


def test_failed_verdict_gives_exit_1(dataset, capsys):
    rc = main(["calibrate", "sensor", str(dataset), "--backend", "emcee", "--draws", "60",
               "--tune", "10", "--no-progress"])
    out = capsys.readouterr().out
    assert rc == 1 and "verdict: FAILED" in out and "autocorrelation times" in out


@pytest.mark.parametrize("argv, message", [
    (["calibrate", "sensor", "nowhere.txt"], "nowhere.txt: not a dataset directory"),
    (["calibrate", "sensor", "DATA", "--backend", "exact", "--noise", "student"], "exact needs noise=gaussian"),
    (["calibrate", "sensor", "DATA", "--rel-sd", "-1"], "--rel-sd=-1.0: must be a finite number > 0"),
])
def test_bad_input_is_one_line_exit_2(dataset, capsys, argv, message):
    argv = [str(dataset) if a == "DATA" else a for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and len([ln for ln in err.splitlines() if ln.startswith("feeler:")]) == 1


def test_csv_without_scene_needs_c0(dataset, tmp_path, capsys):
    csv = tmp_path / "points.csv"
    csv.write_text((dataset / "calibration.csv").read_text())
    assert main(["calibrate", "sensor", str(csv)]) == 2
    assert "--c0" in capsys.readouterr().err
    assert main(["calibrate", "sensor", str(csv), "--c0", "0.25", "0", "0", "0", "0.2", "0", "0", "0", "0.25"]) == 0


def test_calibrate_without_target_names_its_commands(capsys):
    assert main(["calibrate"]) == 2
    out, err = capsys.readouterr()
    assert out == "" and "sensor, neuron or sensors" in err and len(err.splitlines()) == 1


def test_validate_sbc_matrix(tmp_path, capsys):
    rc = main(["validate", "sbc", "--model", "matrix", "--n", "20", "--scheduler", "serial",
               "--out", str(tmp_path)])
    out = capsys.readouterr().out
    assert rc == 0 and "SBC ok" in out
    ranks = pd.read_csv(tmp_path / "ranks.csv")
    assert ranks.shape == (20, 23) and ranks.drop(columns="dataset").to_numpy().max() <= 99
    assert set(pd.read_csv(tmp_path / "sbc.csv").columns) == {"name", "chi2_p", "ecdf_p"}


def test_printed_means_never_lie_outside_their_printed_intervals(capsys):
    from feeler.calib.fit import FitResult, Verdict
    from feeler.commands._fit_output import format_estimate, print_summary, round_inside
    assert round_inside(0.9996, 0.99995, 1.0, 4) == ("1.000", "1.000", "1.000")
    assert round_inside(0.5, 0.4, 0.6, 4) == ("0.5000", "0.4000", "0.6000")
    m, lo, hi = round_inside(0.95, 0.99, 1.0, 4)                   # really outside: rounded until inside
    assert float(lo) <= float(m) <= float(hi)
    assert format_estimate(0.0245, 0.0238, 0.0249, 2, 1e3) == "24.50 [23.80, 24.90]"
    row = {"name": "pc", "mean": 0.99962, "sd": 0.001, "eti95_lb": 0.99995, "eti95_ub": 1.0, "r_hat": 1.0,
           "ess_bulk": 4000.0, "ess_tail": 4000.0}
    print_summary(FitResult(posterior=None, summary=pd.DataFrame([row]), verdict=Verdict(True)))
    line = [s for s in capsys.readouterr().out.splitlines() if s.strip().startswith("pc")][0].split()
    assert float(line[3]) <= float(line[1]) <= float(line[4])          # name mean sd lb ub ...
    tiny = row | {"name": "s", "mean": 3.2e-154, "eti95_lb": 1.1e-154, "eti95_ub": 5.01e-154}
    huge = row | {"name": "k", "mean": -2.5e12, "sd": 2.5e11, "eti95_lb": -3e12, "eti95_ub": -2e12}
    print_summary(FitResult(posterior=None, summary=pd.DataFrame([tiny, huge]), verdict=Verdict(True)))
    out = capsys.readouterr().out
    assert "s 3.2000e-154 0.001 1.1000e-154 5.0100e-154" in " ".join(out.split())
    assert "k -2.5000e+12 2.5e+11 -3.0000e+12 -2.0000e+12" in " ".join(out.split())
    assert max(len(x) for x in out.split()) < 20


def test_validate_sbc_neuron(tmp_path, capsys):
    rc = main(["validate", "sbc", "--model", "neuron", "--n", "20", "--draws", "19", "--scheduler", "serial",
               "--out", str(tmp_path)])
    out = capsys.readouterr().out
    assert rc == 0 and "SBC ok" in out
    assert "with 20 datasets only a gross miscalibration shows" in out       # a small run says what ok covers
    ranks = pd.read_csv(tmp_path / "ranks.csv")
    assert {"a", "h", "growth", "plate_sd_mm[3]"} <= set(ranks.columns)


@pytest.mark.parametrize("problems, head", [((), "verdict: ok"), (("a: x",), "verdict: FAILED (1 problem)"),
                                            (("a: x", "b: y"), "verdict: FAILED (2 problems)")])
def test_verdict_line_counts_its_problems(problems, head):
    from feeler.calib.diagnostics import Verdict
    from feeler.commands._fit_output import verdict_text

    lines = verdict_text(Verdict(ok=not problems, problems=problems)).splitlines()
    assert lines == [head] + [f"  {p}" for p in problems]


def test_summary_prints_rounding_noise_of_a_pinned_quantity_as_zero(capsys):
    """A two-plate decoder pins its plates' heights exactly: the plate at 0 printed
    -0.4632e-17 [-1.3878e-17, 0.5204e-17]. Noise below 1e-12 of the quantity's scale is 0."""
    from feeler.calib.fit import FitResult, Verdict
    from feeler.commands._fit_output import print_summary
    base = {"sd": 5.21e-18, "r_hat": 1.0, "ess_bulk": 4000.0, "ess_tail": 3717.0}
    rows = [base | {"name": "plate_mean_mm[0]", "mean": -4.632e-18, "eti95_lb": -1.3878e-17, "eti95_ub": 5.204e-18},
            base | {"name": "plate_mean_mm[1]", "mean": 0.1, "sd": 2.59e-17, "eti95_lb": 0.1, "eti95_ub": 0.1},
            base | {"name": "s", "mean": 3.2e-15, "sd": 1e-16, "eti95_lb": 3.0e-15, "eti95_ub": 3.4e-15}]
    print_summary(FitResult(posterior=None, summary=pd.DataFrame(rows), verdict=Verdict(True)))
    out = " ".join(capsys.readouterr().out.split())
    assert "plate_mean_mm[0] 0.00000 0 0.00000 0.00000 1.0000" in out
    assert "plate_mean_mm[1] 0.10000 0 0.10000 0.10000" in out
    assert "e-17" not in out and "e-18" not in out
    assert "s 3.2000e-15 1e-16 3.0000e-15 3.4000e-15" in out        # a small quantity on its own scale stays


def test_summary_prints_a_quantity_without_finite_draws_as_dashes(capsys):
    """A neuron fit of one plate has no gain or offset: its summary printed whole rows of
    'nan' (an outside audit). They print as dashes; the verdict names why."""
    from feeler.calib.fit import FitResult, Verdict
    from feeler.commands._fit_output import print_summary
    nan = float("nan")
    rows = [{"name": "a", "mean": nan, "sd": nan, "eti95_lb": nan, "eti95_ub": nan, "r_hat": nan,
             "ess_bulk": nan, "ess_tail": nan},
            {"name": "tau_s", "mean": 3.1, "sd": 2.5, "eti95_lb": 0.53, "eti95_ub": 9.3, "r_hat": 1.0,
             "ess_bulk": 4369.0, "ess_tail": 4012.0}]
    print_summary(FitResult(posterior=None, summary=pd.DataFrame(rows),
                            verdict=Verdict(False, ("a: no finite posterior draws",))))
    out = capsys.readouterr().out
    assert "nan" not in out.lower()
    assert " ".join(out.split()).count("a — — — — — — —") == 1
    assert "tau_s 3.1000 2.5 0.5300 9.3000 1.0000 4369 4012" in " ".join(out.split())
