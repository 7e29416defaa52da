"""Scene kind ``robot-scan``: the robot rubs the sensor over one or more plates (paper §5).

One plate per entry of ``surface.heights_mm``, each scanned ``repeats.scans_per_plate``
times; every scan is a fresh touch (press, tilt, start offset and drift drawn anew).
``[noise]`` is the sensor's white noise at the ``displacement`` fidelity; at ``areas`` and
``images`` the noise comes from the optical element of the optional ``[optics]`` table
(:mod:`feeler.scenes._optics`). At ``images`` the check also renders nothing it could not
read: the contact discs of the scene's lightest and hardest touches must suit the camera
(:mod:`feeler.scenes._frames`).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from feeler.errors import SceneError
from feeler.scene import SEED_MAX, param
from feeler.scenes._optics import Optics, check_optics

__all__ = ["Scene", "Head", "Surface", "MotionTable", "Probe", "Sensor", "Noise", "Neuron", "Repeats", "Optics"]


@dataclass(frozen=True, kw_only=True)
class Head:
    kind: str = param(choices=("robot-scan",), doc="scene kind")
    name: str = param(doc="short name of the dataset")
    description: str = param("", doc="free text")
    seed: int = param(lo=0, hi=SEED_MAX, doc="root seed of every random draw")
    outputs: tuple[str, ...] = param(("scans",), choices=("scans", "features"), min_len=1,
                                     doc="files to produce: scans (scans.csv), features (features.csv)")


@dataclass(frozen=True, kw_only=True)
class Surface:
    profile: str = param("step", choices=("step", "staircase", "grating"), doc="plate profile")
    heights_mm: tuple[float, ...] = param(lo=-5.0, hi=5.0, min_len=1,
                                          doc="mm, one plate each: step height (< 0 step down) or grating depth")
    position_mm: float = param(lo=-1000.0, hi=1000.0, doc="mm, first edge in plate coordinates")
    count: int = param(1, lo=1, hi=1000, doc="steps of a staircase or periods of a grating")
    spacing_mm: float = param(1.0, lo=0.0, lo_open=True, hi=1000.0, doc="mm, staircase spacing or grating period")


@dataclass(frozen=True, kw_only=True)
class MotionTable:
    speed_mm_s: float = param(lo=0.0, lo_open=True, hi=100.0, doc="mm/s, stage speed")
    traverse_mm: float = param(lo=0.0, lo_open=True, hi=1000.0, doc="mm, stroke of one scan")
    dt_s: float = param(lo=0.0, lo_open=True, hi=60.0, doc="s, sampling interval")
    x0_mm: float = param(0.0, lo=-1000.0, hi=1000.0, doc="mm, nominal start in plate coordinates")
    x0_sd_mm: float = param(0.0, lo=0.0, hi=100.0, doc="mm, touch-to-touch scatter of the start")


@dataclass(frozen=True, kw_only=True)
class Probe:
    pad_width_mm: float = param(lo=0.0, hi=50.0, doc="mm, width of the tip's flat face along x")
    uy0_mean_mm: float = param(lo=0.0, lo_open=True, hi=5.0, doc="mm, mean initial press U_y0")
    uy0_sd_mm: float = param(0.0, lo=0.0, hi=5.0, doc="mm, touch-to-touch sd of U_y0")
    tilt_sd_deg: float = param(0.0, lo=0.0, hi=30.0, doc="deg, touch-to-touch sd of the face tilt")
    drift_sd_mm_s: float = param(0.0, lo=0.0, hi=1.0, doc="mm/s, sd of the per-touch linear drift rate")
    shear_per_normal: float = param(0.0, lo=0.0, hi=5.0, doc="U_x / U_y from kinetic friction, dimensionless")
    breakaway_frac: float = param(0.0, lo=0.0, hi=1.0, doc="fraction of U_y0 released when sliding starts")
    breakaway_s: float = param(0.2, lo=0.0, lo_open=True, hi=60.0, doc="s, time constant of that release")
    snap_prob: float = param(0.0, lo=0.0, hi=1.0, doc="probability per touch that the tip catches on a "
                             "rising edge and snaps up within one frame (stick-slip), dimensionless")


@dataclass(frozen=True, kw_only=True)
class Sensor:
    fidelity: str = param("displacement", choices=("displacement", "areas", "images"),
                          doc="sensor model level")


@dataclass(frozen=True, kw_only=True)
class Noise:
    ux_sd_mm: float = param(lo=0.0, hi=1.0, doc="mm, white noise sd on U_x")
    uy_sd_mm: float = param(lo=0.0, hi=1.0, doc="mm, white noise sd on U_y")
    uz_sd_mm: float = param(lo=0.0, hi=1.0, doc="mm, white noise sd on U_z")


@dataclass(frozen=True, kw_only=True)
class Neuron:
    a: float = param(1.0, lo=0.0, lo_open=True, hi=1e9, doc="V·s, receptor gain")
    tau_s: float = param(lo=0.0, lo_open=True, hi=1e4, doc="s, temporal summation window")
    h: float = param(0.0, lo=0.0, hi=1e9, doc="V, threshold")
    kernel: str = param("boxcar", choices=("boxcar", "exponential"), doc="temporal window shape")
    length_mm: float = param(lo=0.0, lo_open=True, hi=1000.0,
                             doc="mm, representative length: strain = U_y / length (paper §5.2)")


@dataclass(frozen=True, kw_only=True)
class Repeats:
    scans_per_plate: int = param(lo=1, hi=100000, doc="touches (scans) per plate")


@dataclass(frozen=True, kw_only=True)
class Scene:
    scene: Head
    surface: Surface
    motion: MotionTable
    probe: Probe
    noise: Noise
    neuron: Neuron
    repeats: Repeats
    sensor: Sensor = field(default_factory=Sensor)
    optics: Optics | None = None

    def last_edge_mm(self) -> float:
        """Position of the last edge of every plate (mm)."""
        s = self.surface
        if s.profile == "staircase":
            return s.position_mm + (s.count - 1) * s.spacing_mm
        if s.profile == "grating":
            return s.position_mm + (s.count - 0.5) * s.spacing_mm
        return s.position_mm

    def plate_levels_mm(self) -> tuple[float, float]:
        """(lowest, highest) surface level (mm) of any plate, 0 (the base) included."""
        from feeler.simulate.robot import plate_profile

        levels = [0.0]
        for height in self.surface.heights_mm:
            profile = plate_profile(self.surface, height)
            levels += list(profile.base_mm + np.cumsum((0.0,) + tuple(profile.jumps_mm)))
        return min(levels), max(levels)

    def press_range_mm(self) -> tuple[float, float]:
        """(lowest, highest) U_y (mm) of the scene's touches, with 5 sds of every draw: the
        press (at least 0; less the breakaway at the low end), the plates' levels, and the
        drift over one scan."""
        p, m = self.probe, self.motion
        low, top = self.plate_levels_mm()
        drift = 5 * p.drift_sd_mm_s * m.traverse_mm / m.speed_mm_s
        press_lo = max(0.0, p.uy0_mean_mm - 5 * p.uy0_sd_mm) * (1 - p.breakaway_frac)
        return press_lo + low - drift, p.uy0_mean_mm + 5 * p.uy0_sd_mm + top + drift

    def _check_frames(self, path) -> None:
        """At ``images``: the contact discs of the lightest and hardest touches suit the camera."""
        from feeler.models.probe import samples_per_scan
        from feeler.scenes._frames import check_frames, check_photons, contact_areas, round_down, scene_layout

        optics, layout = self.optics or Optics(), scene_layout(self.optics, path)
        m, n_el = self.motion, len(layout.elements)
        n_time = samples_per_scan(m.speed_mm_s, m.traverse_mm, m.dt_s)
        n_scans = len(self.surface.heights_mm) * self.repeats.scans_per_plate
        check_photons(optics, path, -(-n_scans // n_el) * n_time, n_el)
        along = np.array([-self.probe.shear_per_normal, 1.0, 0.0])      # U per mm of U_y
        lo, hi = self.press_range_mm()
        areas = contact_areas(optics, np.stack([lo * along, hi * along]), optics.c_mm_per_n)
        per_mm = contact_areas(optics, along[None], optics.c_mm_per_n)[0] - optics.rest_area_px2

        def growth(peak, budget, lim, where):
            p, s = self.probe, self.surface
            press = p.uy0_mean_mm + 5 * p.uy0_sd_mm
            top = self.plate_levels_mm()[1]
            drift = hi - press - top
            reach = budget / per_mm.max() if per_mm.max() > 0 else 0.0  # U_y (mm) whose discs fit
            said = (f"the hardest touch (U_y up to {hi:.3g} mm: press {p.uy0_mean_mm:g} mm + 5 sd, highest "
                    f"plate level {top:.3g} mm, drift {drift:.2g} mm) renders contact discs of {peak:.0f} px², "
                    f"but only {lim.largest_px2:.0f} px² with the blur's {lim.reach_px} px fit {where}")
            if top > press and reach > press + drift:
                per_level = max(abs(h) for h in s.heights_mm) / top       # height per mm of level
                return SceneError(path, "surface.heights_mm",
                                  f"{list(s.heights_mm)}: {said}; with this press heights up to "
                                  f"{round_down((reach - press - drift) * per_level):g} mm fit")
            return SceneError(path, "probe.uy0_mean_mm",
                              f"{p.uy0_mean_mm:g}: {said}; with these plates at most "
                              f"{round_down(reach - top - drift - 5 * p.uy0_sd_mm):g} mm fits")

        check_frames(optics, path, areas, growth, layout)

    def check(self, path) -> None:
        """Cross-field rules: raise :class:`SceneError` on an impossible combination."""
        s, m, p = self.surface, self.motion, self.probe
        check_optics(self.optics, self.sensor.fidelity, path)
        if s.profile == "step" and s.count != 1:
            raise SceneError(path, "surface.count", f"{s.count}: a single step has count = 1")
        twice = sorted({h for h in s.heights_mm if list(s.heights_mm).count(h) > 1})
        if s.profile == "step" and twice:        # one plate per entry: two entries alike are one plate, mislabelled
            raise SceneError(path, "surface.heights_mm",
                             f"{list(s.heights_mm)}: {', '.join(f'{h:g}' for h in twice)} more than once; one entry "
                             f"per plate (repeats.scans_per_plate sets its touches)")
        if m.traverse_mm < 2 * m.speed_mm_s * m.dt_s:
            raise SceneError(path, "motion.traverse_mm",
                             f"{m.traverse_mm}: shorter than two samples (speed_mm_s*dt_s*2 = {2 * m.speed_mm_s * m.dt_s:g} mm)")
        if m.traverse_mm / (m.speed_mm_s * m.dt_s) > 1e6:
            raise SceneError(path, "motion.dt_s", f"{m.dt_s}: more than 1e6 samples per scan")
        margin = p.pad_width_mm / 2 + 3 * m.x0_sd_mm
        lo, hi = m.x0_mm + margin, m.x0_mm + m.traverse_mm - margin
        if lo > hi:                                 # no edge fits at all: say which lengths clash
            raise SceneError(path, "probe.pad_width_mm",
                             f"{p.pad_width_mm}: the pad plus 3 sds of start scatter on each side "
                             f"({2 * margin:g} mm) must be shorter than motion.traverse_mm = {m.traverse_mm:g} mm")
        if s.position_mm < lo or self.last_edge_mm() > hi:
            raise SceneError(path, "surface.position_mm",
                             f"{s.position_mm}: edges at {s.position_mm:g}..{self.last_edge_mm():g} mm must lie "
                             f"inside the traverse less the pad and start scatter, [{lo:g}, {hi:g}] mm")
        if p.uy0_sd_mm * 3 >= p.uy0_mean_mm:
            raise SceneError(path, "probe.uy0_sd_mm",
                             f"{p.uy0_sd_mm}: must be below uy0_mean_mm/3 = {p.uy0_mean_mm / 3:g} mm "
                             "(the tip must stay pressed on nearly every touch)")
        duration_s = (m.traverse_mm / m.speed_mm_s)
        if self.neuron.tau_s >= duration_s:
            raise SceneError(path, "neuron.tau_s",
                             f"{self.neuron.tau_s}: must be shorter than one scan ({duration_s:g} s)")
        if self.neuron.tau_s < m.dt_s:
            # calibrate neuron searches windows from one sample up (calib.neuron.data): a shorter truth
            # could be simulated but never recovered
            raise SceneError(path, "neuron.tau_s",
                             f"{self.neuron.tau_s}: shorter than one sample (motion.dt_s = {m.dt_s:g} s); a window "
                             "must hold at least one frame for a neuron calibration to find it")
        if self.sensor.fidelity == "images":
            self._check_frames(path)
