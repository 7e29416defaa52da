"""Calibrated confidence of the M2 decoder on hard plates, beside plug-in baselines (issue 14).

Scenes: ``datasets-synthetic/hard/*.toml`` (plates hard to tell apart: at the noise
floor, close steps, a noisier read-out, few touches, a tilted face; accuracy 60–95 %),
and six built afterwards and never tuned: six plates from 0.01 mm with 6 touches each,
three plates under an exponential-kernel neuron, unevenly spaced plates, a neuron
window of 0.7 s (near the prior's 0.5 s bound, shorter than the ride over the face),
and two from session 36: five plates under a 5 s window with a 3 deg tilt, a firmer
press and a 3 um read-out, and four plates from 0.005 mm under an exponential-kernel
neuron with 0.25 s frames.
One control, ``datasets-synthetic/controls/few-scans-no-snap.toml``: few-scans (same
seeds) with no touch snapping onto the upper level. Where half the touches snap and half
ride over the edge, a plate's touches are two modes mixed, flatter than Gaussian, and a
Gaussian band covered the upper plates above 0.95; the two-mode models read each touch's
mode from its scan (:mod:`feeler.calib.neuron.modes`). Without snapping the one-mode
models describe the touches; the control shows the default choice does no harm there.
Per scene, ``REPLICATES`` training sets (the scene with seeds seed+1…) are fitted with the
default backend, and each classifies its own ``FRESH`` fresh touches per plate (seeds
seed + 10⁶ + r: independent test sets, so the ECE's sampling noise shrinks with every
replicate instead of repeating the same scans). A fit whose verdict failed and that
``classify`` refuses to read (more than 5 % undecodable draws) is counted and left out.

Baselines, the five-line Gaussian classifier a lab would write without a posterior
(per-plate mean and sd by maximum likelihood, equal plate priors) on the peak pulse
density:
- ``plug-in, true tau``: at the scene's own neuron τ — it knows what no fit knows;
- ``plug-in, fitted tau``: at the fit's posterior median τ.

Reported per scene (over all replicates' predictions pooled; 10 equal-width bins of the
top probability; log-loss in nats per scan): accuracy, ECE and log-loss of feeler and of
both baselines, the ECE a perfectly calibrated forecaster would show at this sample size
(``ece_floor``: labels drawn from feeler's own probabilities, median of 20 draws), the
fitted sharpness γ (:mod:`feeler.calib.neuron.recalibrate`), and the coverage of feeler's
90 % height intervals per plate (mean and minimum over replicates); in brackets, how far
a figure moves with the training sets drawn: for the ECE its jackknife standard error
over the sets, for each plate's coverage the 5–95 % range over bootstrap resamples of
them; then ECE, log-loss and
coverage again over the fits whose verdict is ok — the ones ``classify`` accepts without
``--accept-failed``, so what a user is given — with the reasons the others failed. Goals (issue 14): ECE
≤ 0.03, log-loss below the plug-in's, coverage 0.85–0.95 on every plate; they are
recorded beside the measured values (ratios), not asserted — only the scene's accuracy
range, the condition of the comparison, is. With ``FEELER_FULL=1`` more replicates and
fresh touches.
"""
import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy.special import logsumexp

from _ratios import FULL, record_ratio
from feeler.calib.neuron import fit_neuron
from feeler.calib.neuron.classify import classify, expected_calibration_error, log_loss
from feeler.calib.neuron.synth import HARD_SCENES, scene_scans
from feeler.errors import ArgumentError
from feeler.models import neuron

REPLICATES = 20 if FULL else 10
FRESH = 400 if FULL else 100
SCENES = sorted(Path(HARD_SCENES).glob("*.toml"))
CONTROLS = sorted((Path(HARD_SCENES).parent / "controls").glob("*.toml"))
ROWS = []


def plugin_log_prob(scene, train, test, tau_s: float) -> np.ndarray:
    """log P(plate | scan) of the plug-in Gaussian classifier on peak z at window ``tau_s``."""
    nrn = scene.neuron

    def peak_z(d):
        return np.maximum(nrn.a * neuron.peak_window_sum(d.strain, d.t_s, tau=tau_s, kernel=nrn.kernel) - nrn.h, 0)

    z, zn = peak_z(train), peak_z(test)
    plates = np.unique(train.step_mm)
    ll = np.stack([-0.5 * ((zn - z[train.step_mm == c].mean()) / z[train.step_mm == c].std()) ** 2
                   - np.log(z[train.step_mm == c].std()) for c in plates], axis=1)
    return ll - logsumexp(ll, axis=1, keepdims=True)


def ece_floor(prob: np.ndarray, rng: np.random.Generator, draws: int = 20) -> float:
    """Median ECE of labels drawn from ``prob (ndarray[n, C])`` itself: what a perfectly
    calibrated forecaster shows at this sample size."""
    cum = np.cumsum(prob, axis=1)
    return float(np.median([expected_calibration_error(prob, np.minimum((rng.random((prob.shape[0], 1)) > cum)
                                                                        .sum(axis=1), prob.shape[1] - 1))
                            for _ in range(draws)]))


def between_sets(stat, n_sets: int, rng: np.random.Generator, draws: int = 200) -> np.ndarray:
    """5 % and 95 % quantiles of ``stat(indices)`` over bootstrap resamples of the
    training sets (with replacement): how much a figure moves with the sets drawn, the
    sets being what varies most (each brings its own fit). ndarray[2, ...]."""
    return np.quantile([stat(rng.integers(0, n_sets, n_sets)) for _ in range(draws)], [0.05, 0.95], axis=0)


def jackknife_se(stat, n_sets: int) -> float:
    """Jackknife standard error of ``stat(indices)`` over the training sets left out one
    at a time. For the ECE, not the bootstrap: a resample repeats sets, and repeated
    predictions raise the ECE (it is biased upwards by noise), so its percentiles missed
    the estimate itself."""
    loo = np.array([stat(np.delete(np.arange(n_sets), k)) for k in range(n_sets)])
    return float(np.sqrt((n_sets - 1) / n_sets * np.sum((loo - loo.mean()) ** 2)))


def evaluate(path: Path, replicates: int = REPLICATES, fresh: int = FRESH) -> dict:
    """The row of one scene: ``replicates`` training sets, each classifying ``fresh``
    fresh touches a plate (see the module docstring)."""
    seed = load_seed(path)
    ours, base_true, base_fit, cover, truth, gammas, ok, failed = [], [], [], [], [], [], [], []
    refused = 0
    for r in range(1, replicates + 1):
        scene, _, train = scene_scans(path, seed=seed + r)
        _, _, test = scene_scans(path, seed=seed + 10 ** 6 + r, per_plate=fresh)
        plates = np.sort(np.asarray(scene.surface.heights_mm, float))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = fit_neuron(train, seed=r)
        failed += [p.split(":")[0] + ": " + p.split(":")[1].split("(")[0].strip()[:40] for p in res.verdict.problems]
        try:
            c = classify(res, test.strain, test.t_s, rng=np.random.default_rng(r))
        except ArgumentError:                   # a failed fit classify cannot read (e.g. > 5 % undecodable draws)
            if res.verdict.ok:
                raise                           # a fit said ok that cannot be read: a defect, not a measurement
            refused += 1
            continue
        ok.append(res.verdict.ok)
        ours.append(c.log_prob)
        truth.append(np.searchsorted(plates, test.step_mm))
        base_true.append(plugin_log_prob(scene, train, test, scene.neuron.tau_s))
        base_fit.append(plugin_log_prob(scene, train, test, float(np.median(c.tau_s))))
        gammas.append(float(res.posterior["posterior"].attrs["prob_sharpness"]))
        inside = (test.step_mm >= c.lo90_mm) & (test.step_mm <= c.hi90_mm)
        cover.append([inside[test.step_mm == v].mean() for v in plates])
    t = np.concatenate(truth)
    lo, lt, lf = np.concatenate(ours), np.concatenate(base_true), np.concatenate(base_fit)
    kept = np.concatenate([np.full(v.size, k) for v, k in zip(truth, ok)])
    said_ok = {"n_ok": int(sum(ok)), "n_refused": refused, "failed_because": sorted(set(failed)),
               "ece_ok": expected_calibration_error(np.exp(lo[kept]), t[kept]) if kept.any() else float("nan"),
               "log_loss_ok": log_loss(lo[kept], t[kept]) if kept.any() else float("nan"),
               "log_loss_plugin_ok": log_loss(lt[kept], t[kept]) if kept.any() else float("nan"),
               "coverage_ok": (np.mean([c for c, k in zip(cover, ok) if k], axis=0) if kept.any()
                               else np.full(len(cover[0]), np.nan))}
    rng = np.random.default_rng(seed)
    ece_se = jackknife_se(lambda i: expected_calibration_error(
        np.exp(np.concatenate([ours[k] for k in i])), np.concatenate([truth[k] for k in i])), len(ours))
    cov_lo, cov_hi = between_sets(lambda i: np.mean([cover[k] for k in i], axis=0), len(cover), rng)
    return said_ok | {"scene": path.stem, "accuracy": float(np.mean(lo.argmax(1) == t)),
            "confidence": float(np.mean(np.exp(lo).max(axis=1))),
            "ece": expected_calibration_error(np.exp(lo), t), "ece_se": ece_se,
            "coverage_lo90": cov_lo, "coverage_hi90": cov_hi,
            "ece_floor": ece_floor(np.exp(lo), np.random.default_rng(seed)),
            "ece_plugin": expected_calibration_error(np.exp(lt), t),
            "ece_plugin_fitted_tau": expected_calibration_error(np.exp(lf), t),
            "log_loss": log_loss(lo, t), "log_loss_plugin": log_loss(lt, t),
            "log_loss_plugin_fitted_tau": log_loss(lf, t),
            "accuracy_plugin": float(np.mean(lt.argmax(1) == t)),
            "accuracy_plugin_fitted_tau": float(np.mean(lf.argmax(1) == t)),
            "sharpness_median": float(np.median(gammas)), "n_predictions": int(t.size),
            "coverage": np.mean(cover, axis=0), "coverage_min": np.min(cover, axis=0), "plates": plates}


def load_seed(path) -> int:
    from feeler.scene import load_scene
    return int(load_scene(path).scene.seed)


@pytest.mark.parametrize("path", SCENES + CONTROLS, ids=[p.stem for p in SCENES + CONTROLS])
def test_calibrated_confidence(benchmark, path):
    row = benchmark.pedantic(lambda: evaluate(path), rounds=1, iterations=1)
    ROWS.append(row)
    benchmark.extra_info.update({k: (float(v) if np.ndim(v) == 0 and not isinstance(v, str) else
                                     (v if isinstance(v, str) or k == "failed_because" else [float(x) for x in v]))
                                 for k, v in row.items()})
    record_ratio(benchmark, f"{row['scene']}: log-loss feeler / plug-in (true tau)",
                 row["log_loss"] / row["log_loss_plugin"], "< 1")
    record_ratio(benchmark, f"{row['scene']}: log-loss feeler / plug-in (fitted tau)",
                 row["log_loss"] / row["log_loss_plugin_fitted_tau"], "< 1")
    record_ratio(benchmark, f"{row['scene']}: ECE feeler", row["ece"], "<= 0.03")
    print(f"\n{row['scene']:12s} n {row['n_predictions']}  acc {row['accuracy']:.3f} (plug-in {row['accuracy_plugin']:.3f}"
          f" / {row['accuracy_plugin_fitted_tau']:.3f})  ECE {row['ece']:.4f} (jackknife se over the "
          f"sets {row['ece_se']:.4f}; calibrated-forecaster floor "
          f"{row['ece_floor']:.4f}; plug-in {row['ece_plugin']:.4f} / {row['ece_plugin_fitted_tau']:.4f})  "
          f"log-loss {row['log_loss']:.4f} (plug-in {row['log_loss_plugin']:.4f} / "
          f"{row['log_loss_plugin_fitted_tau']:.4f}; true / fitted tau)  gamma {row['sharpness_median']:.3f}  "
          "90 % coverage per plate " + ", ".join(f"{p:g} mm {c:.2f} [{a:.2f}, {b:.2f}] (min {m:.2f})"
                                                 for p, c, a, b, m in zip(row["plates"], row["coverage"],
                                                                          row["coverage_lo90"], row["coverage_hi90"],
                                                                          row["coverage_min"])))
    print(f"  fits whose verdict is ok (what classify accepts): {row['n_ok']} of {REPLICATES}; ECE "
          f"{row['ece_ok']:.4f}, log-loss {row['log_loss_ok']:.4f} (plug-in, true tau {row['log_loss_plugin_ok']:.4f}), "
          "coverage " + " ".join(f"{c:.2f}" for c in row["coverage_ok"])
          + ("; the others failed for: " + "; ".join(row["failed_because"]) if row["failed_because"] else ""))
    assert 0.6 <= row["accuracy"] <= 0.95, "the scene is not in the 60-95 % accuracy range it was built for"
