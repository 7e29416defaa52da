"""M2: the decoder of plate scans — the neuron's window τ, its gain and offset (a, h), and
each plate's decoded-height distribution — from labelled plate scans (DESIGN §6).

Re-exports the entry point :func:`fit_neuron`, its data record and the model helpers;
backends live in :mod:`.grid` (default, exact) and :mod:`.mcmc` (NUTS, emcee); the
decoder of new scans, draw by draw, in :mod:`.decoder`; the streaming decoder of scans
as they are acquired, :class:`LiveDecoder`, in :mod:`.live`.
"""
from feeler.calib.neuron.data import NeuronData, data_from_scans
from feeler.calib.neuron.live import LiveDecoder
from feeler.calib.neuron.fit import BACKENDS, NOISE_CHOICES, DecoderMisfitWarning, fit_neuron
from feeler.calib.neuron.model import (NOISE_MODELS, PARAMS, PeakTable, PlatePrior, Plates, Priors,
                                       make_priors, peak_table)

__all__ = ["BACKENDS", "NOISE_CHOICES", "NOISE_MODELS", "DecoderMisfitWarning", "LiveDecoder", "NeuronData", "data_from_scans",
           "fit_neuron", "PARAMS", "PeakTable", "PlatePrior", "Plates", "Priors", "make_priors", "peak_table"]
