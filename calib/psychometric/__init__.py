"""M4 internals: trial cells, priors, and the Laplace and NUTS backends.

The entry point is :func:`feeler.calib.psychometric.fit.fit_psychometric`.
"""
__all__: list[str] = []
