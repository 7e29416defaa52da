"""calib.convergence against arviz-stats (the reference implementation it replaces)."""
import numpy as np
import pytest

from feeler.calib import convergence as C

A = pytest.importorskip("arviz_stats.base").array_stats
KW = dict(chain_axis=0, draw_axis=1)


def _chains(kind: str, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    if kind == "iid":
        return rng.normal(size=(4, 500))
    if kind == "ar1":                                   # strongly autocorrelated
        e = rng.normal(size=(4, 800))
        x = np.zeros_like(e)
        for t in range(1, e.shape[1]):
            x[:, t] = 0.9 * x[:, t - 1] + e[:, t]
        return x
    if kind == "shifted":                               # chains disagree: R-hat >> 1
        return rng.normal(size=(4, 300)) + np.arange(4)[:, None]
    if kind == "ties":                                  # many tied values (discrete draws)
        return rng.integers(0, 4, size=(3, 401)).astype(float)
    if kind == "heavy":
        return rng.standard_t(2, size=(2, 1001))
    raise AssertionError(kind)


KINDS = ["iid", "ar1", "shifted", "ties", "heavy"]


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("seed", [0, 1])
def test_matches_arviz_stats(kind, seed):
    x = _chains(kind, seed)
    pairs = [
        (C.rhat(x), A.rhat(x, **KW)),
        (C.ess_bulk(x), A.ess(x, method="bulk", **KW)),
        (C.ess_tail(x), A.ess(x, method="tail", prob=(0.05, 0.95), **KW)),
        (C.mcse_mean(x), A.mcse(x, method="mean", **KW)),
        (C.mcse_sd(x), A.mcse(x, method="sd", **KW)),
    ]
    for ours, ref in pairs:                             # same formulas: agree to rounding
        assert ours == pytest.approx(float(ref), rel=1e-9, abs=1e-12)


def test_constant_chain_is_full_size_and_nan_is_nan():
    x = np.ones((4, 100))
    assert C.ess_bulk(x) == 400
    y = _chains("iid", 3)
    y[1, 7] = np.nan
    assert np.isnan(C.rhat(y)) and np.isnan(C.ess_bulk(y)) and np.isnan(C.mcse_sd(y))


def test_too_short_or_one_chain():
    assert np.isnan(C.ess_bulk(np.zeros((2, 3)) + np.arange(3)))
    assert np.isnan(C.rhat(_chains("iid", 0)[:1]))
    assert np.isfinite(C.ess_bulk(_chains("iid", 0)[:1]))


@pytest.mark.parametrize("d2", [0.0, 0.1, 1.0, 3.0, 10.0, 40.0, 200.0])
def test_chi2_sf_3_closed_form_matches_scipy(d2):
    stats = pytest.importorskip("scipy.stats")
    from feeler.calib.matrix.checks import _chi2_sf_3
    assert _chi2_sf_3(d2) == pytest.approx(stats.chi2.sf(d2, 3), rel=1e-12, abs=1e-300)
