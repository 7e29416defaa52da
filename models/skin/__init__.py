"""Finger skin mechanics: strain ε_y at the Meissner corpuscle for a step and a speed.

Three fidelities behind one interface, :func:`strain_history`:
``"l0"`` closed-form half-space, ``"l1"`` influence functions from one adjoint FEM solve,
``"l2"`` viscoelastic contact FEM (scikit-fem on a gmsh mesh). Vectorised slides for
samplers: :func:`feeler.models.skin.l0.l0_slide_strain` and
:func:`feeler.models.skin.l1.l1_slide_strain`. scikit-fem and gmsh are imported only
when L1/L2 first build a mesh.
"""
from feeler.models.skin.history import LEVELS, as_step_profile, strain_history
from feeler.models.skin.l0 import l0_slide_strain
from feeler.models.skin.loading import Loading, loading_history
from feeler.models.skin.params import SkinParams, StepProfile

__all__ = ["SkinParams", "StepProfile", "Loading", "loading_history", "strain_history", "LEVELS",
           "as_step_profile", "l0_slide_strain"]
