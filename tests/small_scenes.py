"""Shipped scenes made small for tests (same physics, fewer and coarser runs)."""
from __future__ import annotations

from pathlib import Path

__all__ = ["SCENES", "small_finger_scene"]

SCENES = Path(__file__).resolve().parents[1] / "datasets-synthetic"

_FINGER = (("heights_um = [5.0, 7.5, 10.0, 12.5, 15.0]", "heights_um = [5.0, 10.0, 15.0]"),
           ("travel_step_mm = 0.01 ", "travel_step_mm = 0.05 "), ("h_contact_mm = 0.0177", "h_contact_mm = 0.05"),
           ("h_corpuscle_mm = 0.0071", "h_corpuscle_mm = 0.02"), ("h_far_mm = 0.567", "h_far_mm = 1.5"),
           ("grade = 0.25", "grade = 0.4"))


def small_finger_scene(path: Path) -> Path:
    """Write the shipped finger-steps scene (skin L1) at ``path`` with 3 heights x 2 speeds
    on a coarse mesh and 50 µm travel steps; returns ``path``."""
    text = (SCENES / "finger-steps.toml").read_text(encoding="utf-8")
    for old, new in _FINGER:
        assert old in text, old
        text = text.replace(old, new)
    path.write_text(text, encoding="utf-8")
    return path
