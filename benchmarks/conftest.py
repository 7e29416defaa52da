"""Prints every ratio the benchmarks measured against their same-run baselines, and
writes them to ``runs/benchmarks/ratios.csv`` plus one table per benchmark module
(``runs/benchmarks/<module>.csv``: timings and each benchmark's measured quantities).
The demo copies these tables into its run directory for the report's speed/accuracy
section."""
import csv
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))

from _ratios import RATIOS  # noqa: E402

OUT = Path(__file__).resolve().parents[1] / "runs" / "benchmarks"


def _write_tables(config, stamp: str) -> list[Path]:
    """One CSV per benchmark module: each benchmark's timings and its extra_info (ESS/s,
    errors, verdicts, speed-ups...), for the report's speed/accuracy section."""
    session = getattr(config, "_benchmarksession", None)
    rows: dict[str, list[dict]] = {}
    for bench in getattr(session, "benchmarks", None) or []:
        stats = getattr(bench, "stats", None)
        module = Path(str(bench.fullname).split("::")[0]).stem.removeprefix("test_bench_")
        row = {"benchmark": bench.name, "min_s": getattr(stats, "min", ""), "mean_s": getattr(stats, "mean", ""),
               "rounds": getattr(stats, "rounds", "")}
        row.update({k: v for k, v in bench.extra_info.items() if isinstance(v, (int, float, str, bool))})
        row["measured_at"] = stamp
        rows.setdefault(module, []).append(row)
    written = []
    for module, table in rows.items():
        keys = list(dict.fromkeys(k for row in table for k in row))
        path = OUT / f"{module}.csv"
        with path.open("w", newline="", encoding="utf-8") as fh:
            w = csv.DictWriter(fh, fieldnames=keys)
            w.writeheader()
            w.writerows(table)
        written.append(path)
    return written


def pytest_terminal_summary(terminalreporter):
    if not RATIOS:
        return
    terminalreporter.section("ratios against same-run baselines")
    for name, ratio, goal in RATIOS:
        terminalreporter.write_line(f"{name:70s} {ratio:10.3f}   goal {goal}")
    OUT.mkdir(parents=True, exist_ok=True)
    path = OUT / "ratios.csv"
    stamp = time.strftime("%Y-%m-%dT%H:%M:%S")
    with path.open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(["benchmark", "ratio", "goal", "measured_at"])
        for name, ratio, goal in RATIOS:
            w.writerow([name, f"{ratio:.6g}", goal, stamp])
    for written in [path, *_write_tables(terminalreporter.config, stamp)]:
        terminalreporter.write_line(f"wrote {written}")
