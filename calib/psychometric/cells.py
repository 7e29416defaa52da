"""Trial tables → flat cell arrays, the M4 priors, and the numpy log-likelihood.

A *condition* is one (standard_um, standard_speed_mm_s, comparison_speed_mm_s) triple; a
*cell* is one CSV row (subject, condition, comparison height, n trials, k "comparison
higher"). Every backend works on the same :class:`Cells`.
"""
from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass

import numpy as np
import pandas as pd
from scipy.special import betaln, gammaln

from feeler.errors import ArgumentError
from feeler.models.psychometric import LAPSE_MAX, log_lapse_ndtr

__all__ = ["Cells", "Priors", "make_cells", "log_lik_cells", "POOLED"]

POOLED = "all"  # the subject label of pooled estimates in outputs


@dataclass(frozen=True)
class Priors:
    """Priors of M4 (heights in µm). λ = 0.5·B with B ~ Beta(lapse_a, lapse_b).

    Attributes:
        pse_sd_um: sd of the PSE prior (population PSE in the hierarchical model)
            around the condition's standard height.
        log_sigma_mean, log_sigma_sd: normal prior on log σ (σ in µm).
        pse_spread_um, log_sigma_spread: half-normal scales of the between-subject sds.
        lapse_a, lapse_b: Beta prior of B = λ / 0.5.
        log_phi_mean, log_phi_sd: normal prior on log φ, the beta-binomial concentration.
    """
    pse_sd_um: float = 3.0
    log_sigma_mean: float = math.log(1.5)
    log_sigma_sd: float = 1.0
    pse_spread_um: float = 1.0
    log_sigma_spread: float = 0.5
    lapse_a: float = 2.0
    lapse_b: float = 18.0
    log_phi_mean: float = math.log(30.0)
    log_phi_sd: float = 1.5

    def __post_init__(self):
        for name, value in asdict(self).items():
            if not math.isfinite(value) or (value <= 0 and name not in ("log_sigma_mean", "log_phi_mean")):
                raise ArgumentError(name, value, "prior constants must be finite (scales > 0)")

    def described(self, *, hierarchical: bool, overdispersion: bool) -> dict[str, str]:
        """Each parameter's prior in words with units (for FitResult.priors)."""
        out = {"lapse": f"lapse = {LAPSE_MAX}·B, B ~ Beta({self.lapse_a}, {self.lapse_b}) per subject"}
        if hierarchical:
            out |= {"mu_pse": f"Normal(standard_um, {self.pse_sd_um} µm) per condition",
                    "sd_pse": f"HalfNormal({self.pse_spread_um} µm) per condition",
                    "mu_log_sigma": f"Normal({self.log_sigma_mean:.4g}, {self.log_sigma_sd}) (σ in µm)",
                    "sd_log_sigma": f"HalfNormal({self.log_sigma_spread})",
                    "pse": "mu_pse + sd_pse·Normal(0, 1) per subject × condition",
                    "sigma": "exp(mu_log_sigma + sd_log_sigma·Normal(0, 1)) µm"}
        else:
            out |= {"pse": f"Normal(standard_um, {self.pse_sd_um} µm) per subject × condition",
                    "sigma": f"LogNormal({self.log_sigma_mean:.4g}, {self.log_sigma_sd}) µm"}
        if overdispersion:
            out["phi"] = f"LogNormal({self.log_phi_mean:.4g}, {self.log_phi_sd}) beta-binomial concentration"
        return out


@dataclass(frozen=True)
class Cells:
    """Flat arrays, one entry per CSV row.

    Attributes:
        subjects (tuple[str, ...]): subject labels (index order).
        conditions (tuple[tuple[float, float, float], ...]): (standard_um,
            standard_speed_mm_s, comparison_speed_mm_s) per condition index.
        subject, condition (ndarray[n_cells] int): indices.
        x_um (ndarray[n_cells]): comparison heights, µm.
        n, k (ndarray[n_cells] float): trials and "comparison higher" counts.
    """
    subjects: tuple
    conditions: tuple
    subject: np.ndarray
    condition: np.ndarray
    x_um: np.ndarray
    n: np.ndarray
    k: np.ndarray

    @property
    def standard_um(self) -> np.ndarray:
        """Standard height per condition, µm (ndarray[n_conditions])."""
        return np.array([c[0] for c in self.conditions])

    def attrs(self) -> dict[str, str]:
        """Labels stored with the posterior so outputs can be rebuilt after loading."""
        return {"subjects": json.dumps(list(self.subjects)),
                "conditions": json.dumps([list(c) for c in self.conditions])}

    def select(self, mask: np.ndarray, subjects: tuple) -> "Cells":
        """The cells of ``mask`` with subjects relabelled to ``subjects`` (index 0..)."""
        codes = {s: i for i, s in enumerate(subjects)}
        sub = np.array([codes[self.subjects[i]] for i in self.subject[mask]], dtype=int)
        return Cells(subjects, self.conditions, sub, self.condition[mask], self.x_um[mask],
                     self.n[mask], self.k[mask])

    def pooled(self) -> "Cells":
        """Every subject's trials as one observer labelled :data:`POOLED`."""
        return Cells((POOLED,), self.conditions, np.zeros_like(self.subject), self.condition,
                     self.x_um, self.n, self.k)


def make_cells(trials: pd.DataFrame) -> Cells:
    """Encode a validated trial table (see :func:`feeler.psydata.read_trials`)."""
    if len(trials) == 0:
        raise ArgumentError("trials", "empty table", "needs at least one row")
    subjects = tuple(dict.fromkeys(str(s) for s in trials["subject"]))
    if POOLED in subjects:
        raise ArgumentError("subject", POOLED, f"the label {POOLED!r} is reserved for pooled estimates")
    keys = list(zip(trials["standard_um"].astype(float), trials["standard_speed_mm_s"].astype(float),
                    trials["comparison_speed_mm_s"].astype(float)))
    conditions = tuple(sorted(set(keys)))
    cond_index = {c: i for i, c in enumerate(conditions)}
    sub_index = {s: i for i, s in enumerate(subjects)}
    return Cells(subjects, conditions,
                 np.array([sub_index[str(s)] for s in trials["subject"]], dtype=int),
                 np.array([cond_index[c] for c in keys], dtype=int),
                 trials["comparison_um"].to_numpy(dtype=float),
                 trials["n_trials"].to_numpy(dtype=float),
                 trials["n_comparison_higher"].to_numpy(dtype=float))


def log_lik_cells(cells: Cells, pse, sigma, lapse, phi=None) -> np.ndarray:
    """Log-likelihood of every cell (binomial, or beta-binomial with concentration φ).

    Args:
        pse, sigma (ndarray[..., n_cells]): per-cell PSE and σ (µm).
        lapse (ndarray[..., n_cells]): per-cell lapse rate in (0, 0.5).
        phi (ndarray[..., n_cells] | None): beta-binomial concentration, > 0.
    Returns:
        ndarray[..., n_cells]; a zero-trial cell contributes exactly 0.
    """
    n, k = cells.n, cells.k
    log_p, log_q = log_lapse_ndtr((cells.x_um - pse) / sigma, lapse)
    log_choose = gammaln(n + 1) - gammaln(k + 1) - gammaln(n - k + 1)
    if phi is None:
        return log_choose + _xlog(k, log_p) + _xlog(n - k, log_q)
    tiny = np.finfo(float).tiny                 # p = 0 exactly: the k = 0 limit stays finite
    a, b = np.maximum(phi * np.exp(log_p), tiny), np.maximum(phi * np.exp(log_q), tiny)
    return log_choose + betaln(k + a, n - k + b) - betaln(a, b)


def _xlog(count, log_prob):
    """count·log_prob with 0·(−inf) = 0."""
    return np.where(count > 0, count * log_prob, 0.0)
