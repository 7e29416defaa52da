"""Layout checks of a drawn matplotlib figure: what a reader would see as broken.

:func:`check_figure` returns one line per problem (an empty tuple when there is none):

- two pieces of text overlap (tick labels, axis labels, titles, legend entries,
  annotations; measured as rendered, with matplotlib's text extents);
- a piece of text is cut at the figure's edge;
- a text placed in a panel (an annotation, a count beside a point) crosses the panel's
  frame: partly inside, partly outside;
- a legend covers plotted data (a vertex of a data line or marker, lines resampled so
  that a long straight segment counts too);
- a visible panel holds nothing;
- a line drawn against time (x label "t (s)" or "time (s)") goes back in time.

The figure must have been drawn (``fig.canvas.draw()``) at the size it is shown.
"""
from __future__ import annotations

import re

import numpy as np

__all__ = ["check_figure", "TIME_LABEL"]

#: x labels that mean "this axis is time": lines on such axes must have increasing x
TIME_LABEL = re.compile(r"^\s*(t|time)\b.*\(\s*s\s*\)", re.IGNORECASE)
_TOL_PX = 0.5              # overlaps and cuts smaller than this are rounding


def _texts(fig, renderer) -> list[tuple[str, object]]:
    """(text, bbox in display pixels) of every visible, non-empty text of ``fig``."""
    artists = list(fig.texts)
    if getattr(fig, "_suptitle", None) is not None:
        artists.append(fig._suptitle)
    for legend in list(fig.legends) + [ax.get_legend() for ax in fig.axes]:
        if legend is not None and legend.get_visible():
            artists += list(legend.get_texts()) + [legend.get_title()]
    for ax in fig.axes:
        if not ax.get_visible():
            continue
        artists += [ax.title, ax._left_title, ax._right_title, *ax.texts]
        if ax.axison:
            for axis in (ax.xaxis, ax.yaxis):
                artists += [axis.label, axis.get_offset_text()]
                for tick in axis._update_ticks():           # the ticks actually drawn
                    artists += [tick.label1, tick.label2]
    found, seen = [], set()
    for t in artists:
        if id(t) in seen:
            continue
        seen.add(id(t))
        if t is None or not t.get_visible() or not t.get_text().strip():
            continue
        found.append((t.get_text().strip(), t.get_window_extent(renderer)))
    return found


def _overlap(a, b) -> bool:
    w = min(a.x1, b.x1) - max(a.x0, b.x0)
    h = min(a.y1, b.y1) - max(a.y0, b.y0)
    return w > _TOL_PX and h > _TOL_PX


def _text_problems(fig, renderer) -> list[str]:
    texts = _texts(fig, renderer)
    box = fig.bbox
    problems = []
    for text, bb in texts:
        if bb.x0 < box.x0 - _TOL_PX or bb.y0 < box.y0 - _TOL_PX or bb.x1 > box.x1 + _TOL_PX or bb.y1 > box.y1 + _TOL_PX:
            problems.append(f"text {text!r} is cut at the figure's edge")
    for i, (ta, a) in enumerate(texts):
        for tb, b in texts[i + 1:]:
            if _overlap(a, b):
                problems.append(f"texts {ta!r} and {tb!r} overlap")
    return problems


def _frame_problems(ax, renderer) -> list[str]:
    """Texts of the panel ``ax`` that lie partly inside and partly outside its frame (a
    text wholly outside it, such as a note beside the panel, is placed there on purpose)."""
    frame = ax.get_window_extent(renderer)
    problems = []
    for t in ax.texts:
        if not t.get_visible() or not t.get_text().strip():
            continue
        bb = t.get_window_extent(renderer)
        within = (bb.x0 >= frame.x0 - _TOL_PX and bb.y0 >= frame.y0 - _TOL_PX and bb.x1 <= frame.x1 + _TOL_PX
                  and bb.y1 <= frame.y1 + _TOL_PX)
        if _overlap(bb, frame) and not within:
            problems.append(f"panel {_name(ax)}: text {t.get_text().strip()!r} crosses its frame")
    return problems


def _data_lines(ax):
    """Lines drawn in data coordinates (reference lines such as axhline are exempt)."""
    return [ln for ln in ax.lines if ln.get_visible() and ln.get_transform().contains_branch(ax.transData)
            and len(ln.get_xydata()) > 0]


def _resampled(xy: np.ndarray, n: int = 400) -> np.ndarray:
    """Display-space vertices of a polyline, with points added along long segments."""
    xy = xy[np.all(np.isfinite(xy), axis=1)]
    if len(xy) < 2 or len(xy) >= n:
        return xy
    seg = np.linspace(0.0, 1.0, max(2, n // (len(xy) - 1)), endpoint=False)
    pts = [a + (b - a) * s for a, b in zip(xy[:-1], xy[1:]) for s in seg]
    return np.vstack([pts, xy[-1:]])


def _legend_problems(ax, renderer) -> list[str]:
    legend = ax.get_legend()
    if legend is None or not legend.get_visible():
        return []
    bb = legend.get_window_extent(renderer).padded(-1.0)
    inside = 0
    for line in _data_lines(ax):
        xy = line.get_transform().transform(line.get_xydata())
        if line.get_linestyle() not in ("None", "", " ", "none"):
            xy = _resampled(xy)
        inside += int(np.sum((xy[:, 0] > bb.x0) & (xy[:, 0] < bb.x1) & (xy[:, 1] > bb.y0) & (xy[:, 1] < bb.y1)))
    for coll in ax.collections:
        offsets = np.asarray(coll.get_offsets())
        if type(coll).__name__ != "PathCollection" or offsets.size == 0:
            continue
        xy = coll.get_offset_transform().transform(offsets)
        inside += int(np.sum((xy[:, 0] > bb.x0) & (xy[:, 0] < bb.x1) & (xy[:, 1] > bb.y0) & (xy[:, 1] < bb.y1)))
    return [f"panel {_name(ax)}: the legend covers {inside} plotted point(s)"] if inside else []


def _name(ax) -> str:
    return repr(ax.get_title() or ax.get_ylabel() or "untitled")


def _empty(ax) -> bool:
    drawn = [*ax.lines, *ax.collections, *ax.images, *ax.patches, *ax.texts, *ax.tables]
    return not any(a.get_visible() for a in drawn)


def _time_problems(ax) -> list[str]:
    if not TIME_LABEL.match(ax.get_xlabel() or ""):
        return []
    problems = []
    for line in _data_lines(ax):
        x = np.asarray(line.get_xydata()[:, 0], float)
        x = x[np.isfinite(x)]
        back = np.flatnonzero(np.diff(x) <= 0)
        if back.size:
            problems.append(f"panel {_name(ax)}: line {line.get_label()!r} does not increase in time "
                            f"(point {int(back[0]) + 1} of {x.size})")
    return problems


def check_figure(fig) -> tuple[str, ...]:
    """Layout problems of the drawn figure ``fig``, one line each (empty when none)."""
    renderer = fig.canvas.get_renderer()
    problems = _text_problems(fig, renderer)
    for ax in fig.axes:
        if not ax.get_visible():
            continue
        if ax.axison and _empty(ax):
            problems.append(f"panel {_name(ax)} is empty")
        problems += _frame_problems(ax, renderer)
        problems += _legend_problems(ax, renderer)
        problems += _time_problems(ax)
    return tuple(dict.fromkeys(problems))
