"""The scene an M2 fit was trained on: recorded in the posterior, found again for M3.

``feeler calibrate neuron RUN`` stores the text of ``RUN/scene.toml`` and its path in the
posterior's attributes (``scene_toml``, ``scene_path``). :func:`fit_scene_path` gives the
scene file ``discriminate`` simulates: an explicit ``--scene`` first, else the recorded
path when it still holds the recorded text (relative paths inside it, e.g. an optics
layout, keep working), else the recorded text written to a temporary file, kept as long
as the returned handle lives. A fit without a scene (a bare CSV) needs ``--scene``.
"""
from __future__ import annotations

import tempfile
from pathlib import Path

from feeler.errors import ArgumentError

__all__ = ["fit_scene_path", "check_scene_matches", "scene_note"]

#: what ``discriminate`` sets itself, or names the scene: not a difference in the touches
_OWN = ("scene.", "repeats.", "surface.heights_mm", "neuron.")


def fit_scene_path(result, override=None):
    """(scene file, keep-alive handle or None) for the forward model of ``result``."""
    attrs = result.posterior["posterior"].attrs
    if override is not None:
        path = Path(override)
        check_scene_matches(path, attrs)
        return path, None
    text = attrs.get("scene_toml")
    if not text:
        raise ArgumentError("--scene", None, "the fit records no scene (it was fitted from a bare CSV); "
                                             "give the robot-scan scene of its scans")
    recorded = Path(str(attrs.get("scene_path", "")))
    if str(recorded) and recorded.is_file() and recorded.read_text(encoding="utf-8") == text:
        check_scene_matches(recorded, attrs)
        return recorded, None
    keep = tempfile.TemporaryDirectory(prefix="feeler-scene-")
    path = Path(keep.name) / "scene.toml"
    path.write_text(text, encoding="utf-8")
    check_scene_matches(path, attrs)
    return path, keep


def check_scene_matches(path: Path, attrs) -> None:
    """The scene's neuron must read strain the way the fit did (length and kernel)."""
    from feeler.scene import load_scene

    scene = load_scene(path)
    if not hasattr(scene, "neuron"):
        raise ArgumentError("--scene", str(path), "a robot-scan scene")
    length, kernel = attrs.get("length_mm"), attrs.get("kernel")
    if length is not None and abs(float(scene.neuron.length_mm) - float(length)) > 1e-9 * float(length):
        raise ArgumentError("--scene", str(path), f"a scene with neuron.length_mm = {float(length):g} mm like "
                                                  f"the fit (it has {scene.neuron.length_mm:g})")
    if kernel is not None and scene.neuron.kernel != kernel:
        raise ArgumentError("--scene", str(path), f"a scene with neuron.kernel = {kernel!r} like the fit")


def _fields(obj, prefix: str = "") -> dict:
    """A scene's parameters flattened to ``section.name -> value``."""
    import dataclasses

    out = {}
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        if dataclasses.is_dataclass(value):
            out.update(_fields(value, f"{prefix}{f.name}."))
        else:
            out[f"{prefix}{f.name}"] = value
    return out


def scene_note(result, override) -> str | None:
    """One line when ``override`` (``--scene``) describes touches other than those the fit
    was trained on (stage speed, probe, read-out noise, sensor …: every parameter but the
    heights, the repeats, the seed and the scene's name), else None. ``classify`` flags a
    scan outside the training envelope (speed beyond ×1.25, read-out noise beyond ×1.5);
    ``discriminate`` simulates whole experiments, so it names what changed. A fit of a bare
    scan CSV recorded no scene: its training scans' speed labels against the scene's speed."""
    from feeler.scene import load_scene

    if override is None:
        return None
    attrs = result.posterior["posterior"].attrs
    if not attrs.get("scene_toml"):                 # a bare scan CSV's fit: its scans' speed labels only
        from feeler.calib.neuron.live.envelope import training_speed_mm_s

        trained_speed, given = training_speed_mm_s(attrs), load_scene(Path(override)).motion.speed_mm_s
        if trained_speed is None or abs(given / trained_speed - 1) < 1e-3:
            return None
        return (f"note: --scene {override} moves the stage at {given:g} mm/s, the fit's training scans at "
                f"{trained_speed:g} mm/s (their speed labels): its touches are not the kind the decoder learned, so "
                f"P(correct), the threshold and the PSE describe it reading touches it was not trained on")
    path, keep = fit_scene_path(result)          # the recorded scene (its own file while it holds the text)
    try:
        trained = _fields(load_scene(path))
    finally:
        if keep is not None:
            keep.cleanup()
    given = _fields(load_scene(Path(override)))
    changed = [f"{k} {trained[k]!r} -> {given[k]!r}" for k in given
               if k in trained and not k.startswith(_OWN) and trained[k] != given[k]]
    if not changed:
        return None
    return (f"note: --scene {override} differs from the scene the fit was trained on in {', '.join(changed)}: "
            f"its touches are not the kind the decoder learned, so P(correct), the threshold and the PSE "
            f"describe it reading touches it was not trained on")
