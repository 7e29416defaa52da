"""What a report is made of: sections of figures, tables and notes, each naming its sources.

Every block carries ``sources``: the run-relative paths of the files its numbers come
from, shown beside it in the report and listed in the manifest (DESIGN §7: every number
traceable to a file of the run). Figures are PNG data URIs so the HTML stays
self-contained; each carries the layout problems :func:`feeler.reports.layout.check_figure`
found when it was drawn (none, in a good report).
"""
from __future__ import annotations

import base64
import contextlib
import io
import math
from contextvars import ContextVar
from dataclasses import dataclass, field
from typing import Callable

__all__ = ["Figure", "Gallery", "Table", "Note", "Section", "subplots", "make_figure", "error_span", "fmt", "fmt_sig", "interval",
           "log_axis",
           "report_style", "STYLE", "on_figure",
           "table_from_frame", "DPI"]

DPI = 110                 # pixels per inch of the inlined PNGs (shown at their size in inches)

_ON_FIGURE: ContextVar[Callable[[str], None] | None] = ContextVar("feeler_report_on_figure", default=None)


@dataclass(frozen=True)
class Figure:
    """One inlined figure: ``uri`` is a ``data:image/png;base64,...`` URI shown at
    ``width_in`` inches (less on narrow screens); ``problems`` are its layout faults."""
    title: str
    uri: str
    sources: tuple[str, ...]
    caption: str = ""
    width_in: float = 6.0
    problems: tuple[str, ...] = ()
    kind: str = "figure"


@dataclass(frozen=True)
class Gallery:
    """Images the run already holds (PNGs written by a command), shown small side by side:
    ``items`` are (title, data URI, source) triples. Not drawn here, so not layout-checked."""
    title: str
    items: tuple[tuple[str, str, str], ...]
    sources: tuple[str, ...]
    caption: str = ""
    width_in: float = 2.3
    kind: str = "gallery"


@dataclass(frozen=True)
class Table:
    """A table of already formatted cells (str), one tuple per row; ``marks`` (optional,
    one per row) gives each row a CSS class (e.g. "reproduced", "failed")."""
    title: str
    columns: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]
    sources: tuple[str, ...]
    caption: str = ""
    marks: tuple[str, ...] = ()
    kind: str = "table"


@dataclass(frozen=True)
class Note:
    """A paragraph; ``level`` is "info", "synthetic" (data not measured), "failed",
    "measured" (numbers measured while the report's run was made) or "code"."""
    text: str
    level: str = "info"
    sources: tuple[str, ...] = ()
    kind: str = "note"


@dataclass(frozen=True)
class Section:
    """A titled part of the report; ``failed`` puts it first, under a red banner."""
    key: str
    title: str
    blocks: tuple = ()
    failed: bool = False
    problems: tuple[str, ...] = field(default=())


def subplots(ncols: int = 1, *, nrows: int = 1, width_in: float = 3.4, height_in: float = 2.6, **kw):
    """``plt.subplots`` on the Agg backend with constrained layout; each panel ``width_in``
    x ``height_in`` inches (the printed size); returns (fig, axes)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    kw.setdefault("layout", "constrained")
    fig, axes = plt.subplots(nrows, ncols, figsize=(width_in * ncols, height_in * nrows), **kw)
    fig.set_dpi(DPI)
    return fig, axes


#: matplotlib settings of every report figure (sizes in pt, for figures printed at their size)
STYLE = {"font.size": 8.0, "axes.titlesize": 8.5, "axes.labelsize": 8.0, "xtick.labelsize": 7.0,
         "ytick.labelsize": 7.0, "legend.fontsize": 6.5, "figure.titlesize": 9.0}


def report_style():
    """A context in which figures are made and drawn with :data:`STYLE` (restored after)."""
    import matplotlib

    return matplotlib.rc_context(STYLE)


def _draw(fig) -> None:
    fig.canvas.draw()


def _move_covering_legends(fig) -> bool:
    """Legends that cover data move outside their panel (right of it); True if any moved."""
    from feeler.reports.layout import _legend_problems

    renderer, moved = fig.canvas.get_renderer(), False
    for ax in fig.axes:
        legend = ax.get_legend()
        if legend is None or not _legend_problems(ax, renderer):
            continue
        handles, labels = ax.get_legend_handles_labels()
        size = legend.get_texts()[0].get_fontsize() if legend.get_texts() else 7
        ax.legend(handles, labels, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0,
                  fontsize=size, frameon=False)
        moved = True
    return moved


@contextlib.contextmanager
def on_figure(callback: Callable[[str], None]):
    """Within: ``callback(title)`` as :func:`make_figure` starts drawing each figure (the
    report's progress per figure; section builders need not know of it)."""
    token = _ON_FIGURE.set(callback)
    try:
        yield
    finally:
        _ON_FIGURE.reset(token)


def error_span(value, lo, hi):
    """``xerr``/``yerr`` of ``errorbar`` for estimates ``value`` with intervals [lo, hi]:
    the distances to each end, never negative. A mean can lie outside its equal-tailed
    interval (a skewed posterior, a bootstrap interval), and matplotlib then raised
    "'xerr' must not contain negative values"; the bar then ends at the mean on that side."""
    import numpy as np

    v, lo, hi = (np.asarray(x, float) for x in (value, lo, hi))
    with np.errstate(invalid="ignore"):
        return np.stack([np.clip(v - lo, 0.0, None), np.clip(hi - v, 0.0, None)])


def make_figure(title: str, fig, sources, caption: str = "") -> Figure:
    """Draw ``fig`` at its printed size, move legends that cover data, check the layout,
    encode the PNG and close the figure (announced to :func:`on_figure`'s callback)."""
    import matplotlib.pyplot as plt
    from PIL import Image

    from feeler.reports.layout import check_figure

    announce = _ON_FIGURE.get()
    if announce is not None:
        announce(title)

    try:
        _draw(fig)
        if _move_covering_legends(fig):
            _draw(fig)
        problems = check_figure(fig)
        width, height = fig.canvas.get_width_height()
        image = Image.frombuffer("RGBA", (width, height), fig.canvas.buffer_rgba(), "raw", "RGBA", 0, 1)
        buf = io.BytesIO()
        image.convert("RGB").save(buf, format="PNG", optimize=False)
        width_in = float(fig.get_figwidth())
    finally:
        plt.close(fig)
    uri = "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")
    return Figure(title=title, uri=uri, sources=tuple(sources), caption=caption, width_in=width_in,
                  problems=problems)


def log_axis(ax, which: str = "x") -> None:
    """A log axis labelled at its decades only (plain numbers, no crowded minor labels),
    spanning at least one decade so that two labels show."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    axis = ax.xaxis if which == "x" else ax.yaxis
    (ax.set_xscale if which == "x" else ax.set_yscale)("log")
    lo, hi = (ax.get_xlim() if which == "x" else ax.get_ylim())
    if hi / lo < 10.0:
        mid = math.sqrt(lo * hi)
        (ax.set_xlim if which == "x" else ax.set_ylim)(mid / 3.5, mid * 3.5)
    axis.set_major_locator(LogLocator(base=10.0, numticks=8))
    axis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    lo, hi = (ax.get_xlim() if which == "x" else ax.get_ylim())
    if hi / lo < 100.0:                        # under two decades: also label 2 and 5 of each decade
        def two_five(v, _):
            mantissa = v / 10.0 ** math.floor(math.log10(v)) if v > 0 else 0.0
            return f"{v:g}" if any(abs(mantissa - m) < 1e-6 for m in (2.0, 5.0)) else ""
        axis.set_minor_formatter(FuncFormatter(two_five))
    else:
        axis.set_minor_formatter(NullFormatter())


def fmt(value, digits: int = 4) -> str:
    """A number to ``digits`` significant figures ("–" for None/NaN); other values as str."""
    if value is None:
        return "–"
    if isinstance(value, bool):
        return str(value)
    if isinstance(value, (int, float)) or hasattr(value, "dtype"):
        x = float(value)
        if math.isnan(x):
            return "–"
        if math.isinf(x):
            return "∞" if x > 0 else "−∞"
        if x == int(x) and abs(x) < 1e15 and not isinstance(value, float):
            return str(int(x))
        return f"{x:.{digits}g}"
    return str(value)


def fmt_sig(value, digits: int = 4) -> str:
    """Like :func:`fmt`, but a float keeps its ``digits`` significant figures, trailing
    zeros included ("11.0", "2.00", "0.9963"): an estimate and its interval then read with
    the same precision."""
    if value is None or isinstance(value, bool) or not isinstance(value, (int, float)) and not hasattr(value, "dtype"):
        return fmt(value, digits)
    x = float(value)
    floating = isinstance(value, float) or "float" in str(getattr(value, "dtype", ""))
    if not math.isfinite(x) or (x == int(x) and not floating):
        return fmt(value, digits)
    text = f"{x:#.{digits}g}"
    mantissa, e, exponent = text.partition("e")
    return mantissa.rstrip(".") + e + exponent


def interval(mean, lo, hi, digits: int = 3, unit: str = "") -> str:
    """``"4.39 [4.16, 4.59] µm"``: an estimate with its interval, each to ``digits``
    significant figures ("10.8 [10.5, 11.0]", not "10.8 [10.5, 11]")."""
    tail = f" {unit}" if unit else ""
    return f"{fmt_sig(mean, digits)} [{fmt_sig(lo, digits)}, {fmt_sig(hi, digits)}]{tail}"


def table_from_frame(frame, *, title: str, sources: tuple[str, ...], caption: str = "",
                     max_rows: int = 60, digits: int = 4, marks: tuple[str, ...] = ()) -> Table:
    """A :class:`Table` from a pandas DataFrame (at most ``max_rows`` rows, noted if cut);
    ``marks``: one CSS class a row of the frame, as :class:`Table`'s."""
    rows = tuple(tuple(fmt(v, digits) for v in row) for row in frame.head(max_rows).itertuples(index=False))
    if len(frame) > max_rows:
        caption = (caption + " " if caption else "") + f"First {max_rows} of {len(frame)} rows."
    return Table(title=title, columns=tuple(str(c) for c in frame.columns), rows=rows,
                 sources=sources, caption=caption, marks=tuple(marks[:len(rows)]) if any(marks) else ())
