"""M1: exact posterior maths, attenuation, recovery, extremes, and backend agreement."""
from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.stats import multivariate_normal

from feeler.calib.fit import DiagnosticWarning, load
from feeler.calib.matrix import (CalibrationData, DesignWarning, MatrixPrior, fit_matrix,
                                 predict_u)
from feeler.calib.matrix.exact import sample_sigma, sigma_log_density
from feeler.scene import load_scene
from feeler.simulate.calibration import draw_campaign

SCENE = load_scene("datasets-synthetic/sensor-calibration.toml")
C_TRUE = np.asarray(SCENE.sensor.c_mm_per_n)
PRIOR = MatrixPrior(c0_mm_per_n=SCENE.prior.c0_mm_per_n, rel_sd=SCENE.prior.rel_sd)


def _campaign(seed: int) -> CalibrationData:
    u, _, f = draw_campaign(SCENE, np.random.default_rng(seed))
    return CalibrationData(u, f, np.arange(len(u)))


def _stats(result, name):
    s = result.summary.set_index("name")
    return s.loc[[n for n in s.index if n.startswith(name + "[")]]


def test_sigma_marginal_equals_the_dense_gaussian_marginal_likelihood():
    rng = np.random.default_rng(0)
    x, y = rng.normal(size=(20, 3)), rng.normal(size=20)
    b0, s, scale = np.array([0.1, 0.2, 0.3]), 0.7, 2.0
    ls = np.array([-3.0, -1.0, 0.0, 0.5])
    ref = [multivariate_normal(x @ b0, np.exp(2 * v) * np.eye(20) + s**2 * x @ x.T).logpdf(y)
           - 0.5 * (np.exp(v) / scale) ** 2 + v for v in ls]
    np.testing.assert_allclose(sigma_log_density(ls, x, y, b0, s, scale), ref, rtol=1e-10)


def test_sigma_draws_follow_the_normalised_marginal():
    rng = np.random.default_rng(1)
    x = rng.normal(size=(15, 3))
    y = x @ np.array([1.0, -0.5, 0.2]) + 0.3 * rng.normal(size=15)
    draws = sample_sigma(rng, 20000, x, y, np.zeros(3), 2.0, 1.0)
    grid = np.linspace(np.log(0.05), np.log(3.0), 20001)
    dens = np.exp(sigma_log_density(grid, x, y, np.zeros(3), 2.0, 1.0))
    cdf = np.concatenate([[0], np.cumsum(0.5 * (dens[1:] + dens[:-1]) * np.diff(grid))])
    cdf /= cdf[-1]
    emp = np.searchsorted(np.sort(np.log(draws)), grid) / draws.size
    assert np.max(np.abs(emp - cdf)) < 1.36 / np.sqrt(draws.size) * 1.5   # KS at ~1 %


def test_known_noise_matches_dense_conjugate_formula():
    data = _campaign(11)
    sd = np.array([0.02, 0.03, 0.025])
    res = fit_matrix(data, PRIOR, rng=np.random.default_rng(2), noise_sd=sd, draws=5000)
    rp = PRIOR.for_direction("inverse")
    u, f = data.u_mm, data.f_n
    for j in range(3):                       # row j of K, from dense 3-dim Gaussian algebra
        prec = np.eye(3) / rp.sd**2 + u.T @ u / sd[j] ** 2
        cov = np.linalg.inv(prec)
        mean = cov @ (rp.b0[j] / rp.sd**2 + u.T @ f[:, j] / sd[j] ** 2)
        k = res.posterior["posterior"]["K"].values[:, :, j, :].reshape(-1, 3)
        se = np.sqrt(np.diag(cov) / k.shape[0])
        assert np.all(np.abs(k.mean(0) - mean) < 4 * se)
        np.testing.assert_allclose(np.cov(k.T), cov, rtol=0.06, atol=0.06 * np.diag(cov).max())


def test_naive_regression_is_attenuated_and_the_default_is_not():
    rng = np.random.default_rng(3)
    n, var_f, sd_f = 4000, np.array([1.0, 2.0, 1.0]), np.array([0.5, 0.5, 0.7])
    f_true = rng.normal(size=(n, 3)) * np.sqrt(var_f)       # independent force axes
    u = f_true @ C_TRUE.T                                    # the stage is exact
    f_obs = f_true + rng.normal(size=(n, 3)) * sd_f
    data = CalibrationData(u, f_obs, np.arange(n))
    wide = MatrixPrior(c0_mm_per_n=SCENE.prior.c0_mm_per_n, rel_sd=100.0,
                       sigma_f_scale_n=1.0, sigma_u_scale_mm=1.0)
    lam = var_f / (var_f + sd_f**2)                          # closed-form attenuation
    naive = fit_matrix(data, wide, model="forward", rng=rng)
    good = fit_matrix(data, wide, rng=rng)
    c_naive = naive.posterior["posterior"]["C"].mean(("chain", "draw")).values
    c_good = good.posterior["posterior"]["C"].mean(("chain", "draw")).values
    diag = np.diag_indices(3)
    np.testing.assert_allclose(c_naive[diag], lam * C_TRUE[diag], rtol=0.03)
    np.testing.assert_allclose(c_good[diag], C_TRUE[diag], rtol=0.03)
    s_naive = _stats(naive, "C")
    assert all(s_naive.loc[f"C[{i},{i}]", "eti95_ub"] < C_TRUE[i, i] for i in range(3))
    s_good = _stats(good, "C")
    inside = [(s_good.loc[f"C[{i},{i}]", "eti95_lb"] <= C_TRUE[i, i] <= s_good.loc[f"C[{i},{i}]", "eti95_ub"])
              for i in range(3)]
    assert sum(inside) >= 2


def test_parameter_recovery_on_fresh_seeds():
    hits, total = 0, 0
    for seed in range(100, 130):
        res = fit_matrix(_campaign(seed), PRIOR, rng=np.random.default_rng(seed), draws=500)
        s = _stats(res, "C")
        for i in range(3):
            for j in range(3):
                row = s.loc[f"C[{i},{j}]"]
                hits += row.eti95_lb <= C_TRUE[i, j] <= row.eti95_ub
                total += 1
        assert res.verdict.ok
    assert 0.88 <= hits / total <= 0.995, hits / total          # 270 checks, nominal 0.95


def test_collinear_loads_give_finite_prior_dominated_posterior_and_warning():
    base = _campaign(5)
    u = base.u_mm.copy()
    u[:, 0] = u[:, 1]                                       # ux always equals uy
    u[:, 2] = 0.0                                           # no z shear at all
    f = u @ np.linalg.inv(C_TRUE).T + 0.02 * np.random.default_rng(6).normal(size=u.shape)
    with pytest.warns(DesignWarning) as caught:
        res = fit_matrix(CalibrationData(u, f, base.point_id), PRIOR, rng=np.random.default_rng(7))
    text = " ".join(str(w.message) for w in caught)
    assert "(x=+1.000, y=+0.000, z=+0.000)" not in text
    assert "z=+1.000" in text and "x=+0.707, y=-0.707" in text
    k = res.posterior["posterior"]["K"].values
    assert np.all(np.isfinite(k)) and np.all(np.isfinite(res.posterior["posterior"]["C"].values))
    rp = PRIOR.for_direction("inverse")
    sd_z = k[..., :, 2].reshape(-1, 3).std(axis=0)          # K column for u_z: prior only
    np.testing.assert_allclose(sd_z, rp.sd, rtol=0.05)
    np.testing.assert_allclose(k[..., :, 2].reshape(-1, 3).mean(axis=0), rp.b0[:, 2], atol=0.1 * rp.sd)


def test_noise_free_data_recover_the_matrix_exactly():
    base = _campaign(8)
    f = base.u_mm @ np.linalg.inv(C_TRUE).T
    res = fit_matrix(CalibrationData(base.u_mm, f, base.point_id), PRIOR, rng=np.random.default_rng(9))
    c = res.posterior["posterior"]["C"].values
    assert np.all(np.isfinite(c))
    np.testing.assert_allclose(c.mean(axis=(0, 1)), C_TRUE, rtol=1e-6, atol=1e-9)
    assert c.std(axis=(0, 1)).max() < 1e-6
    # but zero-width intervals are no calibration: the verdict fails, in one line naming why (audit s43 F6)
    assert len(res.verdict.problems) == 1 and "noise-free" in res.verdict.problems[0], res.verdict.problems
    # the same forces as a CSV keeps them (6 significant digits): the rounding is still no noise, and
    # replicated points rounded alike are no lack of fit (that check made it a model failure)
    rounded = np.array([[float(f"{v:.6g}") for v in row] for row in f])
    res = fit_matrix(CalibrationData(base.u_mm, rounded, base.point_id), PRIOR, rng=np.random.default_rng(9))
    assert len(res.verdict.problems) == 1 and "noise-free" in res.verdict.problems[0], res.verdict.problems


@pytest.mark.parametrize("rel_sd", [1e6, 1e-6])
def test_very_wide_and_very_narrow_priors(rel_sd):
    data = _campaign(10)
    prior = MatrixPrior(c0_mm_per_n=SCENE.prior.c0_mm_per_n, rel_sd=rel_sd)
    res = fit_matrix(data, prior, rng=np.random.default_rng(11))
    k = res.posterior["posterior"]["K"].values.reshape(-1, 3, 3)
    assert np.all(np.isfinite(k))
    if rel_sd > 1:                                          # the data alone: least squares
        ls = np.linalg.lstsq(data.u_mm, data.f_n, rcond=None)[0].T
        se = k.std(axis=0) / np.sqrt(k.shape[0])
        assert np.all(np.abs(k.mean(axis=0) - ls) < 5 * se + 1e-12)
    else:                                                   # the prior alone
        rp = prior.for_direction("inverse")
        np.testing.assert_allclose(k.mean(axis=0), rp.b0, atol=5 * rp.sd / np.sqrt(k.shape[0]) + 1e-15)
        np.testing.assert_allclose(k.std(axis=0), rp.sd, rtol=0.08)


def test_predictive_interval_covers_new_displacements():
    """Coverage over fresh campaigns (one fit's error in C is shared by all its points)."""
    hits = []
    for seed in range(300, 340):
        rng = np.random.default_rng(seed)
        res = fit_matrix(_campaign(seed), PRIOR, rng=rng, draws=500)
        f_true = rng.uniform(-0.5, 0.5, size=(6, 3)) + np.array([0, 1.0, 0])
        u_true = f_true @ C_TRUE.T
        # the new force is read with the campaign's own noise (force noise + stage jitter)
        f_obs = (u_true + 0.001 * rng.normal(size=u_true.shape)) @ np.linalg.inv(C_TRUE).T \
            + 0.02 * rng.normal(size=u_true.shape)
        pred = predict_u(res, f_obs, rng=rng, prob=0.9)
        hits.append((pred["lb_mm"] <= u_true) & (u_true <= pred["ub_mm"]))
        assert pred["mean_mm"].shape == (6, 3)
    cover = np.mean(hits)
    assert 0.86 <= cover <= 0.94, cover                    # 720 checks, nominal 0.90


def test_condition_number_posterior_and_saved_result(tmp_path):
    res = fit_matrix(_campaign(13), PRIOR, rng=np.random.default_rng(14))
    s = res.summary.set_index("name")
    assert s.loc["cond_C", "eti95_lb"] <= np.linalg.cond(C_TRUE) <= s.loc["cond_C", "eti95_ub"]
    res.save(tmp_path)
    back = load(tmp_path)
    assert back.posterior["posterior"].attrs["model"] == "inverse"
    assert "K" in back.priors and "matrix-normal" in back.priors["K"]
    a = predict_u(back, [0.1, 1.0, 0.0], rng=np.random.default_rng(1))["mean_mm"]
    b = predict_u(res, [0.1, 1.0, 0.0], rng=np.random.default_rng(1))["mean_mm"]
    np.testing.assert_allclose(a, b)


@pytest.fixture(scope="module")
def exact_reference():
    return fit_matrix(_campaign(20), PRIOR, rng=np.random.default_rng(21), draws=4000)


def _assert_agree(res, ref):
    a, b = res.summary.set_index("name"), ref.summary.set_index("name")
    names = [n for n in b.index if n.startswith(("C[", "K[", "sigma_n["))]
    tol = 4 * np.hypot(a.loc[names, "mcse_mean"], b.loc[names, "mcse_mean"])
    assert np.all(np.abs(a.loc[names, "mean"] - b.loc[names, "mean"]) <= tol)
    np.testing.assert_allclose(a.loc[names, "sd"], b.loc[names, "sd"], rtol=0.10)


def test_nuts_agrees_with_the_conjugate_posterior(exact_reference):
    res = fit_matrix(_campaign(20), PRIOR, backend="nuts", rng=np.random.default_rng(22),
                     chains=4, draws=1000, tune=800)
    assert res.verdict.ok, res.verdict.problems
    _assert_agree(res, exact_reference)


def test_emcee_agrees_with_the_conjugate_posterior(exact_reference):
    res = fit_matrix(_campaign(20), PRIOR, backend="emcee", rng=np.random.default_rng(23),
                     walkers=32, draws=4000, tune=1500)
    _assert_agree(res, exact_reference)
