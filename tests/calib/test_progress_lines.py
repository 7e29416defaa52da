"""Progress off a terminal: a line per finished item with the time left, a line per stage, or silence."""
import pytest

from feeler.calib.progress import duration, progress, stage, stages


def test_a_line_per_item_with_the_time_left(capsys):
    assert list(progress(range(3), desc="SBC datasets", lines=True)) == [0, 1, 2]
    lines = capsys.readouterr().err.splitlines()
    assert [ln.split(",")[0] for ln in lines] == [f"SBC datasets: {i}/3 done" for i in (1, 2, 3)]
    assert all("left" in ln for ln in lines[:2]) and "left" not in lines[2]        # no estimate after the last
    assert list(progress(iter("ab"), desc="runs", lines=True)) == ["a", "b"]       # no length: counts only
    assert capsys.readouterr().err.splitlines()[1].startswith("runs: 2 done, ")


@pytest.mark.parametrize("kwargs", [dict(lines=False), dict(lines=True, enabled=False)])
def test_no_lines_unless_asked_and_none_with_no_progress(capsys, kwargs):
    assert list(progress(range(2), desc="x", **kwargs)) == [0, 1]
    assert capsys.readouterr().err == ""


def test_stages_off_a_terminal(capsys):
    step, close = stages("report")
    step("html")
    close()
    stage("plotting", None)
    stage("hidden", False)
    quiet, close = stages("report", False)
    quiet("pdf")
    close()
    assert capsys.readouterr().err.splitlines() == ["report: html ...", "plotting ..."]


@pytest.mark.parametrize("seconds, text", [(0.0, "0.0 s"), (0.44, "0.4 s"), (12.4, "12 s"), (59.6, "1 min 00 s"),
                                           (185, "3 min 05 s"), (3720, "1 h 02 min"), (-1, "0.0 s")])
def test_duration(seconds, text):
    assert duration(seconds) == text
