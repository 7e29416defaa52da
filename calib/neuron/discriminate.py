"""M3: the robot's discrimination of step heights from an M2 posterior (DESIGN §6).

Responses to any step height come from the forward model: the scan chain of the scene the
fit was trained on (recorded in the posterior; ``scene_path`` overrides it) simulates
``n_scans`` fresh touches of that height, and each posterior draw θ_s = (a, τ, h) decodes
them to peak pulse densities z = max(a·P(τ) − h, 0). The 2AFC proportion correct of
δ₁ < δ₂ under θ_s is P(z₂ > z₁) + ½ P(z₂ = z₁) over all pairs of touches.

Two sources of uncertainty enter every interval: the posterior (the spread over draws)
and the Monte Carlo error of the finite set of simulated touches, which is common to all
draws and so does not average out over them. Each draw is evaluated on its own bootstrap
resample of the touches (Efron's bootstrap of the two-sample U-statistic), so the spread
of those values over draws is the posterior spread plus the simulation spread; the
reported intervals are their quantiles, the estimate the mean over draws on the touches
as simulated, and ``mcse`` the simulation's standard error (the sd of bootstrap minus
simulated value). The touches are part of the forward model: by default they are seeded
from the scene's own seed (every comparison height with the same root seed — common
random touches, smooth curves over Δδ — and the reference with the next one), so a rerun
with another ``seed`` (posterior draws and resamples) reproduces the estimate within its
interval, and ``touch_seed`` gives an independent set of touches, whose estimate the
interval covers as it covers the large-sample value. Measured on a four-plates fit over
120 touch seeds of 200 touches a height (0.1 against 0.103 mm): the sd of the 120
estimates was 0.995 times the mean reported ``mcse`` for P(correct) and 0.997 for the
threshold, and 95.8 % of the intervals held the mean of all 120 (40 seeds, run after an
outside audit, had put the ratio at 1.12-1.15, within their sampling error of about 0.13).
One resample of each touch set serves a whole curve.

Derived: the difference threshold Δδ₇₅ (the increment over ``reference_mm`` at 75 %
correct) and Weber fraction, reported as a bound (``> 25 um``) with the fraction of
draws when the curves of many draws do not reach 75 % in the searched range; the PSE
between scan speeds.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from feeler.calib.neuron.classify import peaks_at
from feeler.calib.neuron.scene_record import fit_scene_path
from feeler.calib.neuron.synth import scene_scans
from feeler.errors import ArgumentError

__all__ = ["Interval", "Discriminator", "Threshold", "proportion_correct", "separation_bound"]


@dataclass(frozen=True)
class Interval:
    """Estimate, 95 % interval and per-draw values.

    Attributes:
        mean (float): mean over draws of the value on the touches as simulated (NaN when
            some draws have no finite value: see ``found``).
        lo95, hi95 (float): 2.5 and 97.5 % quantiles of the bootstrap-resampled values
            (posterior and simulation error); +inf when the value is not reached.
        draws (ndarray[S]): per-draw values on the simulated touches.
        mcse (float): Monte Carlo standard error of the estimate from the finite touches.
        median (float): median of the bootstrap-resampled values (+inf allowed).
        found (float): fraction of draws with a finite value.
    """
    mean: float
    lo95: float
    hi95: float
    draws: np.ndarray
    mcse: float = float("nan")
    median: float = float("nan")
    found: float = 1.0

    @property
    def estimate(self) -> float:
        """The figure to print: the mean when every draw has a value and it lies inside the
        interval, else the median (inside by construction). Near 1 a few low draws pull
        the mean below the 2.5 % point: 0.99900 [0.99951, 0.99999] (an outside audit)."""
        if self.found == 1 and self.lo95 <= self.mean <= self.hi95:
            return self.mean
        return self.median

    @classmethod
    def of(cls, values, resampled=None) -> "Interval":
        """From per-draw ``values`` and their bootstrap-resampled twins (non-finite = not
        reached, counted as +inf in the quantiles)."""
        v = np.asarray(values, float)
        r = v if resampled is None else np.asarray(resampled, float)
        finite = np.isfinite(v)
        rq = np.where(np.isnan(r), np.inf, r)
        lo, med, hi = np.quantile(rq, [0.025, 0.5, 0.975], method="inverted_cdf")
        both = finite & np.isfinite(r)
        mcse = float(np.std(r[both] - v[both], ddof=1)) if both.sum() > 2 and resampled is not None else float("nan")
        mean = float(v.mean()) if finite.all() else float("nan")
        return cls(mean, float(lo), float(hi), v, mcse, float(med), float(finite.mean()))


@dataclass(frozen=True)
class Threshold:
    """Difference threshold Δδ₇₅ (mm) and Weber fraction around ``reference_mm``;
    ``found`` is the fraction of draws whose curve reaches 75 % within ``searched_mm``."""
    reference_mm: float
    delta75_mm: Interval
    weber: Interval
    found: float
    searched_mm: float = float("nan")
    curve: dict | None = None

    @staticmethod
    def curve_of(deltas_mm: np.ndarray, point: np.ndarray, boot: np.ndarray, n_scans: int) -> dict:
        """The psychometric curve the threshold is read from, per increment ``deltas_mm``:
        ``pc`` the mean over draws of P(correct) on the touches as simulated (what each
        draw's crossing is taken on, so the curve crosses 75 % at the threshold) and
        ``lo95``/``hi95`` the 2.5/97.5 % quantiles of the resampled values (posterior and
        simulation error, as the threshold's interval; bounded as :meth:`Discriminator.pc`
        bounds touches that never overlap). Where nearly every pair is told apart, a few
        draws can put the mean below the resampled quantiles (80 touches: 0.9986 under
        [0.99999, 1]); the band is then widened to hold it, so the curve stays monotone
        inside its band."""
        ivs = [_separated(Interval.of(point[:, k], boot[:, k]), n_scans) for k in range(point.shape[1])]
        mean = point.mean(axis=0)
        return {"delta_mm": [float(d) for d in deltas_mm], "pc": [float(v) for v in mean],
                "lo95": [float(min(iv.lo95, m)) for iv, m in zip(ivs, mean)],
                "hi95": [float(max(iv.hi95, m)) for iv, m in zip(ivs, mean)]}

    @property
    def is_bound(self) -> bool:
        """True when the upper end of the interval is not reached (report as a bound): its
        resampled 97.5 % point lies past the searched range, or more than 2.5 % of the
        draws on the touches as simulated never reach 75 % there (the resamples can reach
        it where those draws do not: 3 % of draws unreached printed a finite 70.9 um
        upper end with "3 % of draws do not reach 75 % within 79.67 um")."""
        return not np.isfinite(self.delta75_mm.hi95) or self.found < 0.975


def proportion_correct(z_low: np.ndarray, z_high: np.ndarray) -> np.ndarray:
    """Per draw: P(z_high > z_low) + ½ P(tie) over all pairs, ndarray[n_draws]."""
    out = np.empty(z_low.shape[0])
    for s, (lo, hi) in enumerate(zip(z_low, z_high)):
        lo = np.sort(lo)
        below = np.searchsorted(lo, hi, side="left")            # lower responses under each higher one
        tied = np.searchsorted(lo, hi, side="right") - below
        out[s] = (below.sum() + 0.5 * tied.sum()) / (lo.size * hi.size)
    return out


class Discriminator:
    """Decodes simulated touches with posterior draws.

    Args:
        result (FitResult): an M2 fit; scene_path: a robot-scan scene for the forward model
            (default: the scene recorded in the fit);
        n_scans (int): touches simulated per height (the Monte Carlo sd of a proportion
            correct near 0.86 is about 0.02 at 400, and shrinks as 1/√n_scans);
        n_draws (int): posterior draws used; seed (int): seed of the draws and resamples;
        touch_seed (int | None): root seed of the simulated touches (default: the scene's seed).
    """

    def __init__(self, result, *, scene_path=None, n_scans: int = 1000, n_draws: int = 200, seed: int = 0,
                 touch_seed: int | None = None):
        if n_scans < 2 or n_draws < 2:
            raise ArgumentError("n_scans/n_draws", (n_scans, n_draws), "both >= 2")
        from feeler.calib.neuron.decoder import DecoderDraws

        rng = np.random.default_rng(seed)
        dec = DecoderDraws.from_result(result, rng=rng, n_draws=n_draws, by_mode=False)   # the posterior's windows
        self.a, self.tau, self.h, self.note = dec.a, dec.tau_s, dec.h, dec.note
        # the decoder's widest plate spread (mm, median over draws): with Gaussian touches of
        # sd σ two heights 4σ apart are told apart 99.8 % of the time (Φ(4/√2)), so the
        # threshold lies within 4σ of any reference whatever its size
        self.spread_mm = float(np.median(np.max(dec.sd_mm, axis=1)))
        self.plates_mm = dec.steps_mm
        attrs = result.posterior["posterior"].attrs
        self.log_tau = np.asarray(result.posterior["observed_data"]["log_tau_grid"].values, float)
        self.kernel, self.length_mm = str(attrs.get("kernel", "boxcar")), float(attrs.get("length_mm", np.nan))
        self.scene_path, self._keep = fit_scene_path(result, scene_path)
        if touch_seed is None:
            from feeler.scene import load_scene
            touch_seed = int(load_scene(self.scene_path).scene.seed)
        self.n_scans, self.seed, self.touch_seed = int(n_scans), int(seed), int(touch_seed)
        self._boot = rng.integers(0, self.n_scans, size=(2, self.a.size, self.n_scans))   # reference, comparison
        self._cache: dict = {}

    def outside_note(self, height_mm, *, option: str = "--reference") -> str | None:
        """One line when a height (or any of a sequence) lies outside the fit's training
        plates, else None: the scene's forward model simulates any height, but the window
        τ was only weighted by how it decodes the trained ones. ``option`` names where
        the heights came from: ``--reference`` (threshold and PSE) or ``--pair``."""
        lo, hi = float(self.plates_mm[0]), float(self.plates_mm[-1])
        out = sorted({float(v) for v in np.atleast_1d(height_mm) if not lo <= float(v) <= hi})
        if not out:
            return None
        what = "its threshold and PSE extrapolate" if option == "--reference" else "their P(correct) extrapolates"
        heights = ", ".join(f"{v:g}" for v in out)
        name = "reference" if option == "--reference" else ("pair height" if len(out) == 1 else "pair heights")
        verb = "lies" if len(out) == 1 else "lie"
        return (f"note: {name} {heights} mm {verb} outside the plates the fit was trained on "
                f"({lo:g}-{hi:g} mm): {what} the calibration ({option})")

    def responses(self, height_mm: float, *, speed_mm_s: float | None = None, reference: bool = False) -> np.ndarray:
        """Peak z per draw and touch, ndarray[n_draws, n_scans], for one step height (mm)."""
        key = (float(height_mm), speed_mm_s, bool(reference))
        if key not in self._cache:
            seed = self.touch_seed + (1 if reference else 0)
            _, _, data = scene_scans(self.scene_path, seed=seed, per_plate=self.n_scans,
                                     heights_mm=(float(height_mm),), speed_mm_s=speed_mm_s)
            p = peaks_at(data.strain, data.t_s, self.log_tau, self.tau, kernel=self.kernel)
            self._cache[key] = np.maximum(self.a[:, None] * p - self.h[:, None], 0.0)
        return self._cache[key]

    def _resampled(self, z: np.ndarray, which: int) -> np.ndarray:
        return np.take_along_axis(z, self._boot[which], axis=1)

    def _curve(self, ref: np.ndarray, tests: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """Per-draw proportion correct of each test against ``ref``: simulated and resampled, (S, k) each."""
        ref_b = self._resampled(ref, 0)
        point = np.stack([proportion_correct(ref, z) for z in tests], axis=1)
        boot = np.stack([proportion_correct(ref_b, self._resampled(z, 1)) for z in tests], axis=1)
        return point, boot

    def pc(self, lower_mm: float, higher_mm: float) -> Interval:
        """2AFC proportion correct that ``higher_mm`` gives the larger response than ``lower_mm``."""
        point, boot = self._curve(self.responses(lower_mm, reference=True), [self.responses(higher_mm)])
        return _separated(Interval.of(point[:, 0], boot[:, 0]), self.n_scans)

    @staticmethod
    def _highest_mm() -> float:
        """The highest step a robot-scan scene allows (mm): comparisons stay below it."""
        from feeler.scene import param_bounds
        from feeler.scenes.robot_scan import Surface

        return param_bounds(Surface, "heights_mm")[1]

    def search_top_mm(self, reference_mm: float) -> float:
        """The largest increment over ``reference_mm`` that :meth:`threshold` searches by
        default (mm): a quarter of the reference or four of the decoder's widest plate sds,
        whichever is larger, the comparison staying within a scene's allowed heights. A
        quarter alone never reached 75 % around a small reference: around 1 µm it searched
        to 0.25 µm, where the threshold is ~15 µm."""
        return min(max(0.25 * reference_mm, 4.0 * self.spread_mm), self._highest_mm() - reference_mm)

    def threshold(self, reference_mm: float = 0.1, *, max_delta_mm: float | None = None, n_steps: int = 25) -> Threshold:
        """Δδ₇₅ around ``reference_mm`` (searched on ``n_steps`` increments up to
        ``max_delta_mm``, by default :meth:`search_top_mm`)."""
        if not reference_mm > 0:
            raise ArgumentError("reference_mm", reference_mm, "> 0")
        top = self.search_top_mm(reference_mm) if max_delta_mm is None else max_delta_mm
        if not top > 0:
            raise ArgumentError("max_delta_mm", top, "> 0")
        deltas = np.linspace(0.0, top, n_steps + 1)
        ref = self.responses(reference_mm, reference=True)
        point, boot = self._curve(ref, [self.responses(reference_mm + d) for d in deltas])
        # a curve at or above 75 % already at Δ = 0 (where it is ½ but for the simulation error
        # of few touches) crosses at 0, not −inf: the threshold is ≥ 0
        cross, cross_boot = (np.maximum(_crossing(deltas, c, 0.75), 0.0) for c in (point, boot))
        d75 = Interval.of(cross, cross_boot)
        weber = Interval.of(d75.draws / reference_mm, cross_boot / reference_mm)
        return Threshold(reference_mm=float(reference_mm), delta75_mm=d75, weber=weber, found=d75.found,
                         searched_mm=float(top), curve=Threshold.curve_of(deltas, point, boot, self.n_scans))

    def pse_range_mm(self, reference_mm: float) -> tuple[float, float]:
        """The heights :meth:`pse` searches by default (mm): the reference ± the reference
        or four of the decoder's widest plate sds, whichever is larger, within 0 and a
        scene's highest allowed step (around 1 µm, 0–2 µm alone held no PSE)."""
        span = max(reference_mm, 4.0 * self.spread_mm)
        return max(reference_mm - span, 0.0), min(reference_mm + span, self._highest_mm())

    def pse(self, reference_mm: float, speed_ref_mm_s: float, speed_test_mm_s: float, *, span_mm: float | None = None,
            n_steps: int = 16) -> Interval:
        """Step at ``speed_test_mm_s`` judged larger than ``reference_mm`` at ``speed_ref_mm_s``
        half the time (mm), searched over :meth:`pse_range_mm` (or the reference ± ``span_mm``)."""
        lo, hi = (self.pse_range_mm(reference_mm) if span_mm is None
                  else (max(reference_mm - span_mm, 0.0), reference_mm + span_mm))
        heights = np.linspace(lo, hi, n_steps + 1)
        ref = self.responses(reference_mm, speed_mm_s=speed_ref_mm_s, reference=True)
        point, boot = self._curve(ref, [self.responses(x, speed_mm_s=speed_test_mm_s) for x in heights])
        # near the floor a curve can be at ½ already at height 0 (both touches mostly decode to
        # 0, a tie each): it crosses at 0, not −inf ("1.91 [-inf, 3.71] um" around 2 µm)
        floor = 0.0 if lo == 0.0 else -np.inf
        return Interval.of(*(np.maximum(_crossing(heights, c, 0.5), floor) for c in (point, boot)))

    # kept for callers of the earlier static method
    proportion_correct = staticmethod(proportion_correct)


def separation_bound(n_scans: int) -> float:
    """The 97.5 % lower bound of a P(correct) when all n_scans × n_scans pairs of touches
    are told apart: n of the pairs are disjoint and independent, so all correct has
    probability at most pⁿ, and p ≥ 0.025^(1/n) (:func:`_separated`)."""
    return 0.025 ** (1.0 / n_scans)


def _separated(iv: Interval, n_scans: int) -> Interval:
    """``iv`` with the Monte Carlo bound of touches that never overlap. When every touch of
    one height lies above every touch of the other, in the simulated set and in every
    resample, the bootstrap has no spread to give: 3 touches a height printed "1.0000
    [1.0000, 1.0000]", MC se 0. Of the n² pairs, n are disjoint and independent, so all
    pairs correct has probability at most pⁿ, and P(correct) ≥ 0.025^(1/n) at 97.5 %
    (0.29 at n = 3, 0.9963 at 1000); the MC se is then not defined (NaN)."""
    bound = separation_bound(n_scans)
    if iv.lo95 >= 1.0:
        return replace(iv, lo95=bound, mcse=float("nan"))
    if iv.hi95 <= 0.0:
        return replace(iv, hi95=1.0 - bound, mcse=float("nan"))
    return iv


def _crossing(x: np.ndarray, curve: np.ndarray, level: float) -> np.ndarray:
    """First upward crossing of ``level`` per row of ``curve (ndarray[n_draws, n_x])``, linear
    interpolation; +inf where the row never reaches ``level`` in the range, −inf where it
    starts at or above it."""
    out = np.full(curve.shape[0], np.inf)
    above = curve >= level
    for i, row in enumerate(curve):
        k = int(np.argmax(above[i]))
        if not above[i, k]:
            continue
        if k == 0:
            out[i] = -np.inf
            continue
        y0, y1 = row[k - 1], row[k]
        out[i] = x[k - 1] + (level - y0) / (y1 - y0) * (x[k] - x[k - 1])
    return out
