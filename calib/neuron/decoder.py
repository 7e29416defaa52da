"""The M2 decoder, draw by draw: plate probabilities and the decoded step height of a scan.

Everything a scan contributes is its peak window sum P at each draw's window τ_s; with
the draw's line z = a_s·P − h_s (mm) and the plates' decoded-height means m_cs and sds
s_cs (mm):

- plate probabilities: p(c | scan) = mean_s  N(z_s; m_cs, s_cs) / Σ_c' N(z_s; m_c's, s_c's)
  (equal plate priors; in log space, so nothing underflows), then sharpened by the fit's
  power γ and floored at ε/C (:mod:`.recalibrate`; γ = 1, ε = 0 for posteriors written
  before it) — :meth:`DecoderDraws.class_log_prob`;
- decoded height: the calibration curve m_s(δ) runs piecewise linearly through the plates
  (step c_j, mean m_js) and on past the end plates with the end segments' slopes; its
  spread s_s(δ) is interpolated the same way and held constant past the ends. A taller
  step never reads lower, so each draw's curve is first made non-decreasing (its plate
  means' isotonic regression) and its end slopes kept at least a tenth of its mean slope
  (:func:`monotone_curve`): with six touches a plate (hard/six-plates-few, ten training
  sets) 1-28 % of a fit's draws have two plates' means reversed, 0.4-26 % at an end
  segment; past such an end the curve ran downwards, F turned back up and the bisection
  found the far crossing (an upper bound of 8·10¹² mm, covering every step). The
  predictive CDF of the scan's decoded height at a true step δ is
  F(δ) = mean_s Φ((z_s − m_s(δ)) / s_s(δ)), decreasing in δ. The 90 % interval is
  {δ : 0.05 ≤ F(δ) ≤ 0.95} and the estimate F(δ) = 0.5 (inverting the predictive band,
  the classical-calibration confidence belt): at a true step δ the interval covers δ
  exactly when the scan falls inside δ's own 90 % predictive band, so coverage holds
  plate by plate, not only on average — :meth:`DecoderDraws.height`. When no step can
  be negative the band at δ = 0 is one-sided, turning central within two sds
  (:meth:`DecoderDraws.belt_targets`), so the floor plate is covered at 90 %, not 95 %.

Under a two-mode noise model (:mod:`.modes`) each plate has a ride and a snap
component (means m − πd and m + (1 − π)d, each mode's own sd): a scan whose mode is given
(``snap``, read from the scan) is decoded by its mode's components alone, one without by
the mixture with weights 1 − π and π; the calibration curve, its spread and the belt are
then each component's, F the weighted sum.

With a decoder per mode (:func:`~feeler.calib.neuron.fit.mode_decoders`: the ride and the
snap draws each weighted for the windows that tell their own touches apart, each with
its own γ) a scan whose mode is given is read by its mode's draws alone; its plate
probabilities, F and interval are those of that half of the draws.

A streaming decoder that keeps P(τ_s) of a scan for every draw reproduces both at the end
of the scan by calling these two methods.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.special import ndtr

from feeler.calib.diagnostics import Thresholds
from feeler.calib.neuron.recalibrate import log_sum_exp, recalibrated
from feeler.errors import ArgumentError

__all__ = ["DecoderDraws", "curve_at", "isotonic_rows", "monotone_curve", "undecodable_draws", "MAX_UNDECODABLE",
           "END_SLOPE_MIN"]

# share of posterior draws without a decodable line that is left out, not refused: the share
# for which the fit's summary and verdict do the same (calib.diagnostics)
MAX_UNDECODABLE = Thresholds.nonfinite_max


#: the least slope of a draw's curve past an end plate, as a fraction of its mean slope
END_SLOPE_MIN = 0.1


def _flat(draws, name: str) -> np.ndarray:
    """Draws ``name`` of a posterior group or a dict of arrays, each (chain, draw, ...), as
    ndarray[chain·draw, ...]."""
    v = draws[name]
    v = np.asarray(v.transpose("chain", "draw", ...).values if hasattr(v, "dims") else v, float)
    return v.reshape((-1,) + v.shape[2:])


def undecodable_draws(draws) -> np.ndarray:
    """Draws no height can be decoded from, ndarray[n_draws] bool, of a mapping of named
    draws (a posterior group, or a fit's dict of arrays, each (chain, draw, ...)): a
    window, line or plate mean or sd that is not finite, or a plate sd (and, two-mode
    with a spread per mode, a ride or snap sd) that is not positive."""
    n = _flat(draws, "a").size
    cols = [_flat(draws, k).reshape(n, -1) for k in ("tau_s", "a", "h", "plate_mean_mm", "plate_sd_mm")]
    bad = ~np.isfinite(np.column_stack(cols)).all(axis=1)
    bad |= ~np.all(cols[4] > 0, axis=1)                       # NaN compares False: bad too
    names = draws.data_vars if hasattr(draws, "data_vars") else draws
    if all(k in names for k in ("plate_snap_mm", "snap_share", "plate_ride_sd_mm", "plate_snap_sd_mm")):
        bad |= ~np.all((_flat(draws, "plate_ride_sd_mm") > 0) & (_flat(draws, "plate_snap_sd_mm") > 0), axis=1)
    return bad


def isotonic_rows(x: np.ndarray) -> np.ndarray:
    """Each row of ``x (ndarray[..., C])`` made non-decreasing by isotonic regression with
    equal weights, ndarray[..., C]: f_i = max over j ≤ i of min over k ≥ i of the mean of
    x_j..x_k (Barlow, Bartholomew, Bremner & Brunk 1972, the min–max formula), for every
    row at once; O(C³) a row, for the few plates of a training set."""
    x = np.asarray(x, float)
    C = x.shape[-1]
    csum = np.concatenate([np.zeros(x.shape[:-1] + (1,)), np.cumsum(x, axis=-1)], axis=-1)
    j, k = np.arange(C)[:, None], np.arange(C)[None, :]
    with np.errstate(invalid="ignore", divide="ignore"):
        avg = (csum[..., None, 1:] - csum[..., :-1, None]) / (k - j + 1)         # mean of x_j..x_k, j ≤ k
    out = np.empty_like(x)
    for i in range(C):
        out[..., i] = np.max(np.min(avg[..., :i + 1, i:], axis=-1), axis=-1)
    return out


def _in_order(x) -> np.ndarray:
    """``x (ndarray[..., C])`` with only its rows out of order through :func:`isotonic_rows`."""
    x = np.asarray(x, float)
    bad = np.any(np.diff(x, axis=-1) < 0, axis=-1)
    if not bad.any():
        return x
    out = x.copy()
    out[bad] = isotonic_rows(x[bad])
    return out


def monotone_curve(steps: np.ndarray, mean: np.ndarray, reference: np.ndarray | None = None
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Each row of ``mean (ndarray[..., C])`` made non-decreasing (:func:`isotonic_rows`)
    → (curve ndarray[..., C], slopes past the lower and upper end ndarray[..., 2]: the
    end segments', at least :data:`END_SLOPE_MIN` of the row's mean slope, and positive).
    ``reference (ndarray[..., C])``: the curve whose mean slope bounds the end slopes instead
    (a mode's curve, from a few touches a plate, can come out flat where the plates' is not)."""
    curve = _in_order(mean)
    span = steps[-1] - steps[0]
    ref = curve if reference is None else _in_order(reference)
    overall = np.maximum((ref[..., -1] - ref[..., 0]) / span, np.finfo(float).tiny)
    ends = np.stack([(curve[..., 1] - curve[..., 0]) / (steps[1] - steps[0]),
                     (curve[..., -1] - curve[..., -2]) / (steps[-1] - steps[-2])], axis=-1)
    return curve, np.maximum(ends, END_SLOPE_MIN * overall[..., None])


def curve_at(delta: np.ndarray, steps: np.ndarray, mean: np.ndarray, sd: np.ndarray, end_slopes: np.ndarray):
    """m_s(δ) and s_s(δ) for ``delta (ndarray[n])`` and per-draw plates ``mean, sd
    (ndarray[S, C])`` → two ndarray[S, n] (mm); past the ends the lines from the end
    plates with ``end_slopes (ndarray[S, 2])`` (:func:`monotone_curve`)."""
    seg = np.clip(np.searchsorted(steps, delta) - 1, 0, steps.size - 2)         # (n,)
    c0, dc = steps[seg], steps[seg + 1] - steps[seg]
    m = mean[:, seg] + (delta - c0) * (mean[:, seg + 1] - mean[:, seg]) / dc
    m = np.where(delta < steps[0], mean[:, :1] + (delta - steps[0]) * end_slopes[:, :1], m)
    m = np.where(delta > steps[-1], mean[:, -1:] + (delta - steps[-1]) * end_slopes[:, 1:], m)
    frac = np.clip((delta - c0) / dc, 0.0, 1.0)
    s = sd[:, seg] + frac * (sd[:, seg + 1] - sd[:, seg])
    return m, s


@dataclass(frozen=True)
class DecoderDraws:
    """Posterior draws of the decoder.

    Attributes:
        steps_mm (ndarray[C]): training plates' steps, increasing, mm.
        tau_s, a, h (ndarray[S]): window (s), gain (mm per unit strain), offset (mm).
        mean_mm, sd_mm (ndarray[S, C]): each plate's decoded-height mean and sd, mm.
        sharpness, floor (float): γ and ε of the plate probabilities (:mod:`.recalibrate`).
        undecodable, n_posterior (int): draws of the posterior left out because their line
            has no positive slope (the plates are not ordered at their τ: a = NaN), of all.
        snap_mm (ndarray[S, C]), snap_share (ndarray[S]): two-mode noise: snap mean −
            ride mean and the share of snapping touches (None otherwise). A plate then
            reads as the mixture (1 − π)·N(m − πd, s_w) + π·N(m + (1 − π)d, s_w) with
            mean m and sd ``sd_mm``, s_w² = sd² − π(1 − π)d² (:meth:`components`).
        draw_mode (ndarray[S] int | None): two-mode fits with a decoder per mode
            (:func:`~feeler.calib.neuron.fit.mode_decoders`): the mode (0 ride, 1 snap)
            whose windows each draw was weighted for; a scan whose mode is given is read
            by its mode's draws alone, with that mode's γ (``mode_sharpness``). None: every
            draw reads every scan.
        mode_sharpness (tuple[float, float] | None): γ of the ride and of the snap draws.
    """
    steps_mm: np.ndarray
    tau_s: np.ndarray
    a: np.ndarray
    h: np.ndarray
    mean_mm: np.ndarray
    sd_mm: np.ndarray
    sharpness: float = 1.0
    floor: float = 0.0
    undecodable: int = 0
    n_posterior: int = 0
    snap_mm: np.ndarray | None = None
    snap_share: np.ndarray | None = None
    draw_mode: np.ndarray | None = None
    mode_sharpness: tuple | None = None
    ride_sd_mm: np.ndarray | None = None
    snap_sd_mm: np.ndarray | None = None

    @classmethod
    def from_result(cls, result, *, rng: np.random.Generator | None = None, n_draws: int | None = None,
                    by_mode: bool = True):
        """The decoder of an M2 :class:`FitResult` (a seeded subsample of ``n_draws``).
        ``by_mode``: a two-mode fit's decoder per mode (groups ``ride_decoder`` and
        ``snap_decoder``, half the draws each) where the fit has them; False: the
        posterior's own draws (what ``discriminate`` simulates with)."""
        tree = result.posterior
        post = tree["posterior"]
        need = ("a", "tau_s", "h", "plate_mean_mm", "plate_sd_mm")
        obs = tree["observed_data"] if "observed_data" in tree.children else None
        if any(k not in post.data_vars for k in need) or obs is None or "plate_steps_mm" not in obs.data_vars:
            raise ArgumentError("posterior", "no plate_mean_mm/plate_sd_mm/plate_steps_mm",
                                "a posterior written by this version's neuron fit (refit older ones)")
        steps = np.asarray(obs["plate_steps_mm"].values, float)
        groups = ("ride_decoder", "snap_decoder")
        if by_mode and all(g in tree.children for g in groups):
            parts = [cls._of_group(tree[g], steps, None if n_draws is None else max(1, (n_draws + k) // 2), rng)
                     for k, g in enumerate(groups)]
            names = ("tau_s", "a", "h", "mean_mm", "sd_mm", "snap_mm", "snap_share", "ride_sd_mm", "snap_sd_mm")
            joined = {k: np.concatenate([getattr(p, k) for p in parts]) for k in names
                      if getattr(parts[0], k) is not None}
            return dataclasses.replace(
                parts[0], **joined, draw_mode=np.repeat([0, 1], [p.size for p in parts]),
                mode_sharpness=(parts[0].sharpness, parts[1].sharpness),
                sharpness=float(post.attrs.get("prob_sharpness", 1.0)),
                undecodable=sum(p.undecodable for p in parts), n_posterior=sum(p.n_posterior for p in parts))
        return cls._of_group(post, steps, n_draws, rng)

    @classmethod
    def _of_group(cls, post, steps, n_draws, rng) -> "DecoderDraws":
        """The decoder of one group of draws (the posterior, or a mode's decoder group)."""
        def flat(name):
            return _flat(post, name)

        two = "plate_snap_mm" in post.data_vars and "snap_share" in post.data_vars
        own = two and "plate_ride_sd_mm" in post.data_vars and "plate_snap_sd_mm" in post.data_vars
        out = cls(steps_mm=steps, tau_s=flat("tau_s"), a=flat("a"),
                  h=flat("h"), mean_mm=flat("plate_mean_mm"), sd_mm=flat("plate_sd_mm"),
                  sharpness=float(post.attrs.get("prob_sharpness", 1.0)), floor=float(post.attrs.get("prob_floor", 0.0)),
                  snap_mm=flat("plate_snap_mm") if two else None, snap_share=flat("snap_share") if two else None,
                  ride_sd_mm=flat("plate_ride_sd_mm") if own else None,
                  snap_sd_mm=flat("plate_snap_sd_mm") if own else None)
        if out.steps_mm.size < 2:
            raise ArgumentError("posterior labels", f"{out.steps_mm.size} plate", ">= 2 plates to decode")
        bad = undecodable_draws(post)
        if bad.mean() > MAX_UNDECODABLE:
            raise ArgumentError("posterior", f"{int(bad.sum())} of {bad.size} draws with a non-finite or zero-spread "
                                f"decoder", f"a fit whose plates can be decoded (at most {MAX_UNDECODABLE:.0%} such "
                                "draws; see its verdict)")
        good = np.flatnonzero(~bad)
        if n_draws is not None and n_draws < good.size:
            if rng is None:
                raise ArgumentError("rng", None, "a numpy Generator to subsample draws")
            good = rng.choice(good, size=n_draws, replace=False)
        out = out.take(good) if good.size < out.size else out
        return dataclasses.replace(out, undecodable=int(bad.sum()), n_posterior=int(bad.size))

    @property
    def note(self) -> str | None:
        """One line for the user when draws were left out, else None."""
        if not self.undecodable:
            return None
        return (f"note: {self.undecodable} of {self.n_posterior} posterior draws left out: their plate means "
                f"do not rise with the step at their window, so no height can be decoded from them")

    def take(self, idx) -> "DecoderDraws":
        two = self.snap_mm is not None
        return dataclasses.replace(self, tau_s=self.tau_s[idx], a=self.a[idx], h=self.h[idx],
                                   mean_mm=self.mean_mm[idx], sd_mm=self.sd_mm[idx],
                                   snap_mm=self.snap_mm[idx] if two else None,
                                   snap_share=self.snap_share[idx] if two else None,
                                   draw_mode=None if self.draw_mode is None else self.draw_mode[idx],
                                   ride_sd_mm=None if self.ride_sd_mm is None else self.ride_sd_mm[idx],
                                   snap_sd_mm=None if self.snap_sd_mm is None else self.snap_sd_mm[idx])

    @cached_property
    def _mode_parts(self) -> tuple["DecoderDraws", "DecoderDraws"]:
        """The ride and the snap draws as decoders of their own (γ their mode's)."""
        return tuple(dataclasses.replace(self.take(np.flatnonzero(self.draw_mode == k)), draw_mode=None,
                                         mode_sharpness=None, sharpness=self.mode_sharpness[k]) for k in (0, 1))

    def _by_mode(self, method: str, p_or_z: np.ndarray, snap: np.ndarray, *rest) -> np.ndarray:
        """``method`` of each mode's draws on the scans of that mode (columns of
        ``p_or_z (ndarray[S, n])`` and of the per-scan arrays ``rest``), put back in order."""
        snap = np.asarray(snap, bool)
        out = None
        for k, sel in ((0, ~snap), (1, snap)):
            if not sel.any() and (k or snap.size):          # no scans at all: the rides' empty answer
                continue
            part = self._mode_parts[k]
            rows = self.draw_mode == k
            res = getattr(part, method)(p_or_z[rows][:, sel], *(r[sel] for r in rest), snap[sel])
            if out is None:
                out = np.empty((snap.size,) + res.shape[1:])
            out[sel] = res
        return out

    @cached_property
    def components(self) -> tuple[tuple[np.ndarray, np.ndarray], ...]:
        """The plates' readings as components ((mean ndarray[S, C], sd ndarray[S, C]), ...):
        one (the plate's mean and sd) unless the noise is two-mode, then the ride and the
        snap component (their weights: :meth:`weights`)."""
        if self.snap_mm is None:
            return ((self.mean_mm, self.sd_mm),)
        pi, d = self.snap_share[:, None], self.snap_mm
        if self.ride_sd_mm is not None:                 # each mode's own spread
            return ((self.mean_mm - pi * d, self.ride_sd_mm), (self.mean_mm + (1 - pi) * d, self.snap_sd_mm))
        within = np.sqrt(np.maximum(self.sd_mm ** 2 - pi * (1 - pi) * d ** 2, (1e-6 * self.sd_mm) ** 2))
        return ((self.mean_mm - pi * d, within), (self.mean_mm + (1 - pi) * d, within))

    @property
    def size(self) -> int:
        return int(self.a.size)

    def decoded(self, p_at_tau: np.ndarray) -> np.ndarray:
        """z = a_s·P − h_s (mm) for ``p_at_tau (ndarray[S, n])``, P at each draw's τ."""
        return self.a[:, None] * np.asarray(p_at_tau, float) - self.h[:, None]

    def weights(self, snap: np.ndarray | None, n: int) -> list[np.ndarray]:
        """Each component's weight for ``n`` scans, ndarray[S or 1, n]: the snap share π
        (``two-mode`` noise, mode unknown) or the scans' own modes ``snap (ndarray[n] bool)``
        (:func:`~feeler.calib.neuron.modes.snap_flags`); [1] with one component."""
        if self.snap_mm is None:
            return [np.ones((1, n))]
        if snap is None:
            pi = np.broadcast_to(self.snap_share[:, None], (self.size, n))
            return [1.0 - pi, pi]
        f = np.asarray(snap, float).reshape(1, n)
        return [1.0 - f, f]

    def class_log_prob(self, p_at_tau: np.ndarray, snap: np.ndarray | None = None) -> np.ndarray:
        """log P(plate | scan), ndarray[n, C], from ``p_at_tau (ndarray[S, n])`` (and the
        scans' modes, ``two-mode`` noise: :meth:`weights`; with a decoder per mode each
        scan by its mode's draws)."""
        if self.draw_mode is not None and snap is not None:
            return self._by_mode("class_log_prob", np.asarray(p_at_tau, float), snap)
        z = self.decoded(p_at_tau)[..., None]                                 # (S, n, 1)
        parts = []
        for w, (m, s) in zip(self.weights(snap, z.shape[1]), self.components):
            m, s = m[:, None, :], s[:, None, :]
            with np.errstate(divide="ignore"):
                parts.append(np.log(w)[..., None] - 0.5 * ((z - m) / s) ** 2 - np.log(s))
        ll = parts[0] if len(parts) == 1 else log_sum_exp(np.stack(parts), axis=0)
        cond = ll - log_sum_exp(ll, axis=2, keepdims=True)
        return recalibrated(log_sum_exp(cond, axis=0) - np.log(self.size), self.sharpness, self.floor)

    def plate_distance(self, p_at_tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """How far each scan's reading lies from the nearest training plate, in that plate's
        sds: the median over draws of |z_s − m_cs| / s_cs per plate, then the smallest over
        plates → (distance ndarray[n], nearest plate's index ndarray[n] int). Scans of the
        training plates lie within 4 sds (8200 fresh touches of the nine hard scenes and
        four-plates, two fits each: largest 3.9); a step the fit was not trained on lies
        further (:mod:`.live.envelope`). With a decoder per mode, the larger of the two
        modes' distances: at the snaps' short window a step between or beyond the plates
        can read like a plate (a 0.15 mm scan on plates 0-0.2 mm: 0.1-0.8 sds there, 12 at
        the rides' window)."""
        if self.draw_mode is not None:
            (d0, k0), (d1, k1) = (part.plate_distance(np.asarray(p_at_tau, float)[self.draw_mode == k])
                                  for k, part in enumerate(self._mode_parts))
            return np.maximum(d0, d1), np.where(d1 > d0, k1, k0)
        z = self.decoded(p_at_tau)[..., None]                                 # (S, n, 1)
        d = np.median(np.abs(z - self.mean_mm[:, None, :]) / self.sd_mm[:, None, :], axis=0)    # (n, C)
        k = np.argmin(d, axis=1)
        return d[np.arange(d.shape[0]), k], k

    def predictive_cdf(self, z: np.ndarray, delta: np.ndarray, snap: np.ndarray | None = None) -> np.ndarray:
        """F(δ) = mean_s Φ((z_s − m_s(δ))/s_s(δ)) for ``z (ndarray[S, n])``, ``delta (ndarray[n])``
        (each draw's curve monotone: :func:`monotone_curve`); non-increasing in δ. Two-mode
        noise: Σ_m w_m Φ over the components' curves (:meth:`weights` of ``snap``); with a
        decoder per mode each scan's own mode's draws."""
        if self.draw_mode is not None and snap is not None:
            return self._by_mode("predictive_cdf", z, snap, np.asarray(delta, float))
        if self.snap_mm is not None and snap is not None:      # each scan by its own mode's component alone
            snap = np.asarray(snap, bool)
            f = np.empty(z.shape[1])
            for k, sel in ((0, ~snap), (1, snap)):
                if sel.any():
                    f[sel] = self._component_cdf(k, z[:, sel], delta[sel]).mean(axis=0)
            return f
        return sum(w * self._component_cdf(k, z, delta)
                   for k, w in enumerate(self.weights(snap, z.shape[1]))).mean(axis=0)

    def _component_cdf(self, k: int, z: np.ndarray, delta: np.ndarray) -> np.ndarray:
        """Φ((z_s − m_s(δ))/s_s(δ)) of component ``k`` (:attr:`components`), ndarray[S, n]."""
        curve, ends = self._monotone[k]
        m, s = curve_at(delta, self.steps_mm, curve, self.components[k][1], ends)
        return ndtr((z - m) / s)

    @cached_property
    def _monotone(self) -> tuple[tuple[np.ndarray, np.ndarray], ...]:
        """Each component's curve made monotone (:func:`monotone_curve`)."""
        if self.snap_mm is None:
            return (monotone_curve(self.steps_mm, self.mean_mm),)
        return tuple(monotone_curve(self.steps_mm, m, self.mean_mm) for m, _ in self.components)

    def height(self, p_at_tau: np.ndarray, snap: np.ndarray | None = None, *, prob: float = 0.9,
               iterations: int = 60):
        """Decoded step (F = ½) and its central ``prob`` interval, three ndarray[n] (mm).

        Found by bisection on the monotone F, until every bracket is narrower than 10⁻⁹
        of the training steps' span (about 32 halvings; at most ``iterations``); heights
        are clipped at 0 when every training step is ≥ 0 (the interval then still holds 0
        whenever it did)."""
        z = self.decoded(p_at_tau)
        n = z.shape[1]
        span = self.steps_mm[-1] - self.steps_mm[0]
        # past its ends each draw's curve is a line of positive slope: 12 sds beyond where it
        # meets z, F is 1 (below) or 0 (above) to 10⁻³², so the crossings lie inside
        lo0, hi0 = np.full(n, np.inf), np.full(n, -np.inf)
        for (curve, ends), (_, sd) in zip(self._monotone, self.components):
            reach = 12 * np.max(np.maximum(sd, self.sd_mm), axis=1) / np.min(ends, axis=1)      # mm
            below = self.steps_mm[0] - np.maximum(curve[:, :1] - z, 0.0) / ends[:, :1]
            above = self.steps_mm[-1] + np.maximum(z - curve[:, -1:], 0.0) / ends[:, 1:]
            lo0 = np.minimum(lo0, np.min(below - reach[:, None] - span, axis=0))
            hi0 = np.maximum(hi0, np.max(above + reach[:, None] + span, axis=0))
        lo = np.repeat(lo0[:, None], 3, axis=1)
        hi = np.repeat(hi0[:, None], 3, axis=1)
        tol = 1e-9 * (span if span > 0 else 1.0)
        for _ in range(iterations):
            if np.max(hi - lo, initial=0.0) <= tol:
                break
            mid = 0.5 * (lo + hi)
            f = self.predictive_cdf(np.repeat(z, 3, axis=1), mid.reshape(-1),
                                    None if snap is None else np.repeat(snap, 3)).reshape(n, 3)
            above = f > self.belt_targets(mid, prob)            # F decreases: the crossing lies right of mid
            lo = np.where(above, mid, lo)
            hi = np.where(above, hi, mid)
        out = 0.5 * (lo + hi)
        if self.steps_mm[0] >= 0:
            out = np.maximum(out, 0.0)
        return out[:, 1], out[:, 0], out[:, 2]

    def belt_targets(self, delta: np.ndarray, prob: float = 0.9) -> np.ndarray:
        """The levels of F that bound the ``prob`` band at true steps ``delta (ndarray[n, 3])``
        (columns: lower bound, estimate, upper bound) → ndarray[n, 3].

        Central, (1 + prob)/2 and (1 − prob)/2, away from a boundary. When every training
        step is ≥ 0 no step below 0 exists, so at δ = 0 the band need not exclude low
        readings: it is one-sided there (all readings below F's ``prob`` quantile) and
        turns central over two of the lowest plate's sds, w(δ) = min(1, δ / 2s₀). Each
        δ's band still holds ``prob`` of its readings, so the intervals cover the floor
        plate at the nominal rate instead of (1 + prob)/2 — the clipping at 0 alone gave
        a one-sided 95 % (0.97–0.98 measured on the hard scenes)."""
        tail = (1.0 - prob) / 2
        w = np.clip(delta / self._floor_ramp_mm, 0.0, 1.0)
        return np.stack([prob + tail * w[:, 0], np.full(delta.shape[0], 0.5), tail * w[:, 2]], axis=1)

    @cached_property
    def _floor_ramp_mm(self) -> float:
        """2 s₀ over which the belt turns central past a step of 0 (mm); 0 when steps
        below 0 exist (central everywhere)."""
        return 2.0 * float(np.median(self.sd_mm[:, 0])) if self.steps_mm[0] >= 0 else 0.0
