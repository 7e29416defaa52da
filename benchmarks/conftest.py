"""Prints every ratio the benchmarks measured against their same-run baselines."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))

from _ratios import RATIOS  # noqa: E402


def pytest_terminal_summary(terminalreporter):
    if not RATIOS:
        return
    terminalreporter.section("ratios against same-run baselines")
    for name, ratio, goal in RATIOS:
        terminalreporter.write_line(f"{name:70s} {ratio:10.3f}   goal {goal}")
