"""M2: the neuron's (a, τ, h) and the decoder noise σ from labelled plate scans (DESIGN §6).

Re-exports the entry point :func:`fit_neuron`, its data record and the model helpers;
backends live in :mod:`.grid` (default, deterministic) and :mod:`.mcmc` (NUTS, emcee).
"""
from feeler.calib.neuron.fit import (BACKENDS, DecoderMisfitWarning, NeuronData, data_from_scans,
                                     fit_neuron, posterior_predictive_check)
from feeler.calib.neuron.model import PARAMS, PeakTable, Priors, make_priors, mean_mm, peak_table

__all__ = ["BACKENDS", "DecoderMisfitWarning", "NeuronData", "data_from_scans", "fit_neuron",
           "posterior_predictive_check", "PARAMS", "PeakTable", "Priors", "make_priors", "mean_mm",
           "peak_table"]
