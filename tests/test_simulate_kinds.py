"""`feeler simulate` serves every shipped scene kind, deterministically, without overwriting."""
from pathlib import Path

import pytest

from feeler.cli import main

ROOT = Path(__file__).resolve().parents[1] / "datasets-synthetic"
CASES = [("sensor-calibration", "calibration.csv"), ("psychophysics-2afc", "trials.csv"),
         ("finger-steps", "strain.csv")]


@pytest.mark.parametrize("name, data", CASES)
def test_each_kind_writes_its_files_reproducibly(tmp_path, name, data):
    a, b = tmp_path / "a", tmp_path / "b"
    assert main(["simulate", str(ROOT / f"{name}.toml"), "--out", str(a)]) == 0
    assert main(["simulate", str(ROOT / f"{name}.toml"), "--out", str(b)]) == 0
    for f in ("scene.toml", "truth.json", data):
        assert (a / f).read_bytes() == (b / f).read_bytes(), f
    assert (a / "scene.toml").read_bytes() == (ROOT / f"{name}.toml").read_bytes()


@pytest.mark.parametrize("name, data", CASES)
def test_existing_data_are_kept_without_force(tmp_path, name, data, capsys):
    out = tmp_path / "run"
    assert main(["simulate", str(ROOT / f"{name}.toml"), "--out", str(out)]) == 0
    before = (out / data).read_bytes()
    assert main(["simulate", str(ROOT / f"{name}.toml"), "--out", str(out)]) == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("feeler:")]
    assert len(err) == 1 and "--force" in err[0]
    assert (out / data).read_bytes() == before
    assert main(["simulate", str(ROOT / f"{name}.toml"), "--out", str(out), "--force"]) == 0
