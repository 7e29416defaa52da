"""Decoding while scans arrive: a streaming M2 decoder, the training envelope that flags
scans unlike the fit's, and the scan CSV any lab can write."""
from feeler.calib.neuron.live.decoder import Decision, LiveDecoder, LiveState

__all__ = ["Decision", "LiveDecoder", "LiveState"]
