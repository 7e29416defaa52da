"""Classification with an M2 posterior: calibrated probabilities, covering intervals, log space."""
import numpy as np
import pandas as pd
import pytest
from scipy.stats import t as student_t

from feeler.calib.neuron.classify import classify, expected_calibration_error
from feeler.calib.fit import FitResult, Verdict, posterior_from_draws
from feeler.calib.neuron import fit_neuron
from feeler.calib.neuron.synth import scene_scans
from feeler.errors import ArgumentError
from feeler.models import neuron


@pytest.fixture(scope="module")
def fitted():
    data = scene_scans()[2]
    with pytest.warns(UserWarning):          # the PPC reports the per-plate bias of the decoder
        return data, fit_neuron(data, seed=2)


def _fixed_posterior(data, a, tau_s, h, sigma_mm, n=3):
    tab = data.table(n_grid=32)
    draws = {k: np.full((1, n), v) for k, v in (("a", a), ("tau_s", tau_s), ("h", h), ("sigma_mm", sigma_mm))}
    tree = posterior_from_draws(draws, observed={"step_mm": data.step_mm, "peak_u1": tab.peak,
                                                 "log_tau_grid": tab.log_tau},
                                dims={"step_mm": ["scan"], "peak_u1": ["scan", "tau_grid"],
                                      "log_tau_grid": ["tau_grid"]}, attrs={"kernel": "boxcar"})
    return FitResult(posterior=tree, summary=pd.DataFrame(), verdict=Verdict(True)), tab


def test_ece_and_coverage_on_400_fresh_scans(fitted):
    _, res = fitted
    new = scene_scans(seed=777, per_plate=100)[2]
    c = classify(res, new.strain, new.t_s, rng=np.random.default_rng(0))
    true = np.searchsorted(c.plates_mm, new.step_mm)
    ece = expected_calibration_error(c.prob, true)
    inside = (new.step_mm >= c.lo90_mm) & (new.step_mm <= c.hi90_mm)
    per_plate = {float(v): float(inside[new.step_mm == v].mean()) for v in c.plates_mm}
    print(f"\n{new.step_mm.size} fresh scans: accuracy {np.mean(c.prob.argmax(1) == true):.3f}, "
          f"ECE {ece:.4f}, 90 % interval coverage {inside.mean():.3f}, per plate {per_plate}")
    assert new.step_mm.size >= 400
    assert ece <= 0.05
    assert 0.85 <= inside.mean() <= 0.95


def test_single_draw_matches_bayes_rule_by_hand(fitted):
    data, _ = fitted
    tau = float(np.exp(data.table(n_grid=32).log_tau[20]))       # a grid node: P(τ) exact
    res, tab = _fixed_posterior(data, a=3.0, tau_s=tau, h=0.03, sigma_mm=0.01)
    new = scene_scans(seed=5, per_plate=2)[2]
    c = classify(res, new.strain, new.t_s, rng=np.random.default_rng(1), n_draws=3)
    z_tr = 3.0 * neuron.peak_window_sum(data.strain, data.t_s, tau=tau) - 0.03
    z_new = 3.0 * neuron.peak_window_sum(new.strain, new.t_s, tau=tau) - 0.03
    dens = []
    for v in np.unique(data.step_mm):
        zc = z_tr[data.step_mm == v]
        n = zc.size
        dens.append(student_t.pdf(z_new, n - 1, zc.mean(), zc.std(ddof=1) * np.sqrt(1 + 1 / n)))
    dens = np.array(dens).T
    np.testing.assert_allclose(c.prob, dens / dens.sum(axis=1, keepdims=True), rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(c.height_mm, np.maximum(z_new, 0), atol=4 * 0.01 / np.sqrt(60))


def test_far_out_scan_stays_finite_in_log_space(fitted):
    data, res = fitted
    wild = data.strain[[0, -1]] * np.array([[1.0], [60.0]])         # a 60x larger 0.2 mm step
    c = classify(res, wild, data.t_s, rng=np.random.default_rng(3))
    assert np.all(np.isfinite(c.log_prob))
    np.testing.assert_allclose(np.exp(c.log_prob).sum(axis=1), 1.0, rtol=1e-9)
    clean = classify(res, data.strain[-1:], data.t_s, rng=np.random.default_rng(3))   # a 0.2 mm scan
    print("\nlog P(plate | 0.2 mm scan):", clean.log_prob[0])
    assert clean.log_prob[0, 0] < -20 and np.isfinite(clean.log_prob).all()   # resolved, not rounded to 0
    assert c.lo90_mm[1] > 10 * c.plates_mm.max()       # the decoded height shows it is off every plate


def test_ece_exact_small_case():
    prob = np.array([[0.9, 0.1], [0.9, 0.1], [0.6, 0.4], [0.3, 0.7]])
    true = np.array([0, 1, 0, 1])
    # bins: 0.9 (2 scans, accuracy 0.5), 0.6 (accuracy 1), 0.7 (accuracy 1)
    expected = 0.5 * abs(0.5 - 0.9) + 0.25 * abs(1 - 0.6) + 0.25 * abs(1 - 0.7)
    assert expected_calibration_error(prob, true) == pytest.approx(expected)


def test_posterior_without_training_table_is_refused(fitted):
    data, res = fitted
    bare = FitResult(posterior=posterior_from_draws({"a": np.ones((1, 2))}), summary=pd.DataFrame(),
                     verdict=Verdict(True))
    with pytest.raises(ArgumentError, match="observed_data"):
        classify(bare, data.strain, data.t_s, rng=np.random.default_rng(0))


def test_single_plate_posterior_is_refused(fitted):
    data, _ = fitted
    import dataclasses
    one = dataclasses.replace(data, step_mm=np.full_like(data.step_mm, 0.1))
    res, _ = _fixed_posterior(one, a=3.0, tau_s=2.0, h=0.0, sigma_mm=0.01)
    with pytest.raises(ArgumentError, match="plates"):
        classify(res, data.strain, data.t_s, rng=np.random.default_rng(0))
