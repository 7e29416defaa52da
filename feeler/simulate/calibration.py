"""Simulate a ``sensor-calibration`` campaign: ``calibration.csv``, ``truth.json``, ``scene.toml``.

Generative model in :mod:`feeler.scenes.sensor_calibration`. One
``numpy.random.default_rng(scene.scene.seed)`` draws, in order, the stage errors
(n×3) and the force noise (n×3), so a scene always yields the same data.
"""
from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np

from feeler.calib.progress import stage
from feeler.rundir import prepare_out_dir, write_json
from feeler.scene import scene_as_dict
from feeler.scenes.sensor_calibration import commanded_displacements

__all__ = ["simulate_sensor_calibration", "draw_campaign", "CALIBRATION_FILES", "scene_to_toml"]

CALIBRATION_FILES = ("calibration.csv", "truth.json", "scene.toml")
_HEADER = "point_id,ux_mm,uy_mm,uz_mm,fx_n,fy_n,fz_n"


def draw_campaign(scene, rng: np.random.Generator, scene_path=None, out_dir=None,
                  progress: bool | None = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Commanded U (mm), true U (mm) and measured F (N), each ndarray[n, 3].

    At an optical fidelity F is read through the element (areas or rendered frames) with
    the same ``rng`` after the stage errors; ``scene_path`` locates ``optics.layout``,
    ``out_dir`` receives ``sensor.avi`` when ``optics.video``. ``progress``: None or True,
    a line per stage on stderr (and at ``images`` a bar over the frames on a terminal);
    False, silent.
    """
    u_cmd = commanded_displacements(scene.design)
    n = u_cmd.shape[0]
    stage(f"simulating a calibration campaign of {n} points ({scene.sensor.fidelity} fidelity)", progress)
    u_true = u_cmd + scene.noise.stage_sd_mm * rng.standard_normal((n, 3))
    if scene.sensor.fidelity != "displacement":
        return u_cmd, u_true, _optical_force(scene, u_true, rng, scene_path, out_dir, progress)
    k = np.linalg.inv(np.asarray(scene.sensor.c_mm_per_n, dtype=float))
    if scene.noise.kind == "student":
        eta = rng.standard_t(scene.noise.student_nu, size=(n, 3))
    else:
        eta = rng.standard_normal((n, 3))
    f = u_true @ k.T + eta * np.asarray(scene.noise.f_sd_n, dtype=float)
    return u_cmd, u_true, f


def _optical_force(scene, u_true: np.ndarray, rng: np.random.Generator, scene_path, out_dir,
                   progress: bool | None = False) -> np.ndarray:
    """F (n, 3) N read through the optical element whose C is the scene's true C."""
    from feeler.models import sensor
    from feeler.models.optics import force_from_displacement
    from feeler.scenes._frames import rejection_error
    from feeler.scenes._optics import fidelity_params
    from feeler.simulate.images import FramesRejected

    c = np.asarray(scene.sensor.c_mm_per_n, dtype=float)
    params = fidelity_params(scene.optics, scene.sensor.fidelity, scene_path=scene_path, out_dir=out_dir,
                             c_mm_per_n=c, progress=progress)
    try:
        u_read = sensor.observe(u_true[:, None, :], fidelity=scene.sensor.fidelity, params=params, rng=rng)[:, 0]
    except FramesRejected as exc:
        raise rejection_error(exc, scene.optics, scene_path, "point") from None
    return force_from_displacement(u_read, c)


def simulate_sensor_calibration(scene, out_dir: str | Path, force: bool = False,
                                scene_path: str | Path | None = None,
                                progress: bool | None = False) -> dict[str, Path]:
    """Write the campaign of ``scene`` into ``out_dir``.

    Args:
        scene: a loaded ``sensor-calibration`` scene.
        out_dir: run directory (created).
        force (bool): overwrite existing files.
        scene_path: the scene file, copied byte for byte to ``scene.toml`` when given;
            otherwise ``scene.toml`` is written from the validated scene.
        progress (bool | None): as in :func:`draw_campaign`.
    Returns:
        dict with the paths ``calibration``, ``truth`` and ``scene``.
    Raises:
        OverwriteError: a file exists and ``force`` is false.
    """
    video = scene.optics is not None and scene.optics.video and scene.sensor.fidelity == "images"
    out = prepare_out_dir(out_dir, CALIBRATION_FILES + (("sensor.avi",) if video else ()), force=force)
    rng = np.random.default_rng(scene.scene.seed)
    u_cmd, u_true, f = draw_campaign(scene, rng, scene_path, out, progress=progress)
    ids = np.arange(u_cmd.shape[0])
    table = np.column_stack([ids, u_cmd, f])
    np.savetxt(out / "calibration.csv", table, delimiter=",", header=_HEADER, comments="",
               fmt=["%d"] + ["%.6f"] * 3 + ["%.9g"] * 3)
    c = np.asarray(scene.sensor.c_mm_per_n, dtype=float)
    write_json(out / "truth.json", {
        "synthetic": True,
        "C_mm_per_n": c, "K_n_per_mm": np.linalg.inv(c), "cond_C": float(np.linalg.cond(c)),
        "f_sd_n": list(scene.noise.f_sd_n), "stage_sd_mm": scene.noise.stage_sd_mm,
        "noise_kind": scene.noise.kind, "u_true_mm": u_true,
        "scene": scene_as_dict(scene),
    })
    if scene_path is not None:
        shutil.copyfile(scene_path, out / "scene.toml")
    else:
        (out / "scene.toml").write_text(scene_to_toml(scene_as_dict(scene)), encoding="utf-8")
    return {"calibration": out / "calibration.csv", "truth": out / "truth.json", "scene": out / "scene.toml"}


def scene_to_toml(tables: dict) -> str:
    """TOML text of a scene as nested dicts (tables of numbers, strings, bools, lists)."""
    lines = []
    for name, table in tables.items():
        if table is None:            # an optional table that is absent
            continue
        lines.append(f"[{name}]")
        for key, value in table.items():
            if value is not None:
                lines.append(f"{key} = {_toml_value(value)}")
        lines.append("")
    return "\n".join(lines)


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {type(v).__name__} as TOML")
