"""Priors of M4, scaled to each condition's stimulus range unless set in µm.

For a condition whose tested levels span [lo, hi] (range R = hi − lo, over every
subject's trials in it):

- location m (the PSE): Normal(centre, sd) with centre = the standard (comparison design)
  or (lo + hi)/2 (nAFC), sd = ``pse_sd_um`` or ``pse_sd_range``·R (default R/2);
- spread σ: log σ ~ Normal(log σ₀, ``log_sigma_sd``), σ₀ = ``sigma_um`` or
  ``sigma_range``·R (default R/4), so the 95 % prior range of σ is σ₀·e^(±1.96);
- lapse λ = 0.5·B, B ~ Beta(``lapse_a``, ``lapse_b``) (default mean 0.05);
- hierarchical model: between-subject sds HalfNormal(``pse_spread_range``·R µm) for the
  PSE and HalfNormal(``log_sigma_spread``) for log σ;
- beta-binomial concentration φ: LogNormal(``log_phi_mean``, ``log_phi_sd``).

A condition with a single tested level has R = 0; its scale falls back to a tenth of the
level (the verdict fails such a condition anyway: the data cannot pin σ down).
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from feeler.errors import ArgumentError
from feeler.models.psychometric import LAPSE_MAX

__all__ = ["Priors", "Resolved", "stimulus_ranges"]


@dataclass(frozen=True)
class Priors:
    """What the user chose (None: scaled to the stimulus range); see the module doc."""
    pse_sd_um: float | None = None
    pse_sd_range: float = 0.5
    sigma_um: float | None = None
    sigma_range: float = 0.25
    log_sigma_sd: float = 1.0
    pse_spread_range: float = 0.2
    log_sigma_spread: float = 0.5
    lapse_a: float = 2.0
    lapse_b: float = 18.0
    log_phi_mean: float = math.log(30.0)
    log_phi_sd: float = 1.5

    def __post_init__(self):
        for name, value in asdict(self).items():
            if value is None:
                continue
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
                    or (value <= 0 and name != "log_phi_mean"):
                raise ArgumentError(name, value, "prior constants must be finite numbers (scales > 0)")
        if self.lapse_a < 1.0:
            raise ArgumentError("lapse_a", self.lapse_a, "must be >= 1 (a Beta density finite at lapse 0)")

    def resolve(self, cells) -> "Resolved":
        """Per-condition numbers for ``cells`` (a :class:`~feeler.calib.psychometric.model.cells.Cells`)."""
        lo, hi = stimulus_ranges(cells)
        span = np.where(hi > lo, hi - lo, 0.1 * np.maximum(np.abs(hi), 1e-12))
        centre = (lo + hi) / 2 if cells.task.is_nafc else cells.standard_um
        pse_sd = np.full(span.shape, self.pse_sd_um) if self.pse_sd_um else self.pse_sd_range * span
        sigma0 = np.full(span.shape, self.sigma_um) if self.sigma_um else self.sigma_range * span
        return Resolved(pse_mean=centre, pse_sd=pse_sd, log_sigma_mean=np.log(sigma0),
                        log_sigma_sd=self.log_sigma_sd, pse_spread=self.pse_spread_range * span,
                        log_sigma_spread=self.log_sigma_spread, lapse_a=self.lapse_a,
                        lapse_b=self.lapse_b, log_phi_mean=self.log_phi_mean,
                        log_phi_sd=self.log_phi_sd, lo=lo, hi=hi, source=self)


@dataclass(frozen=True)
class Resolved:
    """Priors in numbers, arrays over conditions (µm); see :meth:`Priors.resolve`."""
    pse_mean: np.ndarray
    pse_sd: np.ndarray
    log_sigma_mean: np.ndarray
    log_sigma_sd: float
    pse_spread: np.ndarray
    log_sigma_spread: float
    lapse_a: float
    lapse_b: float
    log_phi_mean: float
    log_phi_sd: float
    lo: np.ndarray
    hi: np.ndarray
    source: Priors

    def described(self, cells, *, hierarchical: bool, overdispersion: bool) -> dict[str, str]:
        """Each prior in words, with the numbers of every condition (FitResult.priors)."""
        p = self.source
        where = "the standard" if not cells.task.is_nafc else "the middle of the tested levels"
        pse_how = "set by --prior-pse-sd" if p.pse_sd_um else f"{p.pse_sd_range:g} × the range of tested levels"
        sig_how = "set by --prior-sigma" if p.sigma_um else f"{p.sigma_range:g} × the range of tested levels"
        out = {}
        for c, cond in enumerate(cells.conditions):
            tag = f"[{cells.condition_label(c)}]"
            out[f"pse{tag}"] = (f"Normal({self.pse_mean[c]:.4g} µm = {where}, sd {self.pse_sd[c]:.3g} µm = {pse_how}; "
                                f"tested {self.lo[c]:.4g}–{self.hi[c]:.4g} µm)")
            out[f"sigma{tag}"] = (f"LogNormal(median {math.exp(self.log_sigma_mean[c]):.3g} µm = {sig_how}, "
                                  f"log-sd {self.log_sigma_sd:g}): 95 % in "
                                  f"[{math.exp(self.log_sigma_mean[c] - 1.96 * self.log_sigma_sd):.3g}, "
                                  f"{math.exp(self.log_sigma_mean[c] + 1.96 * self.log_sigma_sd):.3g}] µm")
            if hierarchical:
                out[f"sd_pse{tag}"] = f"HalfNormal({self.pse_spread[c]:.3g} µm) between subjects"
        if hierarchical:
            out["sd_log_sigma"] = f"HalfNormal({self.log_sigma_spread:g}) between subjects (log σ)"
            out["population"] = "the pse and sigma priors above are the population means' priors"
        mean = LAPSE_MAX * p.lapse_a / (p.lapse_a + p.lapse_b)
        out["lapse"] = (f"lapse = {LAPSE_MAX}·B, B ~ Beta({p.lapse_a:g}, {p.lapse_b:g}) (mean {mean:.3g}); "
                        f"a lapse is a guess")
        if overdispersion:
            out["phi"] = (f"LogNormal(median {math.exp(p.log_phi_mean):.3g}, log-sd {p.log_phi_sd:g}) "
                          f"beta-binomial concentration")
        return out


def stimulus_ranges(cells) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) of the tested levels per condition (rows with trials; all rows if none)."""
    n_cond = len(cells.conditions)
    lo, hi = np.full(n_cond, np.nan), np.full(n_cond, np.nan)
    for c in range(n_cond):
        sel = cells.condition == c
        tested = sel & (cells.n > 0)
        x = cells.x_um[tested if tested.any() else sel]
        if x.size:
            lo[c], hi[c] = x.min(), x.max()
    return lo, hi
