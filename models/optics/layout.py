"""Camera layout of an element array: each element's region and its four feeler centres.

A layout file is TOML::

    [layout]
    name = "sensor-16"
    width_px = 640            # frame width (px)
    height_px = 480           # frame height (px)
    window_px = 24            # half-size of the square window measured around each feeler (px)

    [[element]]               # one table per element, in array order
    region = [0, 0, 160, 120] # x0, y0, w, h (px): columns x0..x0+w-1, rows y0..y0+h-1
    feelers = [[110, 85], [110, 35], [50, 85], [50, 35]]   # (column, row) centres (px)

Image columns grow with the sensor's +x and rows with +z, so the feeler order of
:mod:`.law` — (+x+z, +x−z, −x+z, −x−z) — is (right-bottom, right-top, left-bottom,
left-top). Each feeler's window (centre ± ``window_px``) must lie inside its element's
region; regions must lie inside the frame and must not overlap.
"""
from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from feeler.errors import DataFileError, SceneError

__all__ = ["Element", "Layout", "load_layout", "grid_layout", "layout_toml"]


@dataclass(frozen=True)
class Element:
    """One element: ``region`` (x0, y0, w, h) px and ``feelers`` 4 × (column, row) px."""

    region: tuple[int, int, int, int]
    feelers: tuple[tuple[float, float], ...]


@dataclass(frozen=True)
class Layout:
    """The frame size and the elements seen by the camera.

    Attributes:
        width_px, height_px (int): frame size (px).
        window_px (int): half-size of each feeler's square measuring window (px).
        elements (tuple[Element]): the elements, in array order.
        name (str): a label.
    """

    width_px: int
    height_px: int
    window_px: int
    elements: tuple[Element, ...]
    name: str = ""

    @property
    def centres_px(self) -> np.ndarray:
        """Feeler centres (n_elements, 4, 2) as (column, row) px."""
        return np.array([e.feelers for e in self.elements], dtype=float)

    def check(self, path: object = "<layout>") -> None:
        """Raise :class:`SceneError` naming ``path`` and the key for an impossible layout."""
        w = self.window_px
        if not self.elements:
            raise SceneError(path, "element", "needs at least one element")
        boxes = []
        for i, el in enumerate(self.elements):
            x0, y0, bw, bh = el.region
            key = f"element[{i}].region"
            if bw <= 0 or bh <= 0:
                raise SceneError(path, key, f"{list(el.region)}: width and height must be > 0")
            if x0 < 0 or y0 < 0 or x0 + bw > self.width_px or y0 + bh > self.height_px:
                raise SceneError(path, key, f"{list(el.region)} leaves the "
                                 f"{self.width_px}×{self.height_px} frame")
            for j, box in enumerate(boxes):
                if x0 < box[0] + box[2] and box[0] < x0 + bw and y0 < box[1] + box[3] and box[1] < y0 + bh:
                    raise SceneError(path, key, f"{list(el.region)} overlaps element[{j}] {list(box)}")
            boxes.append(el.region)
            if len(el.feelers) != 4:
                raise SceneError(path, f"element[{i}].feelers", f"needs 4 centres, got {len(el.feelers)}")
            for k, (cx, cy) in enumerate(el.feelers):
                if not (x0 + w <= cx <= x0 + bw - 1 - w and y0 + w <= cy <= y0 + bh - 1 - w):
                    raise SceneError(path, f"element[{i}].feelers[{k}]",
                                     f"({cx}, {cy}) ± window {w} px is not inside region {list(el.region)}")
            c = np.array(el.feelers, float)
            gap = np.abs(c[:, None, :] - c[None, :, :]).max(axis=-1) + np.eye(4) * 1e9
            if gap.min() < 2 * w + 1:
                raise SceneError(path, f"element[{i}].feelers",
                                 f"feeler windows (±{w} px) overlap; centres must be ≥ {2 * w + 1} px apart")
            if not (c[0, 0] > c[2, 0] and c[1, 0] > c[3, 0] and c[0, 1] > c[1, 1] and c[2, 1] > c[3, 1]):
                raise SceneError(path, f"element[{i}].feelers",
                                 "order must be (+x+z, +x−z, −x+z, −x−z): right-bottom, right-top, "
                                 "left-bottom, left-top")


def load_layout(path: str | Path) -> Layout:
    """Read and validate a layout TOML file.

    Raises:
        DataFileError: missing or unreadable file, not TOML.
        SceneError: a missing or mistyped key, or an impossible geometry (naming the key).
    """
    path = Path(path)
    try:
        raw = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise DataFileError(path, "no such layout file") from None
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise DataFileError(path, f"not a readable TOML layout: {exc}") from None
    head = raw.get("layout")
    if not isinstance(head, dict):
        raise SceneError(path, "layout", "missing [layout] table (width_px, height_px, window_px)")
    dims = [_int(head, key, path, "layout.") for key in ("width_px", "height_px", "window_px")]
    if dims[0] <= 0 or dims[1] <= 0 or dims[2] < 1:
        raise SceneError(path, "layout", f"sizes {dims} must be > 0")
    tables = raw.get("element")
    if not isinstance(tables, list):
        raise SceneError(path, "element", "missing [[element]] tables")
    elements = []
    for i, tab in enumerate(tables):
        region = _numbers(tab.get("region"), 4, path, f"element[{i}].region", integer=True)
        feelers = tab.get("feelers")
        if not isinstance(feelers, list):
            raise SceneError(path, f"element[{i}].feelers", "must be a list of [column, row] pairs")
        centres = tuple(_numbers(c, 2, path, f"element[{i}].feelers[{k}]") for k, c in enumerate(feelers))
        elements.append(Element(region=region, feelers=centres))
    layout = Layout(*dims, elements=tuple(elements), name=str(head.get("name", path.stem)))
    layout.check(path)
    return layout


def grid_layout(rows: int = 4, cols: int = 4, *, width_px: int = 640, height_px: int = 480,
                window_px: int = 24, offset_px: tuple[int, int] = (48, 35)) -> Layout:
    """A regular grid of ``rows × cols`` elements filling the frame; feelers at the centre
    of each region ± ``offset_px`` (columns, rows)."""
    bw, bh = width_px // cols, height_px // rows
    elements = []
    for r in range(rows):
        for c in range(cols):
            cx, cy = c * bw + (bw - 1) / 2, r * bh + (bh - 1) / 2
            dx, dy = offset_px
            feelers = ((cx + dx, cy + dy), (cx + dx, cy - dy), (cx - dx, cy + dy), (cx - dx, cy - dy))
            elements.append(Element(region=(c * bw, r * bh, bw, bh), feelers=feelers))
    layout = Layout(width_px, height_px, window_px, tuple(elements), name=f"grid-{rows}x{cols}")
    layout.check("grid_layout")
    return layout


def layout_toml(layout: Layout) -> str:
    """The TOML text of ``layout`` (what :func:`load_layout` reads back)."""
    def num(v):
        return str(int(v)) if float(v).is_integer() else repr(float(v))
    lines = ["[layout]", f'name = "{layout.name}"', f"width_px = {layout.width_px}",
             f"height_px = {layout.height_px}", f"window_px = {layout.window_px}"]
    for el in layout.elements:
        feelers = ", ".join(f"[{num(cx)}, {num(cy)}]" for cx, cy in el.feelers)
        lines += ["", "[[element]]", f"region = [{', '.join(map(str, el.region))}]",
                  f"feelers = [{feelers}]"]
    return "\n".join(lines) + "\n"


def _int(table: dict, key: str, path, prefix: str) -> int:
    value = table.get(key)
    if not isinstance(value, int) or isinstance(value, bool):
        raise SceneError(path, prefix + key, f"must be an integer, got {value!r}")
    return value


def _numbers(value, n: int, path, key: str, integer: bool = False) -> tuple:
    kinds = (int,) if integer else (int, float)
    if (not isinstance(value, list) or len(value) != n
            or not all(isinstance(v, kinds) and not isinstance(v, bool) for v in value)):
        what = "integers" if integer else "numbers"
        raise SceneError(path, key, f"must be a list of {n} {what}, got {value!r}")
    return tuple(value) if integer else tuple(float(v) for v in value)
