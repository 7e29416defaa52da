"""What a report is made of: sections of figures, tables and notes, each naming its sources.

Every block carries ``sources``: the run-relative paths of the files its numbers come
from, shown beside it in the report (DESIGN §7: every number traceable to a file of the
run). Figures are PNG data URIs so the HTML stays self-contained.
"""
from __future__ import annotations

import base64
import io
import math
from dataclasses import dataclass, field

__all__ = ["Figure", "Table", "Note", "Section", "subplots", "figure_uri", "fmt", "table_from_frame"]


@dataclass(frozen=True)
class Figure:
    """One inlined figure: ``uri`` is a ``data:image/png;base64,...`` URI."""
    title: str
    uri: str
    sources: tuple[str, ...]
    caption: str = ""
    kind: str = "figure"


@dataclass(frozen=True)
class Table:
    """A table of already formatted cells (str), one tuple per row."""
    title: str
    columns: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]
    sources: tuple[str, ...]
    caption: str = ""
    kind: str = "table"


@dataclass(frozen=True)
class Note:
    """A paragraph; ``level`` is "info", "synthetic" (data not measured) or "failed"."""
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


def subplots(ncols: int = 1, *, nrows: int = 1, width_in: float = 5.6, height_in: float = 3.4, **kw):
    """``plt.subplots`` on the Agg backend (no display needed); each panel ``width_in`` x
    ``height_in`` inches; returns (fig, axes)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt.subplots(nrows, ncols, figsize=(width_in * ncols, height_in * nrows), **kw)


def figure_uri(fig, *, dpi: int = 90) -> str:
    """Render a matplotlib figure to a PNG data URI and close it."""
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.tight_layout()
    fig.savefig(buf, format="png", dpi=dpi)
    plt.close(fig)
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


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
        if x == int(x) and abs(x) < 1e15 and not isinstance(value, float):
            return str(int(x))
        return f"{x:.{digits}g}"
    return str(value)


def table_from_frame(frame, *, title: str, sources: tuple[str, ...], caption: str = "",
                     max_rows: int = 60, digits: int = 4) -> Table:
    """A :class:`Table` from a pandas DataFrame (at most ``max_rows`` rows, noted if cut)."""
    rows = tuple(tuple(fmt(v, digits) for v in row) for row in frame.head(max_rows).itertuples(index=False))
    if len(frame) > max_rows:
        caption = (caption + " " if caption else "") + f"First {max_rows} of {len(frame)} rows."
    return Table(title=title, columns=tuple(str(c) for c in frame.columns), rows=rows,
                 sources=sources, caption=caption)
