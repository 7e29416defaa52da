"""Scan plans: schema rules, scans and moves, soft-limit checks, the virtual set-up (no devices)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from feeler.errors import SceneError
from feeler.hardware.acquire import check_moves, load_plan, moves_of, sample_times_s, scans_of
from feeler.hardware.acquire.world import VirtualWorld, plan_layout, tip_displacement_mm
from feeler.hardware.stage import StageLimits
from feeler.models.optics import force_from_areas

DATA = Path(__file__).parent / "data"
TINY = DATA / "tiny-plan.toml"
SHIPPED = Path(__file__).parents[2] / "datasets-synthetic" / "plans" / "four-plates-plan.toml"


def variant(tmp_path: Path, name: str = "plan.toml", **replace: str) -> Path:
    text = TINY.read_text()
    for old, new in replace.items():
        assert old in text, old
        text = text.replace(old, new)
    path = tmp_path / name
    path.write_text(text)
    return path


def test_shipped_plan_matches_four_plates_sampling():
    plan = load_plan(SHIPPED)
    t = sample_times_s(plan)
    assert plan.n_scans == 96 and len(t) == 41 and t[-1] == pytest.approx(20.0)
    assert plan_layout(plan, SHIPPED).name == "sensor-16"
    check_moves(plan, SHIPPED, StageLimits(), "stage")       # on a board with Grbl's default settings
    check_moves(plan, SHIPPED, StageLimits(), "stage", start_mm=(-1.0, -1.0, -1.0))   # from the homed corner


def test_scans_are_numbered_plate_by_plate_and_moves_follow_the_plan():
    plan = load_plan(TINY)
    scans = scans_of(plan)
    assert [(s.scan_id, s.plate, s.repeat, s.step_mm, s.origin_x_mm) for s in scans] == [
        (0, 0, 0, 0.0, -20.0), (1, 0, 1, 0.0, -20.0), (2, 1, 0, 0.2, -16.0), (3, 1, 1, 0.2, -16.0)]
    np.testing.assert_array_equal(sample_times_s(plan), np.arange(4) * 0.1)
    moves = moves_of(plan, scans[2])
    np.testing.assert_allclose([m[1] for m in moves], [(-16.0, -10.0, -19.8), (-16.0, -10.0, -19.8),
                                                       (-16.0, -10.0, -20.0), (-16.0, -10.0, -20.05),
                                                       (-13.0, -10.0, -20.05), (-13.0, -10.0, -19.8)])
    assert [m[2] for m in moves] == [6000.0, 6000.0, 3000.0, 3000.0, 600.0, 6000.0]
    assert [m[3] for m in moves] == ["z", "xy", "z", "z", "x", "z"]


FAST = {"max_rate_mm_min": (1e4,) * 3}


@pytest.mark.parametrize("limits, key, words", [
    (StageLimits(x_mm=(-200.0, -14.0), **FAST), "scan.traverse_mm", "moves x to -13 mm, beyond the soft limits [-200, -14]"),
    (StageLimits(x_mm=(-200.0, -16.5), **FAST), "plates.origin_x_mm[1]", "moves x to -16 mm"),
    (StageLimits(z_mm=(-20.04, 0.0), **FAST), "scan.press_mm", "moves z to -20.05 mm"),
    (StageLimits(z_mm=(-200.0, -19.9), **FAST), "scan.clearance_mm", "moves z to -19.8 mm"),
    # the plates themselves below the stage's reach: the clearance move was blamed (an outside audit)
    (StageLimits(z_mm=(-10.0, 0.0), **FAST), "plates.surface_z_mm", "moves z to -19.8 mm"),
    (StageLimits(y_mm=(-5.0, 0.0), **FAST), "plates.y_mm", "moves y to -10 mm"),
    (StageLimits(max_rate_mm_min=(5000.0, 1e4, 1e4)), "scan.move_feed_mm_min",
     "6000 mm/min is above the ceiling of 5000 mm/min of /dev/pts/9 for this move ($110, the x axis' maximum rate, is "
     "5000 mm/min): lower scan.move_feed_mm_min or raise $110"),
    (StageLimits(max_rate_mm_min=(1e4, 1e4, 2000.0)), "scan.press_feed_mm_min", "3000 mm/min is above"),
])
def test_moves_beyond_the_stage_are_refused_naming_the_plan_key(limits, key, words):
    with pytest.raises(SceneError) as err:
        check_moves(load_plan(TINY), TINY, limits, "/dev/pts/9")
    msg = str(err.value)
    assert key in msg and words in msg and "/dev/pts/9" in msg and "\n" not in msg


def test_traverse_feed_above_ceiling_names_the_speed(tmp_path):
    """On a board with Grbl's defaults (500 mm/min per axis) a 10 mm/s traverse is refused
    (Grbl would run it at 8.3 mm/s and every time stamp would be off)."""
    path = variant(tmp_path, **{"move_feed_mm_min = 6000.0": "move_feed_mm_min = 500.0",
                                "press_feed_mm_min = 3000.0": "press_feed_mm_min = 500.0"})
    with pytest.raises(SceneError) as err:
        check_moves(load_plan(path), path, StageLimits(), "/dev/ttyUSB0")
    assert str(err.value) == (f"{path}: scan.speed_mm_s: 10 mm/s (600 mm/min) is above the ceiling of "
                              "500 mm/min of /dev/ttyUSB0 for this move ($110, the x axis' maximum rate, is "
                              "500 mm/min): lower scan.speed_mm_s or raise $110")


@pytest.mark.parametrize("replace, key", [
    ({"move_feed_mm_min = 6000.0": "move_feed_mm_min = 0.0"}, "scan.move_feed_mm_min"),
    ({"speed_mm_s = 10.0": "speed_mm_s = 0"}, "scan.speed_mm_s"),
    ({"origin_x_mm = [-20.0, -16.0]": "origin_x_mm = [-20.0]"}, "plates.origin_x_mm"),
    ({"traverse_mm = 3.0": "traverse_mm = 0.5"}, "scan.traverse_mm"),
    ({"sample_period_s = 0.1": "sample_period_s = 0.01", "traverse_mm = 3.0": "traverse_mm = 1000.0",
      "speed_mm_s = 10.0": "speed_mm_s = 0.001"}, "scan.sample_period_s"),
    ({"element = 5": "element = 16"}, "optics.element"),
])
def test_impossible_plans_are_refused_naming_the_key(tmp_path, replace, key):
    path = variant(tmp_path, **replace)
    with pytest.raises(SceneError) as err:
        plan = load_plan(path)
        plan_layout(plan, path)
    assert key in str(err.value) and str(path) in str(err.value)


def test_a_plan_moved_away_from_its_layout_names_the_plan_and_the_key(tmp_path):
    """A copy of the shipped plan elsewhere: its relative layout path breaks, and the error
    named only the layout's path, not the plan or optics.layout (an outside audit)."""
    moved = tmp_path / "plan.toml"
    moved.write_text(SHIPPED.read_text())
    with pytest.raises(SceneError) as err:
        plan_layout(load_plan(moved), moved)
    text = str(err.value)
    assert str(moved) in text and "optics.layout" in text and "'../layouts/sensor-16.toml': no such layout file" in text


def test_emulation_needs_the_virtual_table(tmp_path):
    text = TINY.read_text()
    path = tmp_path / "plan.toml"
    path.write_text(text[: text.index("[virtual]")])
    with pytest.raises(SceneError, match=r"virtual: missing \[virtual\] table"):
        VirtualWorld.of_plan(load_plan(path), path)


def test_tip_displacement_of_the_virtual_plate():
    plan = load_plan(TINY)
    v = plan.virtual
    assert np.all(tip_displacement_mm(v, -20.0, -20.0, 0.2, (-20.0, -10.0, -19.99)) == 0.0)   # lifted
    before = tip_displacement_mm(v, -20.0, -20.0, 0.2, (-20.0, -10.0, -20.05))             # before the step
    after = tip_displacement_mm(v, -20.0, -20.0, 0.2, (-17.0, -10.0, -20.05))              # past it (+1.5 mm)
    np.testing.assert_allclose(before, [-0.3 * 0.05, 0.05, 0.0], rtol=1e-9)
    np.testing.assert_allclose(after, [-0.3 * 0.25, 0.25, 0.0], rtol=1e-9)
    mid = tip_displacement_mm(v, -20.0, -20.0, 0.2, (-18.5, -10.0, -20.05))                # face centred on the edge
    assert mid[1] == pytest.approx(0.15)


def test_virtual_frame_reads_back_the_true_force():
    from feeler.hardware.camera import AreaExtractor

    plan = load_plan(TINY)
    world = VirtualWorld.of_plan(plan, TINY)
    stage = (-13.0, -10.0, -20.05)
    frame = world.render(2, stage, np.random.default_rng(0))
    areas, problem = AreaExtractor(world.layout)(frame)
    assert problem is None
    f_true = np.linalg.solve(world.optics.c_matrix, world.truth_mm(2, stage))
    rest = force_from_areas(areas[4], world.optics)            # a neighbour at zero force
    np.testing.assert_allclose(rest, 0.0, atol=0.006)          # the reader's offset: < 1 px² per feeler
    f = force_from_areas(areas[5], world.optics) - rest        # tared by the neighbour
    np.testing.assert_allclose(f, f_true, atol=0.02 * np.abs(f_true).max())


@pytest.mark.parametrize("argv, words", [
    (["--emulate", "--stage", "/dev/ttyUSB0"], "--stage='/dev/ttyUSB0': no port with --emulate"),
    (["--emulate", "--resume", "--force"], "--force"),
    (["--stage", "/dev/ttyUSB0"], "--stage/--camera"),
    (["--camera", "0"], "--stage/--camera"),
    (["--emulate", "--plan-kind"], "four-plates.toml': a scan-plan scene, not 'robot-scan'"),
])
def test_acquire_arguments_are_checked_before_any_device(tmp_path, capsys, argv, words):
    from feeler.cli import main

    plan = TINY
    if "--plan-kind" in argv:
        argv = [a for a in argv if a != "--plan-kind"]
        plan = Path(__file__).parents[2] / "datasets-synthetic" / "four-plates.toml"
    code = main(["acquire", "--plan", str(plan), "--out", str(tmp_path / "run"), *argv])
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("feeler:")]
    assert code == 2 and len(err) == 1 and words in err[0], err
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("replace, key, problem", [
    ({"speed_mm_s = 10.0": "speed_mm_s = 120.0"}, "scan.traverse_mm",
     "3.0: shorter than one sample step (speed_mm_s*sample_period_s = 12 mm at scan.speed_mm_s = 120 mm/s); "
     "if 120 is mm/min, that is scan.speed_mm_s = 2 (mm/s): 16 samples a scan"),
    ({"speed_mm_s = 10.0": "speed_mm_s = 1200.0"}, "scan.speed_mm_s",
     "1200.0 out of range: must be <= 1000.0 (mm/s, traverse speed); "
     "if 1200 is mm/min, that is scan.speed_mm_s = 20 (mm/s): 2 samples a scan"),
    # no hint where a sixtieth is refused too
    ({"speed_mm_s = 10.0": "speed_mm_s = 60000.0"}, "scan.speed_mm_s",
     "60000.0 out of range: must be <= 1000.0 (mm/s, traverse speed)"),
    ({"traverse_mm = 3.0": "traverse_mm = 0.01"}, "scan.traverse_mm",
     "0.01: shorter than one sample step (speed_mm_s*sample_period_s = 1 mm at scan.speed_mm_s = 10 mm/s)"),
])
def test_a_speed_in_mm_per_minute_is_named_where_a_sixtieth_would_load(tmp_path, replace, key, problem):
    """A plan's speed written in mm/min (Grbl's feed unit) where mm/s is meant was refused
    for a stroke shorter than one sample step, or a speed out of range, and the error named
    neither the units nor the likely value; it does when the speed divided by 60 loads."""
    path = variant(tmp_path, **replace)
    with pytest.raises(SceneError) as err:
        load_plan(path)
    assert str(err.value) == f"{path}: {key}: {problem}"
    if "if 120 is mm/min" in problem:                                 # the hint's plan loads as it says
        assert len(sample_times_s(load_plan(variant(tmp_path, "meant.toml", **{"speed_mm_s = 10.0": "speed_mm_s = 2.0"})))) == 16


DEFAULT_FEEDS = {"move_feed_mm_min = 6000.0": "move_feed_mm_min = 500.0", "press_feed_mm_min = 3000.0": "press_feed_mm_min = 500.0"}


@pytest.mark.parametrize("replace, hint", [
    # 0.25 mm/s written 15: two samples a scan load, and the board's 500 mm/min refuse 900 mm/min
    ({"speed_mm_s = 10.0": "speed_mm_s = 15.0", "sample_period_s = 0.1": "sample_period_s = 0.2"},
     "; if 15 is mm/min, that is scan.speed_mm_s = 0.25 (mm/s): 61 samples a scan"),
    ({}, ""),                                  # four samples a scan: meant in mm/s, too fast for the board
    ({"speed_mm_s = 10.0": "speed_mm_s = 600.0", "traverse_mm = 3.0": "traverse_mm = 100.0",   # two samples,
      "origin_x_mm = [-20.0, -16.0]": "origin_x_mm = [-150.0, -140.0]"}, ""),  # but 600 mm/min is too fast too
])
def test_a_traverse_too_fast_for_the_board_names_mm_per_minute_only_where_plausible(tmp_path, replace, hint):
    path = variant(tmp_path, **replace, **DEFAULT_FEEDS)
    with pytest.raises(SceneError) as err:
        check_moves(load_plan(path), path, StageLimits(), "/dev/ttyUSB0")
    assert err.value.key == "scan.speed_mm_s" and "is above the ceiling of 500 mm/min" in err.value.problem
    assert err.value.problem.endswith("lower scan.speed_mm_s or raise $110" + hint)
