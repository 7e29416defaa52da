"""The one interface of the skin ladder: :func:`strain_history`."""
from __future__ import annotations

from feeler.errors import ArgumentError
from feeler.models.skin.l0 import l0_strain_history
from feeler.models.skin.params import SkinParams, StepProfile

__all__ = ["LEVELS", "strain_history"]

LEVELS = ("l0", "l1", "l2")


def strain_history(profile: StepProfile, speed_mm_s: float, *, level: str = "l0",
                   params: SkinParams | None = None, dt_s: float | None = None, mesh=None):
    """Strain ε_y at the corpuscle for a step slid under the finger.

    Args:
        profile: the step (height µm, position mm, edge ramp µm).
        speed_mm_s (float): sliding speed in mm/s, > 0.
        level (str): ``"l0"``, ``"l1"`` or ``"l2"``.
        params: the skin parameters (defaults: the paper's).
        dt_s (float | None): slide time step in s; None → 10 µm of travel per step.
        mesh (MeshSpec | None): mesh sizes for L1/L2 (ignored by L0).
    Returns:
        (t_s ndarray[n_time], eps_y ndarray[n_time]): times from the start of the press
        (s) and the corpuscle-averaged normal strain (compression < 0).
    """
    params = SkinParams() if params is None else params
    if level == "l0":
        return l0_strain_history(profile, speed_mm_s, params=params, dt_s=dt_s)
    if level == "l1":
        from feeler.models.skin.l1 import l1_strain_history
        return l1_strain_history(profile, speed_mm_s, params=params, dt_s=dt_s, mesh=mesh)
    if level == "l2":
        from feeler.models.skin.l2 import l2_strain_history
        return l2_strain_history(profile, speed_mm_s, params=params, dt_s=dt_s, mesh=mesh)
    raise ArgumentError("level", level, f"allowed: {', '.join(LEVELS)}")
