"""Frames → contact area of every conical feeler (threshold, connected components, sub-pixel).

For one grey frame:

1. levels: the background is the mean of the pixels outside every feeler window; the
   threshold is Otsu's (or halfway between given levels);
2. ``cv2.connectedComponentsWithStats`` on the thresholded frame; each component is
   assigned to the feeler window holding its centroid;
3. the peak level is the mean of the disc interiors (the mask eroded by the blur reach),
   pooled over the whole frame;
4. a feeler's area is Σ (I − background) / (peak − background) over its components
   dilated by the blur reach — the blur conserves the integrated light, so this sum
   recovers the sub-pixel area of the disc, tails included.

The frame is rejected (a reason returned, never silently used) when a bright blob lies
outside the feeler windows, a window holds two blobs or a bright window holds none, a
disc reaches its window's edge, a window is saturated, or no disc interior is left to
measure the peak level.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from feeler.models.optics import Layout

__all__ = ["AreaExtractor"]

_SPECK_PX = 8  # components smaller than this are shot-noise specks, ignored
_DARK_PX2 = 5.0  # a window without a disc must integrate to less than this (px²)


@dataclass(frozen=True)
class _Windows:
    rows: np.ndarray  # (n_feelers, P, 1) row index of each window pixel
    cols: np.ndarray  # (n_feelers, 1, P)
    owner: np.ndarray  # (H, W) int32: feeler number of each pixel, -1 outside windows
    outside: np.ndarray  # (H, W) uint8 mask of pixels outside every window


class AreaExtractor:
    """Measure the feelers' contact areas in frames of one layout.

    Args:
        layout (Layout): frame size, elements and feeler centres.
        blur_sd_px (float): the optics' blur (px); sets how far light spreads past a disc.
        levels (tuple[float, float] | None): (background, peak) grey levels when known
            from a flat-field calibration; ``None`` estimates both in every frame.
    """

    def __init__(self, layout: Layout, *, blur_sd_px: float = 1.2,
                 levels: tuple[float, float] | None = None):
        self.layout, self.levels = layout, levels
        self.reach_px = int(np.ceil(4.0 * blur_sd_px)) + 1
        self.erode_px = int(np.ceil(3.0 * blur_sd_px))
        self._w = _make_windows(layout)
        self._dilate = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * self.reach_px + 1,) * 2)
        self._erode = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * self.erode_px + 1,) * 2)

    def __call__(self, frame: np.ndarray) -> tuple[np.ndarray, str | None]:
        """Areas (n_elements, 4) px² of one grey frame, and ``None`` or the reason to reject it."""
        n_el = len(self.layout.elements)
        nan = np.full((n_el, 4), np.nan)
        win = self._w
        if self.levels is None:
            background = cv2.mean(frame, mask=win.outside)[0]
            _, binary = cv2.threshold(frame, 0, 255, cv2.THRESH_BINARY | cv2.THRESH_OTSU)
        else:
            background = self.levels[0]
            _, binary = cv2.threshold(frame, 0.5 * (self.levels[0] + self.levels[1]), 255,
                                      cv2.THRESH_BINARY)
        n_comp, labels, stats, centroids = cv2.connectedComponentsWithStats(binary, connectivity=8)
        owner = win.owner[np.rint(centroids[1:, 1]).astype(int), np.rint(centroids[1:, 0]).astype(int)]
        big = stats[1:, cv2.CC_STAT_AREA] >= _SPECK_PX
        if np.any(big & (owner < 0)):
            return nan, "a bright blob outside the feeler windows"
        counts = np.bincount(owner[big & (owner >= 0)], minlength=4 * n_el)
        if counts.max(initial=0) > 1:
            e, k = divmod(int(np.argmax(counts)), 4)
            return nan, f"{counts.max()} blobs in the window of element {e} feeler {k}"
        if self.levels is None:
            interior = cv2.erode(binary, self._erode)
            if not interior.any():
                return nan, "no disc interior left to measure the peak level"
            peak = cv2.mean(frame, mask=interior)[0]
        else:
            peak = self.levels[1]
        reach = cv2.dilate(binary, self._dilate)
        stack = frame[win.rows, win.cols].astype(np.float32) - np.float32(background)
        mask = reach[win.rows, win.cols] > 0
        if np.any(mask[:, 0, :] | mask[:, -1, :] | mask[:, :, 0] | mask[:, :, -1]):
            return nan, "a disc reaches the edge of its feeler window"
        if np.any(frame[win.rows, win.cols] == 255):
            return nan, "saturated pixels in a feeler window"
        areas = np.where(mask, stack, 0.0).sum(axis=(1, 2)) / (peak - background)
        empty = counts == 0
        if np.any(empty):
            dark = stack[empty].sum(axis=(1, 2)) / (peak - background) < _DARK_PX2
            if not np.all(dark):
                e, k = divmod(int(np.flatnonzero(empty)[np.argmin(dark)]), 4)
                return nan, f"no disc found in the bright window of element {e} feeler {k}"
            areas[empty] = 0.0
        return areas.reshape(n_el, 4), None


def _make_windows(layout: Layout) -> _Windows:
    w = layout.window_px
    centres = np.rint(layout.centres_px.reshape(-1, 2)).astype(int)
    offsets = np.arange(-w, w + 1)
    rows = (centres[:, 1, None] + offsets)[:, :, None]
    cols = (centres[:, 0, None] + offsets)[:, None, :]
    owner = np.full((layout.height_px, layout.width_px), -1, dtype=np.int32)
    for i, (cx, cy) in enumerate(centres):
        owner[cy - w: cy + w + 1, cx - w: cx + w + 1] = i
    outside = (owner < 0).astype(np.uint8)
    return _Windows(rows=rows, cols=cols, owner=owner, outside=outside)
