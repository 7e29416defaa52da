"""--progress/--no-progress honoured by the commands that used to ignore it: decode (a line
per decision, also with --follow), discriminate (a line per pair off a terminal, then the
threshold and PSE stages), fit finger-route (its fit and check stages). Off a terminal the
default is a line per stage; --no-progress leaves stderr empty and the results unchanged."""
from __future__ import annotations

import pandas as pd
import pytest

from feeler.cli import main
from tests.cli._run import ROOT

SCENES = ROOT / "datasets-synthetic"


@pytest.fixture(scope="module")
def neuron(tmp_path_factory) -> tuple:
    """(M2 fit directory, its simulated four-plates run with 6 scans per plate)."""
    tmp = tmp_path_factory.mktemp("neuron")
    scene = tmp / "four-plates-small.toml"
    text = (SCENES / "four-plates.toml").read_text(encoding="utf-8")
    assert "scans_per_plate = 24" in text
    scene.write_text(text.replace("scans_per_plate = 24", "scans_per_plate = 6"), encoding="utf-8")
    assert main(["simulate", str(scene), "--out", str(tmp / "run"), "--no-progress"]) == 0
    assert main(["calibrate", "neuron", str(tmp / "run"), "--out", str(tmp / "m2"), "--draws", "300",
                 "--no-progress"]) == 0
    return tmp / "m2", tmp / "run"


def test_decode_a_line_per_decision_and_none_with_no_progress(neuron, tmp_path, capsys):
    fit, run = neuron
    capsys.readouterr()
    assert main(["decode", str(fit), str(run), "--n-draws", "40", "--out", str(tmp_path / "a")]) == 0
    err = capsys.readouterr().err.splitlines()
    assert err[0].startswith("feeler decode: ") and len(err) > 1
    assert all(ln.startswith("scan ") for ln in err[1:]) and any(": decided " in ln for ln in err[1:])
    assert main(["decode", str(fit), str(run), "--n-draws", "40", "--out", str(tmp_path / "b"), "--no-progress"]) == 0
    out = capsys.readouterr()
    assert out.err == "" and "wrote" in out.out
    pd.testing.assert_frame_equal(pd.read_csv(tmp_path / "a" / "decisions.csv"),
                                  pd.read_csv(tmp_path / "b" / "decisions.csv"))


def test_decode_follow_with_no_progress(neuron, tmp_path, capsys):
    """--follow on a run nobody writes any more: decoded as far as it goes, in silence."""
    fit, run = neuron
    live = tmp_path / "live"
    live.mkdir()
    pd.read_csv(run / "scans.csv").to_csv(live / "samples.csv", index=False)
    capsys.readouterr()
    assert main(["decode", str(fit), str(live), "--follow", "--poll-s", "0.02", "--wait-s", "1", "--n-draws", "40",
                 "--no-progress"]) == 0
    out = capsys.readouterr()
    assert out.err == "" and f"wrote {live / 'decisions.csv'}" in out.out
    assert len(pd.read_csv(live / "decisions.csv")) == 24


def test_discriminate_a_line_per_pair_then_its_stages(neuron, tmp_path, capsys):
    fit, _ = neuron
    argv = ["discriminate", str(fit), "--n-scans", "30", "--n-draws", "20", "--pair", "0", "0.1",
            "--pair", "0.1", "0.2"]
    capsys.readouterr()
    assert main(argv) == 0
    out, err = capsys.readouterr()
    lines = err.splitlines()[1:]
    assert [ln.split(" done")[0] for ln in lines[:2]] == ["2AFC pairs: 1/2", "2AFC pairs: 2/2"]
    assert lines[2:] == ["difference threshold at 75 % around 0.1 mm ...",
                         "PSE of 0.1 mm between 0.5 and 1 mm/s ..."]
    assert main([*argv, "--no-progress"]) == 0
    quiet = capsys.readouterr()
    assert quiet.err == "" and quiet.out == out


def test_finger_route_says_what_it_fits(tmp_path, capsys):
    data = tmp_path / "psy"
    assert main(["simulate", str(SCENES / "psychophysics-2afc.toml"), "--out", str(data), "--no-progress"]) == 0
    capsys.readouterr()
    argv = ["fit", "finger-route", str(data / "trials.csv"), "--n-tau", "31", "--draws", "200"]
    assert main(argv) in (0, 1)
    out, err = capsys.readouterr()
    assert err.splitlines()[1:] == ["fitting tau, sigma_d and the lapse through skin l0 -> neuron -> observer "
                                    "(31 tau nodes) ..."]
    assert main([*argv, "--no-progress"]) in (0, 1)
    quiet = capsys.readouterr()
    assert quiet.err == "" and _untimed(quiet.out) == _untimed(out)


def _untimed(text: str) -> list[str]:
    """The lines of a fit's output without its timing line ("backend ..., 0.194 s")."""
    return [ln for ln in text.splitlines() if not ln.startswith("backend ")]


def test_demo_passes_no_progress_to_its_simulation(tmp_path, capsys):
    from feeler.demo import STAGES, run_demo

    scene = tmp_path / "four-plates-small.toml"
    scene.write_text((SCENES / "four-plates.toml").read_text(encoding="utf-8")
                     .replace("scans_per_plate = 24", "scans_per_plate = 6"), encoding="utf-8")
    said = []
    run_demo(tmp_path / "a", scene_path=scene, stages=STAGES[:1], echo=said.append)
    assert said == ["[1/1] simulate ..."]
    assert capsys.readouterr().err == "simulating 24 scans of 4 plates (displacement fidelity) ...\n"
    said.clear()
    run_demo(tmp_path / "b", scene_path=scene, stages=STAGES[:1], echo=said.append, progress=False)
    assert said == [] and capsys.readouterr().err == ""


def test_the_demo_says_its_stages_apart_from_its_results(tmp_path):
    """`feeler demo` printed its "[i/n] stage ..." lines on stdout among the results; the
    command gives them to stderr (``stage_echo``) and keeps the results' tables on stdout."""
    from feeler.demo import STAGES, run_demo

    scene = tmp_path / "four-plates-small.toml"
    scene.write_text((SCENES / "four-plates.toml").read_text(encoding="utf-8")
                     .replace("scans_per_plate = 24", "scans_per_plate = 6"), encoding="utf-8")
    results, stages = [], []
    run_demo(tmp_path / "a", scene_path=scene, stages=STAGES[:3], echo=results.append, stage_echo=stages.append)
    assert [ln.split(" ...")[0] for ln in stages] == ["[1/3] simulate", "[2/3] features", "[3/3] table"]
    assert results and not any(ln.startswith("[") for ln in results)
    assert any("step_mm" in ln for ln in results)                   # the table stage's table


def test_the_demo_stages_progress_goes_to_stderr_and_no_progress_drops_it(tmp_path):
    """`feeler demo` echoed the campaign commands' output by markers in one stream that held
    stdout and stderr: the progress after a marker (calibrate sensor's "writing DIR ...",
    the discrimination's "2AFC pairs: 1/6 done, ... left") landed on stdout among the
    results, with --no-progress too. Now results come from the command's stdout only, its
    progress goes to the stage lines (stderr) as it comes, and --no-progress passes on."""
    from feeler.demo import STAGES, run_demo

    stage = [s for s in STAGES if s[0] == "calibrate sensor"]
    results, said = [], []
    run_demo(tmp_path / "a", stages=stage, echo=results.append, stage_echo=said.append)
    shown = "\n".join(results)
    assert "C[0,0]" in shown and "verdict: ok" in shown and f"wrote {tmp_path / 'a' / 'm1'}" in shown
    assert "writing" not in shown and not any(ln.endswith("...") for ln in shown.splitlines())
    assert f"writing {tmp_path / 'a' / 'm1'} ..." in said                  # the progress, on the stage lines
    assert "writing" in (tmp_path / "a" / "logs" / "calibrate-sensor.txt").read_text()    # and in the log
    results.clear(), said.clear()
    run_demo(tmp_path / "b", stages=stage, echo=results.append, stage_echo=said.append, progress=False)
    assert said == []
    assert _untimed("\n".join(results).replace(str(tmp_path / "b"), "")) == _untimed(shown.replace(str(tmp_path / "a"), ""))
    log = (tmp_path / "b" / "logs" / "calibrate-sensor.txt").read_text()
    assert "--no-progress" in log.splitlines()[0] and "writing" not in log


@pytest.mark.parametrize("progress", [None, False])
def test_the_demo_discrimination_table_holds_no_progress_lines(neuron, tmp_path, progress):
    """The reported case: the discrimination stage's "2AFC pairs: 1/6 done, 0.3 s, about
    1.5 s left" lines stood between its table's rows on stdout."""
    from feeler.demo.campaign import _discriminate

    fit, _ = neuron
    (tmp_path / "m2").symlink_to(fit, target_is_directory=True)
    results, said = [], []
    ctx = {"out": tmp_path, "print": results.append, "say": said.append, "force": False, "progress": progress,
           "discriminate_scans": 40}
    _discriminate(ctx)
    shown = "\n".join(results)
    assert "low mm" in shown and "threshold at 75 %" in shown and "PSE of" in shown
    assert "2AFC pairs" not in shown and "done" not in shown and not any(ln.endswith("...") for ln in results)
    if progress is False:
        assert said == []
    else:
        assert any(ln.startswith("2AFC pairs: 1/") and "left" in ln for ln in said)


@pytest.mark.parametrize("progress", [None, False])
def test_feeler_demo_prints_results_on_stdout_and_progress_on_stderr(tmp_path, capsys, monkeypatch, progress):
    """The command itself: its stage lines go to sys.stderr, which a stage's command has
    redirected into its capture while it runs (the first version of this recursed)."""
    import argparse

    import feeler.demo
    from feeler.commands import demo as demo_command
    from feeler.demo import STAGES, run_demo

    stage = [s for s in STAGES if s[0] == "calibrate sensor"]
    monkeypatch.setattr(feeler.demo, "run_demo", lambda out, **k: run_demo(out, stages=stage, **k))
    capsys.readouterr()
    code = demo_command.run(argparse.Namespace(out=str(tmp_path / "demo"), force=False, scene=None, progress=progress))
    out, err = capsys.readouterr()
    assert code == 0 and "C[0,0]" in out and "verdict: ok" in out and "writing" not in out
    if progress is False:
        assert err == ""
    else:
        assert f"writing {tmp_path / 'demo' / 'm1'} ...\n" in err and "[1/1] calibrate sensor ..." in err
        assert "C[0,0]" not in err
