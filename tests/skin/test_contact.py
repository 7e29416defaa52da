"""The condensed contact solver: KKT conditions, the NNLS fallback, the failure branch."""
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

import feeler.models.skin.contact as contact
from feeler.errors import SolverError
from feeler.models.skin.contact import solve_contact


def _problem(seed, n=30):
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(n, n))
    return a @ a.T / n + np.eye(n), rng.normal(size=n)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000))
def test_kkt_conditions_hold(seed):
    c, need = _problem(seed)
    p, active = solve_contact(c, need)
    gap = c @ p - need
    assert np.all(p >= 0) and np.all(gap >= -1e-9)
    assert np.all(np.abs(p * gap) < 1e-9)
    np.testing.assert_array_equal(active, p > 0)


def test_nnls_fallback_gives_the_same_forces(monkeypatch):
    c, need = _problem(3)
    p, _ = solve_contact(c, need)
    monkeypatch.setattr(contact, "MAX_ITER", 0)
    q, _ = solve_contact(c, need)
    np.testing.assert_allclose(q, p, atol=1e-9)


def test_unconverged_contact_raises(monkeypatch):
    c, need = _problem(4)
    monkeypatch.setattr(contact, "MAX_ITER", 0)
    monkeypatch.setattr(contact, "_nnls_contact", lambda c, need: np.zeros(len(need)))
    with pytest.raises(SolverError, match="contact"):
        solve_contact(c, need)
