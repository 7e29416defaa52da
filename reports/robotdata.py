"""A robot-scan part read once for the report: scans, the neuron, z(t) and per-scan features.

Simulated runs carry their scene (``four-plates``: the neuron's a, τ, h and the probe);
acquired runs carry the plan, which sets only the neuron's representative length: their
pulse density is computed with the paper's constants for the robot (§5.2: a = 1 V s,
τ = 3 s, h = 0), and the report says so. Each scan keeps its own sample times.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["RobotNeuron", "RobotData", "robot_data", "PAPER_ROBOT"]

PAPER_ROBOT = {"a": 1.0, "tau_s": 3.0, "h": 0.0}       # paper §5.2, the robot's constants
_DEFAULT_PAD_MM = 1.5                                    # tip's flat face when no scene says


@dataclass(frozen=True)
class RobotNeuron:
    """The neuron applied to the scans, and where its constants come from (words)."""
    a: float
    tau_s: float
    h: float
    kernel: str
    length_mm: float
    source: str


@dataclass(frozen=True)
class RobotData:
    """Attributes: part; scans (:class:`feeler.datasets.Scans`); neuron; eps, z
    (ndarray[n_scans, n_time]); peak_z, jump_uy_mm, peak_rate_uy_mm_s (ndarray[n_scans],
    jump NaN when scans are too short for its windows); steps (plate heights, mm, in order
    of appearance); first (index of each plate's first scan); name, description (of the
    scene or plan); summary (acquisitions: summary.json, else None); timing (acquisitions:
    per-sample t_sched_s, status_rtt_s, late as a DataFrame, else None)."""
    part: object
    scans: object
    neuron: RobotNeuron
    eps: np.ndarray
    z: np.ndarray
    peak_z: np.ndarray
    jump_uy_mm: np.ndarray
    peak_rate_uy_mm_s: np.ndarray
    steps: list
    first: list
    name: str
    description: str
    summary: dict | None
    timing: object


def _scene(inv, part):
    from feeler.scene import load_scene

    path = inv.run_dir / part.path("scene.toml")
    return load_scene(path) if path.is_file() else None


def _neuron_and_windows(scene, part, scans):
    """(RobotNeuron, gap_s, span_s) for the scene's kind (robot scene, plan or none)."""
    rel = part.path("scene.toml")
    dt = float(np.median(np.diff(scans.t_s, axis=-1)))
    speed = float(scans.speed_mm_s[0])
    if scene is not None and hasattr(scene, "probe"):                  # a simulated robot scene
        n = scene.neuron
        nrn = RobotNeuron(n.a, n.tau_s, n.h, n.kernel, n.length_mm, f"the scene ({rel})")
        pad, speed, dt = scene.probe.pad_width_mm, scene.motion.speed_mm_s, scene.motion.dt_s
    else:
        length = scene.neuron.length_mm if scene is not None else 3.0
        kernel = scene.neuron.kernel if scene is not None else "boxcar"
        words = (f"the plan ({rel}) sets the length; a, τ, h are the paper's (§5.2)" if scene is not None
                 else "no scene file: the paper's constants (§5.2) and length 3 mm")
        nrn = RobotNeuron(PAPER_ROBOT["a"], PAPER_ROBOT["tau_s"], PAPER_ROBOT["h"], kernel, length, words)
        virtual = getattr(scene, "virtual", None)
        pad = virtual.pad_width_mm if virtual is not None else _DEFAULT_PAD_MM
    return nrn, pad / speed + dt, max(4 * dt, 1.0)


def _acquired(inv, part):
    """(summary.json or None, per-sample timing columns or None)."""
    import pandas as pd

    from feeler.reports.readers import read_json

    summary_path = inv.run_dir / part.path("summary.json")
    summary = read_json(summary_path) if summary_path.is_file() else None
    cols = ["scan_id", "t_s", "t_sched_s", "status_rtt_s", "late"]
    try:
        timing = pd.read_csv(inv.run_dir / part.path("scans.csv"), usecols=lambda c: c in cols)
    except (OSError, ValueError):
        timing = None
    if timing is not None and not {"t_sched_s", "late"} <= set(timing.columns):
        timing = None
    return summary, timing


def _load(inv, part) -> RobotData:
    from feeler.datasets import jump_uy_mm, peak_rate_uy_mm_s, read_scans, strain
    from feeler.models import neuron

    scans = read_scans(inv.run_dir / part.path("scans.csv"))
    scene = _scene(inv, part)
    nrn, gap_s, span_s = _neuron_and_windows(scene, part, scans)
    eps = strain(scans.uy_mm, nrn.length_mm)
    z = neuron.per_time_base(lambda s, t: neuron.pulse_density(s, t, a=nrn.a, tau=nrn.tau_s, h=nrn.h,
                                                                kernel=nrn.kernel), eps, scans.t_s)
    try:
        jump = jump_uy_mm(scans.uy_mm, scans.t_s, gap_s=gap_s, span_s=span_s)
    except ValueError:                          # scans shorter than the two windows and the gap
        jump = np.full(len(scans.scan_id), np.nan)
    steps = list(dict.fromkeys(scans.step_mm.tolist()))
    first = [int(np.flatnonzero(scans.step_mm == s)[0]) for s in steps]
    head = getattr(scene, "scene", None)
    summary, timing = _acquired(inv, part) if part.kind == "acquisition" else (None, None)
    return RobotData(part=part, scans=scans, neuron=nrn, eps=eps, z=z, peak_z=z.max(axis=-1),
                     jump_uy_mm=jump, peak_rate_uy_mm_s=peak_rate_uy_mm_s(scans.uy_mm, scans.t_s),
                     steps=steps, first=first, name=getattr(head, "name", part.rel or "run"),
                     description=getattr(head, "description", ""), summary=summary, timing=timing)


def robot_data(inv, part) -> RobotData:
    """The part's :class:`RobotData`, computed once per report."""
    return inv.cached(("robot", part.rel), lambda: _load(inv, part))
