"""Mesh convergence of L2 and the ladder's accuracy goals, at a small size.

``FEELER_FULL=1`` runs the full-size study (the same as ``feeler skin ladder``).
"""
import os

import pytest

from feeler.skin.study import run_ladder_study


@pytest.mark.slow
def test_ladder_converges_and_l1_is_within_ten_percent(tmp_path):
    full = os.environ.get("FEELER_FULL") == "1"
    result = run_ladder_study(tmp_path, small=not full)
    assert result["convergence_change"]["peak_step_eps"] < 0.01
    assert result["l1_rate_error"] <= 0.10
    fitted = next(t for t in result["trade"] if t["level"] == "l0-fitted")
    raw = next(t for t in result["trade"] if t["level"] == "l0")
    assert fitted["rate_error"] < raw["rate_error"]
    for name in ("convergence.csv", "trade.csv", "ladder.json", "ladder.png"):
        assert (tmp_path / name).stat().st_size > 0
