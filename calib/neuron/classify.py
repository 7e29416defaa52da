"""Classify new scans with an M2 posterior: plate probabilities and a decoded step height.

The decoder (:class:`~feeler.calib.neuron.decoder.DecoderDraws`) needs one statistic per
scan and posterior draw: the peak window sum P at the draw's window τ_s, read exactly as
the fit read its training scans — linearly interpolated in ln τ between the two nodes of
the fit's τ grid around τ_s (:func:`peaks_at`). Only the nodes some draw needs are
computed. :func:`classify` then averages the per-draw plate probabilities (in log
space) and inverts the predictive band for the decoded height and its 90 % interval.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from feeler.calib.neuron.decoder import DecoderDraws
from feeler.calib.neuron.modes import snap_flags

__all__ = ["Classification", "classify", "chance_mode_notes", "peaks_at", "peaks_of", "expected_calibration_error", "log_loss"]


@dataclass(frozen=True)
class Classification:
    """Result for ``n_scans`` new scans.

    Attributes:
        plates_mm (ndarray[n_plates]): step of each training plate, mm.
        log_prob (ndarray[n_scans, n_plates]): log P(plate | scan).
        height_mm, lo90_mm, hi90_mm (ndarray[n_scans]): decoded step height (the median of
            the predictive belt, always inside its interval) and its 90 % interval, mm.
        p_at_tau (ndarray[S, n_scans]): each scan's P at each draw's window; tau_s (ndarray[S]):
            those windows, s (for the training-envelope checks).
        note (str | None): why posterior draws were left out, if any (:attr:`DecoderDraws.note`).
        plate_sds, nearest_mm (ndarray[n_scans] | None): each scan's distance from the nearest
            training plate, in its sds, and that plate's step, mm (:meth:`DecoderDraws.plate_distance`).
        snap (ndarray[n_scans] bool | None): which scans snapped onto the upper level, as the
            decoder read them (:func:`scan_modes`), when the fit is a two-mode one.
    """
    plates_mm: np.ndarray
    log_prob: np.ndarray
    height_mm: np.ndarray
    lo90_mm: np.ndarray
    hi90_mm: np.ndarray
    p_at_tau: np.ndarray | None = None
    tau_s: np.ndarray | None = None
    note: str | None = None
    plate_sds: np.ndarray | None = None
    nearest_mm: np.ndarray | None = None
    snap: np.ndarray | None = None

    @property
    def prob(self) -> np.ndarray:
        return np.exp(self.log_prob)

    @property
    def plate_mm(self) -> np.ndarray:
        """Most probable plate's step per scan, mm."""
        return self.plates_mm[np.argmax(self.log_prob, axis=1)]


def peaks_at(strain, t_s, log_tau_grid: np.ndarray, tau_s: np.ndarray, *, kernel: str = "boxcar") -> np.ndarray:
    """P of each scan at each τ in ``tau_s (ndarray[S])``: ndarray[S, n_scans].

    Linear in ln τ between the grid nodes around each τ, exactly like
    :meth:`~feeler.calib.neuron.model.PeakTable.at` on the full table of the fit."""
    from feeler.calib.neuron.model import PeakTable
    from feeler.models import neuron

    lt = np.asarray(log_tau_grid, float)
    step = lt[1] - lt[0]
    pos = np.clip((np.log(np.asarray(tau_s, float)) - lt[0]) / step, 0.0, lt.size - 1.0)
    i = np.minimum(np.floor(pos).astype(int), lt.size - 2)
    need = np.unique(np.concatenate([i, i + 1]))
    strain = np.atleast_2d(np.asarray(strain, float))
    t = np.asarray(t_s, float)

    def peak(tau):
        if t.ndim == 1:
            return neuron.peak_window_sum(strain, t, tau=tau, kernel=kernel)
        return neuron.per_time_base(lambda s, tt: neuron.peak_window_sum(s, tt, tau=tau, kernel=kernel), strain, t)

    full = np.zeros((strain.shape[0], lt.size))
    for j in need:
        full[:, j] = peak(float(np.exp(lt[j])))
    return PeakTable(log_tau=lt, peak=full).at(tau_s)


def peaks_of(strain, t_s, log_tau_grid, tau_s, *, kernel: str = "boxcar") -> np.ndarray:
    """:func:`peaks_at` of scans that may differ in length: ``strain`` and ``t_s`` as for
    :func:`peaks_at`, or two lists of ndarray[n_time_i] → ndarray[S, n_scans]."""
    if not isinstance(strain, (list, tuple)):
        return peaks_at(strain, t_s, log_tau_grid, tau_s, kernel=kernel)
    out = np.zeros((np.asarray(tau_s).size, len(strain)))
    lengths = np.array([np.size(s) for s in strain])
    for n in np.unique(lengths):
        idx = np.flatnonzero(lengths == n)
        t = np.stack([np.asarray(t_s[i], float) for i in idx])
        t = t[0] if np.all(t == t[:1]) else t
        out[:, idx] = peaks_at(np.stack([np.asarray(strain[i], float) for i in idx]), t, log_tau_grid, tau_s,
                               kernel=kernel)
    return out


def scan_modes(strain) -> np.ndarray:
    """Which scans snapped onto the upper level (:func:`~feeler.calib.neuron.modes.snap_flags`,
    the plate unknown: on a plate of step 0 both modes read alike), ndarray[n_scans] bool;
    ``strain`` one array or a list of scans of different lengths."""
    if isinstance(strain, np.ndarray) and strain.ndim == 2:
        return snap_flags(strain, np.ones(strain.shape[0]))
    return np.array([bool(snap_flags(np.asarray(s, float)[None, :], np.ones(1))[0]) for s in strain], bool)


#: scans decoded at a time, bounding the (draws × scans × plates) temporaries: classify of
#: 20 160 scans peaked at 1.86 GB decoded at once, 0.59 GB in blocks
BLOCK = 2048


def classify(result, strain, t_s, *, rng: np.random.Generator, n_draws: int = 400,
             progress: bool | None = False) -> Classification:
    """Plate probabilities and decoded heights of scans ``strain (ndarray[n_scans, n_time])``.

    Args:
        result (FitResult): an M2 fit (its observed data hold the training plates and τ grid).
        t_s (ndarray[n_time] | ndarray[n_scans, n_time]): sample times, s (shared, or
            each scan's own). Scans of different lengths come as two lists of
            ndarray[n_time_i] (``strain`` and ``t_s``).
        n_draws (int): posterior draws used (a seeded subsample).
        progress: over more than one block of scans, a bar (terminal) or a line per block
            (None: a bar on a terminal, lines otherwise; False: silent).
    """
    dec = DecoderDraws.from_result(result, rng=rng, n_draws=n_draws)
    grid = np.asarray(result.posterior["observed_data"]["log_tau_grid"].values, float)
    kernel = str(result.posterior["posterior"].attrs.get("kernel", "boxcar"))
    p = peaks_of(strain, t_s, grid, dec.tau_s, kernel=kernel)
    snap = scan_modes(strain) if dec.snap_mm is not None else None
    from feeler.calib.progress import progress as shown

    parts = []
    starts = range(0, max(p.shape[1], 1), BLOCK)
    for i in shown(starts, desc=f"decoding {p.shape[1]} scans", enabled=progress if len(starts) > 1 else False,
                   lines=True):                    # the (draws × scans × plates) temporaries, a block at a time
        block = p[:, i:i + BLOCK]
        mode = None if snap is None else snap[i:i + BLOCK]
        parts.append((*dec.height(block, mode), *dec.plate_distance(block), dec.class_log_prob(block, mode)))
    height, lo, hi, distance, nearest, log_prob = (np.concatenate(v) for v in zip(*parts))
    return Classification(plates_mm=dec.steps_mm, log_prob=log_prob, height_mm=height,
                          lo90_mm=lo, hi90_mm=hi, p_at_tau=p, tau_s=dec.tau_s, note=dec.note,
                          plate_sds=distance, nearest_mm=dec.steps_mm[nearest], snap=snap)


def chance_mode_notes(attrs, snap) -> list[str]:
    """A line for each mode whose training scans a fit reads no better than their plates'
    shares (its leave-one-out reading per mode, the posterior's ``attrs["mode_decoders"]``)
    when some new scans are of it (``snap``: each scan's mode as read, ndarray[n_scans]
    bool; None: read without modes); classify and decode say them."""
    import json

    if snap is None:
        return []
    by_mode = json.loads(attrs.get("mode_decoders", "{}"))
    lines = []
    for name, snapped in (("ride", False), ("snap", True)):
        loo = by_mode.get(name, {}).get("loo")
        n = int(np.sum(np.asarray(snap) == snapped))
        if loo and not loo["informative"] and n:
            lines.append(f"{n} of {len(snap)} scans are {name}s, which this fit reads no better than its training "
                         f"{name}s' plate shares when each is left out (log score per scan {loo['log_score']:+.3f} "
                         f"against {loo['base_log_score']:+.3f}): their plate probabilities say little")
    return lines


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


def log_loss(log_prob, true_index) -> float:
    """Mean −log P(true plate) over scans (nats); ``log_prob (ndarray[n, n_classes])``."""
    lp = np.asarray(log_prob, float)
    return float(-np.mean(lp[np.arange(lp.shape[0]), np.asarray(true_index)]))
