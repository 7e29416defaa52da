"""Robot-scan scenes: scene → plates → touches → sensor → files.

Only the stages the scene's ``outputs`` need are built: ``"scans"`` runs surface, probe
and sensor; ``"features"`` also runs the neuron. A ``displacement``-fidelity scene imports
neither OpenCV nor PyMC. Every scan draws from its own child of
``numpy.random.SeedSequence(scene.seed)`` (one per scan id, split into probe and sensor
streams), so a scan's data do not depend on the order of the others.

Files written into the run directory: ``scene.toml`` (byte copy), ``truth.json`` (the
scene and every per-touch true parameter), ``scans.csv`` (long format, :data:`CSV_COLUMNS`)
and, when asked, ``features.csv`` (and ``sensor.avi``, the rendered frames, when an
``images``-fidelity scene sets ``optics.video``).
"""
from __future__ import annotations

import shutil
from dataclasses import asdict
from pathlib import Path

import numpy as np

from feeler.calib.progress import progress as bar
from feeler.calib.progress import stage
from feeler.datasets import Scans, scan_features
from feeler.models import probe, sensor, surface
from feeler.rundir import prepare_out_dir, write_json
from feeler.scene import scene_as_dict

__all__ = ["CSV_COLUMNS", "plate_profile", "simulate_scans", "features_of", "simulate_robot_scan"]

CSV_COLUMNS = ("scan_id", "plate", "step_mm", "speed_mm_s", "t_s", "x_mm", "ux_mm", "uy_mm", "uz_mm")
_FORMATS = ("%d", "%d", "%.6g", "%.6g", "%.6g", "%.9g", "%.9g", "%.9g", "%.9g")


def plate_profile(surf, height_mm: float) -> surface.Profile:
    """The profile of one plate of a robot-scan scene's ``[surface]`` table."""
    if surf.profile == "staircase":
        return surface.staircase(surf.position_mm, surf.spacing_mm, height_mm, surf.count)
    if surf.profile == "grating":
        return surface.grating(surf.position_mm, surf.spacing_mm, height_mm, surf.count)
    return surface.step(surf.position_mm, height_mm)


def _sensor_params(scene, scene_path=None, out_dir=None, progress: bool | None = False):
    if scene.sensor.fidelity == "displacement":
        n = scene.noise
        return sensor.DisplacementNoise(n.ux_sd_mm, n.uy_sd_mm, n.uz_sd_mm)
    from feeler.scenes._optics import fidelity_params

    return fidelity_params(scene.optics, scene.sensor.fidelity, scene_path=scene_path, out_dir=out_dir,
                           progress=progress)


def simulate_scans(scene, *, scene_path=None, out_dir=None,
                   progress: bool | None = None) -> tuple[Scans, list[dict]]:
    """All scans of a robot-scan scene, and the true state of every touch.

    At the ``images`` fidelity the scans are observed together (packed onto the camera's
    elements, :mod:`feeler.simulate.images`) with one extra child of the seed; ``scene_path``
    locates ``optics.layout``, ``out_dir`` receives ``sensor.avi`` when ``optics.video``.

    ``progress``: a line per stage on stderr and a bar over the scans (and, at ``images``,
    over the frames) on a terminal (:mod:`feeler.calib.progress`); False: silent.

    Raises:
        SceneError: frames rejected by the reader, naming the ``optics`` key their reasons
            point to (shot noise, discs too small or too large for the blur).

    Returns:
        scans (Scans): arrays ``(n_plates * scans_per_plate, n_time)``; scan_id =
            plate * scans_per_plate + repeat.
        touches (list[dict]): per scan, its ids, step and drawn touch (U_y0, tilt, x0, drift).
    """
    m, p = scene.motion, scene.probe
    motion = probe.Motion(m.speed_mm_s, m.traverse_mm, m.dt_s, m.x0_mm)
    params = probe.ProbeParams(pad_width_mm=p.pad_width_mm, uy0_mean_mm=p.uy0_mean_mm, uy0_sd_mm=p.uy0_sd_mm,
                               tilt_sd_deg=p.tilt_sd_deg, x0_sd_mm=m.x0_sd_mm,
                               drift_sd_mm_s=p.drift_sd_mm_s, shear_per_normal=p.shear_per_normal,
                               breakaway_frac=p.breakaway_frac, breakaway_s=p.breakaway_s,
                               snap_prob=p.snap_prob)
    noise = _sensor_params(scene, scene_path, out_dir, progress)
    fidelity = scene.sensor.fidelity
    per_plate = scene.repeats.scans_per_plate
    heights = scene.surface.heights_mm
    n = len(heights) * per_plate
    children = np.random.SeedSequence(scene.scene.seed).spawn(n + 1)
    t_all, x_all, u_all, touches = [], [], [], []
    profiles = [plate_profile(scene.surface, height) for height in heights]
    stage(f"simulating {n} scans of {len(heights)} plates ({fidelity} fidelity)", progress)
    for scan_id in bar(range(n), desc="scans", enabled=progress):
        plate, height = scan_id // per_plate, heights[scan_id // per_plate]
        probe_ss, sensor_ss = children[scan_id].spawn(2)
        touch = probe.draw_touch(params, motion, np.random.default_rng(probe_ss))
        t, x, u_true = probe.tip_displacement(profiles[plate], motion, params, touch)
        if fidelity != "images":
            u_true = sensor.observe(u_true, fidelity=fidelity, params=noise,
                                    rng=np.random.default_rng(sensor_ss))
        t_all.append(t), x_all.append(x), u_all.append(u_true)
        touches.append({"scan_id": scan_id, "plate": plate, "step_mm": height, **asdict(touch)})
    u = np.stack(u_all)
    if fidelity == "images":                   # its stages: rendering, (video,) reading the frames
        from feeler.scenes._frames import rejection_error
        from feeler.simulate.images import FramesRejected

        try:
            u = sensor.observe(u, fidelity=fidelity, params=noise, rng=np.random.default_rng(children[n]))
        except FramesRejected as exc:
            raise rejection_error(exc, scene.optics, scene_path, "scan") from None
    scans = Scans(scan_id=np.arange(n), step_mm=np.repeat(np.asarray(heights, float), per_plate),
                  speed_mm_s=np.full(n, m.speed_mm_s), t_s=np.stack(t_all), x_mm=np.stack(x_all),
                  ux_mm=u[..., 0], uy_mm=u[..., 1], uz_mm=u[..., 2])
    return scans, touches


def features_of(scene, scans: Scans):
    """Per-scan features with the scene's neuron; the ΔU_y windows follow the probe's rise time."""
    nrn, m = scene.neuron, scene.motion
    rise_s = scene.probe.pad_width_mm / m.speed_mm_s
    return scan_features(scans, a=nrn.a, tau_s=nrn.tau_s, h=nrn.h, length_mm=nrn.length_mm,
                         kernel=nrn.kernel, gap_s=rise_s + m.dt_s, span_s=max(4 * m.dt_s, 1.0))


def _write_scans_csv(path: Path, scans: Scans, per_plate: int) -> None:
    n_scans, n_time = scans.t_s.shape
    ids = np.repeat(scans.scan_id, n_time)
    cols = [ids, ids // per_plate, np.repeat(scans.step_mm, n_time), np.repeat(scans.speed_mm_s, n_time),
            scans.t_s.ravel(), scans.x_mm.ravel(), scans.ux_mm.ravel(), scans.uy_mm.ravel(), scans.uz_mm.ravel()]
    np.savetxt(path, np.column_stack(cols), fmt=list(_FORMATS), delimiter=",",
               header=",".join(CSV_COLUMNS), comments="")


def _write_features_csv(path: Path, scans: Scans, feats, per_plate: int) -> None:
    cols = [scans.scan_id, scans.scan_id // per_plate, scans.step_mm, feats.peak_z, feats.jump_uy_mm,
            feats.peak_rate_uy_mm_s]
    np.savetxt(path, np.column_stack(cols), fmt=["%d", "%d", "%.6g", "%.9g", "%.9g", "%.9g"], delimiter=",",
               header="scan_id,plate,step_mm,peak_z,jump_uy_mm,peak_rate_uy_mm_s", comments="")


def simulate_robot_scan(scene, scene_path: str | Path, out: str | Path, force: bool,
                        progress: bool | None = None) -> None:
    """Robot-scan scenes: ``scans.csv`` (and ``features.csv`` when asked); ``progress`` as
    in :func:`simulate_scans`."""
    outputs = set(scene.scene.outputs)
    files = ["scene.toml", "truth.json", "scans.csv"] + (["features.csv"] if "features" in outputs else [])
    if scene.optics is not None and scene.optics.video and scene.sensor.fidelity == "images":
        files.append("sensor.avi")
    out = prepare_out_dir(out, files, force=force)
    scans, touches = simulate_scans(scene, scene_path=scene_path, out_dir=out, progress=progress)
    shutil.copyfile(scene_path, out / "scene.toml")
    write_json(out / "truth.json", {"scene": scene_as_dict(scene), "n_time": int(scans.t_s.shape[1]),
                                    "touches": touches})
    per_plate = scene.repeats.scans_per_plate
    _write_scans_csv(out / "scans.csv", scans, per_plate)
    if "features" in outputs:
        stage(f"features of {scans.scan_id.size} scans (the scene's neuron)", progress)
        _write_features_csv(out / "features.csv", scans, features_of(scene, scans), per_plate)
