"""`feeler demo` from a cold start (issue 6: goal ≤ 90 s wall on this 2-core machine).

Cold means empty compile caches: a fresh numba cache directory and a fresh pytensor
compile directory, in a new process. The same run is then repeated warm (caches filled),
the baseline of the ratio. The absolute seconds are printed and attached to the JSON.
Two whole demos, one of them compiling every model cold (77–108 s measured): run with
``FEELER_FULL=1`` (``make bench`` stays within 10 minutes without it).
"""
import os
import subprocess
import sys
import time

from _ratios import full_only, record_ratio


def _demo(out, env) -> float:
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "feeler", "demo", "--out", str(out), "--force"], env=env,
                   check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t0


@full_only("two whole demos, one cold (77-108 s measured)")
def test_demo_cold_start(benchmark, tmp_path):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba"), MPLBACKEND="Agg",
               PYTENSOR_FLAGS=f"base_compiledir={tmp_path / 'pytensor'}")
    benchmark.pedantic(_demo, args=(tmp_path / "cold", env), rounds=1, iterations=1)
    cold = benchmark.stats["min"]
    warm = _demo(tmp_path / "warm", env)
    benchmark.extra_info.update({"cold_s": cold, "warm_s": warm})
    print(f"\nfeeler demo: cold start {cold:.1f} s (goal <= 90 s), warm {warm:.1f} s")
    record_ratio(benchmark, "cold start / warm run", cold / warm, "cold <= 90 s")
