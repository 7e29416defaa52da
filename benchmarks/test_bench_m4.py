"""M4 speed/accuracy ladder on the shipped psychophysics-2afc data (synthetic).

NUTS without pooling (4 x 1000) is the reference for the per-subject exact and Laplace
backends: the ratio of wall times and the largest error of their PSE/DT means and sds in
units of the NUTS sd are recorded. The hierarchical NUTS fit and the finger route's grid
are timed beside them. (The exact backend beside psignifit: test_bench_m4_exact.py.)
"""
import tempfile
import warnings

import numpy as np
import pytest

from _ratios import record_ratio
from feeler.calib.psychometric.finger_route import fit_finger_route
from feeler.calib.psychometric.fit import fit_psychometric
from feeler.psydata import read_trials
from feeler.scene import load_scene
from feeler.simulate.psychophysics import simulate_psychophysics

RESULTS = {}


@pytest.fixture(scope="module")
def trials():
    with tempfile.TemporaryDirectory() as tmp:
        scene = load_scene("datasets-synthetic/psychophysics-2afc.toml")
        return read_trials(simulate_psychophysics(scene, tmp)["trials"])


def _fit(trials, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fit_psychometric(trials, rng=np.random.default_rng(0), **kw)


@pytest.mark.parametrize("label, kw", [("nuts-separate", dict(backend="nuts", hierarchical=False)),
                                       ("nuts-hierarchical", dict(backend="nuts")),
                                       ("exact", dict(backend="exact")),
                                       ("laplace", dict(backend="laplace"))])
def test_m4_backend(benchmark, trials, label, kw):
    res = benchmark.pedantic(lambda: _fit(trials, **kw), rounds=1, iterations=1)
    RESULTS[label] = res
    s = res.summary.set_index("name")
    benchmark.extra_info.update({"seconds": res.seconds, "ok": res.verdict.ok,
                                 "min_ess_bulk": float(s["ess_bulk"].min())})
    print(f"\n{label}: {res.seconds:.2f} s, verdict ok={res.verdict.ok} {res.verdict.problems[:2]}")
    if label in ("exact", "laplace") and "nuts-separate" in RESULTS:
        ref = RESULTS["nuts-separate"].summary.set_index("name")
        names = [n for n in s.index if n.startswith(("pse[", "dt["))]
        z_mean = np.abs(s.loc[names, "mean"] - ref.loc[names, "mean"]) / ref.loc[names, "sd"]
        sd_err = np.abs(s.loc[names, "sd"] / ref.loc[names, "sd"] - 1)
        record_ratio(benchmark, f"nuts_separate_seconds_over_{label}",
                     RESULTS["nuts-separate"].seconds / res.seconds, ">= 10")
        record_ratio(benchmark, f"{label}_max_mean_error_in_nuts_sd", float(z_mean.max()), "<= 0.3")
        record_ratio(benchmark, f"{label}_max_rel_sd_error", float(sd_err.max()), "<= 0.3")


def test_finger_route_grid(benchmark, trials):
    res = benchmark.pedantic(lambda: fit_finger_route(trials, rng=np.random.default_rng(0)),
                             rounds=1, iterations=1)
    benchmark.extra_info.update({"seconds": res.seconds, "ok": res.verdict.ok})
    print(f"\nfinger route (grid, L0): {res.seconds:.2f} s, verdict ok={res.verdict.ok}")
