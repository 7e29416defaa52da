"""Prints every ratio the benchmarks measured against their same-run baselines, and
writes them to ``runs/benchmarks/ratios.csv`` (the demo copies that table into its run
directory for the report's speed/accuracy section)."""
import csv
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))

from _ratios import RATIOS  # noqa: E402

OUT = Path(__file__).resolve().parents[1] / "runs" / "benchmarks"


def pytest_terminal_summary(terminalreporter):
    if not RATIOS:
        return
    terminalreporter.section("ratios against same-run baselines")
    for name, ratio, goal in RATIOS:
        terminalreporter.write_line(f"{name:70s} {ratio:10.3f}   goal {goal}")
    OUT.mkdir(parents=True, exist_ok=True)
    path = OUT / "ratios.csv"
    with path.open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(["benchmark", "ratio", "goal", "measured_at"])
        stamp = time.strftime("%Y-%m-%dT%H:%M:%S")
        for name, ratio, goal in RATIOS:
            w.writerow([name, f"{ratio:.6g}", goal, stamp])
    terminalreporter.write_line(f"wrote {path}")
