"""Progress bars for samplers and validation loops (tqdm on stderr).

Bars show only when stderr is a terminal unless asked explicitly, so tests and logs
stay clean. PyMC and emcee take a boolean (``progressbar=`` / ``progress=``): pass
:func:`show_progress` to them; loops of our own wrap their iterable in :func:`progress`.
Off a terminal, ``progress(..., lines=True)`` prints a line per finished item with the
elapsed time and an estimate of the time left (SBC replicates, simulated scans), and
:func:`stage` a line per stage; ``enabled=False`` (--no-progress) silences both.
"""
from __future__ import annotations

import os
import sys
from typing import Callable, Iterable, Iterator, TypeVar

__all__ = ["show_progress", "progress", "bar_width", "stage", "stages", "duration"]

T = TypeVar("T")


def show_progress(enabled: bool | None = None) -> bool:
    """``enabled`` if given, else whether stderr is an interactive terminal."""
    if enabled is not None:
        return bool(enabled)
    return bool(getattr(sys.stderr, "isatty", lambda: False)())


def progress(iterable: Iterable[T], *, desc: str, total: int | None = None,
             enabled: bool | None = None, lines: bool = False) -> Iterable[T]:
    """``iterable`` wrapped in a tqdm bar labelled ``desc``; off a terminal (``enabled``
    None) with ``lines``, a line per finished item (``desc: i/n done, 12 s, about 40 s
    left``); otherwise unchanged."""
    if not show_progress(enabled):
        if lines and enabled is None:
            return _lines(iterable, desc, total)
        return iterable
    from tqdm.auto import tqdm
    return tqdm(iterable, desc=desc, total=total, file=sys.stderr, leave=False, **bar_width())


def _lines(iterable: Iterable[T], desc: str, total: int | None) -> Iterator[T]:
    """Yield from ``iterable``; after each item, ``desc: i/n done, <elapsed>, about <eta> left``
    on stderr (the time left from the mean time per item so far)."""
    import time

    if total is None and hasattr(iterable, "__len__"):
        total = len(iterable)
    start = time.monotonic()
    for i, item in enumerate(iterable, 1):
        yield item
        took = time.monotonic() - start
        if total:
            left = f", about {duration(took / i * (total - i))} left" if i < total else ""
            print(f"{desc}: {i}/{total} done, {duration(took)}{left}", file=sys.stderr, flush=True)
        else:
            print(f"{desc}: {i} done, {duration(took)}", file=sys.stderr, flush=True)


def duration(seconds: float) -> str:
    """``seconds`` (≥ 0) as ``"0.4 s"``, ``"12 s"``, ``"3 min 05 s"`` or ``"1 h 02 min"``."""
    seconds = max(float(seconds), 0.0)
    if seconds < 9.95:
        return f"{seconds:.1f} s"
    s = int(round(seconds))
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {s % 3600 // 60:02d} min"


def bar_width() -> dict:
    """tqdm size keywords: follow the terminal when it reports its size; where it reports
    none (a 0x0 pseudo-terminal, as under `script` or CI: tqdm then draws nothing, as it
    takes 0 rows for "no room"), a fixed size from COLUMNS/LINES, else 80 x 24."""
    import shutil
    try:
        cols, rows = os.get_terminal_size(sys.stderr.fileno())
    except (OSError, ValueError, AttributeError):
        cols, rows = 0, 0
    if cols > 0 and rows > 0:
        return {"dynamic_ncols": True}
    env = shutil.get_terminal_size((0, 0))
    return {"ncols": cols or env.columns or 80, "nrows": rows or env.lines or 24}


def stage(text: str, enabled: bool | None = None) -> None:
    """``<text> ...`` on stderr: a line per stage of a long command, unless ``enabled`` is
    False (--no-progress). Stdout stays the command's result."""
    if enabled is not False:
        print(f"{text} ...", file=sys.stderr, flush=True)


def stages(desc: str, enabled: bool | None = None,
           tick_s: float = 1.0) -> tuple[Callable[[str], None], Callable[[], None]]:
    """(step(text), close()) for a command of named stages: on a terminal one live line
    ``desc: <text> [elapsed]`` (tqdm; redrawn every ``tick_s`` seconds, so the time runs
    on through a long stage), otherwise ``desc: <text> ...`` per stage on stderr; nothing
    when ``enabled`` is False. Call ``close()`` when done (also on errors)."""
    if enabled is False:
        return (lambda text: None), (lambda: None)
    if not show_progress(enabled):
        return (lambda text: stage(f"{desc}: {text}")), (lambda: None)
    import threading

    from tqdm.auto import tqdm
    bar = tqdm(desc=desc, file=sys.stderr, leave=False, bar_format="{desc} [{elapsed}]", **bar_width())
    done = threading.Event()

    def tick() -> None:
        while not done.wait(tick_s):
            bar.refresh()
    ticker = threading.Thread(target=tick, name=f"{desc} progress", daemon=True)
    ticker.start()

    def step(text: str) -> None:
        bar.set_description_str(f"{desc}: {text}")

    def close() -> None:
        done.set()
        ticker.join()
        bar.close()
    return step, close
