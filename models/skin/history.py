"""The one interface of the skin ladder: :func:`strain_history`."""
from __future__ import annotations

from feeler.errors import ArgumentError
from feeler.models.skin.l0 import l0_strain_history
from feeler.models.skin.params import SkinParams, StepProfile

__all__ = ["LEVELS", "strain_history", "as_step_profile"]

LEVELS = ("l0", "l1", "l2")


def as_step_profile(profile, edge_um: float = 50.0) -> StepProfile:
    """A :class:`StepProfile` from itself or from a one-edge ``feeler.models.surface.Profile``.

    The surface module's edges are sharp; the skin ladder rounds them with a ramp of
    ``edge_um`` (invisible at the corpuscle's depth, needed by the FEM).
    """
    if isinstance(profile, StepProfile):
        return profile
    from feeler.models.surface import Profile
    if isinstance(profile, Profile):
        if len(profile.edges_mm) != 1:
            raise ArgumentError("profile", profile, "the skin ladder takes a plate with exactly one step")
        return StepProfile(height_um=profile.jumps_mm[0] * 1e3, position_mm=profile.edges_mm[0], edge_um=edge_um)
    raise ArgumentError("profile", profile, "a StepProfile or a one-step feeler.models.surface.Profile")


def strain_history(profile: StepProfile, speed_mm_s: float, *, level: str = "l0",
                   params: SkinParams | None = None, dt_s: float | None = None, mesh=None):
    """Strain ε_y at the corpuscle for a step slid under the finger.

    Args:
        profile: the step: a :class:`StepProfile` (height µm, position mm, edge ramp µm)
            or a one-step ``feeler.models.surface.Profile`` (edge rounded over 50 µm).
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
    profile = as_step_profile(profile)
    if level == "l0":
        return l0_strain_history(profile, speed_mm_s, params=params, dt_s=dt_s)
    if level == "l1":
        from feeler.models.skin.l1 import l1_strain_history
        return l1_strain_history(profile, speed_mm_s, params=params, dt_s=dt_s, mesh=mesh)
    if level == "l2":
        from feeler.models.skin.l2 import l2_strain_history
        return l2_strain_history(profile, speed_mm_s, params=params, dt_s=dt_s, mesh=mesh)
    raise ArgumentError("level", level, f"allowed: {', '.join(LEVELS)}")
