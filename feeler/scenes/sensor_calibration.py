"""Scene kind ``sensor-calibration``: a stage imposes tip displacements, the sensor reports forces.

The stage commands displacements U (mm) — normal presses along y, then shear offsets
along x and z on top of a normal preload — each ``design.repeats`` times. The stage
reaches U_true = U + N(0, ``noise.stage_sd_mm``²); the element's true compliance C
(mm/N, ``sensor.c_mm_per_n``) gives the true force F = C⁻¹ U_true, and the sensor
reports F + η, η per axis Gaussian or Student-t with scale ``noise.f_sd_n`` (at
``sensor.fidelity = "displacement"``); at ``"areas"`` or ``"images"`` it reports the force
read from the element's contact areas / rendered camera frames (``[optics]``, whose C is
replaced by the true C), and ``noise.f_sd_n`` is not used. The
``[prior]`` table is the lab's nominal knowledge (C₀ from the sensor's design), used by
``feeler calibrate sensor``. Axes as in the paper: x along the scan, y normal, z lateral.
At ``images`` the check also refuses a design whose contact discs the camera could not
read (:mod:`feeler.scenes._frames`).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from feeler.errors import SceneError
from feeler.scene import SEED_MAX, param
from feeler.scenes._optics import Optics, check_optics

__all__ = ["Scene", "Head", "Sensor", "Design", "Noise", "Prior", "Optics", "commanded_displacements"]

_MATRIX_DOC = "3x3 compliance matrix, rows = displacement axis x, y, z, columns = force axis, mm/N"


@dataclass(frozen=True)
class Head:
    kind: str = param(choices=("sensor-calibration",), doc="scene kind")
    description: str = param("", doc="free text")
    seed: int = param(0, lo=0, hi=SEED_MAX, doc="seed of the numpy Generator")


@dataclass(frozen=True)
class Sensor:
    c_mm_per_n: tuple[tuple[float, ...], ...] = param(lo=-10.0, hi=10.0, min_len=3, doc=_MATRIX_DOC)
    fidelity: str = param("displacement", choices=("displacement", "areas", "images"),
                          doc="how the force is read: displacement (F + noise), areas, images")


@dataclass(frozen=True)
class Design:
    normal_presses_mm: tuple[float, ...] = param((0.05, 0.10, 0.15, 0.20, 0.25), lo=0.0, hi=2.0,
                                                 min_len=1, doc="normal press depths U_y, mm")
    shear_offsets_mm: tuple[float, ...] = param((-0.10, -0.05, 0.05, 0.10), lo=-2.0, hi=2.0,
                                                doc="shear offsets applied along x and along z, mm")
    shear_preload_mm: float = param(0.15, lo=0.0, hi=2.0, doc="normal press held during shear, mm")
    repeats: int = param(3, lo=1, hi=1000, doc="repetitions of the whole design")


@dataclass(frozen=True)
class Noise:
    f_sd_n: tuple[float, ...] = param((0.02, 0.02, 0.02), lo=0.0, hi=100.0, min_len=3,
                                      doc="force noise scale per axis x, y, z, N")
    stage_sd_mm: float = param(0.001, lo=0.0, hi=1.0, doc="stage positioning error sd, mm")
    kind: str = param("gaussian", choices=("gaussian", "student"), doc="force noise distribution")
    student_nu: float = param(4.0, lo=0.0, lo_open=True, hi=1000.0, doc="Student-t degrees of freedom")


@dataclass(frozen=True)
class Prior:
    c0_mm_per_n: tuple[tuple[float, ...], ...] = param(lo=-10.0, hi=10.0, min_len=3, doc=_MATRIX_DOC)
    rel_sd: float = param(0.5, lo=0.0, lo_open=True, hi=1e6, doc="prior sd per entry / largest entry")
    sigma_f_scale_n: float = param(0.1, lo=0.0, lo_open=True, hi=100.0,
                                   doc="half-normal scale of the force noise sd, N")


@dataclass(frozen=True)
class Scene:
    scene: Head
    sensor: Sensor
    prior: Prior
    design: Design = Design()
    noise: Noise = Noise()
    optics: Optics | None = None

    def check(self, path) -> None:
        """3x3 invertible matrices, exactly 3 noise sds, a design that spans 3 axes,
        ``[optics]`` only at an optical fidelity."""
        check_optics(self.optics, self.sensor.fidelity, path)
        for key, m in (("sensor.c_mm_per_n", self.sensor.c_mm_per_n),
                       ("prior.c0_mm_per_n", self.prior.c0_mm_per_n)):
            if len(m) != 3 or any(len(row) != 3 for row in m):
                raise SceneError(path, key, f"must be 3 rows of 3 numbers ({_MATRIX_DOC})")
            if np.linalg.cond(np.asarray(m, dtype=float)) > 1e8:
                raise SceneError(path, key, "must be invertible (condition number <= 1e8)")
        if len(self.noise.f_sd_n) != 3:
            raise SceneError(path, "noise.f_sd_n", f"needs exactly 3 values (x, y, z), got {len(self.noise.f_sd_n)}")
        if not any(o != 0 for o in self.design.shear_offsets_mm):
            raise SceneError(path, "design.shear_offsets_mm",
                             "needs a non-zero offset: without shear the x and z columns are unidentified")
        if self.sensor.fidelity == "images":
            self._check_frames(path)

    def _check_frames(self, path) -> None:
        """At ``images``: the contact discs of every design point (± 5 stage sds) suit the camera."""
        from feeler.scenes._frames import check_frames, check_photons, contact_areas, round_down, scene_layout

        optics, c, d = self.optics or Optics(), self.sensor.c_mm_per_n, self.design
        layout = scene_layout(self.optics, path)
        u = commanded_displacements(dataclasses.replace(d, repeats=1))
        n_el = len(layout.elements)
        check_photons(optics, path, -(-len(u) * d.repeats // n_el), n_el)
        per_mm = contact_areas(optics, np.eye(3), c) - optics.rest_area_px2        # (axis, feeler) px²/mm
        slack = 5 * self.noise.stage_sd_mm * np.abs(per_mm).sum(axis=0)
        areas = contact_areas(optics, u, c)

        n_normal, n_shear = len(d.normal_presses_mm), len(d.shear_offsets_mm)
        preloaded = optics.rest_area_px2 + d.shear_preload_mm * per_mm[1]

        def offsets_error(worst, lim, said) -> SceneError:
            # the largest |offset| along the worst point's axis that keeps every disc inside and readable
            axis = 0 if worst < n_normal + n_shear else 2
            k = np.maximum(np.abs(per_mm[axis]), 1e-12)
            room = np.minimum(lim.largest_px2 - slack - preloaded, preloaded - slack - lim.smallest_px2) / k
            return SceneError(path, "design.shear_offsets_mm",
                              f"{list(d.shear_offsets_mm)}: {said}; at this preload offsets up to "
                              f"±{round_down(float(room.min())):g} mm keep the discs inside and readable")

        def press_most(lim, extra) -> float:
            # the largest press along y that keeps every disc, grown by extra (px²), inside its window
            up = per_mm[1] > 0
            room = (lim.largest_px2 - optics.rest_area_px2 - slack - extra)[up] / per_mm[1][up]
            return round_down(float(room.min())) if up.any() else 0.0

        def growth(peak, budget, lim, where):
            worst = int(np.argmax((areas + slack).max(axis=1)))
            said = (f"the design's contact discs reach {peak:.0f} px² (compliance sensor.c_mm_per_n), but only "
                    f"{lim.largest_px2:.0f} px² with the blur's {lim.reach_px} px fit {where}")
            if worst < n_normal:
                return SceneError(path, "design.normal_presses_mm", f"{list(d.normal_presses_mm)}: {said}; "
                                                                    f"presses up to {press_most(lim, 0.0):g} mm fit")
            if (preloaded + slack).max() > lim.largest_px2:
                sheared = max(np.abs(d.shear_offsets_mm)) * np.maximum(np.abs(per_mm[0]), np.abs(per_mm[2]))
                return SceneError(path, "design.shear_preload_mm", f"{d.shear_preload_mm:g}: {said}; with these "
                                  f"offsets a preload up to {press_most(lim, sheared):g} mm fits")
            return offsets_error(worst, lim, said)

        def shrink(least, lim, where):
            worst = int(np.argmin((areas - slack).min(axis=1)))
            said = (f"the design shrinks a contact disc to {max(least, 0.0):.0f} px² (compliance "
                    f"sensor.c_mm_per_n), below the {lim.smallest_px2:.0f} px² (π (σ + 1.6)², blur "
                    f"{optics.blur_sd_px:g} px) the frame reader tells from shot-noise specks")
            if worst < n_normal:
                return SceneError(path, "design.normal_presses_mm", f"{list(d.normal_presses_mm)}: {said}")
            return offsets_error(worst, lim, said)

        check_frames(optics, path, np.concatenate([areas + slack, areas - slack]), growth, layout, shrink)


def commanded_displacements(design: Design) -> np.ndarray:
    """The design's commanded tip displacements, ndarray[n, 3] (ux, uy, uz), mm."""
    rows = [(0.0, d, 0.0) for d in design.normal_presses_mm]
    rows += [(o, design.shear_preload_mm, 0.0) for o in design.shear_offsets_mm]
    rows += [(0.0, design.shear_preload_mm, o) for o in design.shear_offsets_mm]
    return np.tile(np.asarray(rows, dtype=float), (design.repeats, 1))
