"""M1 variants (Student-t, errors-in-variables) and one negative test per argument check."""
from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

from feeler.calib.fit import DiagnosticWarning
from feeler.calib.matrix import CalibrationData, MatrixPrior, fit_matrix, predict_u
from feeler.errors import ArgumentError
from feeler.scene import load_scene
from feeler.simulate.calibration import draw_campaign

SCENE = load_scene("datasets-synthetic/sensor-calibration.toml")
C_TRUE = np.asarray(SCENE.sensor.c_mm_per_n)
PRIOR = MatrixPrior(c0_mm_per_n=SCENE.prior.c0_mm_per_n)


def _student_campaign(seed):
    scene = dataclasses.replace(SCENE, noise=dataclasses.replace(SCENE.noise, kind="student", student_nu=3.0))
    u, _, f = draw_campaign(scene, np.random.default_rng(seed))
    return CalibrationData(u, f, np.arange(len(u)))


def _covered(result, frac):
    s = result.summary.set_index("name")
    inside = [s.loc[f"C[{i},{j}]", "eti95_lb"] <= C_TRUE[i, j] <= s.loc[f"C[{i},{j}]", "eti95_ub"]
              for i in range(3) for j in range(3)]
    assert np.mean(inside) >= frac, s.loc[[f"C[{i},{j}]" for i in range(3) for j in range(3)]]


def test_nuts_eiv_with_student_noise_recovers_the_matrix():
    data = _student_campaign(31)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DiagnosticWarning)    # short chains: the verdict may fail
        res = fit_matrix(data, PRIOR, model="eiv", noise="student", student_nu=3.0, backend="nuts",
                         rng=np.random.default_rng(32), chains=2, draws=400, tune=400)
    assert np.all(np.isfinite(res.posterior["posterior"]["C"].values))
    assert "eps" in res.priors and "Student-t" in res.priors["noise"]
    assert "eps" not in res.posterior["posterior"]                 # latents are not reported
    _covered(res, 8 / 9)
    p = predict_u(res, [0.0, 1.0, 0.0], rng=np.random.default_rng(1))
    assert np.all(p["lb_mm"] < p["mean_mm"]) and np.all(p["mean_mm"] < p["ub_mm"])


def test_emcee_student_noise_recovers_the_matrix():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DiagnosticWarning)
        res = fit_matrix(_student_campaign(33), PRIOR, noise="student", student_nu=3.0, backend="emcee",
                         rng=np.random.default_rng(34), draws=1500, tune=1000)
    _covered(res, 8 / 9)


DATA = CalibrationData(*draw_campaign(SCENE, np.random.default_rng(0))[::2], np.arange(39))


@pytest.mark.parametrize("kw, match", [
    ({"model": "sideways"}, "model='sideways': must be one of inverse, eiv, forward"),
    ({"noise": "cauchy"}, "noise='cauchy': must be one of gaussian, student"),
    ({"backend": "gibbs"}, "backend='gibbs': must be one of exact, nuts, emcee"),
    ({"noise": "student"}, "exact needs noise=gaussian"),
    ({"model": "eiv"}, "exact needs noise=gaussian and model inverse or forward"),
    ({"model": "eiv", "backend": "emcee"}, "emcee cannot sample the eiv model"),
    ({"noise_sd": (0.1, 0.1)}, "noise_sd=(0.1, 0.1): must be 3 finite numbers > 0"),
    ({"noise_sd": (0.1, 0.0, 0.1)}, "must be 3 finite numbers > 0"),
    ({"stage_sd_mm": 0.0}, "stage_sd_mm=0.0: must be a finite number > 0"),
    ({"student_nu": -1.0}, "student_nu=-1.0: must be a finite number > 0"),
    ({"chains": 0}, "chains=0: must be an integer >= 1"),
    ({"draws": 2}, "draws=2: must be an integer >= 4"),
    ({"tune": -1}, "tune=-1: must be an integer >= 0"),
    ({"walkers": 4}, "walkers=4: must be an integer >= 8"),
])
def test_fit_arguments_are_checked(kw, match):
    with pytest.raises(ArgumentError, match=match.replace("(", r"\(").replace(")", r"\)")):
        fit_matrix(DATA, PRIOR, rng=np.random.default_rng(0), **kw)


@pytest.mark.parametrize("kw, match", [
    ({"c0_mm_per_n": ((1, 0), (0, 1))}, "must be a finite 3x3 matrix"),
    ({"c0_mm_per_n": ((1, 0, 0), (0, 1, 0), (0, 0, float("nan")))}, "must be a finite 3x3 matrix"),
    ({"c0_mm_per_n": ((1, 2, 3), (2, 4, 6), (0, 0, 1))}, "must be invertible"),
    ({"rel_sd": 0.0}, "rel_sd=0.0: must be a finite number > 0"),
    ({"sigma_f_scale_n": float("inf")}, "sigma_f_scale_n=inf: must be a finite number > 0"),
    ({"sigma_u_scale_mm": -1.0}, "sigma_u_scale_mm=-1.0: must be a finite number > 0"),
])
def test_prior_arguments_are_checked(kw, match):
    args = {"c0_mm_per_n": SCENE.prior.c0_mm_per_n, **kw}
    with pytest.raises(ArgumentError, match=match):
        MatrixPrior(**args)


def test_predict_arguments_are_checked():
    res = fit_matrix(DATA, PRIOR, rng=np.random.default_rng(0), draws=100)
    with pytest.raises(ArgumentError, match="must be finite forces of shape"):
        predict_u(res, [1.0, 2.0], rng=np.random.default_rng(0))
    with pytest.raises(ArgumentError, match="prob=1.0: must be in"):
        predict_u(res, [1.0, 2.0, 3.0], rng=np.random.default_rng(0), prob=1.0)
