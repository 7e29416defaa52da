"""Shared fixtures of the psychophysics tests: the shipped scene and synthetic data."""
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from feeler.psydata import TRIAL_COLUMNS
from feeler.scene import load_scene
from feeler.simulate.psychophysics import draw_trials, draw_truth

SCENE_PATH = Path(__file__).parents[2] / "datasets-synthetic" / "psychophysics-2afc.toml"


@pytest.fixture(scope="session")
def scene():
    return load_scene(SCENE_PATH)


@pytest.fixture(scope="session")
def simulate(scene):
    """simulate(seed, n_subjects=6, n_trials=20) -> (trials DataFrame, truth list)."""
    def make(seed: int, n_subjects: int = 6, n_trials: int = 20):
        sc = replace(scene, design=replace(scene.design, n_subjects=n_subjects, n_trials=n_trials))
        rng = np.random.default_rng(seed)
        truth = draw_truth(sc, rng)
        return draw_trials(sc, truth, rng), truth
    return make


@pytest.fixture(scope="session")
def extreme() -> pd.DataFrame:
    """One subject: all correct at 20 mm/s, all wrong at 40 mm/s, plus zero-trial rows."""
    rows = []
    for x in (7.6, 8.4, 9.2, 10.8, 11.6, 12.4):
        rows.append(("A", 10.0, 20.0, x, 20.0, 12, 12 if x > 10 else 0))
        rows.append(("A", 10.0, 40.0, x, 20.0, 12, 0 if x > 10 else 12))
    rows += [("A", 10.0, 20.0, 10.0, 20.0, 0, 0), ("A", 10.0, 40.0, 10.0, 20.0, 0, 0)]
    return pd.DataFrame(rows, columns=list(TRIAL_COLUMNS))
