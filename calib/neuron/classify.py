"""Classify new scans with an M2 posterior: plate probabilities and a decoded step height.

For each posterior draw θ_s = (a, τ, h, σ) the decoder output of a scan is
z = a·P(τ) − h (P the peak window sum). Plate c's predictive of z under θ_s is the
Student-t of the training scans of that plate (mean m_cs, sd s_cs, n_c scans:
ν = n_c − 1, scale s_cs·√(1 + 1/n_c)); Bayes' rule with equal plate priors gives
p(c | scan, θ_s), and the posterior integrates over draws:
p(c | scan) = mean_s p(c | scan, θ_s) — all in log space (``logsumexp``), so
probabilities near 0 or 1 never underflow. The continuous estimate is the posterior
predictive of the label, δ ~ Normal(max(z, 0), σ), mixed over draws: its mean and
central 90 % interval.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from feeler.calib.neuron.model import PeakTable, peak_table
from feeler.errors import ArgumentError

__all__ = ["Classification", "classify", "expected_calibration_error", "fit_tables"]


@dataclass(frozen=True)
class Classification:
    """Result for ``n_scans`` new scans.

    Attributes:
        plates_mm (ndarray[n_plates]): step of each training plate, mm.
        log_prob (ndarray[n_scans, n_plates]): log P(plate | scan).
        height_mm, lo90_mm, hi90_mm (ndarray[n_scans]): decoded step height (predictive
            mean) and its central 90 % interval, mm.
    """
    plates_mm: np.ndarray
    log_prob: np.ndarray
    height_mm: np.ndarray
    lo90_mm: np.ndarray
    hi90_mm: np.ndarray

    @property
    def prob(self) -> np.ndarray:
        return np.exp(self.log_prob)

    @property
    def plate_mm(self) -> np.ndarray:
        """Most probable plate's step per scan, mm."""
        return self.plates_mm[np.argmax(self.log_prob, axis=1)]


def fit_tables(result):
    """(training PeakTable, labels, draws dict, attrs) out of an M2 :class:`FitResult`."""
    tree = result.posterior
    obs = tree["observed_data"] if "observed_data" in tree.children else None
    for name in ("peak_u1", "log_tau_grid", "step_mm"):
        if obs is None or name not in obs.data_vars:
            raise ArgumentError("posterior", f"no observed_data/{name}", "a posterior written by the neuron fit")
    table = PeakTable(log_tau=np.asarray(obs["log_tau_grid"].values, float),
                      peak=np.asarray(obs["peak_u1"].values, float))
    draws = {k: np.ravel(v) for k, v in result.draws().items()}
    return table, np.asarray(obs["step_mm"].values, float), draws, dict(result.posterior["posterior"].attrs)


def classify(result, strain, t_s, *, rng: np.random.Generator, n_draws: int = 400,
             n_pred: int = 20) -> Classification:
    """Plate probabilities and decoded heights of scans ``strain (ndarray[n_scans, n_time])``.

    Args:
        result (FitResult): an M2 fit (its observed_data holds the training peak table).
        t_s (ndarray[n_time] | ndarray[n_scans, n_time]): sample times, s (shared, or
            each scan's own).
        n_draws (int): posterior draws used (a seeded subsample); n_pred label samples per draw.
    """
    from scipy.special import logsumexp
    from scipy.stats import t as student_t

    train, labels, draws, attrs = fit_tables(result)
    lt = train.log_tau
    new = peak_table(np.atleast_2d(strain), np.asarray(t_s, float), tau_lo_s=float(np.exp(lt[0])),
                     tau_hi_s=float(np.exp(lt[-1])), n_grid=lt.size, kernel=str(attrs.get("kernel", "boxcar")))
    total = draws["a"].size
    pick = rng.choice(total, size=min(n_draws, total), replace=False)
    a, tau, h, sig = (draws[k][pick] for k in ("a", "tau_s", "h", "sigma_mm"))
    z_train = a[:, None] * train.at(tau) - h[:, None]               # (S, n_train)
    z_new = a[:, None] * new.at(tau) - h[:, None]                   # (S, n_new)
    plates, group = np.unique(labels, return_inverse=True)
    if plates.size < 2 or np.min(np.bincount(group)) < 3:
        raise ArgumentError("posterior labels", f"{plates.size} plates", "≥ 2 plates with ≥ 3 scans each")
    logp = np.empty((a.size, z_new.shape[1], plates.size))
    for c in range(plates.size):
        zc = z_train[:, group == c]
        n = zc.shape[1]
        scale = zc.std(axis=1, ddof=1) * np.sqrt(1 + 1 / n)
        logp[..., c] = student_t.logpdf(z_new, df=n - 1, loc=zc.mean(axis=1)[:, None], scale=scale[:, None])
    cond = logp - logsumexp(logp, axis=2, keepdims=True)            # log p(c | scan, θ_s)
    log_prob = logsumexp(cond, axis=0) - np.log(a.size)
    mu = np.maximum(z_new, 0.0)
    pred = mu[None] + sig[None, :, None] * rng.standard_normal((n_pred,) + mu.shape)
    pred = pred.reshape(-1, mu.shape[1])
    lo, hi = np.quantile(pred, [0.05, 0.95], axis=0)
    return Classification(plates_mm=plates, log_prob=log_prob, height_mm=pred.mean(axis=0), lo90_mm=lo, hi90_mm=hi)


def expected_calibration_error(prob, true_index, *, n_bins: int = 10) -> float:
    """ECE of the top-class confidence: Σ_b (n_b/N)·|accuracy_b − confidence_b| over
    ``n_bins`` equal-width confidence bins. ``prob (ndarray[n, n_classes])``."""
    p = np.asarray(prob, float)
    conf, pred = p.max(axis=1), p.argmax(axis=1)
    hit = pred == np.asarray(true_index)
    bins = np.minimum((conf * n_bins).astype(int), n_bins - 1)
    ece = 0.0
    for b in np.unique(bins):
        m = bins == b
        ece += m.mean() * abs(hit[m].mean() - conf[m].mean())
    return float(ece)
