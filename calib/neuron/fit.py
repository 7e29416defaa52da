"""M2 entry point: labelled scans → posterior of the decoder as a :class:`FitResult`.

Pipeline: strain = U_y / length → peak-u₁ table over ln τ → plates → checks of what the
data can pin down and of their units → noise model and τ weights by leave-one-out
prediction of the labels (:mod:`.window`) → the sharpness of the pooled plate
probabilities, by leave-one-out too (:mod:`.recalibrate`) → backend (``grid`` default and exact,
``nuts``, ``emcee``; a two-mode model is also drawn at each mode's own windows,
:func:`mode_decoders`) → the decoder's predictive checks (:mod:`.checks`) → DataTree with
the posterior, the observed labels and plates, the peak table (so a saved posterior can
classify new scans), the scene the scans came from (so ``discriminate`` simulates the
same experiment) and every check. See :mod:`.model` for the model.
"""
from __future__ import annotations

import json
import time
import warnings

import numpy as np

from feeler.calib.fit import FitResult, make_result, posterior_from_draws
from feeler.calib.neuron.checks import data_problems, posterior_problems, unit_problems, window_edge_notes
from feeler.calib.neuron.data import NeuronData, data_from_scans, shared_times
from feeler.calib.neuron.decoder import MAX_UNDECODABLE, undecodable_draws
from feeler.calib.neuron.grid import sample_grid
from feeler.calib.neuron.model import NOISE_MODELS, Plates, Priors, make_priors
from feeler.calib.neuron.modes import Cells, snap_flags, within_noise
from feeler.calib.neuron.recalibrate import FLOOR, LOG_GAMMA_SD, LOG_GAMMA_SD_FLAT, fit_sharpness, recalibrated
from feeler.calib.neuron.window import (choose_noise, loo_class_cond, loo_elpd, pooled_class_log_prob,
                                        tau_log_weights, usable_noise_models)
from feeler.errors import ArgumentError

__all__ = ["NeuronData", "data_from_scans", "shared_times", "fit_neuron", "BACKENDS", "NOISE_CHOICES",
           "DecoderMisfitWarning", "mode_decoders", "MODE_DECODER_MIN"]

BACKENDS = ("grid", "nuts", "emcee")
NOISE_CHOICES = ("auto",) + NOISE_MODELS


class DecoderMisfitWarning(UserWarning):
    """The decoder's predictive checks say it does not describe the labelled scans."""


#: samples a training scan needs: its windows, one sample interval to half the scan, must differ
MIN_SAMPLES = 5


def _check_arguments(data: NeuronData, backend: str, noise: str) -> np.ndarray:
    if backend not in BACKENDS:
        raise ArgumentError("backend", backend, ", ".join(BACKENDS))
    if noise not in NOISE_CHOICES:
        raise ArgumentError("noise", noise, ", ".join(NOISE_CHOICES))
    if backend != "grid" and within_noise(noise):
        raise ArgumentError("noise", noise, f"constant, growing or per-plate with the {backend} backend (the two-mode "
                            "models are drawn exactly, by the grid backend)")
    d = np.asarray(data.step_mm, float)
    if d.size < 4 or not np.all(np.isfinite(d)):
        raise ArgumentError("step_mm", f"{d.size} labels", "at least 4 finite labels")
    _, counts = np.unique(d, return_counts=True)
    lone = int(np.sum(counts == 1))
    if lone == counts.size:
        # no plate has two scans: the decoder noise (a plate's spread) has no degree of freedom at all
        hint = _rounding_hint(d)                 # labels that change touch to touch: the grid they round to
        raise ArgumentError("step_mm", f"one scan on each of {d.size} plates",
                            "at least 2 scans of a plate (the decoder's noise is the spread of a plate's scans; "
                            "about 10 per plate pin it down" + (f"; these change from touch to touch, like "
                                                                f"measured heights{hint}" if hint else "") + ")")
    if lone >= 3 and 2 * lone >= counts.size:
        # labels that differ touch to touch (a gauge's reading of each touch) make plates of one scan each
        raise ArgumentError("step_mm", f"{counts.size} distinct steps over {d.size} scans, {lone} of them with one "
                            f"scan", "the decoder learns each plate from its repeated touches, so every touch of a "
                            "plate needs that plate's one step (these change from touch to touch, like measured "
                            "heights" + _rounding_hint(d) + ")")
    s = np.asarray(data.strain, float)
    if s.shape[-1] < MIN_SAMPLES:
        # the windows run from one sample interval to half a scan: fewer samples leave no window at all
        raise ArgumentError("t_s", f"{s.shape[-1]} samples a scan", f"scans of at least {MIN_SAMPLES} samples (the "
                            "neuron's windows run from one sample interval to half the scan; the paper's scans "
                            "have 41)")
    if not np.all(np.isfinite(s)):
        raise ArgumentError("scans", "non-finite displacements", "finite U_y in every sample")
    if np.all(np.ptp(s, axis=-1) == 0):
        raise ArgumentError("scans", "U_y constant in every scan (all-zero displacements?)",
                            "scans whose U_y changes over the plate")
    # a plate the sensor read nothing on (U_y exactly 0 in every sample) was called noise-free and
    # 'labels swapped' (an outside audit); a constant nonzero U_y is a noise-free flat plate: the verdict's
    zero = ~np.any(np.atleast_2d(s) != 0, axis=-1)
    dead = [float(v) for v in np.unique(d) if np.all(zero[d == v])]
    if dead:
        raise ArgumentError("scans", f"U_y 0 in every sample of plate(s) {', '.join(f'{v:g}' for v in dead)} mm",
                            "scans whose U_y changes over the plate (the sensor read nothing there: unplugged, or "
                            "its readings not written?)")
    return d


#: grids (mm) tried by :func:`_rounding_hint`, finest first
_ROUNDING_MM = (0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0)


def _rounding_hint(d: np.ndarray) -> str:
    """"; rounded to the nearest 0.05 mm they form 4 plates …" for labels ``d`` (mm): the
    finest grid of :data:`_ROUNDING_MM` on which they form at least 2 plates, none with
    fewer than 2 scans or than half the largest plate's (a finer grid splits a plate's
    touches at a rounding boundary into a large and a small plate); "" when no grid does."""
    for grid in _ROUNDING_MM:
        steps, counts = np.unique(np.round(d / grid) * grid, return_counts=True)
        if steps.size >= 2 and counts.min() >= max(2.0, 0.5 * counts.max()):
            sizes = f"{counts[0]} scans each" if counts.min() == counts.max() else \
                f"{counts.min()} to {counts.max()} scans"
            return (f"; rounded to the nearest {grid:g} mm they form {steps.size} plates "
                    f"({', '.join(f'{v + 0.0:g}' for v in steps)} mm) of {sizes}")
    return ""


def _readout_noise(data: NeuronData) -> np.ndarray:
    """Each training scan's read-out noise (mm), the envelope that classify checks new scans
    against (:func:`~feeler.calib.neuron.live.envelope.readout_noise_mm`)."""
    from feeler.calib.neuron.live.envelope import readout_noise_mm

    strain = np.atleast_2d(np.asarray(data.strain, float))
    return np.array([readout_noise_mm(row * data.length_mm) for row in strain])


#: scans of each mode a training set needs for the modes to be decoded at their own windows
MODE_DECODER_MIN = 8


def loo_reading(log_prob: np.ndarray, group: np.ndarray) -> dict:
    """How the training scans read when each is left out, from their leave-one-out plate
    probabilities as the decoder gives them (sharpened, floored) ``log_prob (ndarray[n, C])``:
    ``accuracy`` (the most probable plate is its own) and ``log_score`` (mean log
    probability of its own plate) over ``scans`` scans, beside what a decoder that ignores
    the scan would get by saying the scans' own plate shares (``base_accuracy``, the most
    common plate's share; ``base_log_score``, minus their entropy). ``informative``: the
    log score beats the base one; a decoder that does not reads its scans no better than
    knowing how many scans each plate has."""
    lp = np.asarray(log_prob, float)
    g = np.asarray(group, int)
    share = np.bincount(g, minlength=lp.shape[1]) / g.size
    base = float(np.sum(share[share > 0] * np.log(share[share > 0])))
    out = {"scans": int(g.size), "accuracy": float(np.mean(np.argmax(lp, axis=1) == g)),
           "log_score": float(np.mean(lp[np.arange(g.size), g])), "base_accuracy": float(share.max()),
           "base_log_score": base}
    return out | {"informative": bool(out["log_score"] > base)}


def reading_text(r: dict) -> str:
    """:func:`loo_reading`'s figures in words (the fit's CLI and the report say the same)."""
    n = r["scans"]
    return (f"{round(r['accuracy'] * n)} of {n} training scans ({100 * r['accuracy']:.0f} %) read as their own "
            f"plate when each is left out, against {100 * r['base_accuracy']:.0f} % for the most common plate "
            f"alone; log score per scan {r['log_score']:+.3f} (the plates' shares alone: {r['base_log_score']:+.3f})")


def mode_decoders(table, plates: Plates, priors: Priors, noise: str, elpd: np.ndarray, *, chains: int, draws: int,
                  rng: np.random.Generator, cond: np.ndarray | None = None) -> dict:
    """Draws of a two-mode model weighted for each mode's own decoding, ``{"ride": …,
    "snap": …}`` (each ``{"draws": name -> ndarray (chains, draws[, C]), "sharpness": γ,
    "scans": n, "mask": its scans (ndarray[n_scans] bool), "loo_log_prob": their leave-one-out
    plate probabilities as its decoder gives them (sharpened, floored), "loo":``
    :func:`loo_reading` ``of them}``), or {} when a mode has fewer than
    :data:`MODE_DECODER_MIN` scans or
    when a mode's draws leave more than :data:`~.decoder.MAX_UNDECODABLE` of them without
    a decodable line (its windows may be ones where its plates are not in order): classify
    would refuse those, while the verdict checks the joint draws (a random scene of the
    open-world benchmark: 3.9 % of the joint draws, 5.9 % of the rides').

    A ride and a snap are different readings of a riser: a snap takes the step in one
    frame, a ride spreads it over the frames the pad needs to pass the edge, so the window
    τ that best tells the plates apart differs (the eleven hard scenes, ten training sets
    each: the median of the snap draws' window lay at 0.54-1.37 s in 80 % of the fits, the
    rides' at 0.7-5.5 s). One set of τ weights for both modes leans to the snaps' (they
    score the sharper leave-one-out densities), and rides are then read at a window that blurs
    them: on hard/exponential-fast-frames rides decoded at accuracy 0.33 with confidence
    0.42. Here each mode's τ weights are the pseudo-BMA+ weights of its own scans'
    leave-one-out densities (:func:`.window.tau_log_weights` on those columns of
    ``elpd``), the sharpness γ is fitted on its own scans' leave-one-out plate
    probabilities, and the whole model is drawn at those windows; :mod:`.decoder` reads a
    scan of each mode with its mode's draws. A mode's scans are those read in it as
    classify reads a new scan, the plate unknown (:attr:`.model.Plates.read`): a flat
    plate's scan whose noise reads as a snap goes to the snaps' decoder. With every flat
    scan counted as a ride, the snaps' window and γ were fitted on riser snaps alone (on
    an untuned random scene: training snaps read at accuracy 1.0, fresh ones at
    0.90-0.93). The posterior itself (summary, verdict, discriminate) keeps the joint
    weights. ``cond``: the leave-one-out plate
    probabilities per node (:func:`.window.loo_class_cond`), if the caller has them."""
    from feeler.calib.neuron.grid import sample_grid

    if min(int(plates.read.sum()), int((~plates.read).sum())) < MODE_DECODER_MIN:
        return {}
    if cond is None:
        cond = loo_class_cond(table, plates, noise, growth_max=priors.growth_max)
    out = {}
    for name, mask in (("ride", ~plates.read), ("snap", plates.read)):
        log_w = tau_log_weights(elpd[:, mask], rng)
        lp = pooled_class_log_prob(cond, log_w)
        gamma = fit_sharpness(lp[mask], plates.group[mask])
        read = recalibrated(lp[mask], gamma, FLOOR)
        out[name] = {"draws": sample_grid(table, plates, priors, noise, log_w, chains=chains, draws=draws, rng=rng),
                     "sharpness": gamma, "scans": int(mask.sum()), "loo": loo_reading(read, plates.group[mask]),
                     "loo_log_prob": read, "mask": mask}
        if np.mean(undecodable_draws(out[name]["draws"])) > MAX_UNDECODABLE:
            return {}               # more undecodable draws than classify reads: the joint draws, which the verdict checked
    return out


def fit_neuron(data: NeuronData, *, backend: str = "grid", noise: str = "auto", seed: int = 0, chains: int = 4,
               draws: int = 1000, tune: int = 1000, emcee_steps: int | None = None, walkers: int = 32,
               priors: Priors | None = None, progress: bool | None = None, scene_toml: str | None = None,
               scene_path: str | None = None) -> FitResult:
    """Posterior of the M2 decoder from labelled scans.

    Args:
        noise (str): ``auto`` (chosen by leave-one-out prediction) or one of
            :data:`~feeler.calib.neuron.model.NOISE_MODELS`.
        emcee_steps (int | None): emcee steps per walker; None runs until the chains
            are 50 autocorrelation times long (up to a cap; see :mod:`.mcmc`).
        scene_toml, scene_path: the scene the scans were simulated or acquired from,
            recorded in the posterior for ``discriminate``.
    Raises:
        ArgumentError: unknown backend or noise model, fewer than 4 labels, one scan on
            every plate or on most of them (labels that look like measured heights), labels
            or scans not finite, scans that never change.
    """
    d = _check_arguments(data, backend, noise)
    start = time.perf_counter()
    table = data.table()
    plates = Plates.of(d, snap_flags(data.strain, d), snap_flags(data.strain, np.ones(d.size)))
    pri = priors or make_priors(table)
    rng = np.random.default_rng(seed)
    names = data.scan_names if data.scan_names is not None and len(data.scan_names) == d.size else None
    problems = data_problems(table, plates, data.strain, data.length_mm, names) + unit_problems(
        table, plates, length_mm=data.length_mm, t_s=data.t_s, x_mm=data.x_mm, speed_mm_s=data.speed_mm_s)
    usable = usable_noise_models(plates)
    if backend != "grid":                   # the two-mode models: exact draws only
        usable = tuple(m for m in usable if not within_noise(m))
    scores: dict[str, float] = {}
    passed_over = None
    if noise == "auto":
        if usable:
            noise, scores, elpd, passed_over = choose_noise(table, plates, growth_max=pri.growth_max,
                                                            candidates=usable, explain=True)
        else:
            noise, elpd = "constant", np.zeros((table.log_tau.size, 1))
    else:
        if noise not in usable:
            problems.append(f"plate_sd_mm: the {noise} noise model needs more scans per plate than these data have")
            elpd = np.zeros((table.log_tau.size, 1))
        else:
            elpd = loo_elpd(table, plates, noise, growth_max=pri.growth_max, pointwise=True)
    log_w = tau_log_weights(elpd, rng)
    cond = loo_class_cond(table, plates, noise, growth_max=pri.growth_max) if noise in usable else None
    loo_lp = pooled_class_log_prob(cond, log_w) if noise in usable else None
    sharpness = fit_sharpness(loo_lp, plates.group) if noise in usable else 1.0
    stats = None
    by_mode = {}
    if backend == "grid":
        post = sample_grid(table, plates, pri, noise, log_w, chains=chains, draws=draws, rng=rng)
        if within_noise(noise) and noise in usable:
            by_mode = mode_decoders(table, plates, pri, noise, elpd, chains=chains, draws=draws, rng=rng, cond=cond)
    elif backend == "nuts":
        from feeler.calib.neuron.mcmc import sample_nuts
        post, stats = sample_nuts(table, plates, pri, noise, log_w, chains=chains, draws=draws, tune=tune,
                                  seed=seed, progress=progress)
    else:
        from feeler.calib.neuron.mcmc import sample_emcee
        post, stats, note = sample_emcee(table, plates, pri, noise, log_w, walkers=walkers, steps=emcee_steps,
                                         rng=rng, progress=progress)
        problems += note
    fit_problems, info = posterior_problems(table, plates, noise, log_w, post, growth_max=pri.growth_max,
                                            scan_names=names,
                                            mode_tau={k: v["draws"]["tau_s"] for k, v in by_mode.items()})
    problems += fit_problems
    info["window_edge"] = window_edge_notes(post["tau_s"], pri)
    cells = Cells(plates, plates.snap)
    attrs = {"model": "neuron", "length_mm": data.length_mm, "kernel": data.kernel, "noise": noise,
             "noise_scores": json.dumps(scores), "noise_passed_over": json.dumps(passed_over),
             "checks": json.dumps(info),
             "touch_modes": json.dumps({"snaps": cells.snaps, "rides": cells.rides}),
             "prob_sharpness": sharpness, "prob_floor": FLOOR}
    if loo_lp is not None and np.all(np.isfinite(loo_lp)):     # as classify reads them: by mode when it can
        read = recalibrated(loo_lp, sharpness, FLOOR)
        for v in by_mode.values():
            read[v["mask"]] = v["loo_log_prob"]
        attrs["loo_reading"] = json.dumps(loo_reading(read, plates.group))
    if "loo_coverage90" in info:                      # overall, kept for readers of the earlier attribute
        cover = np.asarray(info["loo_coverage90"], float)
        known = np.isfinite(cover)                    # a plate of one scan has no left-out check
        attrs["ppc_coverage90"] = float(np.average(cover[known], weights=plates.counts[known]))
        attrs["ppc_p_value"] = info["p_min"]          # smallest p of the per-plate checks (fails below 0.01/C)
    if scene_toml is not None:
        attrs.update(scene_toml=scene_toml, scene_path=str(scene_path or ""))
    speeds = None if data.speed_mm_s is None else np.asarray(data.speed_mm_s, float)
    if speeds is not None and speeds.size and np.all(np.isfinite(speeds)) and np.all(speeds > 0):
        attrs["scan_speed_mm_s"] = float(np.median(speeds))      # a bare CSV's speed labels: no scene to read it from
    if by_mode:
        attrs["mode_decoders"] = json.dumps({k: {"sharpness": v["sharpness"], "scans": v["scans"],
                                                 "tau_s": float(np.median(v["draws"]["tau_s"])), "loo": v["loo"]}
                                             for k, v in by_mode.items()})
    tree = posterior_from_draws(post, sample_stats=stats,
                                observed={"step_mm": d, "peak_u1": table.peak, "log_tau_grid": table.log_tau,
                                          "readout_noise_mm": _readout_noise(data),
                                          "plate_steps_mm": plates.steps_mm, "tau_log_weight": log_w},
                                dims={"step_mm": ["scan"], "peak_u1": ["scan", "tau_grid"],
                                      "readout_noise_mm": ["scan"], "log_tau_grid": ["tau_grid"],
                                      "tau_log_weight": ["tau_grid"],
                                      "plate_steps_mm": ["plate"], "plate_mean_mm": ["plate"],
                                      "plate_sd_mm": ["plate"], "plate_snap_mm": ["plate"],
                                      "plate_ride_sd_mm": ["plate"], "plate_snap_sd_mm": ["plate"]},
                                extra_groups={f"{k}_decoder": v["draws"] for k, v in by_mode.items()},
                                attrs=attrs)
    for k, v in by_mode.items():
        tree[f"{k}_decoder"].attrs.update(prob_sharpness=v["sharpness"], prob_floor=FLOOR, scans=v["scans"])
    seconds = time.perf_counter() - start
    if fit_problems:
        warnings.warn("decoder misfit: " + "; ".join(fit_problems), DecoderMisfitWarning, stacklevel=2)
    priors_text = pri.as_text(noise) | {
        "plate probabilities": f"pooled over tau, then p^gamma renormalised with a floor {FLOOR:g}/plates; "
                               f"ln gamma ~ Normal(0, {LOG_GAMMA_SD:g}^2) above 0 and Normal(0, {LOG_GAMMA_SD_FLAT:g}^2) below, "
                               f"fitted by leave-one-out (gamma = {sharpness:.3g})"}
    return make_result(tree, backend=backend, priors=priors_text, seconds=seconds, checks=problems)
