"""Sharpening of the pooled plate probabilities (calib/neuron/recalibrate.py) and the
leave-one-out plate probabilities it is fitted to — each against a reference."""
import dataclasses
import json

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from scipy import stats
from scipy.special import logsumexp, softmax

from feeler.calib.neuron import fit_neuron
from feeler.calib.neuron.classify import classify
from feeler.calib.neuron.decoder import DecoderDraws
from feeler.calib.neuron.model import PeakTable, Plates, plate_stats
from feeler.calib.neuron.recalibrate import FLOOR, fit_sharpness, recalibrated
from feeler.calib.neuron.window import loo_class_log_prob
from feeler.errors import ArgumentError


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-30, 30), min_size=2, max_size=6), st.floats(0.2, 5.0), st.floats(0.0, 0.2))
def test_recalibrated_is_a_distribution_that_keeps_the_order(logits, gamma, floor):
    lp = np.asarray(logits) - logsumexp(logits)
    q = recalibrated(lp, gamma, floor)
    assert np.exp(logsumexp(q)) == pytest.approx(1.0, abs=1e-12)
    assert np.all(np.exp(q) >= floor / lp.size * (1 - 1e-12))        # never below the floor
    order = np.argsort(lp, kind="stable")
    assert np.all(np.diff(q[order]) >= -1e-12)                          # the most probable plate stays first


def test_recalibrated_exact_cases():
    lp = np.log([[0.7, 0.2, 0.1]])
    np.testing.assert_array_equal(recalibrated(lp), lp)                 # γ = 1, ε = 0: the identity
    p2 = np.array([0.49, 0.04, 0.01]) / 0.54                            # γ = 2 squares and renormalises
    np.testing.assert_allclose(np.exp(recalibrated(lp, 2.0)), [p2], rtol=1e-12)
    np.testing.assert_allclose(np.exp(recalibrated(lp, 1.0, 0.3)), [[0.59, 0.24, 0.17]], rtol=1e-12)
    with pytest.raises(ArgumentError, match="sharpness"):
        recalibrated(lp, 0.0)
    with pytest.raises(ArgumentError, match="floor"):
        recalibrated(lp, 1.0, 1.0)


@pytest.mark.parametrize("gamma_true", [0.7, 1.0, 1.6])
def test_fit_sharpness_recovers_the_power_of_a_tempered_forecaster(gamma_true):
    """Labels drawn from softmax(L); the forecaster reports softmax(L / γ): the fit finds γ."""
    rng = np.random.default_rng(int(gamma_true * 10))
    logits = 1.5 * rng.standard_normal((6000, 4))
    truth = (rng.random((6000, 1)) > np.cumsum(softmax(logits, axis=1), axis=1)).sum(axis=1)
    reported = logits / gamma_true - logsumexp(logits / gamma_true, axis=1, keepdims=True)
    got = fit_sharpness(reported, np.minimum(truth, 3), floor=0.0)
    assert got == pytest.approx(gamma_true, rel=0.08)


def test_fit_sharpness_flattens_scans_read_at_chance(monkeypatch):
    """Twenty scans whose leave-one-out probabilities are confident but unrelated to their
    labels (a mode read at chance): γ goes well below 1, towards even odds. Under the
    sharpening side's prior (sd 0.35) on both sides it would stay above 0.55 (0.38 against 0.61)."""
    from feeler.calib.neuron import recalibrate

    rng = np.random.default_rng(3)
    g = np.arange(20) % 3
    lp = np.log(softmax(1.5 * rng.standard_normal((20, 3)), axis=1))
    flat = fit_sharpness(lp, g)
    read = recalibrated(lp, flat, FLOOR)[np.arange(20), g].mean()
    assert flat < 0.45
    assert read > -np.log(3) - 0.05                     # about what even odds score
    monkeypatch.setattr(recalibrate, "LOG_GAMMA_SD_FLAT", recalibrate.LOG_GAMMA_SD)
    assert fit_sharpness(lp, g) > 0.55


def test_fit_sharpness_without_information_is_one_and_checks_shapes():
    assert fit_sharpness(np.full((10, 3), -np.log(3)), np.zeros(10, int)) == 1.0
    with pytest.raises(ArgumentError, match="loo_log_prob"):
        fit_sharpness(np.zeros((10, 3)), np.zeros(9, int))


@pytest.mark.parametrize("noise", ["per-plate", "constant"])
def test_loo_class_log_prob_equals_refitting_without_each_scan(noise):
    """Each scan classified by plates refitted without it (Student-t predictive of the
    plug-in fit), pooled over the τ nodes with the given weights — by brute force."""
    rng = np.random.default_rng(5)
    plates = Plates.of(np.repeat([0.0, 0.05, 0.1], 5))
    p = np.array([1.0, 1.8, 2.9])[plates.group] + 0.4 * rng.standard_normal(plates.group.size)
    table = PeakTable(log_tau=np.log([1.0, 2.0]), peak=np.column_stack([p, 1.3 * p + 0.2 * rng.standard_normal(p.size)]))
    log_w = np.log([0.3, 0.7])
    got = loo_class_log_prob(table, plates, noise, log_w)
    for k in range(p.size):
        keep = np.arange(p.size) != k
        pk = Plates.of(plates.steps_mm[plates.group[keep]])
        pooled = 0.0
        for j in range(2):
            mean, ss = plate_stats(table.peak[keep, j], pk)
            if noise == "per-plate":
                var, dof = ss / (pk.counts - 1), pk.counts - 1.0
            else:
                var, dof = np.full(3, ss.sum() / (keep.sum() - 3)), np.full(3, keep.sum() - 3.0)
            dens = stats.t.pdf(table.peak[k, j], dof, mean, np.sqrt(var * (1 + 1 / pk.counts)))
            pooled = pooled + np.exp(log_w[j]) * dens / dens.sum()
        np.testing.assert_allclose(np.exp(got[k]), pooled, rtol=1e-9)


def test_fit_records_the_sharpness_and_classify_applies_it():
    """The fit stores γ and ε; classify's probabilities are the unsharpened pool of the
    same draws, recalibrated with them (and an older posterior without them is unchanged)."""
    from feeler.calib.neuron.classify import scan_modes
    from feeler.calib.neuron.synth import scene_scans

    _, _, train = scene_scans(seed=11, per_plate=8)
    res = fit_neuron(train, seed=1)
    attrs = res.posterior["posterior"].attrs
    gamma, floor = float(attrs["prob_sharpness"]), float(attrs["prob_floor"])
    assert floor == FLOOR and 0.1 < gamma < 10
    assert "plate probabilities" in res.priors
    c = classify(res, train.strain[:6], train.t_s, rng=np.random.default_rng(0))
    dec = DecoderDraws.from_result(res, rng=np.random.default_rng(0), n_draws=400)
    assert (dec.sharpness, dec.floor) == (gamma, floor)
    modes = scan_modes(train.strain[:6]) if dec.snap_mm is not None else None
    plain = None if dec.mode_sharpness is None else (1.0, 1.0)
    raw = dataclasses.replace(dec, sharpness=1.0, floor=0.0, mode_sharpness=plain).class_log_prob(c.p_at_tau, modes)
    # a decoder per mode: each scan sharpened by its mode's γ (both recorded with the fit)
    g = np.full(6, gamma) if plain is None else np.asarray(dec.mode_sharpness)[modes.astype(int)]
    if plain is not None:
        by_mode = json.loads(attrs["mode_decoders"])
        assert dec.mode_sharpness == (by_mode["ride"]["sharpness"], by_mode["snap"]["sharpness"])
    np.testing.assert_allclose(c.log_prob, np.stack([recalibrated(raw[i], g[i], floor) for i in range(6)]),
                               rtol=1e-12, atol=1e-12)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-700, 700) | st.just(-np.inf), min_size=1, max_size=9), st.integers(1, 3))
def test_log_sum_exp_equals_scipy(values, rows):
    from scipy.special import logsumexp as reference

    from feeler.calib.neuron.recalibrate import log_sum_exp

    x = np.tile(np.asarray(values, float), (rows, 1))
    for axis in (0, 1):
        with np.errstate(divide="ignore"):
            want = reference(x, axis=axis)
        np.testing.assert_allclose(log_sum_exp(x, axis=axis), want, rtol=1e-12, atol=1e-13)   # log(1 + u) vs log1p(u)
    assert log_sum_exp(x, axis=1, keepdims=True).shape == (rows, 1)


@settings(max_examples=80, deadline=None)
@given(st.lists(st.floats(-1e6, 1e6), min_size=1, max_size=30))
def test_median_of_equals_numpy(values):
    from feeler.calib.neuron.live.envelope import median_of

    x = np.asarray(values, float)
    assert median_of(x) == np.median(x)
    assert np.isnan(median_of(np.append(x, np.nan)))
