"""A finger-steps part read once for the report: the strain histories and Figs 4–6 numbers.

``strain.csv`` (step_um, speed_mm_s, t_s, x_mm, eps_y; one history per step and speed,
in file order) and ``scene.toml`` (the neuron, τ sweep, loading and skin level) give
:class:`feeler.skin.figures.FigureData` exactly as ``feeler skin figures`` computes it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["FingerData", "finger_data", "runs_from_table"]

COLUMNS = ("step_um", "speed_mm_s", "t_s", "x_mm", "eps_y")


@dataclass(frozen=True)
class FingerData:
    """Attributes: part; scene (finger-steps scene); runs (list of FingerRun, heights
    outer); figures (FigureData); level ("l0", "l1", "l2"); sources (run-relative)."""
    part: object
    scene: object
    runs: list
    figures: object
    level: str
    sources: tuple


def runs_from_table(frame) -> list:
    """FingerRun per (step, speed) of a strain table; the slide starts at the last sample
    before the travel x begins to grow."""
    from feeler.simulate.finger import FingerRun

    runs = []
    for (step, speed), g in frame.groupby(["step_um", "speed_mm_s"], sort=True):
        t, x, eps = (g[c].to_numpy(float) for c in ("t_s", "x_mm", "eps_y"))
        order = np.argsort(t, kind="stable")
        t, x, eps = t[order], x[order], eps[order]
        moving = np.flatnonzero(x > x[0])
        start = max(int(moving[0]) - 1, 0) if moving.size else 0
        runs.append(FingerRun(float(step), float(speed), t, x, eps, start))
    return runs


def _load(inv, part) -> FingerData:
    from feeler.errors import DataFileError
    from feeler.reports.readers import read_table
    from feeler.scene import load_scene
    from feeler.skin.figures import figure_data

    rel_csv, rel_scene = part.path("strain.csv"), part.path("scene.toml")
    if not (inv.run_dir / rel_scene).is_file():
        raise DataFileError(inv.run_dir / rel_scene, "missing; the finger's strain histories need their scene "
                                                     "(neuron, τ sweep, loading)")
    frame = read_table(inv.run_dir / rel_csv, COLUMNS, COLUMNS)
    scene = load_scene(inv.run_dir / rel_scene)
    if not hasattr(scene, "skin"):
        raise DataFileError(inv.run_dir / rel_scene, f"scene kind {scene.scene.kind!r}; strain.csv needs a "
                                                     "finger-steps scene")
    runs = runs_from_table(frame)
    grid = {(r.step_um, r.speed_mm_s) for r in runs}
    heights, speeds = {h for h, _ in grid}, {v for _, v in grid}
    if len(heights) < 2 or len(grid) != len(heights) * len(speeds) or any(np.any(np.diff(r.t_s) <= 0)
                                                                          for r in runs):
        raise DataFileError(inv.run_dir / rel_csv, "needs every step height at every speed (at least two "
                                                   "heights), each history with strictly increasing t_s")
    figures = figure_data(runs, scene.neuron, scene.loading.press_s)
    return FingerData(part=part, scene=scene, runs=runs, figures=figures, level=scene.model.level,
                      sources=(rel_csv, rel_scene))


def finger_data(inv) -> FingerData | None:
    """The run's finger strain histories (the first strain.csv found), read once."""
    part = inv.first("finger", prefer="finger")
    return None if part is None else inv.cached("finger", lambda: _load(inv, part))
