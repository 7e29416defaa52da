"""Pipeline composition: a scene file → its kind's simulator → a run directory.

One module per scene kind: :mod:`~feeler.simulate.robot` (robot-scan: surface → probe →
sensor → scans.csv), :mod:`~feeler.simulate.calibration` (sensor-calibration),
:mod:`~feeler.simulate.finger` (finger-steps), :mod:`~feeler.simulate.psychophysics`
(psychophysics-2afc); :mod:`~feeler.simulate.images` composes the camera-image fidelity
(models → rendered frames → the hardware's OpenCV reading). Only the stages a scene
needs are imported: a displacement-fidelity robot scene imports neither OpenCV nor PyMC.
"""
from __future__ import annotations

import importlib
import shutil
from pathlib import Path

from feeler.errors import SceneError
from feeler.rundir import prepare_out_dir
from feeler.scene import load_scene
from feeler.simulate.robot import CSV_COLUMNS, features_of, plate_profile, simulate_robot_scan, simulate_scans

__all__ = ["SIMULATORS", "run_simulation", "CSV_COLUMNS", "features_of", "plate_profile", "simulate_scans",
           "simulate_robot_scan"]


def run_simulation(scene_path: str | Path, out: str | Path, *, force: bool = False) -> Path:
    """Simulate any shipped kind of scene into the run directory ``out``; returns ``out``.

    The scene's kind picks the simulator (:data:`SIMULATORS`); each writes ``scene.toml``
    (a byte copy), ``truth.json`` and its data files.

    Raises:
        SceneError: the scene does not validate. OverwriteError: data exist and not ``force``.
        ArgumentError: the scene asks for a sensor fidelity not available here.
    """
    scene = load_scene(scene_path)
    kind = scene.scene.kind
    if kind not in SIMULATORS:
        hint = " (a scan plan: run it with `feeler acquire --plan`, --emulate without hardware)" \
            if kind == "scan-plan" else ""
        raise SceneError(scene_path, "scene.kind", f"{kind!r} is not a scene to simulate{hint}; "
                                                   f"simulate takes {', '.join(sorted(SIMULATORS))}")
    module, func = SIMULATORS[kind].split(":")
    getattr(importlib.import_module(module), func)(scene, scene_path, out, force)
    return Path(out)


def _simulate_calibration(scene, scene_path, out, force) -> None:
    from feeler.simulate.calibration import simulate_sensor_calibration

    simulate_sensor_calibration(scene, out, force=force, scene_path=scene_path)


def _simulate_psychophysics(scene, scene_path, out, force) -> None:
    from feeler.simulate.psychophysics import simulate_psychophysics

    prepare_out_dir(out, ["scene.toml"], force=force)
    simulate_psychophysics(scene, out, force=force)
    shutil.copyfile(scene_path, Path(out) / "scene.toml")


# scene kind → "module:function(scene, scene_path, out, force)"; imported only when used
SIMULATORS = {
    "robot-scan": "feeler.simulate.robot:simulate_robot_scan",
    "sensor-calibration": "feeler.simulate:_simulate_calibration",
    "psychophysics-2afc": "feeler.simulate:_simulate_psychophysics",
    "finger-steps": "feeler.simulate.finger:simulate_finger_scene",
}
