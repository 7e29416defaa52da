"""M1 as an SBC problem: prior draws of (K, σ), data on the shipped design, exact fit.

The simulator draws exactly from the model's prior (:mod:`.prior`, inverse direction):
K entries ~ N(K₀, s_K²), σ_j ~ HalfNormal(sigma_f_scale_n), then F = U Kᵀ + σ ⊙ η on the
commanded displacements of the scene's design. Ranks are checked for K, σ and the
derived C = K⁻¹ and cond(C) (any function of the parameters must be rank-uniform too).
"""
from __future__ import annotations

from functools import partial
from pathlib import Path

import numpy as np

from feeler.calib.matrix.exact import exact_posterior
from feeler.calib.matrix.prior import MatrixPrior
from feeler.calib.posterior import entry_name

__all__ = ["matrix_sbc_problem", "simulate_matrix", "fit_matrix_draws"]


def _named(K: np.ndarray, sigma: np.ndarray) -> dict[str, np.ndarray]:
    """``K (d, 3, 3)``, ``sigma (d, 3)`` → flat named draws incl. C and cond_C."""
    C = np.linalg.inv(K)
    out = {}
    for j, k in np.ndindex(3, 3):
        out[entry_name("K", (j, k))] = K[:, j, k]
        out[entry_name("C", (k, j))] = C[:, k, j]
    for j in range(3):
        out[entry_name("sigma_n", (j,))] = sigma[:, j]
    out["cond_C"] = np.linalg.cond(C)
    return out


def simulate_matrix(rng: np.random.Generator, *, u_mm: np.ndarray, prior: MatrixPrior):
    """One (truth, data) pair from the prior predictive; data = (u_mm, f_n)."""
    rp = prior.for_direction("inverse")
    K = rp.b0 + rp.sd * rng.standard_normal((3, 3))
    sigma = np.abs(rp.sigma_scale * rng.standard_normal(3))
    f = u_mm @ K.T + sigma * rng.standard_normal(u_mm.shape)
    truth = {name: float(v[0]) for name, v in _named(K[None], sigma[None]).items()}
    return truth, (u_mm, f)


def fit_matrix_draws(data, rng: np.random.Generator, *, prior: MatrixPrior, n_draws: int = 999):
    """Independent exact posterior draws (the ``exact`` backend's core)."""
    u, f = data
    rp = prior.for_direction("inverse")
    K, sigma = exact_posterior(rng, u, f, rp.b0, rp.sd, rp.sigma_scale, n_draws=n_draws)
    return _named(K, sigma)


# the shipped scene, found from the source tree (not the working directory: issue 16 item 7)
SENSOR_CALIBRATION = Path(__file__).resolve().parents[2] / "datasets-synthetic" / "sensor-calibration.toml"


def matrix_sbc_problem(scene_path: str | Path = SENSOR_CALIBRATION):
    """``(simulate, fit)`` for :func:`feeler.calib.sbc.run_sbc`, picklable, on a scene's design."""
    from feeler.scene import load_scene
    from feeler.scenes.sensor_calibration import commanded_displacements

    scene = load_scene(scene_path)
    prior = MatrixPrior(c0_mm_per_n=scene.prior.c0_mm_per_n, rel_sd=scene.prior.rel_sd,
                        sigma_f_scale_n=scene.prior.sigma_f_scale_n)
    u = commanded_displacements(scene.design)
    return (partial(simulate_matrix, u_mm=u, prior=prior),
            partial(fit_matrix_draws, prior=prior))
