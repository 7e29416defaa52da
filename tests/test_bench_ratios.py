"""The benchmarks' ratios.csv: a run of some benchmarks keeps the rows of the others."""
import csv
import importlib.util
import sys
from pathlib import Path

BENCH = Path(__file__).resolve().parents[1] / "benchmarks"


def _conftest(monkeypatch, out: Path):
    monkeypatch.syspath_prepend(str(BENCH))
    spec = importlib.util.spec_from_file_location("bench_conftest_under_test", BENCH / "conftest.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    monkeypatch.setattr(module, "OUT", out)
    return module


class _Reporter:
    def __init__(self):
        self.config = object()          # no benchmark session: no module tables
        self.lines = []

    def section(self, title):
        self.lines.append(title)

    def write_line(self, line):
        self.lines.append(line)


def _rows(path: Path) -> dict:
    with path.open(newline="", encoding="utf-8") as fh:
        return {r["benchmark"]: r for r in csv.DictReader(fh)}


def test_a_partial_run_replaces_its_own_ratios_and_keeps_the_others(monkeypatch, tmp_path):
    """A run of the live benchmark alone rewrote ratios.csv with its rows only, and the
    demo's report then lost the other benchmarks' page."""
    conf = _conftest(monkeypatch, tmp_path)
    ratios = sys.modules["_ratios"].RATIOS
    saved = list(ratios)
    try:
        ratios[:] = [("test_a: speed-up", 2.0, ">= 1"), ("test_b: speed-up", 3.0, ">= 1",
                                                          {"p10": 2.5, "p90": 3.5, "best": 3.2, "load": "idle",
                                                           "rounds": 9})]
        conf.pytest_terminal_summary(_Reporter())
        first = _rows(tmp_path / "ratios.csv")
        assert set(first) == {"test_a: speed-up", "test_b: speed-up"} and first["test_b: speed-up"]["p90"] == "3.5"
        ratios[:] = [("test_b: speed-up", 4.0, ">= 1"), ("test_c: memory", 0.5, "<= 1")]
        conf.pytest_terminal_summary(_Reporter())
        second = _rows(tmp_path / "ratios.csv")
        assert list(second) == ["test_a: speed-up", "test_b: speed-up", "test_c: memory"]
        assert second["test_a: speed-up"] == first["test_a: speed-up"]          # kept, with its own time
        assert second["test_b: speed-up"]["ratio"] == "4" and second["test_b: speed-up"]["p90"] == ""
        (tmp_path / "ratios.csv").write_text("name,value\nx,1\n", encoding="utf-8")      # another layout: replaced
        conf.pytest_terminal_summary(_Reporter())
        assert list(_rows(tmp_path / "ratios.csv")) == ["test_b: speed-up", "test_c: memory"]
    finally:
        ratios[:] = saved
