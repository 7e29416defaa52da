"""Scene kind ``scan-plan``: an acquisition campaign for ``feeler acquire`` (DESIGN §5).

The stage carries the sensing element over ``plates`` laid along its scan axis (x). For
each plate, ``repeats.scans_per_plate`` times: lift to ``surface_z_mm + clearance_mm``,
go to the plate's start ``origin_x_mm`` (stage x of plate coordinate 0), lower onto the
surface, press ``press_mm`` into it, traverse ``traverse_mm`` at ``speed_mm_s`` while a
sample (stage position + camera frame) is taken every ``sample_period_s``, lift again.

``[neuron]`` carries what ``feeler calibrate neuron`` reads from a run directory's
``scene.toml`` (this plan is copied there); ``[optics]`` how frames are read;
``[virtual]`` the plate and tip that the virtual camera of ``feeler acquire --emulate``
renders (ignored with a real camera). Soft limits are checked against the stage's own
limits when the campaign connects (:func:`feeler.hardware.acquire.plan.check_moves`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from feeler.errors import SceneError
from feeler.models.probe import samples_per_scan    # as the campaign takes them: the simulated probe's rule
from feeler.scene import SEED_MAX, param

__all__ = ["Scene", "Head", "Plates", "ScanMotion", "Repeats", "Neuron", "Optics", "Virtual",
           "MAX_SPEED_MM_S", "samples_per_scan", "per_minute_hint"]

#: mm/s, the fastest traverse a plan may ask for (checked in :meth:`Scene.check`, with a hint)
MAX_SPEED_MM_S = 1000.0
#: a plan may take at most this many samples a scan
MAX_SAMPLES = 1e5


@dataclass(frozen=True, kw_only=True)
class Head:
    kind: str = param(choices=("scan-plan",), doc="scene kind")
    name: str = param(doc="short name of the campaign")
    description: str = param("", doc="free text")
    seed: int = param(0, lo=0, hi=SEED_MAX, doc="seed of the virtual camera's shot noise (--emulate)")


@dataclass(frozen=True, kw_only=True)
class Plates:
    heights_mm: tuple[float, ...] = param(lo=-5.0, hi=5.0, min_len=1,
                                          doc="mm, step height of each plate (its label)")
    origin_x_mm: tuple[float, ...] = param(lo=-10000.0, hi=10000.0, min_len=1,
                                           doc="mm, stage x of each plate's scan start")
    surface_z_mm: float = param(lo=-10000.0, hi=10000.0, doc="mm, stage z where the tip touches the plates")
    y_mm: float = param(lo=-10000.0, hi=10000.0, doc="mm, stage y of the scan line")


@dataclass(frozen=True, kw_only=True)
class ScanMotion:
    # its upper bound is checked with the others in Scene.check, where the plan's stroke and
    # period say whether the value was meant in mm/min
    speed_mm_s: float = param(lo=0.0, lo_open=True, doc="mm/s, traverse speed")
    traverse_mm: float = param(lo=0.0, lo_open=True, hi=1000.0, doc="mm, stroke of one scan")
    sample_period_s: float = param(lo=0.01, hi=60.0, doc="s, interval between samples")
    press_mm: float = param(lo=0.0, lo_open=True, hi=5.0, doc="mm, press depth into the plate")
    clearance_mm: float = param(2.0, lo=0.0, lo_open=True, hi=100.0, doc="mm, lift above the surface between scans")
    move_feed_mm_min: float = param(lo=0.0, lo_open=True, hi=1e5, doc="mm/min, feed of moves between scans")
    press_feed_mm_min: float = param(lo=0.0, lo_open=True, hi=1e5, doc="mm/min, feed of lowering and pressing")


@dataclass(frozen=True, kw_only=True)
class Repeats:
    scans_per_plate: int = param(lo=1, hi=100000, doc="touches (scans) per plate")


@dataclass(frozen=True, kw_only=True)
class Neuron:
    length_mm: float = param(lo=0.0, lo_open=True, hi=1000.0,
                             doc="mm, representative length: strain = U_y / length")
    kernel: str = param("boxcar", choices=("boxcar", "exponential"), doc="temporal window shape")


@dataclass(frozen=True, kw_only=True)
class Optics:
    layout: str = param("", doc="layout TOML of the camera, relative to the plan; empty: a 4x4 grid, 640x480 px")
    element: int = param(0, lo=0, hi=10000, doc="index of the scanning element in the layout")
    blur_sd_px: float = param(1.2, lo=0.0, hi=10.0, doc="px, blur of the optics (extraction reach)")
    # the optics' nominal 150 px²: the extractor measures discs down to ~95 px² at blur 1.2 px
    rest_area_px2: float = param(150.0, lo=0.0, lo_open=True, hi=1e4,
                                 doc="px², contact area of each conical feeler at zero force")


@dataclass(frozen=True, kw_only=True)
class Virtual:
    step_position_mm: float = param(lo=-1000.0, hi=1000.0, doc="mm, step edge in plate coordinates")
    pad_width_mm: float = param(1.5, lo=0.0, hi=50.0, doc="mm, width of the tip's flat face")
    shear_per_normal: float = param(0.0, lo=0.0, hi=5.0, doc="U_x / U_y from friction, dimensionless")


@dataclass(frozen=True, kw_only=True)
class Scene:
    scene: Head
    plates: Plates
    scan: ScanMotion
    repeats: Repeats
    neuron: Neuron
    optics: Optics = field(default_factory=Optics)
    virtual: Virtual | None = None

    @property
    def n_scans(self) -> int:
        return len(self.plates.heights_mm) * self.repeats.scans_per_plate

    def check(self, path) -> None:
        """One origin per plate, a speed of at most :data:`MAX_SPEED_MM_S`, at least two
        samples per scan, at most 1e5. A speed refused that would pass as mm/min says so.
        (Soft limits need the stage's settings: :func:`feeler.hardware.acquire.plan.check_moves`.)"""
        p, s = self.plates, self.scan
        if len(p.origin_x_mm) != len(p.heights_mm):
            raise SceneError(path, "plates.origin_x_mm",
                             f"{len(p.origin_x_mm)} origins for {len(p.heights_mm)} plates: one per plate")
        problem = _scan_problem(s.speed_mm_s, s.traverse_mm, s.sample_period_s)
        if problem is not None:
            key, text = problem
            raise SceneError(path, key, text + per_minute_hint(s))


def _scan_problem(speed_mm_s: float, traverse_mm: float, sample_period_s: float) -> tuple[str, str] | None:
    """(key, what is wrong) for a traverse the plan's rules refuse, else None."""
    step_mm = speed_mm_s * sample_period_s
    if speed_mm_s > MAX_SPEED_MM_S:
        return "scan.speed_mm_s", f"{speed_mm_s!r} out of range: must be <= {MAX_SPEED_MM_S} (mm/s, traverse speed)"
    if traverse_mm < step_mm:
        return "scan.traverse_mm", (f"{traverse_mm}: shorter than one sample step (speed_mm_s*sample_period_s = "
                                    f"{step_mm:g} mm at scan.speed_mm_s = {speed_mm_s:g} mm/s)")
    if traverse_mm / step_mm > MAX_SAMPLES:
        return "scan.sample_period_s", f"{sample_period_s}: more than 1e5 samples per scan"
    return None


def per_minute_hint(scan: ScanMotion, ceiling_mm_min: float = math.inf) -> str:
    """``"; if 120 is mm/min, that is scan.speed_mm_s = 2 (mm/s): 16 samples a scan"`` when the
    plan's speed divided by 60 passes every rule of a scan (and, as mm/min, is within
    ``ceiling_mm_min``, a board's feed ceiling for the traverse), else ``""``. A feed written
    in Grbl's mm/min where mm/s is meant makes a stroke too short for one sample, or a speed
    out of range, and the error named neither the units nor the likely value."""
    meant = scan.speed_mm_s / 60.0
    if _scan_problem(meant, scan.traverse_mm, scan.sample_period_s) is not None or scan.speed_mm_s > ceiling_mm_min:
        return ""
    n = samples_per_scan(meant, scan.traverse_mm, scan.sample_period_s)
    return f"; if {scan.speed_mm_s:g} is mm/min, that is scan.speed_mm_s = {meant:.4g} (mm/s): {n} samples a scan"
