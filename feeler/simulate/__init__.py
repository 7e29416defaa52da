"""Pipeline composition: a scene file → its kind's simulator → a run directory.

One module per scene kind: :mod:`~feeler.simulate.robot` (robot-scan: surface → probe →
sensor → scans.csv), :mod:`~feeler.simulate.calibration` (sensor-calibration),
:mod:`~feeler.simulate.finger` (finger-steps), :mod:`~feeler.simulate.psychophysics`
(psychophysics-2afc); :mod:`~feeler.simulate.images` composes the camera-image fidelity
(models → rendered frames → the hardware's OpenCV reading). Only the stages a scene
needs are imported: a displacement-fidelity robot scene imports neither OpenCV nor PyMC.
"""
from __future__ import annotations

import dataclasses
import importlib
import re
import shutil
import sys
from pathlib import Path

from feeler.errors import ArgumentError, SceneError
from feeler.rundir import prepare_out_dir
from feeler.scene import load_scene
from feeler.simulate.robot import CSV_COLUMNS, features_of, plate_profile, simulate_robot_scan, simulate_scans
from feeler.simulate.stale import not_this_run, outputs_of, remove, removed_line, stale_outputs

__all__ = ["SIMULATORS", "run_simulation", "written_files", "with_seed", "CSV_COLUMNS", "features_of", "plate_profile", "simulate_scans",
           "simulate_robot_scan"]


def run_simulation(scene_path: str | Path, out: str | Path, *, force: bool = False,
                   seed: int | None = None, progress: bool | None = None) -> Path:
    """Simulate any shipped kind of scene into the run directory ``out``; returns ``out``.

    The scene's kind picks the simulator (:data:`SIMULATORS`); each writes ``scene.toml``
    (a byte copy), ``truth.json`` and its data files. ``seed`` (≥ 0) replaces the scene's
    ``[scene] seed``; the run's ``scene.toml`` is then the copy with that seed written in,
    so the run is still reproduced by its own scene file.

    ``progress`` (:mod:`feeler.calib.progress`): None, a line per stage on stderr and a
    bar over scans, frames or skin runs on a terminal (off a terminal, a line per skin
    run); True, bars even off a terminal; False, silent.

    Raises:
        SceneError: the scene does not validate (checked before ``out`` is created), or its
            rendered frames are rejected; a failed run removes ``out`` when it created it.
        OverwriteError: data exist and not ``force``; or, with ``force``, ``out`` holds
            files of feeler's names this run does not write and no earlier simulation
            there wrote (:mod:`feeler.simulate.stale`; those an earlier simulation wrote,
            and an earlier report, are removed once this run is written).
        ArgumentError: the scene asks for a sensor fidelity not available here.
    """
    scene = load_scene(scene_path)
    kind = scene.scene.kind
    if seed is not None:
        if not hasattr(scene.scene, "seed"):
            raise ArgumentError("--seed", seed, f"a {kind} scene draws nothing at random; it has no seed")
        if seed < 0:
            raise ArgumentError("--seed", seed, "an integer >= 0")
        scene = dataclasses.replace(scene, scene=dataclasses.replace(scene.scene, seed=seed))
    if kind not in SIMULATORS:
        hint = " (a scan plan: run it with `feeler acquire --plan`, --emulate without hardware)" \
            if kind == "scan-plan" else ""
        raise SceneError(scene_path, "scene.kind", f"{kind!r} is not a scene to simulate{hint}; "
                                                   f"simulate takes {', '.join(sorted(SIMULATORS))}")
    module, func = SIMULATORS[kind].split(":")
    fresh = not Path(out).exists()
    stale = stale_outputs(out, scene) if force else []     # refused here, before any work
    try:
        getattr(importlib.import_module(module), func)(scene, scene_path, out, force, progress=progress)
    except Exception:
        if fresh:                # a refused run leaves no directory of its own behind
            shutil.rmtree(out, ignore_errors=True)
        raise
    if seed is not None:
        copy = Path(out) / "scene.toml"
        copy.write_text(with_seed(Path(scene_path).read_text(encoding="utf-8"), seed), encoding="utf-8")
    if stale:                    # the earlier run's files this one did not overwrite: one run per directory
        remove(stale)
        if progress is not False:
            print(removed_line(stale, Path(out)), file=sys.stderr, flush=True)
    others = not_this_run(Path(out), written_files(out, scene))
    if others and progress is not False:          # a user's own files: left alone, and not this run's
        print(f"{'--force: ' if force else ''}left {', '.join(others)} in {out} as {'they were' if len(others) > 1 else 'it was'}: "
              f"not written by this simulation, so not part of its run", file=sys.stderr, flush=True)
    return Path(out)


def written_files(out: str | Path, scene) -> list[str]:
    """The names of the files a simulation of ``scene`` wrote into ``out``, sorted
    (:func:`~feeler.simulate.stale.outputs_of`; other files there are not its own)."""
    return sorted(n for n in outputs_of(scene) if (Path(out) / n).is_file())


def with_seed(text: str, seed: int) -> str:
    """A scene file's text with ``seed = <seed>`` in its ``[scene]`` table (replaced, or
    added under the table's header when the file relied on the default)."""
    head = re.search(r"(?m)^\[scene\][^\n]*\n", text)
    if head is None:
        return f"[scene]\nseed = {seed}\n" + text
    end = re.compile(r"(?m)^\[").search(text, head.end())
    stop = len(text) if end is None else end.start()
    body, n = re.subn(r"(?m)^(\s*seed\s*=\s*)[^\n#]*", lambda m: f"{m.group(1)}{seed} ", text[head.end():stop], 1)
    if n == 0:
        body = f"seed = {seed}\n" + body
    return text[:head.end()] + body + text[stop:]


def _simulate_calibration(scene, scene_path, out, force, progress=None) -> None:
    from feeler.simulate.calibration import simulate_sensor_calibration

    simulate_sensor_calibration(scene, out, force=force, scene_path=scene_path, progress=progress)


def _simulate_psychophysics(scene, scene_path, out, force, progress=None) -> None:
    from feeler.simulate.psychophysics import simulate_psychophysics

    prepare_out_dir(out, ["scene.toml"], force=force)
    simulate_psychophysics(scene, out, force=force, progress=progress)
    shutil.copyfile(scene_path, Path(out) / "scene.toml")


# scene kind → "module:function(scene, scene_path, out, force, progress=None)"; imported only when used
SIMULATORS = {
    "robot-scan": "feeler.simulate.robot:simulate_robot_scan",
    "sensor-calibration": "feeler.simulate:_simulate_calibration",
    "psychophysics-2afc": "feeler.simulate:_simulate_psychophysics",
    "finger-steps": "feeler.simulate.finger:simulate_finger_scene",
}
