"""M2 model: the decoded height of a plate scan, calibrated plate by plate.

Data: labelled scans k with plate steps c_k (mm) and P_k(τ), the peak of the unit-gain
window sum u₁ of scan k (strain = U_y / length), tabulated once on a uniform grid in
log τ (one :func:`peak_window_sum` per grid point) and interpolated linearly in log τ.

Model, for a window τ (the "calibration model"; the scans are the response, the
designed steps the covariate, as in classical calibration):

    P_k(τ) | plate c  ~  Normal(μ_c, σ_c),   μ_c free per plate (flat prior),

with the decoder noise σ_c following one of :data:`NOISE_MODELS`:

- ``constant``:  σ_c = σ;
- ``growing``:   σ_c = σ₀·exp(g·x_c), x_c = (c − c_min)/(c_max − c_min), g ~ Uniform(±g_max);
- ``per-plate``: σ_c free;
- ``two-mode``:  a touch snaps onto the upper level (share π) or rides over the edge
  (:mod:`.modes`): P_k | plate c, mode m ~ Normal(μ_cm, σ_m), π ~ Beta(1, 1) from
  the training touches' modes. Every touch's mode is read from its scan, so the decoder
  reads a new scan by its own mode's plates; without one (a live scan's first samples)
  by the mixture (1 − π)·N(μ_c0, σ_0) + π·N(μ_c1, σ_1);
- ``two-mode-growing``: the same with σ_c = σ₀·exp(g·x_c).

  In both two-mode models the ride cells and the snap cells each have a spread of their
  own (σ, or σ₀ and g along their own steps) when each mode has at least 3 scans more
  than cells (:attr:`.modes.Cells.own_spreads`), else one serves both: a snap's peak is
  the step taken in one frame, a ride's spreads it over the pad's passage, and at the
  snaps' short windows the two spread apart (a training set of hard/close-steps at
  0.5 s: snaps 0.0010-0.0038 mm, rides 0.011-0.013). One spread for both had covered the top plates of
  near-floor and five-plates-long-window 0.97-0.98 once each mode was read at its own
  window (:func:`.fit.mode_decoders`). Under the reference prior the scans must also show
  it: draw by draw, at the draw's window, each mode takes a curve of its own with the BIC
  weight of the two spread models and one curve for both otherwise
  (:func:`.modes.own_spread_weight`). A curve fitted to the 8-14 rides of a random untuned
  scene can read spreads far apart, and the plates are then told apart by their spreads.
  Against a curve each whenever the scans allowed it, the log-loss of fresh touches fell
  on 8 of the confidence benchmark's 12 scenes (by 0.0035 a touch on average, se 0.0013;
  the largest rise 0.0044, five-plates-long-window), on 14 of the open-world benchmark's
  16 random scenes in its range (by 0.011, se 0.003), on 20 of 22 random scenes drawn
  with another seed (by 0.010) and on 9 of 10 altered scenes (by 0.009). ECE stayed at most 0.03 on the
  twelve (six-plates-few 0.011 → 0.020); on the random scenes 13 of 16 are at most 0.03
  against 12, but their mean rose from 0.023 to 0.026 and the largest from 0.053 to
  0.059 (random-04, whose rides read at chance with confidence 0.42).

Priors (:class:`PlatePrior`): σ² (or σ₀²) ~ scaled-inv-χ²(ν₀, s₀²) and μ_c | σ_c ~
Normal(m₀_c, σ_c²/κ₀); ν₀ = κ₀ = 0 (the default) is the scale-free reference prior
p(μ, σ) ∝ 1/σ, which makes the fit independent of the units of P. The means are free per
plate because the peak window sum is not linear in the step near the noise floor (a flat
plate's P is the rectified noise, a 0.01 mm step's barely more): a line through the
plates is biased for some of them, which is what the old one-σ regression reported
("per-plate bias p = 0.000") on every fit.

The window τ is a choice of decoder, not a parameter of the scans: P(τ) are different
data for each τ, so τ gets no likelihood of its own. Its weights are those of
pseudo-Bayesian model averaging (pseudo-BMA+, Yao, Vehtari, Simpson & Gelman 2018): prior
× exp(Σ_k log p(δ_k | scan k, other scans, τ)), the leave-one-out predictive density of
each label under the continuous decoder, averaged over Bayesian-bootstrap resamples of
the scans (:mod:`.window`).

Derived per draw: the neuron's gain a (mm per unit strain) and offset h (mm), the
least-squares line μ_c ≈ (c + h)/a through the plate means, so that the pulse density
z = a·P − h is the decoded height in mm; the plate means and sds in mm
(``plate_mean_mm`` = a·μ_c − h, ``plate_sd_mm`` = a·σ_c) and ``sigma_mm``, the root mean
square of the plate sds.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from feeler.errors import ArgumentError

__all__ = ["PeakTable", "Plates", "PlatePrior", "Priors", "peak_table", "make_priors", "plate_stats",
           "decoder_line", "PARAMS", "NOISE_MODELS"]

PARAMS = ("a", "tau_s", "h", "sigma_mm")
NOISE_MODELS = ("constant", "growing", "per-plate", "two-mode", "two-mode-growing")


@dataclass(frozen=True)
class PeakTable:
    """Peak u₁ per scan on a uniform log-τ grid.

    Attributes:
        log_tau (ndarray[n_grid]): ln τ grid (τ in s), uniform.
        peak (ndarray[n_scans, n_grid]): peak u₁ (strain units) per scan and grid τ.
    """
    log_tau: np.ndarray
    peak: np.ndarray

    def at(self, tau_s) -> np.ndarray:
        """P(τ) by linear interpolation in ln τ; ``tau_s`` ndarray[...] → ndarray[..., n_scans]."""
        x = np.log(np.asarray(tau_s, dtype=float))
        lt = self.log_tau
        step = lt[1] - lt[0]
        pos = np.clip((x - lt[0]) / step, 0.0, len(lt) - 1.0)
        i = np.minimum(np.floor(pos).astype(int), len(lt) - 2)
        w = (pos - i)[..., None]
        return self.peak.T[i] * (1.0 - w) + self.peak.T[i + 1] * w


def peak_table(strain, t_s, *, tau_lo_s: float, tau_hi_s: float, n_grid: int = 256,
               kernel: str = "boxcar") -> PeakTable:
    """Tabulate peak u₁ of ``strain (ndarray[n_scans, n_time])`` on ``n_grid`` log-spaced τ.

    ``t_s`` is ndarray[n_time] (one time base) or ndarray[n_scans, n_time] (each scan's
    own sample times, as an acquisition records them)."""
    from feeler.models import neuron

    if not (0 < tau_lo_s < tau_hi_s):
        raise ArgumentError("tau range", (tau_lo_s, tau_hi_s), "0 < tau_lo_s < tau_hi_s")
    log_tau = np.linspace(np.log(tau_lo_s), np.log(tau_hi_s), int(n_grid))

    def peaks(s, t):
        return np.stack([neuron.peak_window_sum(s, t, tau=float(np.exp(x)), kernel=kernel)
                         for x in log_tau], axis=-1)

    strain = np.asarray(strain, dtype=float)
    t_s = np.asarray(t_s, dtype=float)
    peak = peaks(strain, t_s) if t_s.ndim == 1 else \
        neuron.per_time_base(peaks, np.atleast_2d(strain), t_s)
    return PeakTable(log_tau=log_tau, peak=np.atleast_2d(peak))


@dataclass(frozen=True)
class Plates:
    """The plates of a training set.

    Attributes:
        steps_mm (ndarray[C]): distinct steps, increasing, mm.
        group (ndarray[n_scans] int): plate index of each scan.
        counts (ndarray[C] int): scans per plate.
        snap (ndarray[n_scans] bool | None): which scans snapped onto the upper level
            (:mod:`.modes`; the ``two-mode`` noise model's cells), None when not read.
        read_snap (ndarray[n_scans] bool | None): which scans read as snaps when the
            plate is not known, as ``classify`` reads a new scan (a flat plate's scan never
            snaps, but its noise can read as a snap): the mode whose decoder, window and γ
            read it in the leave-one-out (:attr:`read`). None: as ``snap``.
    """
    steps_mm: np.ndarray
    group: np.ndarray
    counts: np.ndarray
    snap: np.ndarray | None = None
    read_snap: np.ndarray | None = None

    @classmethod
    def of(cls, step_mm, snap=None, read_snap=None) -> "Plates":
        steps, group = np.unique(np.asarray(step_mm, float), return_inverse=True)
        return cls(steps_mm=steps, group=group, counts=np.bincount(group, minlength=steps.size),
                   snap=None if snap is None else np.asarray(snap, bool),
                   read_snap=None if read_snap is None else np.asarray(read_snap, bool))

    @property
    def read(self) -> np.ndarray | None:
        """Each scan's mode as a new scan's is read (the plate unknown): ``read_snap``, else ``snap``."""
        return self.snap if self.read_snap is None else self.read_snap

    def subset(self, keep) -> "Plates":
        """The plates of the scans ``keep`` (bool or index array), their modes kept."""
        def kept(v):
            return None if v is None else v[keep]
        return Plates.of(self.steps_mm[self.group[keep]], kept(self.snap), kept(self.read_snap))

    @property
    def x(self) -> np.ndarray:
        """Position of each plate in [0, 1] along the steps (0 for a single plate)."""
        span = self.steps_mm[-1] - self.steps_mm[0]
        return (self.steps_mm - self.steps_mm[0]) / span if span > 0 else np.zeros(self.steps_mm.size)


def plate_stats(p: np.ndarray, plates: Plates) -> tuple[np.ndarray, np.ndarray]:
    """Per-plate mean and within-plate sum of squares of ``p (ndarray[..., n_scans])``:
    two ndarray[..., C]."""
    onehot = np.eye(plates.steps_mm.size)[plates.group]                 # (n, C)
    mean = (p @ onehot) / plates.counts
    resid = p - mean[..., plates.group]
    return mean, (resid ** 2) @ onehot


@dataclass(frozen=True)
class PlatePrior:
    """Conjugate prior of the plate parameters (in the units of P).

    σ² ~ scaled-inv-χ²(nu0, s0_sq) (σ₀² for ``growing``, each σ_c² for ``per-plate``);
    μ_c | σ_c ~ Normal(m0[c], σ_c²/kappa0). ``nu0 = kappa0 = 0`` is the reference prior
    p(μ, σ) ∝ 1/σ (default: units-free); SBC uses a proper one.
    """
    nu0: float = 0.0
    s0_sq: float = 0.0
    kappa0: float = 0.0
    m0: tuple = ()

    def __post_init__(self):
        for name in ("nu0", "s0_sq", "kappa0"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise ArgumentError(name, v, "a finite number >= 0")
        if self.kappa0 > 0 and not self.m0:
            raise ArgumentError("m0", self.m0, "one prior mean per plate when kappa0 > 0")

    @property
    def proper(self) -> bool:
        return self.nu0 > 0 and self.s0_sq > 0 and self.kappa0 > 0


@dataclass(frozen=True)
class Priors:
    """Priors of M2 (stated in every output).

    Attributes:
        tau_lo_s, tau_hi_s (float): ln τ ~ Uniform(ln tau_lo_s, ln tau_hi_s), s.
        growth_max (float): g ~ Uniform(−growth_max, growth_max) for ``growing`` noise.
        plate (PlatePrior): prior of the plate means and sds.
    """
    tau_lo_s: float
    tau_hi_s: float
    growth_max: float = 3.0
    plate: PlatePrior = PlatePrior()

    def as_text(self, noise: str = "per-plate") -> dict[str, str]:
        p = self.plate
        sd = ("reference prior p(mu, sigma) ~ 1/sigma" if not p.proper else
              f"sigma^2 ~ scaled-inv-chi2({p.nu0:g}, {p.s0_sq:.4g}), mu | sigma ~ Normal(m0, sigma^2/{p.kappa0:g})")
        out = {"tau_s": f"ln tau ~ Uniform(ln {self.tau_lo_s:.4g} s, ln {self.tau_hi_s:.4g} s); weights by "
                        f"leave-one-out predictive of the labels (pseudo-BMA)",
               "plates": f"peak window sum of plate c ~ Normal(mu_c, sigma_c), noise {noise}; {sd}",
               "a, h": "least-squares line mu_c = (c + h)/a through the plate means (derived)"}
        if noise in ("growing", "two-mode-growing"):
            out["growth"] = f"sigma_c = sigma_0 exp(g x_c), g ~ Uniform(-{self.growth_max:g}, {self.growth_max:g})"
        if noise in ("two-mode", "two-mode-growing"):
            out["modes"] = ("each touch snaps onto the upper level or rides over the edge (read from its scan: its "
                            "largest one-frame rise against its whole rise); plate c, mode m ~ Normal(mu_cm, sigma_c); "
                            "snap share pi ~ Beta(1, 1)")
            if p.kappa0 == 0:
                out["spreads"] = ("each mode its own sigma_0 (and g) or one curve for both, draw by draw with the "
                                  "BIC weight of the two at the draw's window (own curves need 3 scans more than "
                                  "cells in each mode)")
                out["cell means"] = ("on the plates with a riser (c > 0; three or more), each mode's mu_cm = alpha_m + "
                                     "beta_m c + delta_cm, delta_cm ~ Normal(0, omega_m^2), (alpha_m, beta_m) flat, "
                                     "ln omega_m uniform on 0.05-100 times the cells' standard error; "
                                     "otherwise flat as above")
        return out

    def bounds(self) -> dict[str, tuple[float, float]]:
        """The window range, one sample interval to half a scan (ln τ is uniform between
        them): the ends of the windows the scans have, for :func:`~.checks.window_edge_notes`."""
        return {"tau_s": (self.tau_lo_s, self.tau_hi_s, "log")}


def make_priors(table: PeakTable, *, growth_max: float = 3.0, plate: PlatePrior = PlatePrior()) -> Priors:
    """Priors of a fit on ``table``: τ over the table's range, the reference plate prior."""
    return Priors(tau_lo_s=float(np.exp(table.log_tau[0])), tau_hi_s=float(np.exp(table.log_tau[-1])),
                  growth_max=float(growth_max), plate=plate)


def decoder_line(mu: np.ndarray, plates: Plates) -> tuple[np.ndarray, np.ndarray]:
    """(a, h) of the least-squares line μ_c ≈ (c + h)/a (weights n_c) per row of
    ``mu (ndarray[..., C])``; a ≤ 0 or a single plate give NaN."""
    c, w = plates.steps_mm, plates.counts / plates.counts.sum()
    cbar = float(np.sum(w * c))
    var_c = float(np.sum(w * (c - cbar) ** 2))
    mbar = np.sum(w * mu, axis=-1)
    cov = np.sum(w * (c - cbar) * (mu - mbar[..., None]), axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        slope = cov / var_c if var_c > 0 else np.full(mbar.shape, np.nan)
        a = np.where(slope > 0, 1.0 / slope, np.nan)
        h = a * (mbar - slope * cbar)                     # intercept / slope
    return a, h
