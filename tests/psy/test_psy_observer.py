"""Observer: κ by regression through the origin, accepted heights, 2AFC probabilities."""
import numpy as np
import pytest
from scipy.stats import norm

from feeler.errors import ArgumentError
from feeler.models.observer import (accepted_height, choice_prob, conversion_factor,
                                    log_choice_prob)


def test_kappa_is_inverse_mean_slope_through_origin():
    s = np.array([5.0, 10.0, 15.0, 5.0, 10.0, 15.0])
    speed = np.array([20, 20, 20, 40, 40, 40])
    z = np.where(speed == 20, 2.0, 3.0) * s          # slopes 2 and 3 exactly
    assert conversion_factor(z, s, speed) == pytest.approx(1 / 2.5, rel=1e-14)
    s_hat = accepted_height(z, conversion_factor(z, s, speed))
    np.testing.assert_allclose(s_hat[:3], 0.8 * s[:3])  # slower speed accepted lower
    np.testing.assert_allclose(s_hat[3:], 1.2 * s[3:])


def test_kappa_regression_with_noise_matches_least_squares():
    rng = np.random.default_rng(1)
    s = np.linspace(5, 15, 9)
    z = 0.7 * s + rng.normal(0, 0.1, s.size)
    slope = np.linalg.lstsq(s[:, None], z, rcond=None)[0][0]
    assert conversion_factor(z, s) == pytest.approx(1 / slope, rel=1e-12)


def test_choice_probability_closed_form_and_symmetry():
    assert choice_prob(10.0, 11.0, 2.0) == pytest.approx(norm.cdf(0.5), rel=1e-14)
    assert choice_prob(10.0, 10.0, 2.0, 0.2) == pytest.approx(0.5, abs=1e-15)
    p = choice_prob(10.0, 12.0, 1.0, 0.1)
    assert p == pytest.approx(0.05 + 0.9 * norm.cdf(2.0), rel=1e-14)
    assert choice_prob(12.0, 10.0, 1.0, 0.1) == pytest.approx(1 - p, rel=1e-14)


def test_choice_log_probabilities_far_in_the_tails():
    log_p, log_q = log_choice_prob(0.0, 100.0, 1.0)    # Φ(100): P rounds to 1
    assert -1e-300 < log_p <= 0.0 or log_p == 0.0
    assert np.isfinite(log_q) and log_q == pytest.approx(norm.logcdf(-100.0), rel=1e-12)


@pytest.mark.parametrize("kwargs", [dict(peak_z=[1.0, 2.0], presented_um=[1.0]),
                                    dict(peak_z=[], presented_um=[]),
                                    dict(peak_z=[np.nan], presented_um=[1.0]),
                                    dict(peak_z=[1.0], presented_um=[1.0], groups=[1, 2]),
                                    dict(peak_z=[1.0], presented_um=[0.0]),
                                    dict(peak_z=[0.0, 0.0], presented_um=[1.0, 2.0])])
def test_conversion_factor_rejects_bad_input(kwargs):
    with pytest.raises(ArgumentError):
        conversion_factor(**kwargs)


@pytest.mark.parametrize("sigma_d, lapse", [(0.0, 0.0), (np.inf, 0.0), (1.0, 1.0), (1.0, -0.1)])
def test_choice_rejects_bad_noise_or_lapse(sigma_d, lapse):
    with pytest.raises(ArgumentError):
        choice_prob(1.0, 2.0, sigma_d, lapse)


def test_accepted_height_rejects_bad_kappa():
    with pytest.raises(ArgumentError, match="kappa"):
        accepted_height([1.0], 0.0)
