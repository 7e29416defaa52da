"""A small synthetic run directory for the report tests, built once per session.

Simulated through the CLI: four-plates (its scene renamed to a script tag, to test
escaping), the sensor-calibration scene with an exact M1 fit, the psychophysics scene
with a Laplace M4 fit. Written by hand in the real formats of their commands (faster than
the M2 grid fit they would need): classify/classification.csv with known counts,
discriminate/discrimination.json, finger-route/tau_report.json (without the fit files,
so that section is listed as missing), finger/strain.csv and benchmarks/speed.csv.
"""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from feeler.cli import main

ROOT = Path(__file__).resolve().parents[2]
SCENES = ROOT / "datasets-synthetic"
EVIL = "<script>alert(1)</script>"


def _cli(*argv: str) -> None:
    assert main(list(argv)) == 0, argv


CLASSIFICATION = """scan_id,step_mm,plate_mm,p_0mm,p_0.1mm,height_mm,lo90_mm,hi90_mm
0,0.0,0.0,0.9,0.1,0.01,-0.02,0.04
1,0.0,0.0,0.8,0.2,0.02,-0.01,0.05
2,0.0,0.1,0.4,0.6,0.06,0.03,0.09
3,0.1,0.1,0.05,0.95,0.1,0.07,0.13
4,0.1,0.1,0.3,0.7,0.09,0.06,0.12
5,0.1,0.1,0.02,0.98,0.11,0.12,0.14
"""

DISCRIMINATION = {
    "pairs": [{"low_mm": 0.0, "high_mm": 0.05, "pc": 0.95, "lo95": 0.93, "hi95": 0.96},
              {"low_mm": 0.05, "high_mm": 0.1, "pc": 1.0, "lo95": 1.0, "hi95": 1.0}],
    "reference_mm": 0.1,
    "threshold_mm": {"mean": 0.005, "lo95": 0.0032, "hi95": 0.0074, "found": 1.0},
    "weber": {"mean": 0.05, "lo95": 0.032, "hi95": 0.074},
    "pse": {"speed_ref_mm_s": 0.5, "speed_test_mm_s": 1.0, "mean_mm": 0.0853, "lo95": 0.077, "hi95": 0.0925},
}

ROBOT_TABLE = {  # the layout feeler demo writes
    "plates": [{"step_mm": s, "n_scans": 24, "peak_z_mean": 0.01 + s, "peak_z_sd": 0.002, "raw_rate_mean_mm_s": 0.04,
                "raw_rate_sd_mm_s": 0.01, "jump_uy_mean_mm": s} for s in (0.0, 0.05, 0.1, 0.2)],
    "adjacent_pairs": [{"lower_mm": 0.0, "higher_mm": 0.05, "pc_peak_z": 0.93, "pc_raw_rate": 0.6}],
}

TAU_REPORT = {"tau_mean_s": 0.136, "tau_median_s": 0.135, "tau_eti95_s": [0.119, 0.16], "tau_map_s": 0.136,
              "p_tau_le_300ms": 0.999, "paper": "tau <= 300 ms", "skin_level": "l0", "synthetic_data": True}


def build_run(run: Path) -> Path:
    scene = run.parent / "evil-four-plates.toml"
    text = (SCENES / "four-plates.toml").read_text(encoding="utf-8")
    scene.write_text(text.replace('name = "four-plates"', f'name = "{EVIL}"'), encoding="utf-8")
    _cli("simulate", str(scene), "--out", str(run / "four-plates"))
    _cli("simulate", str(SCENES / "sensor-calibration.toml"), "--out", str(run / "sensor-calibration"))
    _cli("calibrate", "sensor", str(run / "sensor-calibration"), "--out", str(run / "m1"), "--draws", "300",
         "--no-progress")
    _cli("simulate", str(SCENES / "psychophysics-2afc.toml"), "--out", str(run / "psychophysics"))
    _cli("fit", "psychophysics", str(run / "psychophysics" / "trials.csv"), "--backend", "laplace",
         "--draws", "300", "--out", str(run / "m4"), "--no-progress")
    for rel, text in (("classify/classification.csv", CLASSIFICATION),
                      ("discriminate/discrimination.json", json.dumps(DISCRIMINATION)),
                      ("robot_table.json", json.dumps(ROBOT_TABLE)),
                      ("finger-route/tau_report.json", json.dumps(TAU_REPORT)),
                      ("finger/strain.csv", "t_s,strain_l0,strain_l1\n0,0,0\n0.1,0.001,0.0011\n0.2,0.003,0.0028\n"),
                      ("benchmarks/speed.csv", "backend,ms_per_fit,max_error\nexact,4.1,0.0\nnuts,5300,0.002\n")):
        (run / rel).parent.mkdir(parents=True, exist_ok=True)
        (run / rel).write_text(text, encoding="utf-8")
    return run


@pytest.fixture(scope="session")
def run_dir(tmp_path_factory) -> Path:
    return build_run(tmp_path_factory.mktemp("report-run") / "run")


@pytest.fixture(scope="session")
def report(run_dir, tmp_path_factory):
    from feeler.reports import build_report

    return build_report(run_dir, tmp_path_factory.mktemp("report-out"), pdf=True)


@pytest.fixture
def copy_run(run_dir, tmp_path) -> Path:
    """A fresh copy of the run (for tests that damage or remove files)."""
    return Path(shutil.copytree(run_dir, tmp_path / "run"))


@pytest.fixture
def part_run(run_dir, tmp_path):
    """``make(*names)``: a fresh run holding only these top-level entries of the run."""
    def make(*names: str) -> Path:
        dst = tmp_path / "part"
        dst.mkdir()
        for name in names:
            shutil.copytree(run_dir / name, dst / name)
        return dst
    return make
