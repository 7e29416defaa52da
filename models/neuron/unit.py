"""The shared engine of batch and streaming: validate a chunk, run the fused kernel."""
from __future__ import annotations

import math

import numpy as np

from feeler.errors import ArgumentError
from feeler.models.neuron import kernels
from feeler.models.neuron.threads import run_parallel
from feeler.models.neuron.uniform import (UniformStream, boxcar_uniform, split_parts, split_row,
                                          window_shape)
from feeler.models.neuron.validate import (check_signal, check_times_uniform, check_weights,
                                           uniform_grid)

__all__ = ["Engine"]

_ONE = np.ones(1)


class Engine:
    """Runs chunks of one record through the kernel, carrying state between them.

    Args:
        tau (float): validated window length in seconds.
        kernel (str): validated kernel name.
        weights (ndarray[n_receptors] | None): spatial weights (validated on first chunk).
    """

    def __init__(self, tau: float, kernel: str, weights=None):
        self.tau, self.kernel = tau, kernel
        self.weights = None if weights is None else np.asarray(weights, dtype=np.float64)
        self.carry: kernels.Carry | None = None
        self.shape: tuple | None = None  # leading shape of the strain, fixed by the first chunk
        self.t_last: float | None = None
        self.uniform: UniformStream | None = None  # boxcar streams of uniform chunks
        self.general = False                        # set once a chunk broke uniform sampling

    def run(self, strain, t, *, a: float = 1.0, h: float = 0.0, clamp: bool = False,
            whole: bool = False) -> np.ndarray:
        """Window sum u₁ (or z when ``clamp``) for the next chunk, shape ``(..., n)``.

        ``whole`` says the chunk is a whole record (batch call): uniformly sampled
        records then take the pointer-free boxcar loop."""
        with_w = self.weights is not None
        s, tt = check_signal(strain, t, min_ndim=2 if with_w else 1, t_prev=self.t_last,
                             check_finite=False, check_times=False)
        n = tt.shape[0]
        if self.shape is None:
            if with_w:
                self.weights = check_weights(self.weights, s.shape[-2])
            self.shape = s.shape[:-1]
        elif s.shape[:-1] != self.shape:
            raise ArgumentError("strain", f"shape {s.shape}",
                                f"leading shape must stay {self.shape} across chunks")
        lead = self.shape[:-1] if with_w else self.shape
        n_rec = s.shape[-2] if with_w else 1
        x = np.ascontiguousarray(s.reshape(math.prod(lead), n_rec, n))
        w = self.weights if with_w else _ONE
        if self.carry is None:
            self.carry = kernels.Carry(x.shape[0])
        boxcar = self.kernel == "boxcar"
        out = dt = None
        if boxcar and whole and n:
            # validates t; computed here unless t is off a uniform grid
            out = boxcar_record(x, w, tt, self.tau, self.carry.sum, a=a, h=h, clamp=clamp)
        else:
            # one pass: validity of t and, if uniform (continuing the previous chunk), its step
            dt = check_times_uniform(tt if self.t_last is None else np.concatenate([[self.t_last], tt]))
        if n == 0:
            return np.empty((*lead, 0))
        if out is None:
            if (boxcar and not self.general and n_rec == 1 and dt is not None
                    and (self.uniform is None or self.uniform.accepts(dt))):
                if self.uniform is None:
                    self.uniform = UniformStream(x.shape[0], dt, self.tau)
                out = self.uniform.push(x, w, tt, self.carry.sum, a=a, h=h, clamp=clamp)
            else:
                if self.uniform is not None and not self.general:
                    self.carry = self.uniform.general_carry(w)
                self.general = boxcar
                run = kernels.exponential if self.kernel == "exponential" else kernels.boxcar
                out = run(x, w, tt, self.tau, self.carry, a=a, h=h, clamp=clamp)
        if not kernels.finite(self.carry):
            check_signal(strain, t, min_ndim=1)  # raises with the index of the bad sample
            raise ArgumentError("strain", "increments beyond float64",
                                "strain differences overflow; rescale the input")
        self.t_last = float(tt[-1])
        return out.reshape(*lead, n)


def boxcar_record(x: np.ndarray, w: np.ndarray, t: np.ndarray, tau: float, final: np.ndarray, *,
                  a: float = 1.0, h: float = 0.0, clamp: bool = False) -> np.ndarray | None:
    """Check the times ``t`` of a whole record and, when they are uniform, compute its
    boxcar on the fast loops (:func:`~.uniform.boxcar_uniform`); None when they are not
    (the caller takes the general loop). Raises the one-line error of a bad ``t``.

    A long single-receptor record checks t inside the threads that compute it: t is read
    once, in parallel, next to the strain."""
    n = t.shape[0]
    grid = uniform_grid(t)
    if grid is not None and n >= 2 and grid[1] < grid[0]:
        mm, frac = window_shape(grid[0], tau, n)
        parts = split_parts(x, n, mm)
        if parts:
            out = np.empty((1, n))
            fin, far = run_parallel(split_row, parts, x[0, 0], t, grid[0], grid[1], float(w[0]), mm,
                                    frac, float(a), float(h), clamp, out[0], 0, parts)
            if not far:
                final[0] = fin
                return out
            check_times_uniform(t, grid)  # raises for a bad time, else t is off the grid
            return None
    dt = check_times_uniform(t, grid)
    return None if dt is None else boxcar_uniform(x, w, dt, tau, final, a=a, h=h, clamp=clamp)
