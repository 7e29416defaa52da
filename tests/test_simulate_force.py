"""`feeler simulate --force` into a directory holding another run: DIR holds the new run only.

Before, a robot-scan simulation forced over a sensor-calibration one kept its
calibration.csv, and `feeler report` then showed both as one run (an outside audit)."""
from __future__ import annotations

from pathlib import Path

import pytest

from feeler.cli import main
from feeler.scene import load_scene
from feeler.simulate.stale import outputs_of
from tests.small_scenes import small_finger_scene

ROOT = Path(__file__).resolve().parents[1] / "datasets-synthetic"


def _small_robot(tmp_path, features: bool = False) -> Path:
    text = (ROOT / "four-plates.toml").read_text(encoding="utf-8").replace("scans_per_plate = 24", "scans_per_plate = 2")
    if features:
        text = text.replace('outputs = ["scans"]', 'outputs = ["scans", "features"]')
    path = tmp_path / ("robot-features.toml" if features else "robot.toml")
    path.write_text(text, encoding="utf-8")
    return path


def _simulate(scene, out, *flags) -> int:
    return main(["simulate", str(scene), "--out", str(out), "--no-progress", *flags])


def test_an_earlier_simulation_and_its_report_are_replaced_not_mixed(tmp_path, capsys):
    run = tmp_path / "run"
    assert _simulate(ROOT / "sensor-calibration.toml", run) == 0
    for name in ("report.html", "report.pdf", "report-manifest.json"):
        (run / name).write_text("the calibration run's report")
    (run / "notes.txt").write_text("a user's own file")
    capsys.readouterr()
    assert main(["simulate", str(_small_robot(tmp_path)), "--out", str(run), "--force"]) == 0
    err = capsys.readouterr().err
    assert sorted(p.name for p in run.iterdir()) == ["notes.txt", "scans.csv", "scene.toml", "truth.json"]
    assert (run / "notes.txt").read_text() == "a user's own file"
    assert load_scene(run / "scene.toml").scene.kind == "robot-scan"
    assert (f"--force: removed the earlier run's calibration.csv, report.html, report.pdf, report-manifest.json "
            f"from {run}") in err


def test_features_of_an_earlier_run_of_the_same_kind_go_too(tmp_path):
    run = tmp_path / "run"
    assert _simulate(_small_robot(tmp_path, features=True), run) == 0
    assert (run / "features.csv").is_file()
    assert _simulate(_small_robot(tmp_path), run, "--force") == 0
    assert not (run / "features.csv").exists()


@pytest.mark.parametrize("files, first", [
    ({"calibration.csv": "fx_n,ux_mm\n1,0.2\n"}, "calibration.csv"),               # measured: no truth.json
    ({"posterior.nc": "a fit", "summary.csv": "name\n", "verdict.json": "{}"}, "posterior.nc"),
])
def test_files_feeler_cannot_tell_it_wrote_are_refused_before_any_work(tmp_path, capsys, files, first):
    run = tmp_path / "run"
    run.mkdir()
    for name, text in files.items():
        (run / name).write_text(text)
    assert _simulate(_small_robot(tmp_path), run, "--force") == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("feeler:")]
    assert len(err) == 1 and err[0].startswith(f"feeler: error: {run / first}: already exists; this robot-scan "
                                               "simulation does not write it")
    assert "move it away or choose another --out" in err[0]
    assert sorted(p.name for p in run.iterdir()) == sorted(files)                # nothing written, nothing removed
    assert all((run / n).read_text() == t for n, t in files.items())


def test_a_calibration_beside_a_simulated_scan_run_is_not_taken_for_its_own(tmp_path):
    """truth.json alone is not enough: the earlier scene.toml's kind must write the file."""
    run = tmp_path / "run"
    assert _simulate(_small_robot(tmp_path), run) == 0
    (run / "calibration.csv").write_text("fx_n,ux_mm\n1,0.2\n")
    assert _simulate(_small_robot(tmp_path), run, "--force") == 2
    assert (run / "calibration.csv").is_file()


@pytest.mark.parametrize("kind", ["robot", "robot-features", "sensor-calibration", "psychophysics-2afc",
                                  "finger-steps"])
def test_outputs_of_is_what_each_kind_writes(tmp_path, kind):
    scene = {"robot": lambda: _small_robot(tmp_path), "robot-features": lambda: _small_robot(tmp_path, True),
             "finger-steps": lambda: small_finger_scene(tmp_path / "finger.toml")}.get(
        kind, lambda: ROOT / f"{kind}.toml")()
    assert _simulate(scene, tmp_path / "run") == 0
    assert sorted(p.name for p in (tmp_path / "run").iterdir()) == sorted(outputs_of(load_scene(scene)))


def test_decode_and_classify_results_on_the_earlier_scans_go_with_them(tmp_path, capsys):
    """decode's decisions.csv of the earlier scans stayed beside the new scans.csv, and the
    "wrote" line said simulate wrote it (an outside walk-through)."""
    run = tmp_path / "run"
    assert _simulate(_small_robot(tmp_path), run, "--seed", "1") == 0
    (run / "decisions.csv").write_text("scan_id,decision\n0,0.1\n")
    (run / "classification.csv").write_text("scan_id,p\n0,0.9\n")
    capsys.readouterr()
    assert main(["simulate", str(_small_robot(tmp_path)), "--out", str(run), "--force"]) == 0
    out, err = capsys.readouterr()
    assert sorted(p.name for p in run.iterdir()) == ["scans.csv", "scene.toml", "truth.json"]
    assert out == f"wrote {run}: scans.csv, scene.toml, truth.json\n"
    assert (f"--force: removed decode's decisions (decisions.csv) and classify's classification "
            f"(classification.csv) on the earlier run's scans from {run}") in err


@pytest.mark.parametrize("name", ["decisions.csv", "classification.csv", "thresholds.csv", "discrimination.json"])
def test_results_of_other_data_are_refused_like_a_fit(tmp_path, capsys, name):
    """Another command's results where no earlier robot simulation accounts for them: feeler
    cannot tell they are of the old data, so --force refuses them, as a fit's files."""
    run = tmp_path / "run"
    assert _simulate(ROOT / "sensor-calibration.toml", run) == 0
    (run / name).write_text("a result")
    capsys.readouterr()
    assert _simulate(_small_robot(tmp_path), run, "--force") == 2
    err = capsys.readouterr().err
    assert f"feeler: error: {run / name}: already exists; this robot-scan simulation does not write it" in err
    assert "the earlier sensor-calibration simulation there did not" in err
    assert (run / name).read_text() == "a result" and (run / "calibration.csv").is_file()


@pytest.mark.parametrize("force", [True, False])
def test_a_users_own_file_stays_and_is_not_claimed(tmp_path, capsys, force):
    run = tmp_path / "run"
    if force:
        assert _simulate(_small_robot(tmp_path), run) == 0
    else:
        run.mkdir()
    (run / "mynotes.txt").write_text("mine")
    (run / "plots").mkdir()
    capsys.readouterr()
    flags = ["--force"] if force else []
    assert main(["simulate", str(ROOT / "sensor-calibration.toml"), "--out", str(run), *flags]) == 0
    out, err = capsys.readouterr()
    assert out == f"wrote {run}: calibration.csv, scene.toml, truth.json\n"             # not mynotes.txt
    assert (run / "mynotes.txt").read_text() == "mine"
    assert (f"{'--force: ' if force else ''}left mynotes.txt, plots/ in {run} as they were: not written by this "
            "simulation, so not part of its run") in err
    assert _simulate(ROOT / "sensor-calibration.toml", run, "--force") == 0        # --no-progress: the wrote line only
    out, err = capsys.readouterr()
    assert out == f"wrote {run}: calibration.csv, scene.toml, truth.json\n" and err == ""
