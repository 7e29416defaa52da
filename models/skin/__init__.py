"""Finger skin mechanics: strain ε_y at the Meissner corpuscle for a step and a speed.

Three fidelities behind one interface, :func:`strain_history`:
``"l0"`` closed-form half-space, ``"l1"`` influence functions from one adjoint FEM solve,
``"l2"`` viscoelastic contact FEM (scikit-fem on a gmsh mesh). Only L0 is imported
eagerly; L1/L2 import scikit-fem and gmsh when called.
"""
from feeler.models.skin.history import LEVELS, strain_history
from feeler.models.skin.loading import Loading, loading_history
from feeler.models.skin.params import SkinParams, StepProfile

__all__ = ["SkinParams", "StepProfile", "Loading", "loading_history", "strain_history", "LEVELS"]
