"""feeler demo: runs its stages on a small four-plates, prints the table, writes Figs 7-9."""
import json
from pathlib import Path

import pytest

from feeler.cli import main
from feeler.demo import FIGURES, STAGES, run_demo
from feeler.errors import OverwriteError

SHIPPED = Path(__file__).resolve().parents[1] / "datasets-synthetic" / "four-plates.toml"


@pytest.fixture
def small(tmp_path):
    path = tmp_path / "small.toml"
    path.write_text(SHIPPED.read_text(encoding="utf-8").replace("scans_per_plate = 24", "scans_per_plate = 4"),
                    encoding="utf-8")
    return path


def test_demo_writes_figures_and_table(tmp_path, small):
    printed = []
    ctx = run_demo(tmp_path / "demo", scene_path=small, echo=printed.append)
    assert [name for name, _ in STAGES] == ["simulate", "features", "table", "figures"]
    for name in FIGURES:
        data = (tmp_path / "demo" / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 5000
    table = json.loads((tmp_path / "demo" / "robot_table.json").read_text())
    assert [r["step_mm"] for r in table["plates"]] == [0.0, 0.05, 0.1, 0.2]
    assert all(r["n_scans"] == 4 for r in table["plates"])
    assert len(table["adjacent_pairs"]) == 3
    text = printed[0]
    assert "peak z" in text and "0.050 vs 0.100" in text
    assert ctx["z"].shape == ctx["scans"].uy_mm.shape
    # the table's numbers are the features of the run's files
    f, sel = ctx["features"], ctx["scans"].step_mm == 0.2
    assert table["plates"][3]["peak_z_mean"] == pytest.approx(f.peak_z[sel].mean())


def test_demo_refuses_to_overwrite_without_force(tmp_path, small):
    run_demo(tmp_path / "demo", scene_path=small, echo=lambda s: None, stages=STAGES[:1])
    with pytest.raises(OverwriteError):
        run_demo(tmp_path / "demo", scene_path=small, echo=lambda s: None, stages=STAGES[:1])
    run_demo(tmp_path / "demo", scene_path=small, echo=lambda s: None, stages=STAGES[:1], force=True)


def test_demo_cli(tmp_path, small, capsys):
    assert main(["demo", "--out", str(tmp_path / "d"), "--scene", str(small)]) == 0
    out = capsys.readouterr().out
    assert "2AFC" in out and "fig9_pulse_density.png" in out
    assert main(["demo", "--out", str(tmp_path / "d"), "--scene", str(small)]) == 2
    assert "--force" in capsys.readouterr().err
