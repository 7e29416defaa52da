"""Synthetic inputs for M2 checks: robot-scan covariates and labels simulated from the model.

The scans carry no true (a, τ, h) — the neuron is a decoder — so recovery tests and SBC
keep real (simulated) scans as covariates and draw the labels from the model itself.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from feeler.calib.neuron.fit import NeuronData, data_from_scans
from feeler.calib.neuron.model import PeakTable, mean_mm

__all__ = ["Truth", "simulate_labels", "scene_scans", "FOUR_PLATES"]

FOUR_PLATES = Path(__file__).resolve().parents[2] / "datasets-synthetic" / "four-plates.toml"


@dataclass(frozen=True)
class Truth:
    """True M2 parameters: a (mm/strain), tau_s (s), h (mm), sigma_mm (mm)."""
    a: float
    tau_s: float
    h: float
    sigma_mm: float


def simulate_labels(table: PeakTable, truth: Truth, rng: np.random.Generator) -> np.ndarray:
    """δ_k = max(a·P_k(τ) − h, 0) + σ·N(0, 1) for every scan of ``table`` (ndarray[n_scans], mm)."""
    mu = mean_mm(table, truth.a, truth.tau_s, truth.h)
    return mu + truth.sigma_mm * rng.standard_normal(mu.shape)


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
    scans, _ = simulate_scans(scene)
    nrn = scene.neuron
    data: NeuronData = data_from_scans(scans, length_mm=nrn.length_mm, kernel=nrn.kernel)
    return scene, scans, data
