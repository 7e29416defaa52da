"""The bad-input catalogue of issue 16 through the real command line: one line, exit 2, no work.

Each case: exit status 2, exactly one ``feeler: error:`` line naming the argument or file
and what is allowed, no traceback, and nothing computed first (no verdict printed, no
output written).
"""
import os
import subprocess
from pathlib import Path

import pytest

from tests.cli._run import feeler

FIT = ("calibrate", "sensor")


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    d = tmp_path_factory.mktemp("bad")
    assert feeler("simulate", "datasets-synthetic/sensor-calibration.toml", "--out", d / "sc").returncode == 0
    assert feeler("calibrate", "sensor", d / "sc", "--out", d / "m1").returncode == 0
    (d / "a-file").write_text("x")
    (d / "bare.csv").write_text("scan_id,step_mm\n")               # no scene.toml beside it
    (d / "bare-cal").mkdir()
    (d / "bare-cal" / "calibration.csv").write_text((d / "sc" / "calibration.csv").read_text())
    return d


def _one_error_line(out: subprocess.CompletedProcess, *needles: str) -> str:
    assert out.returncode == 2, out.stderr
    assert "Traceback" not in out.stderr and "verdict" not in out.stdout
    errors = [ln for ln in out.stderr.splitlines() if ln.startswith("feeler: ")]
    assert len(errors) == 1 and errors[0].startswith("feeler: error: "), out.stderr
    for n in needles:
        assert n in errors[0]
    return errors[0]


CASES = {
    "out at an existing file": (lambda d: (*FIT, d / "sc", "--out", d / "a-file"), ["--out", "not an existing file"]),
    "out under a file": (lambda d: (*FIT, d / "sc", "--out", d / "a-file" / "x"), ["--out", "is a file"]),
    "earlier fit without --force": (lambda d: (*FIT, d / "sc", "--out", d / "m1"),
                                    ["posterior.nc", "already exists", "--force"]),
    "calibrate sensor --draws 0": (lambda d: (*FIT, d / "sc", "--draws", "0"), ["--draws=0", ">= 1"]),
    "calibrate neuron --draws -5": (lambda d: ("calibrate", "neuron", d / "sc", "--draws", "-5"),
                                    ["--draws=-5", ">= 1"]),
    "calibrate sensor --chains 0": (lambda d: (*FIT, d / "sc", "--chains", "0"), ["--chains=0"]),
    "simulate a scan plan": (lambda d: ("simulate", "datasets-synthetic/plans/four-plates-plan.toml", "--out",
                                        d / "p"), ["scan-plan", "feeler acquire"]),
    "classify given an M1 fit": (lambda d: ("classify", d / "m1", d / "sc"), ["not a neuron (M2) fit"]),
    "discriminate given an M1 fit": (lambda d: ("discriminate", d / "m1"), ["not a neuron (M2) fit"]),
    # discriminate's heights and speeds, checked before the fit is even read (an M1 fit here);
    # they used to fail after the pairs were computed, or gave P = 0 for a reversed pair
    "discriminate --pair reversed": (lambda d: ("discriminate", d / "m1", "--pair", "0.1", "0.05"),
                                     ["--pair='0.1 0.05'", "LOW <= HIGH"]),
    "discriminate --pair nan": (lambda d: ("discriminate", d / "m1", "--pair", "nan", "0.1"), ["--pair='nan 0.1'"]),
    "discriminate --pair 1e9 mm": (lambda d: ("discriminate", d / "m1", "--pair", "0", "1e9"), ["-5..5 mm"]),
    "discriminate --reference -0.1": (lambda d: ("discriminate", d / "m1", "--reference", "-0.1"),
                                      ["--reference='-0.1'", "(0, 2.5] mm"]),
    "discriminate --speeds 0 1": (lambda d: ("discriminate", d / "m1", "--speeds", "0", "1"),
                                  ["--speeds='0'", "(0, 100] mm/s"]),
    # a negative touch seed reached numpy's SeedSequence after the work began: a traceback (an outside audit)
    "discriminate --touch-seed -5": (lambda d: ("discriminate", d / "m1", "--touch-seed", "-5"),
                                     ["--touch-seed=-5", "an integer >= 0"]),
    "decode --threshold 1.5": (lambda d: ("decode", d / "m1", d / "sc", "--threshold", "1.5"),
                               ["--threshold=1.5", "(0, 1]"]),
    "decode --drop 0": (lambda d: ("decode", d / "m1", d / "sc", "--drop", "0"), ["--drop=0", "(0, 1)"]),
    "validate sbc --n 3": (lambda d: ("validate", "sbc", "--model", "matrix", "--n", "3"), ["--n=3", "10"]),
    "validate sbc --draws 5": (lambda d: ("validate", "sbc", "--model", "matrix", "--draws", "5"), ["--draws=5"]),
    "classify --out at a file": (lambda d: ("classify", d / "m1", d / "sc", "--out", d / "a-file"), ["--out"]),
    # a bare CSV needs what its scene.toml would have said; the message named the value None
    "calibrate neuron on a bare CSV": (lambda d: ("calibrate", "neuron", d / "bare.csv"),
                                       ["argument --length-mm: needed: bare.csv has no scene.toml"]),
    "calibrate sensor on a bare CSV": (lambda d: (*FIT, d / "bare-cal"), ["argument --c0: the nominal matrix"]),
    # um typed for mm: 3000 passed with verdict ok, only rescaling a (an outside audit)
    "calibrate neuron --length-mm 3000": (lambda d: ("calibrate", "neuron", d / "bare.csv", "--length-mm", "3000"),
                                          ["--length-mm=3000.0: a length in (0, 1000] mm", "3000 looks like µm: 3 mm?"]),
    # a dataset or fit handed to a command that takes another kind: say what it is and what takes it
    "classify given a dataset as the fit": (lambda d: ("classify", d / "sc", d / "sc"),
                                            ["posterior.nc: missing", "holds a sensor-calibration dataset "
                                             "(calibration.csv): `feeler calibrate sensor` fits it"]),
    "calibrate neuron given a sensor dataset": (lambda d: ("calibrate", "neuron", d / "sc"),
                                                ["sc: holds no scans.csv", "`feeler calibrate sensor` fits it"]),
    "calibrate sensor given a fit": (lambda d: (*FIT, d / "m1"), ["no such calibration file", "holds a fit (posterior.nc)"]),
    # a library argument's name (rel_sd, c0_mm_per_n, target_accept, all) stood for the option typed
    "calibrate sensor --rel-sd -1": (lambda d: (*FIT, d / "sc", "--rel-sd", "-1"), ["--rel-sd=-1.0", "> 0"]),
    "calibrate sensor --c0 singular": (lambda d: (*FIT, d / "sc", "--c0", *"100010000"), ["--c0=", "invertible"]),
    "fit psychophysics --target-accept 2": (lambda d: ("fit", "psychophysics", d / "bare.csv", "--target-accept",
                                                       "2", "--backend", "nuts"), ["--target-accept=2.0", "(0, 1)"]),
    "fit psychophysics --all population --separate": (lambda d: ("fit", "psychophysics", d / "bare.csv", "--all",
                                                                 "population", "--separate", "--backend", "nuts"),
                                                      ["--all='population'", "hierarchical"]),
    "fit psychophysics given calibration.csv": (lambda d: ("fit", "psychophysics", d / "sc" / "calibration.csv"),
                                                ["line 1: not a trial table: calibration.csv is a sensor-calibration"]),
}


@pytest.mark.parametrize("case", list(CASES))
def test_bad_input_is_one_line(runs, case):
    argv, needles = CASES[case]
    _one_error_line(feeler(*argv(runs)), *needles)
    assert not (runs / "p").exists()


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only directories")
def test_read_only_out_directory(runs, tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        _one_error_line(feeler(*FIT, runs / "sc", "--out", ro / "m1"), "--out", "write")
    finally:
        ro.chmod(0o755)


def test_immutable_out_directory(runs, tmp_path):
    imm = tmp_path / "imm"
    imm.mkdir()
    if subprocess.run(["chattr", "+i", str(imm)], capture_output=True).returncode != 0:
        pytest.skip("chattr +i is not available here")
    try:
        _one_error_line(feeler(*FIT, runs / "sc", "--out", imm / "m1"), "--out", "write")
        assert not (imm / "m1").exists()
    finally:
        subprocess.run(["chattr", "-i", str(imm)], check=True)


def test_probe_leaves_nothing_behind(runs):
    before = sorted(p.name for p in Path(runs).iterdir())
    out = feeler(*FIT, runs / "nowhere", "--out", runs / "new" / "deep")
    assert "nowhere" in _one_error_line(out)                      # failed after the --out check
    assert sorted(p.name for p in Path(runs).iterdir()) == before


def test_validate_sbc_runs_outside_the_checkout(tmp_path):
    out = feeler("validate", "sbc", "--model", "matrix", "--n", "10", "--scheduler", "serial", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert "SBC ok" in out.stdout and "Traceback" not in out.stderr
    done = [ln for ln in out.stderr.splitlines() if ln.startswith("SBC datasets: ")]     # a line per replicate
    assert [ln.split(",")[0] for ln in done] == [f"SBC datasets: {i}/10 done" for i in range(1, 11)]
    assert all(", about " in ln and " left" in ln for ln in done[:-1])                  # with the time left
    quiet = feeler("validate", "sbc", "--model", "matrix", "--n", "10", "--scheduler", "serial", "--no-progress",
                   cwd=tmp_path)
    assert quiet.returncode == 0 and quiet.stderr == "" and quiet.stdout == out.stdout


def test_a_fit_says_what_it_does_and_where_it_writes(runs, tmp_path):
    out = feeler(*FIT, runs / "sc", "--out", tmp_path / "m1")
    assert out.returncode == 0, out.stderr
    err = out.stderr.splitlines()
    assert err[0].startswith("feeler calibrate sensor: fitting ") and "fitting M1 (exact backend" in out.stderr
    assert f"writing {tmp_path / 'm1'} ..." in err and f"wrote {tmp_path / 'm1' / 'posterior.nc'}" in out.stdout
    quiet = feeler(*FIT, runs / "sc", "--no-progress")
    assert quiet.returncode == 0 and quiet.stderr == ""
