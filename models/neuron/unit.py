"""The shared engine of batch and streaming: validate a chunk, run the fused kernel."""
from __future__ import annotations

import numpy as np

from feeler.errors import ArgumentError
from feeler.models.neuron import kernels
from feeler.models.neuron.uniform import boxcar_uniform
from feeler.models.neuron.validate import check_signal, check_times_uniform, check_weights

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

    def run(self, strain, t, *, a: float = 1.0, h: float = 0.0, clamp: bool = False,
            whole: bool = False) -> np.ndarray:
        """Window sum u₁ (or z when ``clamp``) for the next chunk, shape ``(..., n)``.

        ``whole`` says the chunk is a whole record (batch call): uniformly sampled
        records then take the pointer-free boxcar loop."""
        with_w = self.weights is not None
        s, tt = check_signal(strain, t, min_ndim=2 if with_w else 1, t_prev=self.t_last,
                             check_finite=False, check_times=False)
        dt = check_times_uniform(tt)  # one pass: validity of t and, if uniform, its step
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
        x = np.ascontiguousarray(s.reshape(int(np.prod(lead, dtype=np.int64)), n_rec, n))
        w = self.weights if with_w else _ONE
        if self.carry is None:
            self.carry = kernels.Carry(x.shape[0])
        if dt is not None and whole and self.kernel == "boxcar":
            out = boxcar_uniform(x, w, dt, self.tau, self.carry, a=a, h=h, clamp=clamp)
        else:
            run = kernels.exponential if self.kernel == "exponential" else kernels.boxcar
            out = run(x, w, tt, self.tau, self.carry, a=a, h=h, clamp=clamp)
        if n and not kernels.finite(self.carry):
            check_signal(strain, t, min_ndim=1)  # raises with the index of the bad sample
            raise ArgumentError("strain", "increments beyond float64",
                                "strain differences overflow; rescale the input")
        if n:
            self.t_last = float(tt[-1])
        return out.reshape(*lead, n)

