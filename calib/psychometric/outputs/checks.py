"""What a verdict checks beyond the sampler: does the model fit, do prior and data agree,
are the heights in µm, can the data pin the function down.

- **Goodness of fit** per table row: the deviance (binomial, against the saturated model)
  at the point estimate, and the posterior predictive p-value of the deviance,
  p = P(D(y_rep, θ) ≥ D(y, θ)) over posterior draws θ with y_rep simulated from θ
  (beta-binomial when φ is fitted). The verdict fails when some p < α/m (Bonferroni over
  the m rows, α = :data:`GOF_ALPHA`).
- **Prior–data conflict**: a posterior mean of the location or log σ more than
  :data:`CONFLICT_Z` prior sds from the prior's centre, or a lapse beyond its prior's
  1 − :data:`CONFLICT_TAIL` quantile; a factor of ~10³ between posterior and prior
  names the likely unit mistake.
- **Units**: heights whose median is below 0.05 µm or above 1000 µm are ~10³ off the
  range of fingertip step heights: likely mm or nm. Scan speeds whose median lies outside
  1–1000 mm/s (:func:`speed_problems`): m/s below; above, mm/min (a stage's feed rate,
  ×60) or µm/s (×10³), each named with what it converts to.
- **Identifiability**: fewer than three tested levels (:func:`level_problems`), fewer
  than two with responses strictly between none and all (:func:`interior_problems`), a
  threshold at ``pc`` the lapse keeps P from reaching (:func:`threshold_problems`), a 95 % interval of the location
  reaching more than the tested range beyond the tested levels, and the boundary models
  of the spread (:func:`spread_problems`): a step at or between two adjacent levels
  (σ → 0) or a flat line (σ → ∞) that the likelihood-ratio test cannot reject against the
  fitted curve — the data then bound the spread on one side only; and comparison
  responses that fall as the comparison rises (coded the other way round).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.special import ndtr
from scipy.stats import beta as beta_dist

from feeler.models.psychometric import LAPSE_MAX

__all__ = ["deviance", "gof", "worst_cell", "unit_problems", "conflict_problems", "drag_problems", "level_problems",
           "bracket_problems", "gof_problems", "interior_problems", "threshold_problems", "MIN_LEVELS",
           "MIN_INTERIOR", "spread_problems", "one_answer_problem", "GOF_ALPHA", "CONFLICT_Z",
           "CONFLICT_TAIL", "PLAUSIBLE_UM", "BOUNDARY_LR", "FALLING_LR", "speed_problems", "PLAUSIBLE_SPEED_MM_S",
           "straddle_problems", "least_deviance", "nafc_slip_problems", "SLIP_NAFC",
           "SLIP_PREFIX"]

GOF_ALPHA = 0.05
CONFLICT_Z = 4.0
CONFLICT_TAIL = 1e-4
PLAUSIBLE_UM = (0.05, 1000.0)   # fingertip step heights: far below the edge threshold .. 1 mm
# mm/s: a fingertip's scan, a window around the paper's 20 and 40 mm/s wide enough for slow
# strokes and fast swipes; a median ×10³ outside it is m/s or µm/s, ×60 above it mm/min
PLAUSIBLE_SPEED_MM_S = (1.0, 1000.0)
# units a speed column may have been written in by mistake, above the window: (name, factor into mm/s)
_FAST_SPEED_UNITS = (("mm/min, a stage's feed-rate unit", 1 / 60), ("µm/s", 1e-3))
# 5 % critical value of a likelihood ratio for a parameter on its boundary (σ → 0 or ∞):
# ½χ²₀ + ½χ²₁ (Self & Liang 1987), i.e. the 90 % point of χ²₁
BOUNDARY_LR = 2.71
# identifiability of a curve (location, spread and lapse): tested levels, and levels whose
# responses lie strictly between none and all (see level_problems, interior_problems)
MIN_LEVELS = 3
MIN_INTERIOR = 2
# a falling curve beating the flat line by the 1 % point of χ²₁: responses that fall, not noise
FALLING_LR = 6.63


def deviance(n: np.ndarray, k: np.ndarray, p: np.ndarray) -> np.ndarray:
    """2 Σ [k log(k/(n p)) + (n − k) log((n − k)/(n (1 − p)))] over the last axis."""
    n, k = np.asarray(n, float), np.asarray(k, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        a = np.where(k > 0, k * np.log(k / (n * p)), 0.0)
        b = np.where(n - k > 0, (n - k) * np.log((n - k) / (n * (1.0 - p))), 0.0)
    return 2.0 * np.sum(a + b, axis=-1)


def gof(task, x, n, k, draws: dict, point: dict, rng: np.random.Generator, max_draws: int = 4000):
    """(deviance at ``point``, posterior predictive p-value) of one row's cells.

    Args:
        x, n, k (ndarray[m]): levels (µm), trials, counts of the row.
        draws (dict): ``pse``, ``sigma``, ``lapse`` (N,) and optional ``phi`` (N,).
        point (dict): ``pse``, ``sigma``, ``lapse`` of the point estimate.
    """
    d_point = float(deviance(n, k, task.p(x, point["pse"], point["sigma"], point["lapse"])))
    take = slice(None, max_draws)
    pse, sig, lam = (np.asarray(draws[v]).ravel()[take][:, None] for v in ("pse", "sigma", "lapse"))
    p = np.clip(task.p(x[None, :], pse, sig, lam), 1e-300, 1 - 1e-16)
    p_rep = p
    if draws.get("phi") is not None:
        phi = np.asarray(draws["phi"]).ravel()[take][:, None]
        p_rep = rng.beta(np.maximum(phi * p, 1e-12), np.maximum(phi * (1 - p), 1e-12))
    y_rep = rng.binomial(n.astype(np.int64)[None, :], p_rep)
    ppp = float(np.mean(deviance(n, y_rep, p) >= deviance(n, k, p) - 1e-9))
    return d_point, ppp


def worst_cell(task, x, n, k, point: dict) -> str:
    """The cell that contributes most to a row's deviance at ``point``, as a clause: "most
    of it at 7.6 µm: 18 of 20, the curve expects 2.1" (a typed count shows there)."""
    x, n, k = (np.asarray(v, float) for v in (x, n, k))
    if not x.size:
        return ""
    p = np.clip(task.p(x, point["pse"], point["sigma"], point["lapse"]), 1e-300, 1 - 1e-16)
    each = deviance(n[:, None], k[:, None], p[:, None])
    i = int(np.argmax(each))
    return f"most of it at {x[i]:g} µm: {k[i]:g} of {n[i]:g}, the curve expects {n[i] * p[i]:.1f}"


def gof_problems(rows: list[dict]) -> list[str]:
    """Rows whose posterior predictive p is below GOF_ALPHA / (number of rows tested)."""
    tested = [r for r in rows if np.isfinite(r["gof_p"])]
    if not tested:
        return []
    cut = GOF_ALPHA / len(tested)
    return [f"{r['label']}: the model does not fit its data (deviance {r['deviance']:.1f} on "
            f"{r['n_cells']} cells, {r['worst'] + ', ' if r.get('worst') else ''}posterior predictive p = "
            f"{r['gof_p']:.4f} < {cut:.2g} = {GOF_ALPHA}/{len(tested)}); check the design (--nafc?) and that "
            f"cell's counts, or try --overdispersion"
            for r in tested if r["gof_p"] < cut]


#: numbers of alternatives tried when a comparison-design fit fails its goodness of fit
SLIP_NAFC = (2, 3, 4)
#: how the verdict's line on a likely missing --nafc begins (the command repeats it on stderr)
SLIP_PREFIX = "likely a missing --nafc"


def least_deviance(task, x, n, k) -> float:
    """The smallest deviance of ``task``'s curve over a grid of location (the tested range
    and as much again on either side), spread (1/200 to 3 times that range, log-spaced) and
    lapse (0 to 0.3): deterministic, and an upper bound on the maximum-likelihood deviance,
    close to it."""
    x, n, k = (np.asarray(v, float) for v in (x, n, k))
    span = float(np.ptp(x)) or max(abs(float(x.mean())), 1.0)
    m = np.linspace(x.min() - span, x.max() + span, 121)[:, None, None, None]
    s = np.geomspace(span / 200, 3 * span, 61)[None, :, None, None]
    lam = np.array([0.0, 0.01, 0.02, 0.05, 0.1, 0.2, 0.3])[None, None, :, None]
    p = np.clip(task.p(x, m, s, lam), 1e-12, 1 - 1e-12)
    return float(np.min(deviance(n, k, p)))


def nafc_slip_problems(task, failing: list[tuple[str, np.ndarray, np.ndarray, np.ndarray]], cut: float,
                       n_rows: int) -> list[str]:
    """One problem, to lead the verdict, when the comparison-design rows that fail their
    goodness of fit (``failing``: label, levels, trials, counts) fit an nAFC curve (P
    correct, floor 1/N) far better: proportions correct read as 'comparison judged
    higher' without --nafc N. Each such row's own misfit line (:func:`gof_problems`) ends
    in '(--nafc?)', late in a long verdict (an outside audit). Far better: the rows' least
    deviance in all at most half the comparison curve's, and at least half of the rows
    fitting the nAFC curve (the χ² p-value of its deviance on cells − 3 degrees of freedom
    at least ``cut``, the rows' goodness-of-fit threshold; a typed count fits neither
    curve). N is the number of alternatives (2-4) with the smallest deviance in all."""
    from scipy.stats import chi2

    from feeler.calib.psychometric.model.task import Task

    if task.is_nafc or not failing:
        return []
    base = sum(least_deviance(task, x, n, k) for _, x, n, k in failing)
    best = None
    for alternatives in SLIP_NAFC:
        devs = [least_deviance(Task(alternatives), x, n, k) for _, x, n, k in failing]
        fit = sum(chi2.sf(d, max(np.size(x) - 3, 1)) >= cut for d, (_, x, _, _) in zip(devs, failing))
        if 2 * fit >= len(failing) and 2 * sum(devs) <= base and (best is None or sum(devs) < best[1]):
            best = (alternatives, sum(devs), fit)
    if best is None:
        return []
    n_alt, dev, fit = best
    one = len(failing) == 1
    return [f"{SLIP_PREFIX} {n_alt}: {len(failing)} of {n_rows} rows {'does' if one else 'do'} not fit the "
            f"comparison design (P 'comparison judged higher', falling to 0 below the PSE), and {n_alt}AFC "
            f"proportions correct (a floor of 1/{n_alt}) fit {'it' if one else 'them'} far better (deviance "
            f"{dev:.1f} in all, against {base:.1f}{'' if one else f'; {fit} of the {len(failing)} within the fit check'}"
            f"); if the counts are correct answers, fit with --nafc {n_alt} "
            f"({'its' if one else 'each row' + chr(39) + 's'} misfit follows)"]


def _off_scale(values, window: tuple[float, float], *, label: str, what: str, unit: str, norm: str,
               below: tuple, above: tuple) -> list[str]:
    """One problem when the median of the positive ``values`` lies outside ``window``,
    naming each likely unit of ``below`` or ``above`` ((name, factor into ``unit``), …)
    that brings the median inside, with what the values convert to."""
    v = np.asarray(values, float).ravel()
    v = v[np.isfinite(v) & (v > 0)]
    if not v.size:
        return []
    med, (lo, hi) = float(np.median(v)), window
    if lo <= med <= hi:
        return []
    side, candidates = ("below", below) if med < lo else ("above", above)
    fits = [f"{name} ({f'× {f:g}' if f >= 1 else f'÷ {1 / f:g}'} → {f * v.min():.4g}–{f * v.max():.4g} {unit})"
            for name, f in candidates if lo <= med * f <= hi]
    return [f"{label}: the {what} {v.min():.4g}–{v.max():.4g} '{unit}' (median {med:.3g}) are {side} {norm} "
            f"({lo:g}–{hi:g} {unit})" + (f": were they given in {' or in '.join(fits)}?" if fits else "")]


def speed_problems(speeds_mm_s) -> list[str]:
    """One problem when the scan speeds' median lies outside :data:`PLAUSIBLE_SPEED_MM_S`:
    m/s below; mm/min or µm/s above, each named when it brings the median inside
    (missing speeds, NaN, are left out)."""
    return _off_scale(speeds_mm_s, PLAUSIBLE_SPEED_MM_S, label="speeds", what="scan speeds", unit="mm/s",
                      norm="a fingertip's", below=(("m/s", 1000.0),), above=_FAST_SPEED_UNITS)


def straddle_problems(task, cells) -> list[str]:
    """One problem per condition of nAFC data whose comparisons lie on both sides of its
    standard and whose proportion correct falls, across the comparisons below it, as they
    near it. The nAFC curve rises with the comparison level; when an answer is right more
    often the further the comparison lies from the standard on either side, proportion
    correct falls and rises again, and no rising curve fits (an audit's 2AFC counts at
    7.6-12.4 µm around a 10 µm standard were told to 'test a wider range'). The fall: the
    slope of proportion correct on the level (weighted by trials, pooled over subjects)
    below the standard, more than 2 standard errors below 0."""
    if not task.is_nafc:
        return []
    out = []
    for c, (standard, _, _) in enumerate(cells.conditions):
        sel = cells.condition == c
        x, n, k = cells.x_um[sel], cells.n[sel].astype(float), cells.k[sel].astype(float)
        low = x < standard
        if standard <= 0 or not np.any(x > standard) or np.unique(x[low]).size < 2 or n[low].sum() <= 0:
            continue
        xl, nl, pl = x[low], n[low], k[low].sum() / n[low].sum()
        centre = np.sum(nl * xl) / nl.sum()
        sxx = np.sum(nl * (xl - centre) ** 2)
        slope = np.sum((xl - centre) * k[low]) / sxx
        if sxx > 0 and 0 < pl < 1 and slope / np.sqrt(pl * (1 - pl) / sxx) < -2.0:
            out.append(f"[{cells.condition_label(c)}]: {task.label} proportion correct with comparisons on both "
                       f"sides of the standard {standard:g} µm ({x.min():.4g}–{x.max():.4g} µm), falling as those "
                       f"below it near it: answers are right more often the further a comparison lies from the "
                       f"standard on either side, which no rising curve fits; give comparison_um as the distance "
                       f"from the standard, or fit the counts of 'comparison judged higher' (n_comparison_higher) "
                       f"without --nafc")
    return out


def unit_problems(levels_um: np.ndarray) -> list[str]:
    """One problem when the tested heights look like mm or nm rather than µm."""
    return _off_scale(levels_um, PLAUSIBLE_UM, label="heights", what="tested levels", unit="µm",
                      norm="fingertip step heights", below=(("mm", 1000.0),), above=(("nm", 1e-3),))


def _unit_hint(ratio: float) -> str:
    if not (np.isfinite(ratio) and ratio > 0):
        return ""
    dec = math.log10(ratio)
    if -4.0 <= dec <= -2.0:
        return f" — the data are ~10^{dec:.1f} × the prior: heights in mm instead of µm?"
    if 2.0 <= dec <= 4.0:
        return f" — the data are ~10^{dec:.1f} × the prior: heights in nm instead of µm?"
    return ""


def conflict_problems(label: str, c: int, r, draws: dict, levels_um=None) -> list[str]:
    """Prior–data conflict of one row (``r``: the resolved priors; ``draws`` of the row;
    ``levels_um``, the tested heights: a unit is named for the spread only when they look
    like it too)."""
    out = []
    pse = float(np.mean(draws["pse"]))
    z = (pse - r.pse_mean[c]) / r.pse_sd[c]
    if abs(z) > CONFLICT_Z:
        ratio = pse / r.pse_mean[c] if r.pse_mean[c] > 0 else np.nan
        out.append(f"{label}: prior–data conflict: location {pse:.4g} µm lies {abs(z):.1f} prior sds from "
                   f"the prior's {r.pse_mean[c]:.4g} µm (sd {r.pse_sd[c]:.3g}){_unit_hint(ratio)}")
    log_s = float(np.mean(np.log(draws["sigma"])))
    z = (log_s - r.log_sigma_mean[c]) / r.log_sigma_sd
    if abs(z) > CONFLICT_Z:
        # a unit named only when the tested heights look like it too: falling responses fit a very
        # wide curve, and "heights in nm instead of µm?" misled on heights in µm (an outside audit)
        hint = _unit_hint(math.exp(log_s - r.log_sigma_mean[c]))
        if levels_um is not None and not unit_problems(levels_um):
            hint = ""
        out.append(f"{label}: prior–data conflict: σ {math.exp(log_s):.3g} µm lies {abs(z):.1f} prior sds "
                   f"(log scale) from the prior's median {math.exp(r.log_sigma_mean[c]):.3g} µm{hint}")
    lam = float(np.median(draws["lapse"]))
    tail = float(beta_dist.sf(lam / LAPSE_MAX, r.lapse_a, r.lapse_b))
    if tail < CONFLICT_TAIL:
        out.append(f"{label}: prior–data conflict: lapse {lam:.3f} is beyond the prior's "
                   f"{100 * (1 - CONFLICT_TAIL):.2f} % quantile (P = {tail:.1e}): the responses do not "
                   f"follow a rising psychometric function")
    return out


def drag_problems(label: str, task, x, n, k, point: dict, what: str = "PSE") -> list[str]:
    """Prior–data conflict seen from the data: a prior so tight that it holds the location
    where the data would not put it. :func:`conflict_problems` compares the posterior with
    the prior, and a tight prior drags the posterior onto itself (--prior-pse-sd 0.01 printed
    every PSE as 10.000 [9.98, 10.02] µm, the data alone saying 10.76 [10.51, 11.02]: no
    conflict was named; an outside audit). Here the location alone is refitted to the row's
    cells by maximum likelihood, with the spread and lapse of ``point``; a deviance at
    ``point`` worse than that by more than CONFLICT_Z² (the location a z of 4 away) fails."""
    from scipy.optimize import minimize_scalar

    x, n, k = (np.asarray(v, float) for v in (x, n, k))
    sig, lam, m0 = float(point["sigma"]), float(point["lapse"]), float(point["pse"])
    if x.size < 2 or not (np.isfinite(sig) and sig > 0 and np.isfinite(m0)):
        return []

    def dev(m):
        return float(deviance(n, k, np.clip(task.p(x, m, sig, lam), 1e-300, 1 - 1e-16)))

    span = max(float(np.ptp(x)), sig)
    best = minimize_scalar(dev, bounds=(float(x.min()) - span, float(x.max()) + span), method="bounded",
                           options={"xatol": 1e-6 * span})
    at_point = dev(m0)
    worse = at_point - min(best.fun, at_point)
    if worse <= CONFLICT_Z ** 2:
        return []
    return [f"{label}: prior–data conflict: the data alone put the {what} at {best.x:.4g} µm, and the posterior's "
            f"{m0:.4g} µm fits them worse by a deviance of {worse:.1f} (> {CONFLICT_Z ** 2:g}): the prior holds it "
            f"there; check the prior (--prior-pse-sd) or the data"]


def level_problems(label: str, n_levels: int, x_um: np.ndarray) -> list[str]:
    """Fewer than :data:`MIN_LEVELS` tested levels: location and spread follow the prior.

    One level gives one proportion: any location and spread reproduce it. Two levels give
    two proportions, and the curve has three parameters (location m, spread σ, lapse λ):
    for every lapse some (m, σ) passes exactly through both, so the data leave a ridge
    along which m and σ follow the lapse's prior, and the fit has no degree of freedom
    left for its goodness-of-fit test (2 levels 2/20 and 20/20 printed a PSE and a DT as
    estimates with a verdict of ok). Three levels are the fewest with one to spare."""
    if n_levels >= MIN_LEVELS:
        return []
    levels = np.unique(np.asarray(x_um, float))
    if n_levels < 2:
        return [f"{label}: a single tested level ({float(levels[0]):.4g} µm): the data cannot pin down "
                f"the location and the spread (they follow the prior)"]
    shown = ", ".join(f"{v:.4g}" for v in levels)
    return [f"{label}: {n_levels} tested levels ({shown} µm), and the curve needs at least {MIN_LEVELS}: through "
            f"{n_levels} proportions a curve passes exactly for every lapse, so the data cannot pin down the "
            f"location and the spread (they follow the prior) nor test the fit; test more levels across the "
            f"transition"]


def interior_problems(label: str, task, x: np.ndarray, n: np.ndarray, k: np.ndarray) -> list[str]:
    """Fewer than :data:`MIN_INTERIOR` levels whose responses lie strictly between none
    and all counted.

    A level where every trial, or none, gives the response counted only bounds the curve
    (P is near an asymptote there: any location far enough and any spread small enough
    fit); a level in between fixes one point of it, Φ⁻¹ of its proportion. The location
    and the spread are two unknowns: they need two such levels. With one (0/20, 10/20,
    20/20) the location is near it but the spread is bounded above only. Rows without
    any such level are :func:`spread_problems`' (a step or one answer throughout)."""
    x, n, k = (np.asarray(v, float) for v in (x, n, k))
    levels, at = np.unique(x, return_inverse=True)
    n_l, k_l = np.bincount(at, n, levels.size), np.bincount(at, k, levels.size)
    inside = (n_l > 0) & (k_l > 0) & (k_l < n_l)
    if inside.sum() >= MIN_INTERIOR:
        return []
    where = f" (only at {levels[inside][0]:.4g} µm)" if inside.any() else ""
    what = "PSE" if not task.is_nafc else "threshold"
    return [f"{label}: the responses lie strictly between none and all '{task.response}' at {int(inside.sum())} "
            f"of the {levels.size} tested levels{where}, and the location and the spread need at least "
            f"{MIN_INTERIOR} (a level where all or none of the trials give it only bounds the curve): the spread "
            f"is not pinned down; test levels closer together around the {what}"]


def threshold_problems(label: str, task, pc: float, stats: dict) -> list[str]:
    """The threshold at ``pc`` where the posterior gives it no finite bound.

    P never exceeds the ceiling base + scale (:meth:`Task.ceiling`, 1 − λ/2 in the
    comparison design) nor falls below the floor λ/2: the lapse decides whether P ever
    reaches ``pc``. Where it does not, the threshold is +inf (above the ceiling) or −inf
    (below the floor). With more than 97.5 % of the posterior beyond the ceiling not even
    the lower 95 % bound is finite: nothing holds but "not reached". Below the floor the
    grid's quantiles count the unreached mass on the wrong side (+inf): no number is
    shown, and the verdict fails. Between, the threshold is reported as a bound (see
    :mod:`feeler.calib.psychometric.outputs.display`)."""
    th = stats["threshold"]
    unreached = float(th.get("unreached", 0.0))
    if np.isfinite(th["mean"]) or unreached <= 0:
        return []
    lam_ub = float(stats["lapse"]["ub"])
    top = float(task.ceiling(lam_ub))
    if not task.is_nafc and pc < 0.5:
        low = math.ceil(1000 * (1.0 - top) - 1e-9) / 1000
        return [f"{label}: the threshold at P = {pc:g} is not pinned down: for {100 * unreached:.1f} % of the "
                f"posterior P stays above {pc:g} at every height (the lapse keeps P above λ/2); choose --pc "
                f">= {low:g}, which 97.5 % of it reaches"]
    if np.isfinite(th["lb"]):
        return []
    reach = math.floor(1000 * top + 1e-9) / 1000
    return [f"{label}: the threshold at P = {pc:g} is not pinned down: {100 * unreached:.1f} % of the posterior "
            f"never reaches P = {pc:g} (the lapse keeps P below {task.ceiling_text}, {top:.3f} at the lapse's "
            f"97.5 % point {lam_ub:.3g}); choose --pc <= {reach:g}, which 97.5 % of it reaches"]


def bracket_problems(label: str, what: str, lb: float, ub: float, lo: float, hi: float) -> list[str]:
    """A 95 % interval reaching more than the tested range beyond the tested levels."""
    span = hi - lo
    if not span > 0 or not (np.isfinite(lb) and np.isfinite(ub)):
        return []
    if lo - lb > span or ub - hi > span:
        return [f"{label}: the 95 % interval of the {what} [{lb:.4g}, {ub:.4g}] µm reaches far beyond "
                f"the tested levels {lo:.4g}–{hi:.4g} µm: the data do not pin it down"]
    return []


def one_answer_problem(label: str, task, n_trials: int, counted: bool, span: str) -> str:
    """The line for a row whose every trial gave the response counted (``counted``) or
    none did: the function's location lies outside the tested levels, or the responses
    are coded the other way round."""
    if not task.is_nafc:
        what = f"all {n_trials} trials" if counted else f"none of its {n_trials} trials"
        side = "below" if counted else "above"
        return (f"{label}: {what} '{task.response}' at the tested levels {span}: the PSE lies {side} them, and "
                f"neither it nor the spread is pinned down; test levels that bracket it (or check the response "
                f"column)")
    if counted:
        return (f"{label}: all {n_trials} trials correct at the tested levels {span}: the threshold lies below them "
                f"and is not pinned down; test smaller steps")
    return (f"{label}: none of its {n_trials} trials correct, where guessing alone gives 1/{task.n_alternatives}: "
            f"the responses are probably coded the other way round (1 = incorrect)")


def _falling_deviance(x, n, k, levels, above, base, scale) -> float:
    """Smallest deviance of a falling function of the level: the steps ``above (ndarray[M,
    m])`` turned round, and falling cumulative Gaussians on a grid of locations over the
    tested range and spreads from a quarter of the smallest level spacing to the range."""
    span = float(levels[-1] - levels[0])
    gap = float(np.min(np.diff(levels)))
    loc = np.linspace(levels[0], levels[-1], 25)
    sig = np.geomspace(gap / 4, span, 10)
    smooth = ndtr((x[None, None, :] - loc[:, None, None]) / sig[None, :, None]).reshape(-1, x.size)
    shapes = np.concatenate([above, smooth])                                      # (M', m), rising
    p_fall = np.clip(base[:, None, None] + scale[:, None, None] * (1.0 - shapes[None]), 1e-12, 1 - 1e-12)
    return float(np.min(deviance(n, k, p_fall)))


def spread_problems(label: str, task, x: np.ndarray, n: np.ndarray, k: np.ndarray, fitted_deviance: float,
                    fitted_lapse: float, standard_um: float | None = None) -> list[str]:
    """A spread the data bound on one side only, by likelihood ratio against the fitted curve.

    The boundary models: a step between two adjacent tested levels (σ → 0, with a lapse
    up to the fitted one: a larger lapse turns a step into a shallow curve of its own) or,
    for comparison rows, on the ``standard_um`` level with half the responses there (a
    comparison equal to the standard is judged higher half the time however sharp the
    function, so that cell says nothing of the spread), and a flat line (σ → ∞: one
    proportion at every level). A comparison row that a flat line fits as well as the rising curve, but
    a falling curve far better (:data:`FALLING_LR`), is named as coded the other way round. When either fits the counts
    within :data:`BOUNDARY_LR` of the best deviance, the data cannot reject it, and the
    spread, the difference threshold and the slope are bounds, not estimates: below the
    level spacing (a step), or beyond the tested range (flat). Rows with one level are
    :func:`level_problems`'s."""
    x, n, k = (np.asarray(v, float) for v in (x, n, k))
    levels = np.unique(x)
    if levels.size < 2 or n.sum() <= 0:
        return []
    lam = np.linspace(0.0, min(max(float(fitted_lapse), 0.0), 0.98 * LAPSE_MAX), 11)
    base, scale, _ = task.base_scale_rest(lam)                                    # (L,)
    # steps between adjacent tested levels only: a 'step' below or above every level is a flat
    # line at the guess rate or the ceiling, the flat model's (2AFC at chance everywhere read
    # as a step and got 'more trials are needed', an audit's 720 trials at 50 %)
    cuts = (levels[:-1] + levels[1:]) / 2
    above = (x[None, :] > cuts[:, None]).astype(float)                            # (M, m)
    if standard_um is not None and not task.is_nafc and np.any(x == standard_um):
        above = np.concatenate([above, ((x > standard_um) + 0.5 * (x == standard_um))[None, :]])
    p_step = np.clip(base[:, None, None] + scale[:, None, None] * above[None], 1e-12, 1 - 1e-12)
    d_step = float(np.min(deviance(n, k, p_step)))
    d_fall = _falling_deviance(x, n, k, levels, above, base, scale)
    b0, s0, _ = task.base_scale_rest(0.0)
    p_flat = float(np.clip(k.sum() / n.sum(), max(float(b0), 1e-12), min(float(b0 + s0), 1 - 1e-12)))
    d_flat = float(deviance(n, k, np.full(x.shape, p_flat)))
    best = min(float(fitted_deviance), d_step, d_flat)
    step, flat = d_step - best <= BOUNDARY_LR, d_flat - best <= BOUNDARY_LR
    span = f"{levels[0]:.4g}–{levels[-1]:.4g} µm"
    if k.sum() in (0, n.sum()):                     # one answer throughout: a flat line and a step fit exactly
        return [one_answer_problem(label, task, int(n.sum()), bool(k.sum()), span)]
    if flat and not task.is_nafc and d_flat - d_fall > FALLING_LR:
        return [f"{label}: the responses fall as the comparison rises across {span} (a falling curve fits with "
                f"deviance {d_fall:.2f}, a flat line {d_flat:.2f}, the rising curve {fitted_deviance:.2f}): the "
                f"counts are probably of the standard judged higher; give n_trials minus them as "
                f"n_comparison_higher"]
    if step and flat:
        return [f"{label}: the data cannot pin down the spread: a step between two tested levels and a flat "
                f"line fit its {int(n.sum())} trials as well as the curve (likelihood ratio < {BOUNDARY_LR}); "
                f"more trials are needed"]
    if step:
        return [f"{label}: the responses step at or between two adjacent tested levels (a step function fits as well: "
                f"deviance {d_step:.2f}, the curve's {fitted_deviance:.2f}): the spread and the threshold are below the level "
                f"spacing and not pinned down; test levels closer together around the PSE"]
    if flat:
        return [f"{label}: the responses do not rise across the tested levels {span} (a flat line at "
                f"{p_flat:.2f} fits as well: deviance {d_flat:.2f}, the curve's {fitted_deviance:.2f}): the threshold lies beyond "
                f"them and is not pinned down; test a wider range"]
    return []
