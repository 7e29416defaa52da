"""Posterior containers: build an ArviZ ``DataTree`` from plain draws, and flatten it back.

Every backend ends here. MCMC backends (emcee, exact/conjugate sampling) hand over
``dict[name] -> ndarray (chain, draw, *shape)``; PyMC already returns a ``DataTree``.
Scalar parameters keep their name (``a``, ``tau_s``); array parameters are flattened to
one entry per element with integer indices and no spaces: ``C[0,2]`` is row 0
(displacement axis x), column 2 (force axis z).
"""
from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

__all__ = ["posterior_from_draws", "flat_draws", "entry_name", "entry_names"]


def entry_name(var: str, index: tuple[int, ...]) -> str:
    """The summary name of one element of ``var``: ``C[1,0]``; a scalar keeps ``var``."""
    return var if not index else f"{var}[{','.join(str(int(i)) for i in index)}]"


def posterior_from_draws(draws: Mapping[str, np.ndarray], *,
                         dims: Mapping[str, Sequence[str]] | None = None,
                         sample_stats: Mapping[str, np.ndarray] | None = None,
                         observed: Mapping[str, np.ndarray] | None = None,
                         extra_groups: Mapping[str, Mapping[str, np.ndarray]] | None = None,
                         attrs: Mapping[str, object] | None = None):
    """An ArviZ 1.x ``DataTree`` with groups posterior, sample_stats, observed_data, ...

    Args:
        draws (dict[str, ndarray[chain, draw, *shape]]): posterior draws per variable.
        dims (dict[str, list[str]]): names of the non-sample dimensions per variable,
            e.g. ``{"C": ["disp_axis", "force_axis"]}``.
        sample_stats (dict[str, ndarray[chain, draw]]): e.g. ``diverging``, ``lp``; its
            ``attrs``, if any (:class:`feeler.calib.nuts.SampleStats`), go on the group.
        observed (dict[str, ndarray]): the data the fit saw (no chain/draw dims).
        extra_groups (dict[str, dict]): more groups with (chain, draw) leading dims,
            e.g. ``posterior_predictive``.
        attrs (dict): attributes stored on the posterior group (strings/numbers).
    """
    from arviz_base import from_dict

    from feeler.calib.lazy_dask import install
    install()

    for name, value in draws.items():
        if np.ndim(value) < 2:
            raise ValueError(f"draws[{name!r}] must have leading (chain, draw) dims, "
                             f"got shape {np.shape(value)}")
    data = {"posterior": {k: np.asarray(v) for k, v in draws.items()}}
    if sample_stats:
        data["sample_stats"] = {k: np.asarray(v) for k, v in sample_stats.items()}
    if observed:
        data["observed_data"] = {k: np.asarray(v) for k, v in observed.items()}
    for group, values in (extra_groups or {}).items():
        data[group] = {k: np.asarray(v) for k, v in values.items()}
    tree = from_dict(data, dims={k: list(v) for k, v in (dims or {}).items()},
                     pred_dims={k: list(v) for k, v in (dims or {}).items()})
    if attrs:
        tree["posterior"].attrs.update({k: v for k, v in attrs.items()})
    if getattr(sample_stats, "attrs", None):      # the NUTS runner's timings (calib.nuts)
        tree["sample_stats"].attrs.update(sample_stats.attrs)
    return tree


def entry_names(posterior) -> list[str]:
    """The names of the posterior group's scalar entries, in :func:`flat_draws` order,
    without reading the draws (a summary.csv has one row for each)."""
    group = posterior["posterior"] if "posterior" in getattr(posterior, "children", {}) else posterior
    names: list[str] = []
    for var in group.data_vars:
        da = group[var]
        shape = tuple(da.sizes[d] for d in da.dims if d not in ("chain", "draw"))
        names.extend(entry_name(str(var), index) for index in np.ndindex(*shape))
    return names


def flat_draws(posterior) -> dict[str, np.ndarray]:
    """One ``(chain, draw)`` array per scalar entry of the posterior group.

    Args:
        posterior: a ``DataTree`` with a ``posterior`` group (or that group itself).
    Returns:
        dict[str, ndarray[chain, draw]] keyed by :func:`entry_name`, in variable order.
    """
    group = posterior["posterior"] if "posterior" in getattr(posterior, "children", {}) else posterior
    out: dict[str, np.ndarray] = {}
    for var in group.data_vars:
        da = group[var].transpose("chain", "draw", ...)
        values = np.asarray(da.values, dtype=float)
        for index in np.ndindex(*values.shape[2:]):
            out[entry_name(str(var), index)] = values[(slice(None), slice(None)) + index]
    return out
