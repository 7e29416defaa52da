"""Acquisition campaigns: a scan plan run on the stage and the camera into a run directory.

``acquire(plan, out, stage_port=..., camera_src=...)`` (or ``emulate=True``) is the entry
point of ``feeler acquire``; the run directory is a robot-scan dataset (``scans.csv``,
``scene.toml``) that ``feeler calibrate neuron`` reads directly. Imports OpenCV only when
a campaign runs.
"""
from feeler.hardware.acquire.plan import ScanSpec, check_moves, moves_of, sample_times_s, scans_of
from feeler.hardware.acquire.session import acquire, c_from_calibration, load_plan
from feeler.hardware.acquire.store import SAMPLE_COLUMNS, SCAN_COLUMNS, RunStore

__all__ = ["acquire", "load_plan", "c_from_calibration", "ScanSpec", "scans_of", "sample_times_s",
           "moves_of", "check_moves", "RunStore", "SCAN_COLUMNS", "SAMPLE_COLUMNS"]
