"""One small M2 fit shared by the live-decoding tests (a shipped synthetic scene)."""

import numpy as np
import pytest

from feeler.calib.neuron import fit_neuron
from feeler.calib.neuron.synth import scene_scans


@pytest.fixture(scope="session")
def small_fit():
    """(NeuronData, FitResult): the synthetic plate scene 2, fitted with the grid backend."""
    data = scene_scans()[2]
    return data, fit_neuron(data, seed=2, draws=300)


@pytest.fixture(scope="session")
def scans_frame(small_fit):
    """The fit's scans as a long-format frame (scan_id, t_s, x_mm, uy_mm, step_mm)."""
    import pandas as pd

    data, res = small_fit
    length = float(res.posterior["posterior"].attrs["length_mm"])
    idx = np.arange(0, data.strain.shape[0], 8)
    t = np.broadcast_to(data.t_s, data.strain.shape)
    x = np.broadcast_to(data.x_mm, data.strain.shape) if data.x_mm is not None else t * 0.5
    return pd.DataFrame({"scan_id": np.repeat(idx, data.strain.shape[1]), "t_s": t[idx].ravel(),
                         "x_mm": x[idx].ravel(), "uy_mm": data.strain[idx].ravel() * length,
                         "step_mm": np.repeat(data.step_mm[idx], data.strain.shape[1])})


@pytest.fixture(scope="session")
def fit_dir(small_fit, tmp_path_factory):
    """The small fit saved as `feeler calibrate neuron --out` does."""
    return small_fit[1].save(tmp_path_factory.mktemp("fit") / "fit")


@pytest.fixture(scope="session")
def fresh_frame(small_fit):
    """24 fresh scans of the training scene (6 per plate, another seed), long format with
    labels (scan_id, t_s, uy_mm, step_mm): enough for the checks of a labelled batch."""
    import pandas as pd

    data = scene_scans(seed=77, per_plate=6)[2]
    length = float(small_fit[1].posterior["posterior"].attrs["length_mm"])
    n, m = data.strain.shape
    return pd.DataFrame({"scan_id": np.repeat(np.arange(n), m), "t_s": np.tile(data.t_s, n),
                         "uy_mm": data.strain.ravel() * length, "step_mm": np.repeat(data.step_mm, m)})
