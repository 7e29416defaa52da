"""The exact M4 backend: adaptive-grid integration (:mod:`.grid`), smooth distribution
functions on grids (:mod:`feeler.calib.psychometric.exact.quadrature`) and the summaries and draws of a grid
posterior (:mod:`.stats`)."""
__all__: list[str] = []
