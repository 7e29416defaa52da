"""Streaming FA-I unit: state carried across chunks of any size (same result as batch)."""
from __future__ import annotations

import numpy as np

from feeler.models.neuron.unit import Engine
from feeler.models.neuron.validate import check_kernel, check_params

__all__ = ["FA1Stream"]


class FA1Stream:
    """Push chunks of samples, get the pulse density of each chunk.

    Args:
        a (float): gain, > 0.
        tau (float): window length τ in seconds, > 0.
        h (float): threshold, ≥ 0.
        weights (ndarray[n_receptors] | None): spatial weights.
        kernel (str): ``"boxcar"`` or ``"exponential"``.

    Any chunking of a record gives the batch :func:`~feeler.models.neuron.pulse_density`
    up to float rounding; chunks may be empty. The leading shape of the strain
    (channels, receptors) is fixed by the first chunk, and each chunk's times must
    continue after the previous chunk's. The running sums are compensated, so 10⁸-sample
    streams do not drift.

    Example::

        stream = FA1Stream(a=1.0, tau=3.0, h=0.0)
        for t_chunk, eps_chunk in source:
            z_chunk = stream.push(t_chunk, eps_chunk)
    """

    def __init__(self, *, a: float, tau: float, h: float, weights=None, kernel: str = "boxcar"):
        self.a, self.tau, self.h = check_params(a=a, tau=tau, h=h)
        self.kernel = check_kernel(kernel)
        self._engine = Engine(self.tau, self.kernel, weights)

    def push_u1(self, t_chunk, strain_chunk) -> np.ndarray:
        """Unit-gain membrane potential u₁ for the chunk, shape ``(..., n_chunk)``."""
        return self._engine.run(strain_chunk, t_chunk)

    def push(self, t_chunk, strain_chunk) -> np.ndarray:
        """Pulse density z = max(a·u₁ − h, 0) for the chunk, shape ``(..., n_chunk)``."""
        return self._engine.run(strain_chunk, t_chunk, a=self.a, h=self.h, clamp=True)
