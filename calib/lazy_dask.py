"""Keep xarray from importing dask.array (and SciPy with it) when no dask array exists.

xarray asks "is this a dask array?" of every array it wraps, and answers by importing
``dask.array`` whenever dask is installed: 1–1.5 s on this machine, more than the
whole exact fit (issue 18). No dask array can exist before ``dask.array`` is imported,
so until then the answer is "no" without importing anything; as soon as anything
imports ``dask.array`` (``feeler calibrate sensors``, a user's own code), xarray's own
answer takes over. Anything else xarray asks of dask loads it as xarray would.

Writing NetCDF likewise asks which dask scheduler is active (to close files between
chunked writes), importing dask.distributed (1–2 s): :func:`writing_without_dask` answers
"none" while no dask array can exist.
"""
from __future__ import annotations

import contextlib
import sys

__all__ = ["install", "writing_without_dask"]


class _DaskWhenLoaded:
    """Stands for dask in xarray's cache of duck-array modules until dask.array is loaded."""

    def __init__(self, pycompat):
        self._pycompat = pycompat

    def _real(self):
        real = self._pycompat.DuckArrayModule("dask")
        self._pycompat._cached_duck_array_modules["dask"] = real
        return real

    @property
    def type(self):
        return self._real().type if "dask.array" in sys.modules else ()

    def __getattr__(self, name):              # module, version, available: xarray's own answer
        return getattr(self._real(), name)


def install() -> None:
    """Put the stand-in in xarray's cache (no-op once xarray has looked dask up)."""
    if "dask.array" in sys.modules:
        return
    try:
        from xarray.namedarray import pycompat
        cache = pycompat._cached_duck_array_modules
    except (ImportError, AttributeError):     # another xarray: it imports dask as usual
        return
    cache.setdefault("dask", _DaskWhenLoaded(pycompat))


@contextlib.contextmanager
def writing_without_dask():
    """Within: xarray's writers see no dask scheduler unless dask.array is loaded."""
    install()
    try:
        from xarray.backends import locks, writers
        modules = [m for m in (locks, writers) if hasattr(m, "get_dask_scheduler")]
        original = locks.get_dask_scheduler
    except (ImportError, AttributeError):     # another xarray: nothing to skip
        yield
        return

    def scheduler(*args, **kwargs):
        return original(*args, **kwargs) if "dask.array" in sys.modules else None

    saved = [(m, m.get_dask_scheduler) for m in modules]
    for m in modules:
        m.get_dask_scheduler = scheduler
    try:
        yield
    finally:
        for m, f in saved:
            m.get_dask_scheduler = f
