"""`feeler simulate --progress/--no-progress`: a line per stage off a terminal, a bar on one,
nothing but the "wrote" line with --no-progress, for the robot (displacement and images
fidelities), calibration and finger simulators; the data do not depend on the switch."""
from __future__ import annotations

import re
import sys

import pytest

from feeler.cli import main
from tests.cli._run import ROOT, feeler, in_a_pty
from tests.small_scenes import small_finger_scene

SCENES = ROOT / "datasets-synthetic"
FOUR = SCENES / "four-plates.toml"
IMAGES = SCENES / "four-plates-images.toml"


def _wrote(text: str) -> list[str]:
    return [ln for ln in text.replace("\r\n", "\n").split("\n") if ln.startswith("wrote ")]


def test_off_a_terminal_a_line_per_stage_and_none_with_no_progress(tmp_path):
    out = feeler("simulate", FOUR, "--out", tmp_path / "a")
    assert out.returncode == 0, out.stderr
    assert out.stderr.splitlines() == [f"feeler simulate: simulating {FOUR} (loading libraries) ...",
                                       "simulating 96 scans of 4 plates (displacement fidelity) ..."]
    quiet = feeler("simulate", FOUR, "--out", tmp_path / "b", "--no-progress")
    assert quiet.returncode == 0 and quiet.stderr == ""
    assert quiet.stdout == out.stdout.replace(str(tmp_path / "a"), str(tmp_path / "b"))
    assert _wrote(quiet.stdout) == [f"wrote {tmp_path / 'b'}: scans.csv, scene.toml, truth.json"]
    assert (tmp_path / "a" / "scans.csv").read_bytes() == (tmp_path / "b" / "scans.csv").read_bytes()


def test_progress_draws_the_bar_even_off_a_terminal(tmp_path):
    out = feeler("simulate", FOUR, "--out", tmp_path / "a", "--progress")
    assert out.returncode == 0, out.stderr
    assert "simulating 96 scans of 4 plates" in out.stderr and "scans: " in out.stderr and "/96 [" in out.stderr


def test_on_a_terminal_a_bar_and_with_no_progress_only_the_wrote_line(tmp_path):
    text = in_a_pty([sys.executable, "-m", "feeler", "simulate", str(FOUR), "--out", str(tmp_path / "a")])
    assert "simulating 96 scans of 4 plates (displacement fidelity) ..." in text
    assert "scans: " in text and "\r" in text                                  # a bar redrawn in place
    quiet = in_a_pty([sys.executable, "-m", "feeler", "simulate", str(FOUR), "--out", str(tmp_path / "b"),
                      "--no-progress"])
    assert quiet.replace("\r\n", "\n").strip().split("\n") == _wrote(quiet) == [
        f"wrote {tmp_path / 'b'}: scans.csv, scene.toml, truth.json"]


def test_images_fidelity_stages_off_a_terminal(tmp_path):
    out = feeler("simulate", IMAGES, "--out", tmp_path / "a")
    assert out.returncode == 0, out.stderr
    lines = out.stderr.splitlines()
    assert lines[1] == "simulating 32 scans of 4 plates (images fidelity) ..."
    assert re.fullmatch(r"rendering (\d+) camera frames of 16 elements \.\.\.", lines[2])
    n = lines[2].split()[1]
    assert lines[3:] == [f"reading the contact areas off {n} frames (OpenCV) ..."]           # no bar off a terminal


def test_images_fidelity_silent_on_a_terminal_with_no_progress(tmp_path):
    """The frame reader's bar used to show on a terminal whatever the switch said."""
    text = in_a_pty([sys.executable, "-m", "feeler", "simulate", str(IMAGES), "--out", str(tmp_path / "a"),
                     "--no-progress"])
    assert text.replace("\r\n", "\n").strip().split("\n") == [
        f"wrote {tmp_path / 'a'}: scans.csv, scene.toml, truth.json"]


def test_calibration_campaign_stage(tmp_path, capsys):
    scene = SCENES / "sensor-calibration.toml"
    assert main(["simulate", str(scene), "--out", str(tmp_path / "a")]) == 0
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 2 and re.fullmatch(r"simulating a calibration campaign of \d+ points "
                                          r"\(displacement fidelity\) \.\.\.", err[1])
    assert main(["simulate", str(scene), "--out", str(tmp_path / "b"), "--no-progress"]) == 0
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize("flag", [None, "--no-progress"])
def test_finger_steps_the_shared_mesh_is_a_stage_before_the_runs(tmp_path, capsys, flag):
    scene = small_finger_scene(tmp_path / "finger-small.toml")
    assert re.search(r'(?m)^level = "l1"', scene.read_text(encoding="utf-8"))
    assert main(["simulate", str(scene), "--out", str(tmp_path / "a"), *([flag] if flag else [])]) == 0
    out, err = capsys.readouterr()
    assert _wrote(out) == [f"wrote {tmp_path / 'a'}: scene.toml, strain.csv, truth.json"]
    if flag:
        assert err == ""
        return
    lines = err.splitlines()
    assert lines[1] == "skin L1: meshing the finger, its stiffness and pressed contact (once for the 6 runs) ..."
    assert [ln.split(" done")[0] for ln in lines[2:]] == [f"skin runs (l1, height x speed): {i}/6"
                                                          for i in range(1, 7)]
