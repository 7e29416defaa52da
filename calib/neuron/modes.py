"""Two ways over a riser: a touch snaps onto the upper level or rides over the edge.

On a fraction of touches the tip sticks at the riser and snaps up in one frame; on the
others it rides over as the face passes the edge (:mod:`feeler.models.probe`). The peak
window sum P of a snapping touch is higher: with the touches' true mode, P's sd within a
mode is about the same on every plate (hard/few-scans at τ = 4 s: 0.0037–0.0047) and the
snap − ride offset grows with the step (0.0071, 0.0102, 0.0102). A plate's touches are
then two modes mixed: their spread grows with the step and is flatter than Gaussian, and a
Gaussian band with the right mean and sd holds more than 90 % of them (0.935 on
few-scans' top plate). The ``two-mode`` noise models (:func:`.grid.two_mode_draws`)
describe each plate by a ride mean and a snap mean, an sd for each mode (constant, or
growing with the step; one for both when a mode has too few scans, or, draw by draw,
when the two modes' spreads do not differ: :func:`own_spread_weight`) and the share of
snapping touches; a scan is decoded by its own mode's curve, at its own mode's windows
(:func:`.fit.mode_decoders`).

The mode of a touch, training or new, is read from its scan: a snap takes most of the
rise in one frame, a ride spreads it over the frames the pad needs to pass the edge.
:func:`snap_flags` calls a touch a snap when its largest one-frame rise of U_y is more
than :data:`SNAP_SHARE` of its whole rise. On five hard scenes (60 touches a plate, each
touch's mode recorded by the simulator; 5–95 % ranges) the ratio is 0.67–1.69 for snaps
and 0.19–0.90 for rides on steps of 30 um and more (medians 0.99–1.09 and 0.23–0.62); on
10–20 um steps the read-out noise blurs both (rides up to 1.67). Read this way, the mode
agrees with the simulator's for 1.00 of four-plates' touches, 0.98 of few-scans' and
0.96 of near-floor's (tests/calib/test_neuron_two_mode.py). On a plate of step 0 there
is no riser: its touches count as rides.
"""
from __future__ import annotations

import numpy as np
from scipy.special import expit

from feeler.calib.neuron.conjugate import G_NODES, growth_log_density
from feeler.calib.neuron.model import Plates, PlatePrior

__all__ = ["SNAP_SHARE", "snap_flags", "Cells", "TWO_MODE", "within_noise", "OWN_SPREAD_DOF", "own_spread_weight",
           "spread_profile"]

#: the two-mode noise models and the noise of P within a (plate, mode) cell
TWO_MODE = {"two-mode": "constant", "two-mode-growing": "growing"}


def within_noise(noise: str) -> str | None:
    """The noise within a cell of a two-mode model (``constant`` or ``growing``); None for
    the one-mode models."""
    return TWO_MODE.get(noise)

#: degrees of freedom (scans − cells) each mode needs for a spread curve of its own
OWN_SPREAD_DOF = 3

#: a touch snaps when its largest one-frame rise exceeds this share of its whole rise
SNAP_SHARE = 2.0 / 3.0


def snap_flags(strain: np.ndarray, step_mm: np.ndarray) -> np.ndarray:
    """Snapping touches, ndarray[n_scans] bool, of ``strain (ndarray[n_scans, n_time])``
    labelled ``step_mm``: the largest one-frame rise over the whole rise (the medians of
    the last and first tenth of the scan) above :data:`SNAP_SHARE`; never on a plate of
    step ≤ 0 or a scan that does not rise."""
    s = np.atleast_2d(np.asarray(strain, float))
    if s.shape[1] < 3:                                          # no rise to tell apart
        return np.zeros(s.shape[0], bool)
    k = max(2, s.shape[1] // 10)
    total = np.median(s[:, -k:], axis=1) - np.median(s[:, :k], axis=1)
    jump = np.max(np.diff(s, axis=1), axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        snap = (total > 0) & (jump > SNAP_SHARE * total)
    return snap & (np.asarray(step_mm, float) > 0)


class Cells:
    """The (plate, mode) cells of a training set.

    Attributes:
        plates (Plates): the plates.
        snap (ndarray[n_scans] bool): each scan's mode.
        present (ndarray[2C] bool): which (plate, mode) cells hold scans, ride then snap
            per plate.
        index (ndarray[C, 2] int): the cell of (plate, ride) and (plate, snap), counting
            only cells that hold scans; a mode no scan of a plate shows takes the other
            mode's cell (its mean is the plate's only mean).
        as_plates (Plates): the cells as plates (one mean each, at their plate's step: a
            growing noise grows with the plate), for the pooled noise models.
        snaps, rides (int): touches of each mode on plates with a riser (step > 0).
        mode (ndarray[K] int): each cell's mode, 0 ride, 1 snap.
        own_spreads (bool): each mode has scans enough for a spread curve of its own
            (:meth:`of_mode`; at least :data:`OWN_SPREAD_DOF` scans more than cells).
    """

    def __init__(self, plates: Plates, snap: np.ndarray):
        self.plates = plates
        self.snap = np.asarray(snap, bool)
        raw = 2 * plates.group + self.snap                                     # (n,)
        present = np.bincount(raw, minlength=2 * plates.steps_mm.size) > 0
        self.present = present                                                 # (2C,) ride, snap per plate
        compact = np.cumsum(present) - 1
        idx = np.where(present, compact, -1).reshape(-1, 2)
        idx = np.where(idx < 0, idx[:, ::-1], idx)                             # empty mode: the other one's
        self.index = idx
        group = compact[raw]
        self.as_plates = Plates(steps_mm=np.repeat(plates.steps_mm, 2)[present], group=group,
                                counts=np.bincount(group, minlength=int(present.sum())))
        riser = plates.steps_mm[plates.group] > 0
        self.snaps = int(np.sum(self.snap & riser))
        self.rides = int(np.sum(~self.snap & riser))
        self.mode = (np.arange(present.size) % 2)[present]
        counts = self.as_plates.counts
        self.own_spreads = all(int(counts[self.mode == k].sum()) - int(np.sum(self.mode == k)) >= OWN_SPREAD_DOF
                               for k in (0, 1))

    def of_mode(self, k: int) -> tuple[np.ndarray, np.ndarray, Plates]:
        """The cells of mode ``k`` (0 ride, 1 snap) as plates of their own: (their indices
        among the cells ndarray[K_k] int, their scans ndarray[n_scans] bool, Plates). A
        spread growing with the step grows along these cells' own steps (the snaps' start
        at the lowest riser)."""
        keep = np.flatnonzero(self.mode == k)
        scans = self.snap == bool(k)
        remap = np.full(self.mode.size, -1)
        remap[keep] = np.arange(keep.size)
        group = remap[self.as_plates.group[scans]]
        return keep, scans, Plates(steps_mm=self.as_plates.steps_mm[keep], group=group,
                                   counts=np.bincount(group, minlength=keep.size))

    @property
    def size(self) -> int:
        return int(self.as_plates.steps_mm.size)


def spread_profile(ss: np.ndarray, counts: np.ndarray, x: np.ndarray, within: str, growth_max: float = 3.0) -> np.ndarray:
    """Profile log-likelihood of one spread curve for cells with within-cell sums of squares
    ``ss (ndarray[S, K])``, scan counts and positions ``x`` (ndarray[K]): σ_c = σ₀ (``constant``)
    or σ₀·exp(g·x_c) (``growing``, g on the prior's nodes in ±``growth_max``). Each cell's
    mean is integrated out under its flat prior (the restricted likelihood, Σ_c −r_c ln σ_c
    − SS_c / 2σ_c², r_c = n_c − 1), σ₀ and g at their maximum; up to a constant that
    depends on the scans only → ndarray[S]. With R = Σ r_c:
    max_g [−g Σ r_c x_c − (R/2) ln(Σ_c SS_c e^(−2 g x_c) / R)] − R/2."""
    r = np.maximum(np.asarray(counts, float) - 1.0, 0.0)
    R = float(r.sum())
    if R <= 0:
        return np.zeros(np.shape(ss)[0])
    g = np.linspace(-growth_max, growth_max, G_NODES) if within == "growing" else np.zeros(1)
    ll = growth_log_density(g, np.asarray(ss, float), r, np.asarray(x, float), PlatePrior())
    return ll.max(axis=1) + 0.5 * R * np.log(R) - 0.5 * R


def own_spread_weight(ss: np.ndarray, cells: Cells, within: str, growth_max: float = 3.0) -> np.ndarray:
    """Weight of "each mode has a spread curve of its own" against "one curve serves both",
    per row of the cells' within-cell sums of squares ``ss (ndarray[S, K])`` (each draw's,
    at its window) → ndarray[S] in [0, 1].

    The Schwarz (BIC) approximation to the posterior probability of the two, even prior
    odds (Kass & Raftery 1995, "Bayes factors", §4.1.3): with Λ = 2·(ℓ_ride + ℓ_snap −
    ℓ_both) the likelihood ratio of the profiles (:func:`spread_profile`), d the extra
    parameters (1: σ₀; 2 growing: σ₀ and g) and n the scans, w = 1 / (1 + exp(−(Λ − d·ln n)/2)).

    Why: a mode's curve fitted to the 8–14 rides of a random untuned scene
    (``benchmarks/test_bench_open_world.py``) can read spreads far apart (one training
    set of random-04: rides' sd 1.5, 3.5 and 9.8 um on its three plates), and the plates
    are then told apart by their spreads (its fresh rides read at accuracy 0.30 with
    confidence 0.53); over that scene's eight training sets the mean w at the
    windows the fit weights is 0.05-0.65. Where the modes do differ the data say so: on
    hard/close-steps, at the snaps' windows (about 0.5 s: snaps spread 0.001-0.004 mm, rides
    0.011-0.013), w is 0.95-1.00 in each of eight training sets, and 0.025-0.49 at the rides'
    longer windows. Not finite (a cell that never varies): 1, a curve each."""
    ss = np.asarray(ss, float)
    plates = cells.as_plates
    both = spread_profile(ss, plates.counts, plates.x, within, growth_max)
    own = np.zeros_like(both)
    for k in (0, 1):
        keep, _, sub = cells.of_mode(k)
        own = own + spread_profile(ss[:, keep], sub.counts, sub.x, within, growth_max)
    extra = 2 if within == "growing" else 1
    with np.errstate(invalid="ignore"):
        lam = 2.0 * (own - both)
        w = expit(0.5 * (lam - extra * np.log(max(int(plates.counts.sum()), 2))))
    return np.where(np.isfinite(w), w, 1.0)
