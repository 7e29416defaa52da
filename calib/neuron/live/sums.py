"""Unit-gain window sums u₁ at several windows τ_j at once, one sample at a time.

The same quantity as :func:`feeler.models.neuron.window_sum` (DESIGN §4), computed for a
handful of windows per pushed sample. With c_k = |ε_k − ε_{k−1}| (c_0 = 0: ε̇_0 = 0) the
receptor output integrated over its hold interval (t_{k−1}, t_k]:

- boxcar: u₁(t_k; τ) = Σ_{j ≤ k} c_j · |(t_{j−1}, t_j] ∩ (t_k − τ, t_k]| / (t_j − t_{j−1}),
  whole intervals count whole and the one straddling t_k − τ by its fraction. The history
  kept is the intervals that can still meet the longest window (O(window) memory); each
  sample re-sums them newest first (O(window) work, independent of the record's length,
  and no running sum to drift however long the record);
- exponential: u_k = e^(−Δ/τ)·u_{k−1} + c_k·τ(1 − e^(−Δ/τ))/Δ (O(1) state per window).

The core's :class:`~feeler.models.neuron.FA1Stream` computes one window per object at
~30 µs per call; a live decoder needs tens of windows per sample, so this computes them in
one vectorised step (tested equal to the core to float rounding, uniform or not).
"""
from __future__ import annotations

import math

import numpy as np

from feeler.errors import ArgumentError

__all__ = ["WindowSums"]


class WindowSums:
    """Streams of u₁ at windows ``tau_s (ndarray[K])`` with their running maxima.

    Args:
        tau_s (ndarray[K]): windows (s), > 0.
        kernel (str): ``"boxcar"`` or ``"exponential"``.

    After each :meth:`push`, :attr:`u` (ndarray[K]) holds u₁ at the new sample and
    :attr:`peak` (ndarray[K]) its maximum over the record so far (0 before any sample,
    as :func:`~feeler.models.neuron.peak_window_sum` of an empty record).
    """

    def __init__(self, tau_s, *, kernel: str = "boxcar"):
        tau = np.asarray(tau_s, float).ravel()
        if tau.size == 0 or not np.all(np.isfinite(tau) & (tau > 0)):
            raise ArgumentError("tau_s", tau_s, "one or more finite windows > 0 s")
        if kernel not in ("boxcar", "exponential"):
            raise ArgumentError("kernel", kernel, "boxcar or exponential")
        self.tau_s, self.kernel = tau, kernel
        self._tau_max = float(tau.max())
        self.reset()

    def reset(self) -> None:
        """Start a new record."""
        k = self.tau_s.size
        self.u, self.peak = np.zeros(k), np.zeros(k)
        self.n = 0
        self._eps = self._t = None
        self._ts = np.empty(64)          # history: times t_j and increments c_j, oldest first
        self._cs = np.empty(64)
        self._len = 0

    def push(self, t_s: float, strain: float) -> bool:
        """Add one sample (time in s, after the previous one; strain, dimensionless).
        Returns True when a running maximum grew.

        Raises:
            ArgumentError: a non-finite value, or a time not after the previous one.
        """
        t, e = float(t_s), float(strain)
        if not (math.isfinite(t) and math.isfinite(e)):
            raise ArgumentError("sample", (t_s, strain), "finite time (s) and strain")
        if self._t is not None and not t > self._t:
            raise ArgumentError("t_s", t, f"after the previous sample's {self._t!r} s")
        c = 0.0 if self._eps is None else abs(e - self._eps)
        if self.kernel == "boxcar":
            self.u = self._boxcar(t, c)
        else:
            self.u = self._exponential(t, c)
        self._eps, self._t = e, t
        self.n += 1
        grew = self.u > self.peak
        if grew.any():
            np.maximum(self.peak, self.u, out=self.peak)
            return True
        return False

    def _exponential(self, t: float, c: float) -> np.ndarray:
        if self._t is None:
            return np.zeros(self.tau_s.size)
        d = t - self._t
        x = d / self.tau_s
        return np.exp(-x) * self.u + c * (-np.expm1(-x) / x)

    def _boxcar(self, t: float, c: float) -> np.ndarray:
        if self._len == self._ts.size:
            self._compact(t)
        self._ts[self._len], self._cs[self._len] = t, c
        self._len += 1
        ts, cs = self._ts[: self._len], self._cs[: self._len]
        start = t - self.tau_s                                   # window starts T_j
        # first history time ≥ T_j: the intervals ending after it count whole
        i = np.searchsorted(ts, start, side="left")
        newest_first = np.concatenate([[0.0], np.cumsum(cs[:0:-1])])      # sums of the m newest
        u = newest_first[self._len - 1 - np.minimum(i, self._len - 1)]
        cut = (i >= 1) & (i < self._len)
        if cut.any():
            j = i[cut]
            right = ts[j]
            frac = (right - start[cut]) / (right - ts[j - 1])
            u[cut] += cs[j] * np.where(right > start[cut], frac, 0.0)
        return u

    def _compact(self, t: float) -> None:
        """Drop intervals that no window can reach again; grow the buffer if still full."""
        ts = self._ts[: self._len]
        keep = max(int(np.searchsorted(ts, t - self._tau_max, side="left")) - 1, 0)
        n = self._len - keep
        if n > self._ts.size // 2:
            new_t, new_c = np.empty(2 * self._ts.size), np.empty(2 * self._ts.size)
        else:
            new_t, new_c = self._ts, self._cs
        new_t[:n], new_c[:n] = self._ts[keep: self._len], self._cs[keep: self._len]
        self._ts, self._cs, self._len = new_t, new_c, n
