"""Time to an answer (issue 18 item 1): the real command line, started as a user starts it.

Each command runs as a subprocess (``python -m feeler ...``) on the shipped scenes; its
wall time is set beside ``python -c "import numpy"`` timed in the same run (interleaved),
idle (``make bench``; with two busy-loop processes under ``make bench-load``, which runs
the whole suite loaded: each command takes seconds, and the loaded rounds cost ``make
bench`` over a minute). Goals (wall at idle on the 2-core machine):
``feeler --help`` ≤ 0.3 s, ``calibrate sensor`` (exact) ≤ 2 s, ``calibrate neuron``
(grid) ≤ 4 s, ``classify`` ≤ 3 s. The ratio recorded is call / baseline (lower is
better); the medians in seconds are in the benchmark's extra_info.
"""
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from _ratios import LOADS, Timed, busy_loops, record_median_ratio

ROOT = Path(__file__).resolve().parents[1]
ROUNDS = int(os.environ.get("FEELER_BENCH_CLI_ROUNDS", "3"))
ENV = {**os.environ, "MPLBACKEND": "Agg", "NUMBA_CACHE_DIR": str(ROOT / ".cache" / "numba")}


def _feeler(*args: str) -> None:
    subprocess.run([sys.executable, "-m", "feeler", *args], cwd=ROOT, env=ENV, check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def _baseline() -> None:
    subprocess.run([sys.executable, "-c", "import numpy"], env=ENV, check=True)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    d = tmp_path_factory.mktemp("cli")
    _feeler("simulate", "datasets-synthetic/sensor-calibration.toml", "--out", str(d / "sc"))
    _feeler("simulate", "datasets-synthetic/four-plates.toml", "--out", str(d / "fp"))
    _feeler("calibrate", "neuron", str(d / "fp"), "--out", str(d / "m2"))
    return d


CASES = {
    "help": (lambda d: ("--help",), "<= 0.3 s wall at idle"),
    "calibrate sensor": (lambda d: ("calibrate", "sensor", str(d / "sc")), "<= 2 s wall at idle"),
    "calibrate neuron": (lambda d: ("calibrate", "neuron", str(d / "fp")), "<= 4 s wall at idle"),
    "classify": (lambda d: ("classify", str(d / "m2"), str(d / "fp")), "<= 3 s wall at idle"),
}


@pytest.mark.parametrize("name", list(CASES))
def test_time_to_answer(benchmark, runs, name):
    argv, goal = CASES[name][0](runs), CASES[name][1]
    benchmark.pedantic(lambda: _feeler(*argv), rounds=1, iterations=1, warmup_rounds=1)
    for load, n in list(LOADS.items())[:1]:
        with busy_loops(n):
            timed = Timed.interleaved(lambda: _feeler(*argv), _baseline, rounds=ROUNDS, warmup=1)
        record_median_ratio(benchmark, f"feeler {name} / python -c 'import numpy'", timed,
                            f"informational (absolute goal {goal})", load=load, invert=True)
        benchmark.extra_info[f"feeler {name} [{load}]: wall median s"] = float(np.median(timed.call))
