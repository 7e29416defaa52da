"""Decode a scan sample by sample, as it is acquired: :class:`LiveDecoder`.

Everything the M2 decoder needs of a scan is its peak window sum P at each posterior
draw's window τ_s, read as the fit read its training scans: linear in ln τ between the
two nodes of the fit's τ grid around τ_s (:func:`~feeler.calib.neuron.classify.peaks_at`).
The live decoder streams u₁ at just those nodes (:class:`.sums.WindowSums`, O(window)
state and work per sample, none growing with the record) and keeps their running
maxima; P so far is the same interpolation of the maxima, so at the end of a scan the
plate probabilities and the decoded height are those of
:func:`~feeler.calib.neuron.classify.classify` with the same seed and draws (to float
rounding). Probabilities and height change only when a running maximum grows; between,
the last answer is returned unchanged.

Decision rule (stated, and the benchmark measures its latency against its accuracy): a
scan is decided at the first sample where

1. the response has peaked: the current u₁ at the draws' windows has fallen below
   ``1 − drop`` of its running maximum (median over draws), with that maximum above the
   training scans' smallest peak times ``drop`` (a response, not noise),
2. the most probable plate's probability is ≥ ``threshold``, and
3. that plate is not the lowest training plate: a response the lowest plate explains may
   be the lead-in before the step (a flat stretch, a noise bump), so the lowest plate is
   decided only when the scan ends (:meth:`LiveDecoder.finish`), if its probability is
   then ≥ ``threshold``;
4. the scan so far lies inside the fit's training envelope (no flags): a scan at another
   speed, period, length, response scale or read-out noise, with a one-sample spike, or
   whose reading lies far from every training plate (a step the fit was not trained on),
   is not decided while it is flagged (the read-out noise and spike checks read the
   whole scan so far at that sample); a flag that only the rest of the scan raises (its
   noise over all its samples, a later glitch, or a spike of 15-20 read-out noise sds,
   which is judged at 20 while the scan streams and at 15 once it ends: see
   :data:`.envelope.SPIKE_SDS_STREAM`) comes after the decision, and ``decode`` counts
   such scans;
5. before the spike check can judge (20 samples), no sample stands off both neighbours
   by half the scan's rise without it (:func:`.envelope.early_spike`): it may be a glitch
   that alone sets the peak.

A batch's read-out noise is judged over its scans (:meth:`.envelope.Envelope.batch_noise`),
not by one scan: :class:`~.run.RunDecoder` sets :attr:`LiveDecoder.batch` once the scans
so far show a set-up noisier or far quieter than training, and every scan is then flagged
with that reason from its first sample (:func:`.envelope.with_batch`), so not decided.

A scan that ends below the threshold stays undecided (its final probabilities are still
given).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from feeler.calib.neuron.classify import scan_modes
from feeler.calib.neuron.live.envelope import (SPIKE_SDS, SPIKE_SDS_STREAM, early_spike, median_of, readout_noise_mm,
                                                spike_problem)
from feeler.errors import ArgumentError

__all__ = ["Decision", "LiveState", "LiveDecoder"]


@dataclass(frozen=True)
class Decision:
    """The decision of a scan: plate ``plate_mm`` (mm) with probability ``p``, taken at
    sample ``index`` (0-based), time ``t_s`` (s) and stage position ``x_mm`` (mm, NaN
    when not given)."""
    plate_mm: float
    p: float
    index: int
    t_s: float
    x_mm: float


@dataclass(frozen=True)
class LiveState:
    """The answer after one sample.

    Attributes:
        n (int): samples so far. t_s (float): the last one's time, s.
        prob (ndarray[C]): P(plate | data so far), plates as :attr:`LiveDecoder.plates_mm`.
        height_mm, lo90_mm, hi90_mm (float, properties): decoded step and its 90 % interval
            given the data so far, mm — computed on first access (the bisection costs
            ~40× the probabilities; a display at a few Hz or a decision reads it) and shared
            by every state of the same P.
        z_mm (float): the decoded response so far, a·P − h (median over draws), mm.
        peaked (bool): the response has passed its peak (rule 1).
        decision (Decision | None): the scan's decision once made (then on every later state).
        new_decision (bool): the decision was made at this sample.
        flags (tuple[str, ...]): reasons the scan lies outside the fit's training envelope.
    """
    n: int
    t_s: float
    prob: np.ndarray
    interval: "_Height"
    z_mm: float
    peaked: bool
    decision: Decision | None
    new_decision: bool
    flags: tuple

    @property
    def height_mm(self) -> float:
        return self.interval.get()[0]

    @property
    def lo90_mm(self) -> float:
        return self.interval.get()[1]

    @property
    def hi90_mm(self) -> float:
        return self.interval.get()[2]


class _Height:
    """The decoded height of one P (ndarray[S]), computed once, when first asked."""

    def __init__(self, dec, p_at_tau, mode=None):
        self.dec, self.p, self.mode, self.value = dec, p_at_tau, mode, None

    def get(self) -> tuple[float, float, float]:
        if self.value is None:
            self.value = tuple(float(v[0]) for v in self.dec.height(self.p[:, None], self.mode))
        return self.value


class LiveDecoder:
    """Streaming M2 decoder of one scan at a time.

    Args:
        fit (FitResult): an M2 fit (``feeler calibrate neuron``).
        seed (int): seeds the draw subsample exactly as ``classify`` with ``--seed``.
        n_draws (int): posterior draws used, > 0.
        threshold (float): decision probability, in (0, 1].
        drop (float): fraction the response must fall from its peak, in (0, 1).
        slack, scale_factor (float): the training envelope's tolerances (:class:`.envelope.Envelope`).
        camera (FramePipeline | None): the sensor's frame → displacement chain
            (:class:`feeler.hardware.camera.FramePipeline`, e.g. ``FramePipeline.of_plan(plan)``),
            needed by :meth:`push_frame` and :meth:`push_areas`.

    Samples come as U_y or a displacement vector (:meth:`push`), as the scanning element's
    contact areas (:meth:`push_areas`) or as camera frames (:meth:`push_frame`); areas and
    frames are read exactly as ``feeler acquire`` reads them, so a frame decoded here
    decodes as the displacement ``samples.csv`` records for it.
    """

    def __init__(self, fit, *, seed: int = 0, n_draws: int = 400, threshold: float = 0.9, drop: float = 0.5,
                 slack: float = 1.25, scale_factor: float = 2.0, camera=None):
        from feeler.calib.neuron.decoder import DecoderDraws
        from feeler.calib.neuron.live.envelope import Envelope
        from feeler.calib.neuron.live.sums import WindowSums

        if not (0.0 < threshold <= 1.0):
            raise ArgumentError("--threshold", threshold, "a probability in (0, 1]")
        if not (0.0 < drop < 1.0):
            raise ArgumentError("drop", drop, "a fraction in (0, 1)")
        if not (isinstance(n_draws, int) and n_draws > 0):
            raise ArgumentError("n_draws", n_draws, "an integer > 0")
        post = fit.posterior
        self.fit = fit
        self.dec = DecoderDraws.from_result(fit, rng=np.random.default_rng(seed), n_draws=n_draws)
        top = 1.0 - self.dec.floor * (self.dec.steps_mm.size - 1) / self.dec.steps_mm.size
        if threshold > top:       # the floor ε/C of every plate caps the top probability
            raise ArgumentError("--threshold", threshold, f"a probability in (0, {top:.6g}]: this fit's plate "
                                f"probabilities never exceed it (floor {self.dec.floor:g} over the plates)")
        attrs = post["posterior"].attrs
        self.length_mm = float(attrs["length_mm"])
        lt = np.asarray(post["observed_data"]["log_tau_grid"].values, float)
        step = lt[1] - lt[0]
        pos = np.clip((np.log(self.dec.tau_s) - lt[0]) / step, 0.0, lt.size - 1.0)
        i = np.minimum(np.floor(pos).astype(int), lt.size - 2)
        self._w = pos - i                                   # as PeakTable.at
        nodes = np.unique(np.concatenate([i, i + 1]))
        self._i0, self._i1 = np.searchsorted(nodes, i), np.searchsorted(nodes, i + 1)
        self.sums = WindowSums(np.exp(lt[nodes]), kernel=str(attrs.get("kernel", "boxcar")))
        self.env = Envelope.of_fit(fit, self.dec.tau_s, slack=slack, scale_factor=scale_factor)
        self.threshold, self.drop = float(threshold), float(drop)
        self._floor = float(np.median(self.env.p_lo)) * self.drop
        self.camera = camera
        #: the batch's read-out noise reason (Envelope.batch_noise of the scans so far), set by
        #: the caller that sees the batch (RunDecoder); every scan is flagged with it while set
        self.batch: str | None = None
        #: after finish(): the scan's own flags (without the batch's), the one about its noise
        #: alone (or None), and its read-out noise (mm), for RunDecoder's batch judgement
        self.own_flags: tuple[str, ...] = ()
        self.own_noise: str | None = None
        self.noise_mm = float("nan")
        self.reset()

    @property
    def plates_mm(self) -> np.ndarray:
        """The fit's plates (steps, mm), the order of :attr:`LiveState.prob`."""
        return self.dec.steps_mm

    @property
    def off_plate(self) -> bool:
        """Whether the scan so far reads more than the envelope's ``plate_sds`` from every
        trained plate (:meth:`~feeler.calib.neuron.decoder.DecoderDraws.plate_distance`; the
        flag a scan of a step the fit was not trained on gets once its response has peaked)."""
        return bool(self._answer[3][0] > self.env.plate_sds)

    @property
    def snapped(self) -> bool | None:
        """Whether the scan is read as one that snapped onto the upper level (after
        :meth:`finish`: the mode ``classify`` reads); None when the fit is not two-mode."""
        mode = self._answer[4]
        return None if mode is None else bool(mode[0])

    def at_draws(self, values_at_nodes: np.ndarray) -> np.ndarray:
        """Values at the τ nodes → at each draw's τ (ndarray[S]), as :meth:`PeakTable.at`."""
        return values_at_nodes[self._i0] * (1.0 - self._w) + values_at_nodes[self._i1] * self._w

    def reset(self, *, speed_mm_s: float | None = None) -> None:
        """Start a new scan (``speed_mm_s``: its commanded speed label, mm/s, if known)."""
        self.sums.reset()
        self.speed_label = speed_mm_s
        self._t0 = self._x0 = None
        self._x1 = np.nan
        self._uy: list[float] = []                   # the scan's U_y and times, for its read-out noise
        self._ts: list[float] = []                   # and a one-sample spike
        self._quality, self._recheck_at = (None, None, None), 0
        self._state = None
        self._decision = None
        self._answer = self._answer_of(np.zeros(self.dec.size), self._mode())     # a two-mode fit: a mode from the start

    def _mode(self) -> np.ndarray | None:
        """The scan's mode so far (``two-mode`` fits: did it snap onto the upper level,
        :func:`~feeler.calib.neuron.classify.scan_modes`, read on the samples so far; at
        the end of the scan the mode ``classify`` reads), ndarray[1] bool; None otherwise."""
        if self.dec.snap_mm is None:
            return None
        if len(self._uy) < 3:
            return np.zeros(1, bool)
        return scan_modes(np.asarray(self._uy, float)[None, :])

    def _answer_of(self, p: np.ndarray, mode: np.ndarray | None = None):
        col = p[:, None]
        prob = np.exp(self.dec.class_log_prob(col, mode)[0])
        distance, nearest = self.dec.plate_distance(col)
        return (prob, _Height(self.dec, p, mode), median_of(self.dec.decoded(col)), (float(distance[0]), int(nearest[0])),
                mode)

    @property
    def uy_mm(self) -> np.ndarray:
        """The scan's U_y so far (mm)."""
        return np.asarray(self._uy, float)

    @property
    def p_at_tau(self) -> np.ndarray:
        """P so far at each draw's window (ndarray[S])."""
        return self.at_draws(self.sums.peak)

    def push(self, t_s: float, uy_mm, *, x_mm: float | None = None) -> LiveState:
        """Add one sample: time (s, after the previous), U_y (mm) or a displacement vector
        (U_x, U_y, U_z) in mm, and optionally the stage position (mm).

        Raises:
            ArgumentError: non-finite values, time not increasing, a vector not of 3.
        """
        u = np.asarray(uy_mm, float)
        if u.ndim:
            if u.shape != (3,):
                raise ArgumentError("displacement", uy_mm, "U_y (mm) or a vector (U_x, U_y, U_z) in mm")
            u = u[1]
        grew = self.sums.push(t_s, float(u) / self.length_mm)
        self._uy.append(float(u))
        t = float(t_s)
        self._ts.append(t)
        if self._t0 is None:
            self._t0, self._x0 = t, (np.nan if x_mm is None else float(x_mm))
        self._x1 = np.nan if x_mm is None else float(x_mm)
        if grew:
            self._answer = self._answer_of(self.p_at_tau, self._mode())
        prob, height, z, _, _ = self._answer
        now = median_of(self.at_draws(self.sums.u))
        peak = median_of(self.p_at_tau)
        peaked = bool(peak > self._floor and now < (1.0 - self.drop) * peak)
        new = False
        flags = tuple(self._flags(t, final=False, peaked=peaked))
        k = int(np.argmax(prob))
        if (self._decision is None and peaked and k > 0 and prob[k] >= self.threshold and not flags
                and not early_spike(self._uy)):
            # the noise and spike checks are refreshed only as the scan grows by an eighth: a decision reads
            # them on the scan so far (a 28 um glitch 10 samples back, judged at the 20th sample, was decided)
            flags = tuple(self._flags(t, final=False, peaked=peaked, fresh=True))
            if not flags:
                self._decision = Decision(float(self.plates_mm[k]), float(prob[k]), self.sums.n - 1, t, self._x1)
                new = True
        self._state = LiveState(self.sums.n, t, prob, height, z, peaked, self._decision, new, flags)
        return self._state

    def push_areas(self, t_s: float, areas_px2, *, x_mm: float | None = None) -> LiveState:
        """Add one sample from contact areas (px²): the scanning element's four, or every
        element's (n_elements, 4); force and displacement as :attr:`camera` reads them.

        Raises:
            ArgumentError: no camera, areas of another shape or not finite; as :meth:`push`.
        """
        return self.push(t_s, self._camera().reading(areas_px2).u_mm, x_mm=x_mm)

    def push_frame(self, t_s: float, frame, *, x_mm: float | None = None) -> LiveState:
        """Add one sample from a camera frame (grey uint8, the layout's size): areas of
        every element → the scanning element's force → displacement → :meth:`push`.

        Raises (the decoder's state unchanged):
            ArgumentError: no camera, a frame of another type, dtype or shape; as :meth:`push`.
            FrameRejected: a frame whose discs cannot be measured (the reason in one line).
        """
        return self.push(t_s, self._camera().read(frame).u_mm, x_mm=x_mm)

    def _camera(self):
        if self.camera is None:
            raise ArgumentError("camera", None, "a FramePipeline (LiveDecoder(fit, camera=...)) to decode "
                                "areas or frames")
        return self.camera

    def _flags(self, t: float, *, final: bool, peaked: bool = False, fresh: bool = False) -> list[str]:
        """The scan's flags so far, judged with :attr:`batch` (:func:`.envelope.with_batch`);
        at the end (``final``) its own flags and noise are kept for the batch's judgement."""
        from feeler.calib.neuron.live.envelope import with_batch

        moved = np.isfinite(self._x0) and np.isfinite(self._x1) and self._x1 != self._x0
        ends = (self._x0, self._x1) if (moved or final) and np.isfinite(self._x0) else None
        noise, spike, fall = (self._quality_of(final or fresh, whole=final) if (peaked or final)
                              else (None, None, None))                               # as classify
        out = self.env.problems_of(self.sums.n, self._t0, t, self.p_at_tau, x_ends_mm=ends,
                                   speed_mm_s=self.speed_label, final=final, noise_mm=noise)
        if peaked or final:                     # the reading is the scan's once its response has peaked
            if spike:
                out.append(spike)
            _, height, _, (distance, k), _ = self._answer
            if distance > self.env.plate_sds:   # the height (a bisection) only for the message
                out.append(self.env.plates(distance, float(self.plates_mm[k]), height.get()[0]))
            if fall:
                out.append(fall)
        own_noise = None if noise is None else self.env.noise(noise)
        if final:
            self.own_flags, self.own_noise = tuple(out), own_noise
            self.noise_mm = float("nan") if noise is None else float(noise)
        return with_batch(out, own_noise, self.batch)

    def _quality_of(self, refresh: bool, *, whole: bool = False):
        """(read-out noise, spike line, falling line) of the scan so far. They read the whole
        scan, so they are computed again only when it has grown by an eighth (and when
        ``refresh``: at its end, and before a decision): every push after the peak of a
        2000-sample scan cost 0.2 ms more when they were computed each time. A spike is judged
        as a stream's until the scan is ``whole`` (:data:`.envelope.SPIKE_SDS_STREAM`), then
        as classify judges it."""
        n = len(self._uy)
        if refresh or n >= self._recheck_at:
            uy = np.asarray(self._uy, float)
            self._quality = (readout_noise_mm(uy),
                             spike_problem(uy, self._ts, sds=SPIKE_SDS if whole else SPIKE_SDS_STREAM),
                             self.env.falling(uy, self.plates_mm, lambda: self._answer[1].get()[0]))
            self._recheck_at = max(n + 1, n + n // 8)
        return self._quality

    def finish(self) -> LiveState:
        """The scan's final state: the envelope checks only the whole scan allows, and the
        decision at the last sample if none was made, the scan is not flagged and the top
        plate's probability is ≥ ``threshold`` (``new_decision`` then True)."""
        if self._state is None:
            raise ArgumentError("scan", "no samples", "at least one sample before finish()")
        s = self._state
        mode = self._mode()
        if mode is not None and bool(mode[0]) != bool(self._answer[4][0]):     # the whole scan's mode, as classify
            self._answer = self._answer_of(self.p_at_tau, mode)
            s = LiveState(s.n, s.t_s, self._answer[0], self._answer[1], s.z_mm, s.peaked, s.decision, s.new_decision,
                          s.flags)
        flags = tuple(self._flags(s.t_s, final=True))
        new = False
        k = int(np.argmax(s.prob))
        if self._decision is None and s.prob[k] >= self.threshold and not flags and not early_spike(self._uy):
            self._decision = Decision(float(self.plates_mm[k]), float(s.prob[k]), s.n - 1, s.t_s, self._x1)
            new = True
        return LiveState(s.n, s.t_s, s.prob, s.interval, s.z_mm, s.peaked, self._decision, new, flags)
