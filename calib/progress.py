"""Progress bars for samplers and validation loops (tqdm on stderr).

Bars show only when stderr is a terminal unless asked explicitly, so tests and logs
stay clean. PyMC and emcee take a boolean (``progressbar=`` / ``progress=``): pass
:func:`show_progress` to them; loops of our own wrap their iterable in :func:`progress`.
"""
from __future__ import annotations

import os
import sys
from typing import Iterable, TypeVar

__all__ = ["show_progress", "progress", "bar_width", "stage"]

T = TypeVar("T")


def show_progress(enabled: bool | None = None) -> bool:
    """``enabled`` if given, else whether stderr is an interactive terminal."""
    if enabled is not None:
        return bool(enabled)
    return bool(getattr(sys.stderr, "isatty", lambda: False)())


def progress(iterable: Iterable[T], *, desc: str, total: int | None = None,
             enabled: bool | None = None) -> Iterable[T]:
    """``iterable`` wrapped in a tqdm bar labelled ``desc`` (or unchanged when disabled)."""
    if not show_progress(enabled):
        return iterable
    from tqdm.auto import tqdm
    return tqdm(iterable, desc=desc, total=total, file=sys.stderr, leave=False, **bar_width())


def bar_width() -> dict:
    """tqdm width keywords: follow the terminal, or 80 columns where it reports no size
    by 24 rows where it reports no size (a 0x0 pseudo-terminal: tqdm then draws nothing,
    with ``dynamic_ncols`` or without, as it takes 0 rows for "no room")."""
    import shutil
    cols = shutil.get_terminal_size((0, 0)).columns
    try:
        cols = os.get_terminal_size(sys.stderr.fileno()).columns or cols
    except (OSError, ValueError, AttributeError):
        pass
    return {"dynamic_ncols": True} if cols > 0 else {"ncols": 80, "nrows": 24}


def stage(text: str, enabled: bool | None = None) -> None:
    """``<text> ...`` on stderr: a line per stage of a long command, unless ``enabled`` is
    False (--no-progress). Stdout stays the command's result."""
    if enabled is not False:
        print(f"{text} ...", file=sys.stderr, flush=True)
