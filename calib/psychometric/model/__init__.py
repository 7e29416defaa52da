"""The M4 model: tasks (comparison, nAFC), trial cells, priors, one observer's posterior
density and the mode search every deterministic backend shares."""
__all__: list[str] = []
