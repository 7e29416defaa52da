"""Synthetic inputs for M2 checks: robot-scan scans, and peaks simulated from the model.

The scans carry no true decoder — the neuron is a decoder — so recovery tests and SBC
keep the real (simulated) design, the plates and their counts, and draw the peak window
sums from the model itself at a fixed window (:func:`simulate_peaks`).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from feeler.calib.neuron.data import NeuronData, data_from_scans
from feeler.calib.neuron.model import PeakTable, Plates

__all__ = ["Truth", "simulate_peaks", "single_window_table", "scene_scans", "FOUR_PLATES", "HARD_SCENES"]

FOUR_PLATES = Path(__file__).resolve().parents[2] / "datasets-synthetic" / "four-plates.toml"
HARD_SCENES = Path(__file__).resolve().parents[2] / "datasets-synthetic" / "hard"


@dataclass(frozen=True)
class Truth:
    """True plate parameters at one window, in units of P: ``mu``, ``sigma`` (ndarray[C])."""
    mu: np.ndarray
    sigma: np.ndarray


def simulate_peaks(plates: Plates, truth: Truth, rng: np.random.Generator) -> np.ndarray:
    """P_k ~ Normal(μ_c, σ_c) for every scan of the design, ndarray[n_scans]."""
    g = plates.group
    return truth.mu[g] + truth.sigma[g] * rng.standard_normal(g.size)


def single_window_table(peaks: np.ndarray, tau_s: float) -> PeakTable:
    """A peak table with two nodes around ``tau_s`` holding the same peaks: the model at a
    known window (the τ weights are then flat and every draw reads these peaks)."""
    p = np.asarray(peaks, float)[:, None]
    return PeakTable(log_tau=np.log(tau_s) + np.array([-1e-6, 1e-6]), peak=np.hstack([p, p]))


def scene_scans(scene_path=FOUR_PLATES, *, seed: int | None = None, per_plate: int | None = None,
                heights_mm: tuple[float, ...] | None = None, speed_mm_s: float | None = None):
    """(scene, Scans, NeuronData) of a robot-scan scene, optionally with another root seed,
    number of scans per plate, plate heights or stage speed (traverse duration follows)."""
    from feeler.scene import load_scene
    from feeler.simulate import simulate_scans

    scene = load_scene(scene_path)
    if seed is not None:
        scene = dataclasses.replace(scene, scene=dataclasses.replace(scene.scene, seed=int(seed)))
    if per_plate is not None:
        scene = dataclasses.replace(scene, repeats=dataclasses.replace(scene.repeats, scans_per_plate=int(per_plate)))
    if heights_mm is not None:
        scene = dataclasses.replace(scene, surface=dataclasses.replace(scene.surface, heights_mm=tuple(heights_mm)))
    if speed_mm_s is not None:
        scene = dataclasses.replace(scene, motion=dataclasses.replace(scene.motion, speed_mm_s=float(speed_mm_s)))
    scans, _ = simulate_scans(scene, scene_path=scene_path, progress=False)   # callers show their own progress
    nrn = scene.neuron
    data: NeuronData = data_from_scans(scans, length_mm=nrn.length_mm, kernel=nrn.kernel)
    return scene, scans, data
