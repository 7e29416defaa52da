"""Psychometric function with lapse: exact cases, the DT convention, log-space tails."""
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from scipy.stats import norm

from feeler.errors import ArgumentError
from feeler.models.psychometric import (Psychometric, dt_from_sigma, log_p_higher, p_higher,
                                        sigma_from_dt)


def test_exact_values_against_scipy_norm():
    x = np.array([7.6, 9.2, 10.0, 10.8, 12.4])
    got = p_higher(x, 10.3, 1.7, 0.06)
    want = 0.03 + 0.94 * norm.cdf((x - 10.3) / 1.7)
    np.testing.assert_allclose(got, want, rtol=1e-14)


def test_pse_is_the_half_point_for_every_lapse():
    for lam in (0.0, 0.1, 0.3, 0.49):
        assert p_higher(10.0, 10.0, 1.0, lam) == pytest.approx(0.5, abs=1e-15)


def test_dt_without_lapse_is_the_quartile_of_the_normal():
    assert float(dt_from_sigma(1.0)) == pytest.approx(0.6744897501960817, rel=1e-14)
    assert Psychometric(10.0, 2.0).dt_um == pytest.approx(2 * 0.6744897501960817, rel=1e-14)


def test_dt_with_lapse_closed_form():
    # λ = 0.1: Φ⁻¹((0.75 − 0.05)/0.9) = Φ⁻¹(7/9)
    assert float(dt_from_sigma(1.5, 0.1)) == pytest.approx(1.5 * norm.ppf(7 / 9), rel=1e-13)


@settings(max_examples=60, deadline=None)
@given(pse=st.floats(5, 15), sigma=st.floats(0.05, 5), lam=st.floats(0, 0.45))
def test_dt_is_the_75_percent_point_and_inverts(pse, sigma, lam):
    f = Psychometric(pse, sigma, lam)
    assert float(f.p_higher(pse + f.dt_um)) == pytest.approx(0.75, abs=1e-12)
    assert float(f.p_higher(pse - f.dt_um)) == pytest.approx(0.25, abs=1e-12)
    assert float(sigma_from_dt(f.dt_um, lam)) == pytest.approx(sigma, rel=1e-12)


@settings(max_examples=60, deadline=None)
@given(x=st.floats(-50, 50), lam=st.floats(0, 0.45))
def test_log_probabilities_are_complementary(x, lam):
    log_p, log_q = log_p_higher(x, 0.0, 1.0, lam)
    assert np.exp(log_p) + np.exp(log_q) == pytest.approx(1.0, abs=1e-14)


def test_log_space_deep_tails_do_not_underflow():
    log_p, log_q = log_p_higher(np.array([-60.0, 60.0]), 0.0, 1.0, 0.0)
    # log Φ(−60) ≈ −z²/2 − log(z√(2π)): finite, not −inf
    assert np.isfinite(log_p[0]) and log_p[0] == pytest.approx(norm.logcdf(-60.0), rel=1e-12)
    assert log_q[1] == pytest.approx(norm.logcdf(-60.0), rel=1e-12)
    # near 1: log P = log1p(−Φ(−60)) is ≈ −Φ(−60), not rounded to a positive number
    assert log_p[1] <= 0.0 and log_q[0] <= 0.0
    with_lapse = log_p_higher(-1e6, 0.0, 1.0, 0.02)[0]
    assert with_lapse == pytest.approx(np.log(0.01), rel=1e-12)


@pytest.mark.parametrize("sigma, lapse", [(0.0, 0.0), (-1.0, 0.0), (np.nan, 0.0),
                                          (1.0, -0.01), (1.0, 0.5), (1.0, np.inf)])
def test_bad_sigma_or_lapse_is_an_argument_error(sigma, lapse):
    with pytest.raises(ArgumentError):
        p_higher(10.0, 10.0, sigma, lapse)


def test_bad_pse_and_bad_dt_are_argument_errors():
    with pytest.raises(ArgumentError, match="pse_um"):
        Psychometric(np.nan, 1.0)
    with pytest.raises(ArgumentError, match="dt="):
        sigma_from_dt(0.0)
