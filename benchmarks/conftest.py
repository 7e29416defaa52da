"""Prints every ratio the benchmarks measured against their same-run baselines, and
writes them to ``runs/benchmarks/ratios.csv`` plus one table per benchmark module
(``runs/benchmarks/<module>.csv``: timings and each benchmark's measured quantities).
The demo copies these tables into its run directory for the report's speed/accuracy
section.

A run of some benchmarks (one module, ``-k``) replaces their rows of ratios.csv and keeps
the others, each with the time it was measured at. Columns: ratios.csv has ``benchmark,
ratio, goal, measured_at`` and, for median
figures (``_ratios.record_median_ratio``), ``p10, p90, best, load, rounds``;
``<module>.csv`` has ``benchmark, min_s, mean_s, rounds, median_s, q1_s, q3_s`` (the
pytest-benchmark rounds) then each benchmark's ``extra_info`` (median figures as
``<name> [<load>]: median|p10|p90|best`` and the call's and baseline's median seconds)
and ``measured_at``. Under ``make bench-load`` (``FEELER_BENCH_UNDER_LOAD=1``) they go to
``runs/benchmarks/load/``."""
import csv
import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))

from _ratios import RATIOS  # noqa: E402

OUT = Path(__file__).resolve().parents[1] / "runs" / "benchmarks"
if os.environ.get("FEELER_BENCH_UNDER_LOAD"):    # make bench-load: the whole run under two busy loops
    OUT = OUT / "load"


def _write_tables(config, stamp: str) -> list[Path]:
    """One CSV per benchmark module: each benchmark's timings and its extra_info (ESS/s,
    errors, verdicts, speed-ups...), for the report's speed/accuracy section."""
    session = getattr(config, "_benchmarksession", None)
    rows: dict[str, list[dict]] = {}
    for bench in getattr(session, "benchmarks", None) or []:
        stats = getattr(bench, "stats", None)
        module = Path(str(bench.fullname).split("::")[0]).stem.removeprefix("test_bench_")
        row = {"benchmark": bench.name, "min_s": getattr(stats, "min", ""), "mean_s": getattr(stats, "mean", ""),
               "rounds": getattr(stats, "rounds", ""), "median_s": getattr(stats, "median", ""),
               "q1_s": getattr(stats, "q1", ""), "q3_s": getattr(stats, "q3", "")}
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


RATIO_COLUMNS = ["benchmark", "ratio", "goal", "measured_at", "p10", "p90", "best", "load", "rounds"]


def _earlier_rows(path: Path) -> dict[str, list[str]]:
    """The rows of an earlier ``ratios.csv`` by benchmark name (each keeps its own
    ``measured_at``); none when there is no such file or it has other columns."""
    try:
        with path.open(newline="", encoding="utf-8") as fh:
            table = list(csv.reader(fh))
    except (OSError, UnicodeDecodeError, csv.Error):
        return {}
    if not table or table[0] != RATIO_COLUMNS:
        return {}
    return {row[0]: row for row in table[1:] if len(row) == len(RATIO_COLUMNS)}


def pytest_terminal_summary(terminalreporter):
    if not RATIOS:
        return
    terminalreporter.section("ratios against same-run baselines (median [p10-p90] best; best-of only: ratio)")
    for name, ratio, goal, *extra in RATIOS:
        more = (f"  [{extra[0]['p10']:.3g}-{extra[0]['p90']:.3g}] best {extra[0]['best']:.3g}"
                if extra else "")
        terminalreporter.write_line(f"{name:90s} {ratio:10.3f}{more}   goal {goal}")
    OUT.mkdir(parents=True, exist_ok=True)
    path = OUT / "ratios.csv"
    stamp = time.strftime("%Y-%m-%dT%H:%M:%S")
    rows = _earlier_rows(path)            # a partial run (one module, -k) replaces only what it measured
    for name, ratio, goal, *extra in RATIOS:
        e = extra[0] if extra else {}
        rows[name] = [name, f"{ratio:.6g}", goal, stamp,
                      *(f"{e[k]:.6g}" if k in e else "" for k in ("p10", "p90", "best")),
                      e.get("load", ""), e.get("rounds", "")]
    with path.open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        # ratio: the median ratio for median figures, the best-of ratio for the others
        w.writerow(RATIO_COLUMNS)
        w.writerows(rows.values())
    for written in [path, *_write_tables(terminalreporter.config, stamp)]:
        terminalreporter.write_line(f"wrote {written}")
