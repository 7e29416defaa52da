"""What an M2 fit was trained on, and whether a new scan lies outside it (out of distribution).

A decoder answers for scans like its training scans. A scan at another stage speed, with
another sampling period, much shorter or longer, or whose response is on another scale is
decoded all the same — with numbers that mean nothing (a 2 mm/s scan on a 0.5 mm/s fit
puts no label inside its 90 % interval). So each scan is checked against the fit's
training envelope and flagged with the reason:

- sampling period: the training scans' median sample interval (the first node of the
  fit's τ grid, which starts at one sample interval);
- duration: the shortest training scan's (twice the last node of the τ grid);
- stage speed: the scene the fit recorded (``scene_toml``: a robot-scan scene's
  ``motion.speed_mm_s`` or a scan plan's ``scan.speed_mm_s``), else its training scans'
  speed labels (a fit of a bare scan CSV); not checked for a fit with neither. The
  scan's speed is measured from ``x_mm`` and ``t_s`` when given, else its ``speed_mm_s``
  label;
- response scale: the scan's peak window sum P at each draw's window against the
  training scans' range at that window (the fit's peak table), as the median ratio
  over draws;
- read-out noise: the white noise of the scan's U_y (:func:`readout_noise_mm`, robust to
  the step and to drift) against the noisiest training scan's. The decoder's plates hold
  the noise of the training set-up: scans of four-plates with 1.5× its read-out noise
  put 50 % of labels inside their 90 % intervals (one scan of 96 flagged by the other
  checks), with 4× 28 % and half the plates wrong. One scan's estimate scatters by about
  ±50 % over 41 samples, so :meth:`Envelope.batch_noise` compares a batch's median with
  the training scans' and :func:`with_batch` flags every scan of a batch that is noisier
  (or far quieter) with that reason, in place of its own noise reason (``classify``; ``decode``
  and ``acquire --decode`` as soon as the batch's scans tell). Less noise than in training
  is not flagged scan by scan: intervals then over-cover (0.5×: 95 % inside);
- the plates: the decoded reading against every training plate's predictive, in that
  plate's sds (:meth:`~feeler.calib.neuron.decoder.DecoderDraws.plate_distance`); more
  than ``plate_sds`` (default 5) from the nearest is a step the fit was not trained on
  (its plate probabilities assume a trained plate: a 0.3 mm scan on plates 0-0.2 mm got
  P(0.2 mm) = 0.999). Known once the response has peaked, or at the scan's end;
- the direction: a scan read as a riser whose U_y falls, as a touch onto a step never
  does (reversed in time, or its sign flipped: :meth:`Envelope.falling`); on 4120 fresh
  scans of the shipped, hard and random scenes it fired on none.

Period, speed and duration may differ by the factor ``slack`` (default 1.25) from
training; the response by ``scale_factor`` (default 2) beyond the training range. A ratio
beyond ×30 (:data:`UNIT_FACTOR`) names the likely unit mistake (µm for mm, ms for s).
"""
from __future__ import annotations

import tomllib
from dataclasses import dataclass

import numpy as np

from feeler.errors import ArgumentError

__all__ = ["Envelope", "UNIT_FACTOR", "stage_units", "training_speed_mm_s", "median_of", "readout_noise_mm",
           "spike_of", "spike_problem", "SPIKE_SDS", "SPIKE_SDS_STREAM", "with_batch"]


def median_of(x: np.ndarray) -> float:
    """The median of a 1-D array, equal to ``np.median`` (without its ~40 µs of checks,
    which the live decoder would pay several times per sample); NaN if any is NaN."""
    x = np.asarray(x, float).ravel()
    n = x.size
    k = n // 2
    part = np.partition(x, (k - 1, k) if n % 2 == 0 else k)
    if np.isnan(part[-1]):                 # partition sorts NaN last
        return float("nan")
    return float(part[k] if n % 2 else 0.5 * (part[k - 1] + part[k]))


def readout_noise_mm(uy_mm) -> float:
    """The sd of the white noise on a scan's U_y (mm): the median absolute deviation of its
    second differences (each ~ N(0, 6σ²) for white noise; the step, a snap and drift touch
    only a few of them) × 1.4826 / √6. NaN with fewer than 5 samples."""
    u = np.asarray(uy_mm, float).ravel()
    if u.size < 5:
        return float("nan")
    return _noise_of(u[2:] - 2.0 * u[1:-1] + u[:-2])


def _noise_of(d2: np.ndarray) -> float:
    """White-noise sd from second differences: their MAD × 1.4826 / √6."""
    return float(1.4826 * median_of(np.abs(d2 - median_of(d2))) / np.sqrt(6.0))


#: a single sample this many read-out noise sds off both its neighbours (which agree) is a
#: glitch, not a touch, in a whole scan (classify, a fit's training scans, a stream at its
#: end). On clean scans it reaches 6.9 over 6750 whole scans of the eleven shipped scenes,
#: and 12.4 over 58 750 fresh ones of 53 scenes (the hard ones, a control, four-plates and
#: two families of random scenes no check was tuned on): 18 beyond 8, 6 beyond 10, 1 beyond
#: 12, none beyond 15; the tail is the 21-sample scans', whose noise rests on 16 second
#: differences. At 20, one-sample spikes of 15 um on flat scans of 1 um noise (8.4-25.9
#: sds by this measure) were caught in 2 of 8 and read as 0.05 mm at p 0.999 (an outside
#: audit); at 15, in 5 of 8 (and 20 um ones in 7 of 8, was 5)
SPIKE_SDS = 15.0
#: the same for a stream's prefixes (the live decoder's view before the scan ends), judged
#: at every sample from the 20th on, so their largest lies further out: 60 750 prefixes of
#: the shipped scenes reach 12.6, and the prefixes of 9200 fresh scans of 40 of the scenes
#: above 13.5. A spike of 15-20 sds is then flagged only when the scan ends, after any
#: decision, which ``decode`` reports as not holding
SPIKE_SDS_STREAM = 20.0
#: second differences away from the spike that its noise is measured on (a stream's first
#: samples are not judged: with 3, prefixes of shipped scans reached 2700 sds by chance)
SPIKE_MIN_DIFFERENCES = 15


def spike_of(uy_mm, *, sds: float = SPIKE_SDS) -> tuple[int, float, float] | None:
    """The largest single-sample spike of a scan's U_y: (sample index, its size in mm, in
    read-out noise sds) when beyond ``sds`` (:data:`SPIKE_SDS` for a whole scan,
    :data:`SPIKE_SDS_STREAM` for a stream so far), else None. A spike jumps away from both
    neighbours in the same direction while they agree (within a quarter of it): a snap
    steps up and stays, a ride ramps."""
    u = np.asarray(uy_mm, float).ravel()
    if u.size < SPIKE_MIN_DIFFERENCES + 5:
        return None
    a, size = _excursions(u)
    k = int(np.argmax(size))                     # the candidate: sample k + 1
    # the noise from the second differences that do not touch it (the spike inflates the
    # three around it: with 15 samples, enough to hide a 24-sd spike as 19)
    d2 = u[2:] - 2.0 * u[1:-1] + u[:-2]
    rest = np.delete(d2, [j for j in (k - 1, k, k + 1) if 0 <= j < d2.size])
    if rest.size < SPIKE_MIN_DIFFERENCES:        # too few to know the noise (3 can agree by chance)
        return None
    noise = _noise_of(rest)
    if not noise > 0 or size[k] <= sds * noise:
        return None
    return k + 1, float(size[k] * np.sign(a[k])), float(size[k] / noise)


def _excursions(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(jump from the previous sample, size of the one-sample excursion) of samples 1 … n−2
    of ``u``: the smaller jump to either neighbour when both go the same way and the
    neighbours agree within a quarter of it, else 0."""
    a, b = u[1:-1] - u[:-2], u[1:-1] - u[2:]
    size = np.where(np.sign(a) == np.sign(b), np.minimum(np.abs(a), np.abs(b)), 0.0)
    return a, np.where(np.abs(u[2:] - u[:-2]) < 0.25 * size, size, 0.0)


#: a scan's fall over it must be this many of its read-out noise sds to be called one (a
#: noisy flat plate drifting down can fall by more than half its range and read as a riser)
FALL_NOISE_SDS = 8.0


#: before :func:`spike_of` can judge a stream, a sample standing off both neighbours by at
#: least this share of the rise of the scan so far without it may be what sets the peak
EARLY_SPIKE_SHARE = 0.5


def early_spike(uy_mm) -> bool:
    """Whether the first samples of a stream (too few for :func:`spike_of` to know the
    noise) hold a sample that may be a glitch: a one-sample excursion of at least
    :data:`EARLY_SPIKE_SHARE` of U_y's range over the other samples. A touch does not make
    one (a snap steps up and stays, a ride ramps), so the live decoder waits: a 30 um
    glitch before the 20th sample of a four-plates scan was decided as a 0.05 mm plate at
    p = 0.999, whatever the scan's plate. False once the stream is long enough to judge."""
    u = np.asarray(uy_mm, float).ravel()
    if u.size < 3 or u.size >= SPIKE_MIN_DIFFERENCES + 5:
        return False
    _, size = _excursions(u)
    k = int(np.argmax(size))
    if not size[k] > 0:
        return False
    others = np.delete(u, k + 1)
    return bool(size[k] >= EARLY_SPIKE_SHARE * (others.max() - others.min()))


def spike_problem(uy_mm, t_s=None, *, sds: float = SPIKE_SDS) -> str | None:
    """One line for a scan's spike (:func:`spike_of` beyond ``sds``), or None."""
    found = spike_of(uy_mm, sds=sds)
    if found is None:
        return None
    k, size, sds = found
    when = f"t = {float(np.asarray(t_s, float).ravel()[k]):.4g} s" if t_s is not None else f"sample {k + 1}"
    return (f"U_y jumps {size * 1e3:+.4g} um at {when} and back at the next sample ({sds:.0f} read-out noise sds): "
            f"a glitch of the read-out, which alone can set the scan's peak window sum; repair or drop that sample")


#: a batch is noisier than training when the ratio of medians is beyond this and beyond 3
#: standard errors (the training scans' own scatter of log noise, over both counts)
BATCH_NOISE_FACTOR = 1.2
BATCH_MIN_SCANS = 5
# a batch this many times quieter than training: another set-up, or U_y in a larger unit (cm: 10x)
BATCH_QUIET_FACTOR = 3.0

UNIT_FACTOR = 30.0     # a scale further off than this is a unit mistake, not physics (M2's verdict uses it too)


def with_batch(flags, own_noise: str | None, batch: str | None) -> list[str]:
    """A scan's flags judged with its batch, as ``classify``, ``decode`` and ``acquire
    --decode`` judge them: ``flags`` are the scan's own reasons (:meth:`Envelope.problems`
    and the others), ``own_noise`` the one of them about its read-out noise alone
    (:meth:`Envelope.noise`, or None), ``batch`` the batch's reason
    (:meth:`Envelope.batch_noise`, or None). A batch reason replaces the scan's own noise
    reason (the batch's median says more than one scan's estimate, which scatters by ±50 %)
    and comes last; without one, the flags are the scan's own."""
    if not batch:
        return list(flags)
    return [f for f in flags if f != own_noise] + [batch]


def stage_units(ratio: float) -> str:
    """The likely unit mistake when x and t give ``ratio`` times the commanded stage speed
    (further off than :data:`UNIT_FACTOR`), whichever is nearer on a log scale: below,
    the speed label in mm/min (÷60: Grbl's feed rate F is in mm/min) or times in ms
    (÷1000); above, times in minutes (×60) or x in µm (×1000)."""
    if ratio < 1:
        if ratio > 1 / np.sqrt(60 * 1000):
            return "speed_mm_s probably in mm/min, the unit of Grbl's feed rate F (expected mm/s)"
        return "times probably in ms (expected s)"
    return "times probably in min (expected s)" if ratio < np.sqrt(60 * 1000) else "x probably in um (expected mm)"


def training_speed_mm_s(attrs) -> float | None:
    """The stage speed (mm/s) of the scene recorded in a fit's attributes, else the median
    speed label of its training scans (``scan_speed_mm_s``: a fit of a bare scan CSV), or None."""
    text = attrs.get("scene_toml")
    if text:
        try:
            scene = tomllib.loads(str(text))
        except tomllib.TOMLDecodeError:
            scene = {}
        for table in ("motion", "scan"):
            speed = scene.get(table, {}).get("speed_mm_s")
            if isinstance(speed, (int, float)) and speed > 0:
                return float(speed)
    speed = attrs.get("scan_speed_mm_s")
    return float(speed) if isinstance(speed, (int, float)) and speed > 0 else None


def _times(r: float) -> str:
    return f"{r:.3g}×"


@dataclass(frozen=True)
class Envelope:
    """The training envelope of a fit, per decoder draw where it depends on the window.

    Attributes:
        period_s (float): training sample interval (median), s.
        duration_s (float): shortest training scan, s.
        speed_mm_s (float | None): training stage speed, mm/s (None: not recorded).
        p_lo, p_hi (ndarray[S]): smallest and largest training P at each draw's window.
        slack (float): allowed factor on period, speed and duration, > 1.
        scale_factor (float): allowed factor beyond the training range of P, > 1.
        plate_sds (float): allowed distance of the decoded reading from the nearest
            training plate, in that plate's sds, > 1.
        noise_mm (ndarray[n_train] | None): each training scan's read-out noise, mm
            (:func:`readout_noise_mm`; None for a fit written before it was recorded).
        noise_factor (float): allowed factor on one scan's read-out noise beyond the
            noisiest training scan's, > 1 (1.25 flagged a held-out demo scan at 1.28×: one
            scan's estimate scatters by about ±50 %).
    """
    period_s: float
    duration_s: float
    speed_mm_s: float | None
    p_lo: np.ndarray
    p_hi: np.ndarray
    slack: float = 1.25
    scale_factor: float = 2.0
    plate_sds: float = 5.0
    noise_mm: np.ndarray | None = None
    noise_factor: float = 1.5

    def __post_init__(self):
        for name in ("slack", "scale_factor", "plate_sds", "noise_factor"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and 1.0 < v < float("inf")):
                raise ArgumentError(name, v, "a factor > 1")

    def plates(self, distance_sd: float, nearest_mm: float, height_mm: float) -> str | None:
        """A reading ``distance_sd`` sds from its nearest training plate ``nearest_mm``
        (:meth:`~feeler.calib.neuron.decoder.DecoderDraws.plate_distance`), decoded at
        ``height_mm``: beyond :attr:`plate_sds`, a step the fit was not trained on."""
        if not distance_sd > self.plate_sds:
            return None
        far = f"{distance_sd:.0f}" if distance_sd < 1e4 else "more than 10^4"        # a plate of no spread: 1e14
        # the decoded height stops at 0: a response below the lowest plate's band can decode to
        # that plate's own height ("0 mm lies 6 sds from ... (0 mm)", an outside audit)
        where = ("its response lies beyond that plate's band, where the height scale ends"
                 if f"{height_mm:.3g}" == f"{nearest_mm:.3g}" else "")
        return (f"decoded height {height_mm:.3g} mm lies {far} sds from the nearest trained plate "
                f"({nearest_mm:g} mm{'; ' + where if where else ''}): a step the fit was not trained on, so its plate "
                f"probabilities (which assume a trained plate) do not apply")

    def falling(self, uy_mm, plates_mm, height_mm) -> str | None:
        """A scan whose U_y falls over it by more than half its range (the median of its
        last tenth against its first) while it reads as a step at least half the lowest
        riser of ``plates_mm`` (the fit's steps, all ≥ 0: a touch rises onto a step), or
        None. The fall must happen within a fifth of a training scan's samples (a step's: a
        snap in one frame, a ride while the pad passes the edge; a drift spreads over the
        whole scan) and be :data:`FALL_NOISE_SDS` of its read-out noise. Such a scan is
        reversed in time or has U_y's sign flipped, and it is still read as the right
        plate, since the window sums follow how much U_y changes, but with intervals that
        hold for 59-60 % of them (an outside audit, four-plates).
        ``height_mm``: the decoded height, or a callable giving it (only asked when the
        scan falls)."""
        plates = np.asarray(plates_mm, float)
        u = np.asarray(uy_mm, float).ravel()
        risers = plates[plates > 0]
        if u.size < 10 or plates.min() < 0 or not risers.size:
            return None
        k = max(2, u.size // 10)
        net = median_of(u[-k:]) - median_of(u[:k])
        if not net < -0.5 * float(np.ptp(u)):
            return None
        # without the two conditions below, 13 of 4120 fresh scans of the shipped, hard and random
        # scenes were flagged (the six printed fell 6-16 um, read as 0.013-0.066 mm; the three looked at, of
        # uneven-steps, were flat plates drifting down in noise)
        fifth = int(round(self.duration_s / self.period_s / 5.0))            # samples, as a stream has none yet
        windows = np.lib.stride_tricks.sliding_window_view(u, min(u.size, max(2, fifth)))
        drop = float(np.max(windows[:, 0] - windows.min(axis=1)))       # the largest fall within a fifth
        if not (drop >= 0.7 * -net and -net >= FALL_NOISE_SDS * readout_noise_mm(u)):
            return None
        height = float(height_mm() if callable(height_mm) else height_mm)
        if not height >= 0.5 * float(risers.min()):
            return None
        return (f"U_y falls by {-net * 1e3:.3g} um over the scan, which reads as a {height:.3g} mm step; a touch "
                f"rises onto a step: a scan reversed in time, or U_y's sign flipped?")

    @classmethod
    def of_fit(cls, result, tau_s, *, slack: float = 1.25, scale_factor: float = 2.0) -> "Envelope":
        """The envelope of an M2 fit at the draws' windows ``tau_s (ndarray[S])``."""
        from feeler.calib.neuron.model import PeakTable

        obs = result.posterior["observed_data"]
        grid = np.asarray(obs["log_tau_grid"].values, float)
        table = PeakTable(log_tau=grid, peak=np.atleast_2d(np.asarray(obs["peak_u1"].values, float)))
        p = table.at(np.asarray(tau_s, float))                                  # (S, n_train)
        noise = (np.asarray(obs["readout_noise_mm"].values, float) if "readout_noise_mm" in obs.data_vars
                 else None)
        return cls(period_s=float(np.exp(grid[0])), duration_s=float(2.0 * np.exp(grid[-1])),
                   speed_mm_s=training_speed_mm_s(result.posterior["posterior"].attrs),
                   p_lo=p.min(axis=1), p_hi=p.max(axis=1), slack=slack, scale_factor=scale_factor, noise_mm=noise)

    def _training_noise(self) -> np.ndarray:
        v = np.asarray(self.noise_mm if self.noise_mm is not None else [], float)
        return v[np.isfinite(v)]

    def noise(self, noise_mm: float) -> str | None:
        """One scan's read-out noise (mm) beyond :attr:`noise_factor` × the noisiest training
        scan's."""
        train = self._training_noise()
        if not train.size or not np.isfinite(noise_mm):
            return None
        top = float(train.max())
        if noise_mm <= self.noise_factor * top:
            return None
        if top == 0:
            return (f"read-out noise {noise_mm * 1e3:.3g} um where the training scans had none (noise-free: the "
                    f"plates were learned without noise)")
        return (f"read-out noise {noise_mm * 1e3:.3g} um, {_times(noise_mm / top)} the noisiest training scan's "
                f"{top * 1e3:.3g} um (a noisier set-up: the plates were learned at less noise)")

    def batch_noise(self, noise_mm) -> str | None:
        """A batch of scans noisier than training (:data:`BATCH_NOISE_FACTOR` on the ratio of
        medians, and 3 standard errors of it) or quieter (:data:`BATCH_QUIET_FACTOR`: below a
        fifth, U_y probably in cm or inches), or None; batches of fewer than
        :data:`BATCH_MIN_SCANS` scans are left to :meth:`noise`."""
        train = self._training_noise()
        new = np.asarray(noise_mm, float)
        new = new[np.isfinite(new)]
        if train.size < BATCH_MIN_SCANS or new.size < BATCH_MIN_SCANS or not np.all(train > 0):
            return None                                 # (noise-free training scans: each scan says it)
        ratio = median_of(new) / median_of(train)
        se = 1.2533 * float(np.std(np.log(train), ddof=1)) * np.sqrt(1.0 / new.size + 1.0 / train.size)
        said = (f"these {new.size} scans' read-out noise (median {median_of(new) * 1e3:.3g} um) is {_times(ratio)} "
                f"the training scans' ({median_of(train) * 1e3:.3g} um)")
        if ratio > BATCH_NOISE_FACTOR and np.log(ratio) > 3.0 * se:
            return (f"{said}: the plates were learned at less noise, so the probabilities and intervals do not hold "
                    f"(refit on scans of this set-up)")
        if 0 < ratio < 1 / BATCH_QUIET_FACTOR and -np.log(ratio) > 3.0 * se:
            # U_y in cm scales the noise as it scales the steps' rise: the 0.2 mm plate then reads
            # like 0.02 mm, inside the training range, and was read as plate 0 at p = 0.999
            why = ("U_y probably in cm or inches (expected mm): every rise is as much smaller" if ratio < 0.2 else
                   "a quieter set-up")
            return f"{said}: {why}, so the plates learned at more noise do not describe them (refit on such scans)"
        return None

    def period(self, period_s: float) -> str | None:
        r = period_s / self.period_s
        if 1 / self.slack <= r <= self.slack:
            return None
        hint = ": times probably in ms (expected s)" if r > UNIT_FACTOR else ""
        return f"sampling period {period_s:.3g} s, {_times(r)} the fit's {self.period_s:.3g} s{hint}"

    def speed(self, speed_mm_s: float, *, labelled: float | None = None) -> str | None:
        """The scan's speed (measured, or its label) against training; ``labelled`` (the
        speed_mm_s label when the speed was measured from x and t) names a unit mistake."""
        out = []
        if speed_mm_s == 0:
            return "the stage did not move (x_mm constant)"
        if labelled is not None and labelled > 0:
            r = speed_mm_s / labelled
            if not 1 / UNIT_FACTOR <= r <= UNIT_FACTOR:
                out.append(f"x_mm and t_s give {speed_mm_s:.3g} mm/s, {_times(r)} the labelled {labelled:g} mm/s: "
                           f"{stage_units(r)}")
        if self.speed_mm_s is not None and not out:
            r = speed_mm_s / self.speed_mm_s
            if not 1 / self.slack <= r <= self.slack:
                out.append(f"speed {speed_mm_s:.3g} mm/s, {_times(r)} the fit's {self.speed_mm_s:g} mm/s")
        return "; ".join(out) or None

    def duration(self, duration_s: float, *, final: bool) -> str | None:
        """Longer than training (seen as soon as it happens) or, at the end, shorter."""
        r = duration_s / self.duration_s
        if r > self.slack or (final and r < 1 / self.slack):
            return f"scan of {duration_s:.3g} s, {_times(r)} the fit's {self.duration_s:.3g} s"
        return None

    def response(self, p_at_tau, *, final: bool, short: bool = False) -> str | None:
        """P (ndarray[S]) beyond the training range (above at once; below at the end). A
        ``short`` scan (shorter than training) may end before its step: a small response
        then names no unit."""
        p = np.asarray(p_at_tau, float).ravel()
        with np.errstate(divide="ignore", invalid="ignore"):
            hi = median_of(p / self.p_hi)
            lo = median_of(p / self.p_lo) if np.all(self.p_lo > 0) else np.inf
        if hi > self.scale_factor:
            hint = ": U_y probably in um (expected mm)" if hi > UNIT_FACTOR else ""
            return f"response {_times(hi)} the largest training scan's{hint}"
        if final and lo < 1 / self.scale_factor:
            hint = ": U_y probably in m (expected mm)" if 0 < lo < 1 / UNIT_FACTOR and not short else ""
            what = "no response (U_y constant)" if lo == 0 else f"response {_times(lo)} the smallest training scan's"
            return what + hint
        return None

    def problems(self, t_s, p_at_tau, *, x_mm=None, speed_mm_s: float | None = None, uy_mm=None,
                 noise: bool = True) -> list[str]:
        """Every reason a whole scan lies outside the envelope (empty: inside).

        Args:
            t_s (ndarray[n]): sample times, s. x_mm (ndarray[n] | None): stage position, mm.
            p_at_tau (ndarray[S]): the scan's P at each draw's window.
            speed_mm_s (float | None): the scan's speed label, mm/s.
            uy_mm (ndarray[n] | None): its U_y (mm), for the read-out noise and a spike.
            noise (bool): check the read-out noise of this scan alone (False: the caller
                has judged it with its batch, :meth:`batch_noise`).
        """
        t = np.asarray(t_s, float)
        ends = None if x_mm is None else (float(np.asarray(x_mm, float)[0]), float(np.asarray(x_mm, float)[-1]))
        out = self.problems_of(t.size, float(t[0]) if t.size else 0.0, float(t[-1]) if t.size else 0.0,
                               p_at_tau, x_ends_mm=ends, speed_mm_s=speed_mm_s, final=True,
                               noise_mm=None if uy_mm is None or not noise else readout_noise_mm(uy_mm))
        spike = None if uy_mm is None else spike_problem(uy_mm, t)
        return out + ([spike] if spike else [])

    def problems_of(self, n: int, t0_s: float, t1_s: float, p_at_tau, *, x_ends_mm=None,
                    speed_mm_s: float | None = None, final: bool = True, noise_mm: float | None = None) -> list[str]:
        """:meth:`problems` from what a stream keeps: ``n`` samples from ``t0_s`` to
        ``t1_s`` (s; period = their mean interval), the first and last x (mm) or None, the
        read-out noise so far (mm) or None; ``final=False`` reports only what can be known
        before the scan ends."""
        out, short = [], False
        if n >= 2:
            span = t1_s - t0_s
            out.append(self.period(span / (n - 1)))
            out.append(self.duration(span, final=final))
            short = final and span < self.duration_s / self.slack
            if x_ends_mm is not None and all(np.isfinite(x_ends_mm)):
                out.append(self.speed(abs(x_ends_mm[1] - x_ends_mm[0]) / span, labelled=speed_mm_s))
            elif speed_mm_s is not None:
                out.append(self.speed(float(speed_mm_s)))
        elif final:                                 # one sample: no change to sum, whatever its scale
            return [f"{n} sample: a scan needs samples over the fit's {self.duration_s:.3g} s to be decoded"]
        out.append(self.response(p_at_tau, final=final, short=short))
        if noise_mm is not None:
            out.append(self.noise(noise_mm))
        return [p for p in out if p]
