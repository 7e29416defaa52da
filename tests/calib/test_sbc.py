"""Simulation-based calibration: it passes exact fits, catches wrong ones, and M1 passes."""
from __future__ import annotations

import os
from functools import partial

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from feeler.calib.matrix.sbc_model import matrix_sbc_problem
from feeler.calib.sbc import chi2_uniformity, ecdf_uniformity, ranks_of, run_sbc
from feeler.errors import ArgumentError

FULL = os.environ.get("FEELER_FULL") == "1"


def _simulate_normal(rng):
    mu = rng.normal()
    return {"mu": mu}, mu + rng.normal(size=5)


def _fit_normal(y, rng, *, sd_factor=1.0, shift=0.0, n=199):
    """Exact posterior of mu ~ N(0, 1), y_i ~ N(mu, 1): N(sum y / 6, 1/6), optionally wrong."""
    return {"mu": y.sum() / 6 + shift + sd_factor * rng.normal(size=n) / np.sqrt(6)}


def test_exact_fit_passes_and_wrong_fits_fail():
    good = run_sbc(_simulate_normal, _fit_normal, n_datasets=200, seed=1)
    assert good.failed() == [] and good.ranks.shape == (200, 1)
    assert good.ranks.min() >= 0 and good.ranks.max() <= 99
    over = run_sbc(_simulate_normal, partial(_fit_normal, sd_factor=0.5), n_datasets=200, seed=1)
    assert over.failed() == ["mu"]
    biased = run_sbc(_simulate_normal, partial(_fit_normal, shift=0.4), n_datasets=200, seed=1)
    assert biased.failed() == ["mu"]


def test_uniformity_statistics_exact_cases():
    ranks = np.repeat(np.arange(100), 2)                 # perfectly flat over 0..99
    assert chi2_uniformity(ranks, 99, 10) == pytest.approx(1.0)
    p, z, lo, hi = ecdf_uniformity(ranks, 99, np.random.default_rng(0))
    assert p > 0.9 and np.all(lo <= z) and np.all(z <= hi)
    assert chi2_uniformity(np.zeros(200, int), 99, 10) < 1e-100
    assert ecdf_uniformity(np.zeros(200, int), 99, np.random.default_rng(0))[0] == 0.0


@settings(max_examples=50, deadline=None)
@given(truth=st.floats(-1e6, 1e6, allow_nan=False),
       draws=st.lists(st.floats(-1e6, 1e6, allow_nan=False), min_size=20, max_size=60))
def test_rank_is_within_zero_and_n_draws(truth, draws):
    r = ranks_of({"a": truth}, {"a": np.array(draws)}, 19, np.random.default_rng(0))["a"]
    assert 0 <= r <= 19
    if truth > max(draws):
        assert r == 19
    if truth < min(draws):
        assert r == 0


def test_bad_arguments():
    with pytest.raises(ArgumentError, match="n_datasets=5: must be >= 10"):
        run_sbc(_simulate_normal, _fit_normal, n_datasets=5, seed=0)
    with pytest.raises(ArgumentError, match="n_draws=3: must be >= 9"):
        run_sbc(_simulate_normal, _fit_normal, n_datasets=10, seed=0, n_draws=3)
    with pytest.raises(ArgumentError, match="fit returned only 199 draws of mu"):
        run_sbc(_simulate_normal, _fit_normal, n_datasets=10, seed=0, n_draws=500)


@pytest.mark.slow
def test_matrix_exact_backend_is_rank_uniform():
    sim, fit = matrix_sbc_problem()
    n = 240 if FULL else 40
    res = run_sbc(sim, fit, n_datasets=n, seed=2026)
    assert len(res.names) == 22                             # 9 K, 9 C, 3 sigma_n, cond_C
    assert res.failed() == [], res.table()


@pytest.mark.slow
@pytest.mark.skipif(not FULL, reason="spawns a LocalCluster importing feeler (~20 s); the generic "
                                     "dask == serial test is tests/calib/test_runner.py")
def test_distributed_sbc_equals_serial():
    sim, fit = matrix_sbc_problem()
    serial = run_sbc(sim, fit, n_datasets=10, seed=5)
    dist = run_sbc(sim, fit, n_datasets=10, seed=5, scheduler=None)
    np.testing.assert_array_equal(serial.ranks, dist.ranks)
    assert serial.names == dist.names


def test_validate_draws_bound_is_what_the_fits_return():
    """`validate sbc --draws` is checked against FIT_DRAWS before any work: it must be the
    number of draws the SBC fits actually return."""
    import inspect

    from feeler.calib.matrix.sbc_model import fit_matrix_draws
    from feeler.calib.neuron.sbc import fit_neuron_draws
    from feeler.commands.validate import FIT_DRAWS
    for fit in (fit_matrix_draws, fit_neuron_draws):
        assert inspect.signature(fit).parameters["n_draws"].default == FIT_DRAWS, fit.__name__
