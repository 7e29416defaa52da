"""feeler demo: runs its stages on a small four-plates, prints the table, writes Figs 7-9.

The whole campaign (every stage, the report included) runs once per session in
tests/reports/conftest.py; tests/reports/test_report_demo.py checks what it wrote."""
import json
import os
from pathlib import Path

import pytest

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
    ctx = run_demo(tmp_path / "demo", scene_path=small, echo=printed.append, stages=STAGES[:4])
    assert [name for name, _ in STAGES[:4]] == ["simulate", "features", "table", "figures"]
    for name in FIGURES:
        data = (tmp_path / "demo" / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 5000
    table = json.loads((tmp_path / "demo" / "robot_table.json").read_text())
    assert [r["step_mm"] for r in table["plates"]] == [0.0, 0.05, 0.1, 0.2]
    assert all(r["n_scans"] == 4 for r in table["plates"])
    assert len(table["adjacent_pairs"]) == 3
    assert printed[0] == "[1/4] simulate ..."
    stage_lines = [ln for ln in printed if ln.startswith("[")]
    assert [ln.split(" ...")[0] for ln in stage_lines] == ["[1/4] simulate", "[2/4] features", "[3/4] table",
                                                           "[4/4] figures"]
    assert all(ln.endswith(" so far)") for ln in stage_lines[1:])                   # the time so far
    text = next(p for p in printed if "peak z" in p)
    assert "peak z" in text and "0.050 vs 0.100" in text
    assert ctx["z"].shape == ctx["scans"].uy_mm.shape
    # the table's numbers are the features of the run's files
    f, sel = ctx["features"], ctx["scans"].step_mm == 0.2
    assert table["plates"][3]["peak_z_mean"] == pytest.approx(f.peak_z[sel].mean())


def test_a_scene_of_ones_own_is_filed_under_its_own_name(tmp_path, small):
    """`feeler demo --scene small.toml` wrote its scans into OUT/four-plates/, where a user
    looks for the shipped scene's."""
    run_demo(tmp_path / "demo", scene_path=small, echo=lambda s: None, stages=STAGES[:1])
    assert (tmp_path / "demo" / "small" / "scans.csv").is_file()
    assert "scans_per_plate = 4" in (tmp_path / "demo" / "small" / "scene.toml").read_text(encoding="utf-8")
    assert not (tmp_path / "demo" / "four-plates").exists()
    with pytest.raises(OverwriteError, match="small/scans.csv"):     # its scans are guarded as the shipped ones are
        run_demo(tmp_path / "demo", scene_path=small, echo=lambda s: None, stages=STAGES[:1])


@pytest.mark.parametrize("name, edit, key, words", [
    # an outside audit: a finger-steps or sensor-calibration scene ran its simulation for 12 s, then
    # failed on '.../scans.csv: no such file'; one plate ran every stage (32 s) to a failed verdict
    ("finger-steps.toml", None, "scene.kind", "'finger-steps': demo --scene takes a robot-scan scene"),
    ("sensor-calibration.toml", None, "scene.kind", "'sensor-calibration': demo --scene takes a robot-scan"),
    ("plans/four-plates-plan.toml", None, "scene.kind", "'scan-plan': demo --scene takes a robot-scan scene"),
    ("four-plates.toml", ("heights_mm = [0.0, 0.05, 0.1, 0.2]", "heights_mm = [0.1]"), "surface.heights_mm",
     "[0.1]: one plate; the demo calibrates the neuron on at least 2 plates"),
])
def test_a_scene_the_demo_cannot_run_is_refused_before_any_stage(tmp_path, name, edit, key, words):
    from feeler.errors import SceneError

    path = SHIPPED.parent / name
    if edit is not None:
        text = path.read_text(encoding="utf-8")
        assert edit[0] in text
        path = tmp_path / "edited.toml"
        path.write_text(text.replace(*edit), encoding="utf-8")
    printed = []
    with pytest.raises(SceneError) as info:
        run_demo(tmp_path / "demo", scene_path=path, echo=printed.append)
    assert info.value.key == key and words in info.value.problem
    assert printed == [] and not (tmp_path / "demo").exists()


def test_demo_refuses_to_overwrite_without_force(tmp_path, small):
    run_demo(tmp_path / "demo", scene_path=small, echo=lambda s: None, stages=STAGES[:1])
    with pytest.raises(OverwriteError):
        run_demo(tmp_path / "demo", scene_path=small, echo=lambda s: None, stages=STAGES[:1])
    run_demo(tmp_path / "demo", scene_path=small, echo=lambda s: None, stages=STAGES[:1], force=True)


def test_a_second_demo_into_the_same_directory_is_refused_while_the_first_runs(tmp_path, small):
    """Two `make demo` at once (both --force) overwrote each other's files stage by stage."""
    from feeler.hardware.acquire.lock import RunLocked, lock_run_dir, release_run_dir

    first = lock_run_dir(tmp_path / "demo", then="")                 # the first demo, mid-run
    try:
        with pytest.raises(RunLocked, match=rf"demo: process {os.getpid()} is writing this run directory \(one "
                                            r"writer at a time\); wait for it to finish or stop it$"):
            run_demo(tmp_path / "demo", scene_path=small, echo=lambda s: None, stages=STAGES[:1], force=True)
    finally:
        release_run_dir(first)
    run_demo(tmp_path / "demo", scene_path=small, echo=lambda s: None, stages=STAGES[:1], force=True)


def test_held_out_scene_moves_only_the_seed(tmp_path):
    from feeler.demo.campaign import HELD_OUT_SEED_OFFSET, held_out_scene
    from feeler.scene import load_scene

    a = load_scene(SHIPPED)
    b = load_scene(held_out_scene(SHIPPED, tmp_path / "held.toml"))
    assert b.scene.seed == a.scene.seed + HELD_OUT_SEED_OFFSET
    assert b.surface == a.surface and b.noise == a.noise and b.repeats == a.repeats
    # a seed near the top of TOML's range wraps round instead of leaving it (the held-out stage failed)
    top = tmp_path / "top.toml"
    top.write_text(SHIPPED.read_text(encoding="utf-8").replace(f"seed = {a.scene.seed}", f"seed = {2**63 - 10}", 1))
    assert load_scene(held_out_scene(top, tmp_path / "held-top.toml")).scene.seed == HELD_OUT_SEED_OFFSET - 10


def test_a_failing_stage_is_named_and_earlier_results_stay(tmp_path, small):
    from feeler.demo.campaign import StageFailed, _run

    ctx = {"out": tmp_path, "print": lambda s: None}
    (tmp_path / "kept.txt").write_text("earlier result")
    with pytest.raises(StageFailed) as info:
        _run(ctx, "calibrate-neuron", ["calibrate", "neuron", str(tmp_path / "missing")], keep=lambda l: l)
    assert info.value.stage == "calibrate-neuron" and info.value.code == 2
    assert "calibrate-neuron" in str(info.value) and "\n" not in str(info.value)
    assert (tmp_path / "logs" / "calibrate-neuron.txt").is_file()
    assert (tmp_path / "kept.txt").read_text() == "earlier result"


def test_speed_tables_of_the_last_bench_are_copied_with_their_source(tmp_path):
    from feeler.demo.campaign import _speed_tables

    printed = []
    out = tmp_path / "runs" / "demo"
    out.mkdir(parents=True)
    ctx = {"out": out, "print": printed.append, "measure_trades": False}
    _speed_tables(ctx)                                   # nothing measured yet: says so
    assert "make bench" in printed[-1] and not (out / "benchmarks").exists()
    bench = tmp_path / "runs" / "benchmarks"
    bench.mkdir()
    (bench / "ratios.csv").write_text("benchmark,ratio,goal\nx,0.5,>= 0.25\n")
    _speed_tables(ctx)
    assert (out / "benchmarks" / "ratios.csv").read_text() == (bench / "ratios.csv").read_text()
    assert str(bench) in (out / "benchmarks" / "SOURCE.txt").read_text()


def test_a_failed_fit_skips_what_needs_it_and_the_rest_still_runs(tmp_path, small, capsys, monkeypatch):
    """A neuron fit that fails its verdict (a user's own scene, say) stopped the demo: no
    report, no human fits. Now the stages that need it are skipped, the others run, and
    the demo ends failed, naming the stage, its log and what was skipped."""
    import argparse

    import feeler.demo
    from feeler.commands import demo as demo_command
    from feeler.demo.campaign import DemoIncomplete, StageFailed

    ran = []

    def fit(ctx):
        raise StageFailed("calibrate-neuron", 1, ctx["out"] / "logs" / "calibrate-neuron.txt")

    stages = [("calibrate neuron", fit), ("classify", lambda ctx: ran.append("classify")),
              ("psychophysics", lambda ctx: ran.append("psychophysics"))]
    printed = []
    with pytest.raises(DemoIncomplete) as info:
        run_demo(tmp_path / "demo", scene_path=small, echo=printed.append, stages=stages)
    assert ran == ["psychophysics"] and info.value.skipped == ["classify"] and info.value.code == 1
    assert list(info.value.failed) == ["calibrate neuron"] and "psychophysics" in info.value.ctx["seconds"]
    assert "[2/3] classify: skipped, it needs calibrate neuron, which failed" in printed
    assert str(info.value).startswith("1 demo stage failed: 'calibrate neuron' (exit 1, see ")
    assert str(info.value).endswith("skipped as they need it: 'classify'")
    # the command prints its closing table, then fails with the same line and the stage's exit status
    monkeypatch.setattr(feeler.demo, "run_demo", lambda *a, **k: run_demo(tmp_path / "cli", scene_path=small,
                                                                           echo=lambda s: None, stages=stages))
    code = demo_command.run(argparse.Namespace(out=str(tmp_path / "cli"), force=False, scene=None, progress=False))
    captured = capsys.readouterr()
    assert code == 1
    assert "classify                    -       -   skipped: it needs calibrate neuron, which failed" in captured.out
    assert captured.err.startswith("feeler: failed: 1 demo stage failed: 'calibrate neuron'")


def test_ctrl_c_stops_the_demo_after_the_running_stage_and_builds_no_report(tmp_path, small, capsys, monkeypatch):
    """Ctrl-C killed only the running stage's command (it exits 130 in-process): the demo
    logged it as FAILED, ran the other stages and rebuilt the report, which then showed an
    earlier run's files as this run's. Now it stops there, builds no report and says in one
    line which stages finished (kept) and what is an earlier run's; exit 130."""
    import argparse

    import feeler.demo
    import feeler.simulate
    from feeler.commands import demo as demo_command
    from feeler.demo.campaign import _calibrate_sensor      # runs `feeler simulate` in-process

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    ran = []
    stages = [("table", lambda ctx: ran.append("table")), ("calibrate sensor", _calibrate_sensor),
              ("discriminate", lambda ctx: ran.append("discriminate")), ("report", lambda ctx: ran.append("report"))]
    out = tmp_path / "demo"
    out.mkdir()
    (out / "report.html").write_text("an earlier demo's report")
    monkeypatch.setattr(feeler.simulate, "run_simulation", interrupted)
    monkeypatch.setattr(feeler.demo, "run_demo", lambda *a, **k: run_demo(out, scene_path=small, force=True,
                                                                           echo=lambda s: None, stages=stages))
    code = demo_command.run(argparse.Namespace(out=str(out), force=True, scene=None, progress=False))
    captured = capsys.readouterr()
    assert code == 130 and ran == ["table"]
    assert captured.out == "" and len(captured.err.strip().splitlines()) == 1 and "Traceback" not in captured.err
    line = captured.err.strip()
    assert line.startswith("feeler: demo interrupted during stage 'calibrate sensor': ")
    assert f"outputs are kept in {out} (table)" in line and "no report was built" in line
    assert f"{out / 'report.html'} and the outputs of the stages that did not run are an earlier run's" in line
    assert f"feeler demo --out {out} --force" in line
    assert (out / "report.html").read_text() == "an earlier demo's report"
    assert "interrupted" in (out / "logs" / "simulate-sensor-calibration.txt").read_text()


def test_ctrl_c_in_a_robot_stage_names_it_and_no_finished_stage(tmp_path, small):
    from feeler.demo.campaign import DemoInterrupted

    def interrupted(ctx):
        raise KeyboardInterrupt

    with pytest.raises(DemoInterrupted) as info:
        run_demo(tmp_path / "demo", scene_path=small, echo=lambda s: None,
                 stages=[("simulate", interrupted), ("report", lambda ctx: None)])
    assert isinstance(info.value, KeyboardInterrupt) and info.value.code == 130
    assert info.value.stage == "simulate" and info.value.done == []
    assert "no stage had finished" in info.value.message() and "earlier run" not in info.value.message()
