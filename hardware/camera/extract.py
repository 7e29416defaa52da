"""Frames → contact area of every conical feeler (threshold, connected components, sub-pixel).

For one grey frame:

1. levels: the background is the mean of the pixels outside every feeler window; the
   threshold is Otsu's (or halfway between given levels);
2. the connected components of the thresholded frame (their outer contours,
   ``cv2.findContours``) are assigned to the feeler window holding their centre;
3. the peak level is the mean of the disc interiors, pooled over the whole frame: the
   pixels at least ``4σ + ½`` px (exact Euclidean distance: the mask eroded by the disc of
   that radius, the same pixels as ``cv2.distanceTransform``'s precise mask at a quarter
   of its cost) inside the mask (about 4σ inside the disc's edge), where the blurred disc is within
   3·10⁻⁵ of its peak (no measurable bias). At blur σ = 1.2 px a frame whose discs are
   all below about 95 px² has no such pixel (measured; the optics' rest area is 150 px²);
4. a feeler's area is Σ (I − background) / (peak − background) over its window's
   components dilated by the blur's reach ⌈3σ⌉ + 1 px — the blur conserves the integrated
   light, so this sum recovers the sub-pixel area of the disc, tails included. The sums
   come from integral images, so every window costs four look-ups.

The frame is rejected (a reason returned, never silently used) when a bright blob lies
outside the feeler windows, a window holds two blobs or a bright window holds none, a
disc reaches its window's edge, a window is saturated, or no disc interior is left to
measure the peak level.
"""
from __future__ import annotations

import threading

import cv2
import numpy as np

from feeler.models.optics import Layout

__all__ = ["AreaExtractor"]

_SPECK_PX = 9  # blobs whose bounding box holds fewer pixels are shot-noise specks, ignored
_DARK_PX2 = 5.0  # a window without a disc must integrate to less than this (px²)
#: depth inside a disc's edge, in blur σ, of the pixels that measure the peak level: a
#: straight edge blurred by σ leaves 1 − Φ(4) = 3·10⁻⁵ of the contrast missing there
_INTERIOR_DEPTH_SD = 4.0


class AreaExtractor:
    """Measure the feelers' contact areas in frames of one layout.

    Args:
        layout (Layout): frame size, elements and feeler centres.
        blur_sd_px (float): the optics' blur (px); sets how far light spreads past a disc.
        levels (tuple[float, float] | None): (background, peak) grey levels when known
            from a flat-field calibration; ``None`` estimates both in every frame.

    Calling it on a grey frame (H, W) uint8 returns ``(areas (n_elements, 4) px², None)``
    or ``(NaN areas, reason)``.
    """

    def __init__(self, layout: Layout, *, blur_sd_px: float = 1.2,
                 levels: tuple[float, float] | None = None):
        self.layout, self.levels = layout, levels
        reach = int(np.ceil(3.0 * blur_sd_px)) + 1
        self._dilate = cv2.getStructuringElement(cv2.MORPH_RECT, (2 * reach + 1,) * 2)
        self._depth_px = _INTERIOR_DEPTH_SD * blur_sd_px + 0.5  # + ½: pixel centre to mask edge
        # the offsets closer than the depth: a pixel survives erosion by this disc exactly
        # when no pixel off the mask lies nearer than the depth (its distance transform ≥ depth)
        k = int(np.ceil(self._depth_px))
        dy, dx = np.mgrid[-k:k + 1, -k:k + 1]
        self._interior_disc = ((dx * dx + dy * dy) < self._depth_px ** 2).astype(np.uint8)
        w = layout.window_px
        centres = np.rint(layout.centres_px.reshape(-1, 2)).astype(int)
        self._x0, self._y0 = centres[:, 0] - w, centres[:, 1] - w
        self._size = 2 * w + 1
        self._owner = np.full((layout.height_px, layout.width_px), -1, dtype=np.int32)
        for i, (x0, y0) in enumerate(zip(self._x0, self._y0)):
            self._owner[y0: y0 + self._size, x0: x0 + self._size] = i
        self._outside = np.where(self._owner < 0, 255, 0).astype(np.uint8)
        self._n_outside = int(np.count_nonzero(self._outside))
        self._local = threading.local()

    def _buffers(self) -> dict[str, np.ndarray]:
        """This thread's work images, allocated once: a fresh 2.5 MB float64 integral per
        call averaged 0.77 ms inside a frame's work (profiled; 0.13 ms timed alone), and
        with reused int32 tables a frame went from 3.2 to 1.25 ms (median, same areas)."""
        buf = getattr(self._local, "buffers", None)
        if buf is None:
            shape = (self.layout.height_px, self.layout.width_px)
            buf = {k: np.empty(shape, np.uint8) for k in ("binary", "interior", "reach", "light")}
            buf["table"] = np.empty((shape[0] + 1, shape[1] + 1), np.int32)
            self._local.buffers = buf
        return buf

    def __call__(self, frame: np.ndarray) -> tuple[np.ndarray, str | None]:
        n_feelers = 4 * len(self.layout.elements)
        nan = np.full((n_feelers // 4, 4), np.nan)
        buf = self._buffers()          # OpenCV writes into them (and returns them) when the frame has their shape
        if self.levels is None:
            background = _masked_mean(frame, self._outside, self._n_outside, buf["light"])
            _, binary = cv2.threshold(frame, 0, 255, cv2.THRESH_BINARY | cv2.THRESH_OTSU, dst=buf["binary"])
        else:
            background = float(self.levels[0])
            _, binary = cv2.threshold(frame, 0.5 * (self.levels[0] + self.levels[1]), 255, cv2.THRESH_BINARY,
                                      dst=buf["binary"])
        contours, _ = cv2.findContours(binary, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        boxes = np.array([cv2.boundingRect(c) for c in contours], dtype=int).reshape(-1, 4)
        boxes = boxes[boxes[:, 2] * boxes[:, 3] >= _SPECK_PX]
        owner = self._owner[boxes[:, 1] + boxes[:, 3] // 2, boxes[:, 0] + boxes[:, 2] // 2]
        if np.any(owner < 0):
            return nan, "a bright blob outside the feeler windows"
        counts = np.bincount(owner, minlength=n_feelers)
        if counts.max(initial=0) > 1:
            e, k = divmod(int(np.argmax(counts)), 4)
            return nan, f"{counts.max()} blobs in the window of element {e} feeler {k}"
        if frame.max() == 255 and self._window_sums(frame == 255, buf["table"]).any():
            return nan, "saturated pixels in a feeler window"
        if self.levels is None:
            interior = cv2.erode(binary, self._interior_disc, dst=buf["interior"])
            n_interior = cv2.countNonZero(interior)
            if not n_interior:
                return nan, "no disc interior left to measure the peak level"
            peak = _masked_mean(frame, interior, n_interior, buf["light"])
        else:
            peak = float(self.levels[1])
        reach = cv2.dilate(binary, self._dilate, dst=buf["reach"])
        table = _integral(reach, buf["table"])
        n_mask = self._table_sums(table) // 255
        if np.any(n_mask != self._table_sums(table, inset=1) // 255):
            return nan, "a disc reaches the edge of its feeler window"
        light = (self._window_sums(cv2.bitwise_and(frame, reach, dst=buf["light"]), buf["table"])
                 - background * n_mask)
        areas = light / (peak - background)
        empty = np.flatnonzero(counts == 0)
        if empty.size:
            dark = self._window_sums(frame, buf["table"])[empty] - background * self._size ** 2
            if np.any(dark / (peak - background) >= _DARK_PX2):
                e, k = divmod(int(empty[np.argmax(dark)]), 4)
                return nan, f"no disc found in the bright window of element {e} feeler {k}"
            areas[empty] = 0.0
        return areas.reshape(-1, 4), None

    def _window_sums(self, image: np.ndarray, table: np.ndarray | None = None, inset: int = 0) -> np.ndarray:
        """Σ of ``image`` over every feeler window shrunk by ``inset`` px (n_feelers,);
        ``table`` an int32 (H + 1, W + 1) work array for its integral (None: a new one)."""
        return self._table_sums(_integral(image, table), inset)

    def _table_sums(self, table: np.ndarray, inset: int = 0) -> np.ndarray:
        """:meth:`_window_sums` from the image's integral ``table`` (one table, many insets)."""
        x0, y0 = self._x0 + inset, self._y0 + inset
        x1, y1 = x0 + self._size - 2 * inset, y0 + self._size - 2 * inset
        return table[y1, x1] - table[y0, x1] - table[y1, x0] + table[y0, x0]


def _integral(image: np.ndarray, table: np.ndarray | None = None) -> np.ndarray:
    """Integral image of a uint8 (or bool) image in int32, into ``table`` when given: exact,
    since 255 × 2²³ px still fits (a 640×480 frame sums to at most 7.9·10⁷)."""
    image = image.view(np.uint8)
    if image.size * 255 >= 2 ** 31:
        return cv2.integral(image, sdepth=cv2.CV_64F)
    if table is None:
        return cv2.integral(image, sdepth=cv2.CV_32S)
    return cv2.integral(image, table, sdepth=cv2.CV_32S)


def _masked_mean(frame: np.ndarray, mask: np.ndarray, n: int, work: np.ndarray | None = None) -> float:
    """Mean of ``frame`` over the ``n`` pixels where the 0/255 ``mask`` is set (a masked
    ``cv2.mean`` took 0.3–0.4 ms on the extractor's masks of a 640×480 frame, this ~0.02 ms);
    ``work`` a uint8 image of the frame's shape to hold the masked frame."""
    return cv2.sumElems(cv2.bitwise_and(frame, mask, dst=work))[0] / n if n else 0.0
