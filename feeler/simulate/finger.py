"""Simulate a ``finger-steps`` scene: one corpuscle strain history per (step, speed).

Writes ``strain.csv`` (long format: ``step_um, speed_mm_s, t_s, x_mm, eps_y``; x is the
finger's travel along the plate, 0 during press and hold) and ``truth.json`` (the scene,
the skin level and mesh, and per run the pressed strain and the peaks of the slide), plus
``scene.toml`` (a byte copy) when the scene's path is given.
"""
from __future__ import annotations

import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from feeler.calib.progress import progress as bar
from feeler.calib.progress import stage
from feeler.models.skin import SkinParams, StepProfile, loading_history, strain_history
from feeler.models.skin.ladder import summarise
from feeler.models.skin.mesh import MeshSpec
from feeler.rundir import prepare_out_dir, write_json
from feeler.scene import scene_as_dict

__all__ = ["CSV_COLUMNS", "FingerRun", "skin_params_of", "mesh_spec_of", "finger_runs",
           "simulate_finger_steps", "simulate_finger_scene"]

CSV_COLUMNS = ("step_um", "speed_mm_s", "t_s", "x_mm", "eps_y")


@dataclass(frozen=True)
class FingerRun:
    """One strain history: t_s, x_mm, eps_y (ndarray[n_time]) and where the slide starts."""

    step_um: float
    speed_mm_s: float
    t_s: np.ndarray
    x_mm: np.ndarray
    eps_y: np.ndarray
    slide_start: int


def skin_params_of(scene) -> SkinParams:
    """The scene's ``[skin]``, ``[loading]`` and L0 constants as :class:`SkinParams`."""
    s, ld, m = scene.skin, scene.loading, scene.model
    return SkinParams(e_mpa=tuple(s.e_mpa), nu=s.nu, prony_ratio=s.prony_ratio,
                      prony_tau_s=s.prony_tau_s, radius_mm=s.radius_mm,
                      thickness_mm=tuple(s.thickness_mm), press_mm=ld.press_mm, press_s=ld.press_s,
                      hold_s=ld.hold_s, slide_mm=ld.slide_mm, corpuscle_width_mm=s.corpuscle_width_mm,
                      corpuscle_height_mm=s.corpuscle_height_mm, corpuscle_depth_mm=s.corpuscle_depth_mm,
                      l0_gain=m.l0_gain, l0_base=m.l0_base)


def mesh_spec_of(scene) -> MeshSpec:
    """The scene's ``[mesh]`` as :class:`MeshSpec`."""
    m = scene.mesh
    return MeshSpec(h_contact_mm=m.h_contact_mm, h_corpuscle_mm=m.h_corpuscle_mm, h_far_mm=m.h_far_mm,
                    grade=m.grade, contact_half_width_mm=m.contact_half_width_mm)


def finger_runs(scene, *, level: str | None = None, progress: bool | None = None) -> list[FingerRun]:
    """Strain histories for every (height, speed) of the scene, heights outer.

    At L1 and L2 the finger is meshed and its stiffness assembled (L1: and the pressed
    contact solved) once, as a stage of its own, before the runs that share it.

    ``progress``: a line for that stage and a bar over the runs on a terminal, otherwise
    a line per finished run with the time left (:func:`feeler.calib.progress.progress`);
    False: silent."""
    params, spec = skin_params_of(scene), mesh_spec_of(scene)
    level = scene.model.level if level is None else level
    runs = []
    cases = [(h, v) for h in scene.steps.heights_um for v in scene.loading.speeds_mm_s]
    if level in ("l1", "l2"):
        what = "its stiffness and pressed contact" if level == "l1" else "its stiffness"
        stage(f"skin {level.upper()}: meshing the finger, {what} (once for the {len(cases)} runs)", progress)
        _prepare(level, params, spec)
    for height, speed in bar(cases, desc=f"skin runs ({level}, height x speed)", enabled=progress, lines=True):
        profile = StepProfile(height, scene.steps.position_mm, scene.steps.edge_um)
        dt = scene.loading.travel_step_mm / speed
        t, eps = strain_history(profile, speed, level=level, params=params, dt_s=dt, mesh=spec)
        load = loading_history(params, speed, dt)
        runs.append(FingerRun(height, speed, t, load.travel_mm, eps, load.slide_start))
    return runs


def _prepare(level: str, params: SkinParams, spec: MeshSpec) -> None:
    """Build (into the models' caches) what every run at ``level`` reuses: L1's influence
    function (mesh, stiffness, pressed contact), L2's assembled finger."""
    if level == "l1":
        from feeler.models.skin.l1 import influence
        influence(params, spec)
    else:
        from feeler.models.skin.fem import finger_fem
        finger_fem(params, spec)


def simulate_finger_steps(scene, out_dir: str | Path, force: bool = False,
                          scene_path: str | Path | None = None, progress: bool | None = None) -> dict[str, Path]:
    """Run the scene and write its files into ``out_dir``; returns {name: path}.
    ``progress`` as in :func:`finger_runs`.

    Raises:
        OverwriteError: a file exists and not ``force``.
    """
    files = ["strain.csv", "truth.json"] + (["scene.toml"] if scene_path is not None else [])
    out = prepare_out_dir(out_dir, files, force=force)
    runs = finger_runs(scene, progress=progress)
    table = np.concatenate([np.column_stack([np.full(len(r.t_s), r.step_um), np.full(len(r.t_s), r.speed_mm_s),
                                             r.t_s, r.x_mm, r.eps_y + 0.0]) for r in runs])
    np.savetxt(out / "strain.csv", table, fmt=["%.6g", "%.6g", "%.9g", "%.9g", "%.12g"], delimiter=",",
               header=",".join(CSV_COLUMNS), comments="")
    summaries = []
    for r in runs:
        s = summarise(r.t_s, r.eps_y, r.slide_start)
        summaries.append({"step_um": r.step_um, "speed_mm_s": r.speed_mm_s, "pressed_eps": s.pressed_eps,
                          "peak_step_eps": s.peak_step_eps, "peak_rate_per_s": s.peak_rate_per_s})
    write_json(out / "truth.json", {"scene": scene_as_dict(scene), "level": scene.model.level,
                                    "params": scene_as_dict(skin_params_of(scene)),
                                    "mesh": scene_as_dict(mesh_spec_of(scene)), "runs": summaries})
    if scene_path is not None:
        shutil.copyfile(scene_path, out / "scene.toml")
    return {name: out / name for name in files}


def simulate_finger_scene(scene, scene_path: str | Path, out: str | Path, force: bool,
                          progress: bool | None = None) -> None:
    """The :data:`feeler.simulate.SIMULATORS` entry point for ``finger-steps`` scenes."""
    simulate_finger_steps(scene, out, force=force, scene_path=scene_path, progress=progress)
