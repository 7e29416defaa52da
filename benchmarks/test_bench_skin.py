"""Skin ladder speed per slide as ratios to L2 timed in the same run (issue 5).

Goals: L1 ≥ 100× faster per slide than L2, L0 ≥ 10⁴×. L2 and L1 on the converged mesh
of ``feeler skin ladder`` (2× the default sizes: the trade table's reference), 15 µm step
at 20 mm/s, 10 µm of travel per step. Each level's one-off setup (mesh, assembly,
factorisation, compliance, adjoint) is done before timing; ``feeler skin ladder``
reports it apart.
"""
import pytest

from _ratios import best_seconds, record_ratio
from feeler.models.skin import SkinParams, StepProfile, strain_history
from feeler.models.skin.l1 import influence
from feeler.models.skin.mesh import MeshSpec

PARAMS, MESH, PROFILE, SPEED = SkinParams(), MeshSpec().refined(2.0), StepProfile(15.0), 20.0


@pytest.fixture(scope="module")
def l2_seconds():
    influence(PARAMS, MESH)          # setup outside the timing (cached)
    return best_seconds(lambda: strain_history(PROFILE, SPEED, level="l2", params=PARAMS, mesh=MESH),
                        repeat=2)


@pytest.mark.parametrize("level, goal", [("l1", 100.0), ("l0", 1e4)])
def test_slide_vs_l2(benchmark, l2_seconds, level, goal):
    benchmark.pedantic(strain_history, args=(PROFILE, SPEED),
                       kwargs=dict(level=level, params=PARAMS, mesh=MESH), rounds=50, iterations=1)
    record_ratio(benchmark, f"L2 / {level.upper()} seconds per slide", l2_seconds / benchmark.stats["min"],
                 f">= {goal:g}")
