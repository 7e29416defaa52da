"""M2 entry point: labelled scans → posterior of (a, τ, h, σ) as a :class:`FitResult`.

Pipeline: strain = U_y / length → peak-u₁ table over ln τ → priors scaled to the labels →
backend (``grid`` default, ``nuts``, ``emcee``) → DataTree with the posterior, the
observed labels, the peak table (so a saved posterior can classify new scans) and a
posterior predictive check of the labels (does the decoder fit?).
"""
from __future__ import annotations

import time
import warnings
from dataclasses import dataclass

import numpy as np

from feeler.calib.fit import FitResult, make_result, posterior_from_draws
from feeler.calib.neuron.grid import sample_grid
from feeler.calib.neuron.model import PeakTable, Priors, make_priors, mean_mm, peak_table
from feeler.errors import ArgumentError

__all__ = ["NeuronData", "data_from_scans", "shared_times", "fit_neuron", "posterior_predictive_check",
           "BACKENDS", "DecoderMisfitWarning"]

BACKENDS = ("grid", "nuts", "emcee")


class DecoderMisfitWarning(UserWarning):
    """The posterior predictive check says the decoder does not describe the labels."""


@dataclass(frozen=True)
class NeuronData:
    """Labelled scans for M2.

    Attributes:
        strain (ndarray[n_scans, n_time]): U_y / length, dimensionless.
        t_s (ndarray[n_time] | ndarray[n_scans, n_time]): sample times, s: one time
            base shared by every scan, or each scan's own (acquired scans record when
            each sample was actually taken).
        step_mm (ndarray[n_scans]): label of each scan (its plate's step), mm.
        length_mm (float): representative length used for the strain, mm.
        kernel (str): temporal window of the neuron.
    """
    strain: np.ndarray
    t_s: np.ndarray
    step_mm: np.ndarray
    length_mm: float
    kernel: str = "boxcar"

    def table(self, n_grid: int = 256) -> PeakTable:
        """Peak u₁ on a log-τ grid from half a sample interval to half the scan duration."""
        t = np.atleast_2d(self.t_s)
        dt = float(np.median(np.diff(t, axis=-1)))
        span = float(np.min(t[:, -1] - t[:, 0]))
        return peak_table(self.strain, self.t_s, tau_lo_s=dt / 2, tau_hi_s=span / 2,
                          n_grid=n_grid, kernel=self.kernel)


def data_from_scans(scans, *, length_mm: float, kernel: str = "boxcar") -> NeuronData:
    """:class:`NeuronData` from a :class:`feeler.datasets.Scans` (each scan's own times;
    one shared row when they all agree)."""
    from feeler.datasets import strain

    t = shared_times(scans.t_s)
    return NeuronData(strain=strain(scans.uy_mm, length_mm), t_s=t,
                      step_mm=np.asarray(scans.step_mm, float), length_mm=float(length_mm), kernel=kernel)


def shared_times(t_s) -> np.ndarray:
    """``t_s (ndarray[n_scans, n_time])`` as one row when every scan has the same times,
    else unchanged (each scan keeps its own)."""
    t = np.asarray(t_s, float)
    return t[0] if t.ndim == 2 and np.all(t == t[:1]) else t


def fit_neuron(data: NeuronData, *, backend: str = "grid", seed: int = 0, chains: int = 4,
               draws: int = 1000, tune: int = 1000, emcee_steps: int = 8000, walkers: int = 32,
               priors: Priors | None = None, progress: bool | None = None) -> FitResult:
    """Posterior of (a, τ, h, σ) from labelled scans.

    Raises:
        ArgumentError: unknown backend, fewer than 4 scans, labels not finite.
    """
    if backend not in BACKENDS:
        raise ArgumentError("backend", backend, ", ".join(BACKENDS))
    d = np.asarray(data.step_mm, float)
    if d.size < 4 or not np.all(np.isfinite(d)):
        raise ArgumentError("step_mm", f"{d.size} labels", "at least 4 finite labels")
    start = time.perf_counter()
    table = data.table()
    pri = priors or make_priors(table, d)
    rng = np.random.default_rng(seed)
    stats = None
    if backend == "grid":
        post = sample_grid(table, d, pri, chains=chains, draws=draws, rng=rng)
    elif backend == "nuts":
        from feeler.calib.neuron.mcmc import sample_nuts
        post, stats = sample_nuts(table, d, pri, chains=chains, draws=draws, tune=tune, seed=seed,
                                  progress=progress)
    else:
        from feeler.calib.neuron.mcmc import sample_emcee
        init = sample_grid(table, d, pri, chains=1, draws=4 * walkers, rng=rng, size=16)
        post, stats = sample_emcee(table, d, pri, walkers=walkers, steps=emcee_steps, start=init,
                                   rng=rng, progress=progress)
    ppc, check = posterior_predictive_check(table, d, post, rng)
    tree = posterior_from_draws(post, sample_stats=stats,
                                observed={"step_mm": d, "peak_u1": table.peak, "log_tau_grid": table.log_tau},
                                dims={"step_mm": ["scan"], "peak_u1": ["scan", "tau_grid"],
                                      "log_tau_grid": ["tau_grid"]},
                                extra_groups={"posterior_predictive": {"step_mm": ppc}},
                                attrs={"model": "neuron", "length_mm": data.length_mm, "kernel": data.kernel,
                                       **{f"ppc_{k}": v for k, v in check.items()}})
    seconds = time.perf_counter() - start
    if check["coverage90"] < 0.8 or check["p_value"] < 0.01:
        warnings.warn(f"decoder misfit: {100 * check['coverage90']:.0f} % of labels inside their 90 % "
                      f"predictive interval, discrepancy p = {check['p_value']:.3f}",
                      DecoderMisfitWarning, stacklevel=2)
    return make_result(tree, backend=backend, priors=pri.as_text(), seconds=seconds, bounds=pri.bounds())


def posterior_predictive_check(table: PeakTable, delta_mm, post: dict, rng: np.random.Generator):
    """Replicated labels ``(chain, draw, scan)`` and the check of the real labels.

    Returns:
        (ndarray, dict): replicated labels; ``coverage90`` (fraction of labels inside their
        central 90 % predictive interval) and ``p_value``: posterior predictive p-value
        (replicated ≥ observed) of T = Σ_labels n_c · mean_c(residual)² / σ², which grows
        when the decoder is biased for some plates (a misfit a pooled χ² would average away).
    """
    d = np.asarray(delta_mm, float)
    mu = mean_mm(table, post["a"], post["tau_s"], post["h"])              # (chain, draw, scan)
    sig = post["sigma_mm"][..., None]
    rep = mu + sig * rng.standard_normal(mu.shape)
    lo, hi = np.quantile(rep.reshape(-1, d.size), [0.05, 0.95], axis=0)
    coverage = float(np.mean((d >= lo) & (d <= hi)))
    _, group = np.unique(d, return_inverse=True)
    onehot = np.eye(group.max() + 1)[group]                               # (scan, label)
    counts = onehot.sum(axis=0)

    def stat(y):
        means = ((y - mu) @ onehot) / counts
        return np.sum(counts * means ** 2, axis=-1) / sig[..., 0] ** 2

    return rep, {"coverage90": coverage, "p_value": float(np.mean(stat(rep) >= stat(d)))}
