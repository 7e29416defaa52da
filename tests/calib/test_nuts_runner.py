"""The shared NUTS runner (feeler.calib.nuts): PyMC's layout, the exact posterior of a
conjugate model, reproducible draws whether or not the compiled model came from the
cache, and the uncached and PyMC fallbacks."""
from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

pm = pytest.importorskip("pymc")

from feeler.calib.nuts import available_cores, sample_model, stats_of  # noqa: E402
from feeler.calib.posterior import posterior_from_draws  # noqa: E402

PRIOR_SD = 10.0


def _model(y: np.ndarray):
    """y[:, j] ~ N(μ_j, 1), μ_j ~ N(0, 10²): the posterior of μ_j is normal, in closed form."""
    with pm.Model() as model:
        mu = pm.Normal("mu", 0.0, PRIOR_SD, shape=y.shape[1])
        pm.Deterministic("twice", 2.0 * mu)
        pm.Normal("y", mu, 1.0, observed=y)
    return model


def _exact(y: np.ndarray):
    precision = 1.0 / PRIOR_SD**2 + y.shape[0]
    return y.sum(axis=0) / precision, np.full(y.shape[1], precision**-0.5)


@pytest.fixture(scope="module")
def data():
    # a fresh constant per session: the first compile below is a cache miss
    return np.random.default_rng().normal([1.0, -2.0], 1.0, size=(20, 2))


@pytest.fixture(scope="module")
def first(data):
    return sample_model(_model(data), draws=600, tune=400, chains=2, seed=11)


def test_pymc_layout_and_timings(first):
    assert set(first.children) == {"posterior", "sample_stats"}
    post = first["posterior"]
    assert set(post.data_vars) == {"mu", "twice"}
    assert post["mu"].dims == ("chain", "draw", "mu_dim_0") and post["mu"].shape == (2, 600, 2)
    stats = first["sample_stats"]
    assert {"diverging", "lp", "tree_depth", "step_size", "acceptance_rate"} <= set(stats.data_vars)
    assert stats["diverging"].dtype == bool and stats["lp"].dims == ("chain", "draw")
    attrs = stats.attrs
    assert attrs["compile_cache"] == "miss" and attrs["sampler"].startswith("nutpie")
    assert attrs["compile_seconds"] > 0 and attrs["sampling_seconds"] > 0


def test_posterior_is_the_conjugate_one(first, data):
    mean, sd = _exact(data)
    x = first["posterior"]["mu"].values.reshape(-1, 2)
    # 1 200 draws of an efficient sampler: the mean within 5 of its own standard errors
    # (an ESS of 1 200 / 4 taken as a floor), the sd within 12 %
    assert np.all(np.abs(x.mean(axis=0) - mean) <= 5 * sd / np.sqrt(300))
    np.testing.assert_allclose(x.std(axis=0, ddof=1), sd, rtol=0.12)
    np.testing.assert_array_equal(first["posterior"]["twice"].values, 2.0 * first["posterior"]["mu"].values)


def test_same_seed_same_draws_from_the_cache(first, data):
    again = sample_model(_model(data), draws=600, tune=400, chains=2, seed=11)
    assert again["sample_stats"].attrs["compile_cache"] == "hit"
    np.testing.assert_array_equal(again["posterior"]["mu"].values, first["posterior"]["mu"].values)
    other = sample_model(_model(data), draws=600, tune=400, chains=2, seed=12)
    assert not np.array_equal(other["posterior"]["mu"].values, first["posterior"]["mu"].values)


def _in_a_new_process(data, tmp_path) -> dict:
    np.save(tmp_path / "y.npy", data)
    script = textwrap.dedent(f"""
        import json, sys
        import numpy as np
        sys.path.insert(0, {str(Path(__file__).parent)!r})
        from test_nuts_runner import _model
        from feeler.calib.nuts import sample_model
        tree = sample_model(_model(np.load({str(tmp_path / 'y.npy')!r})), draws=600, tune=400, chains=2, seed=11)
        print(json.dumps({{"cache": tree["sample_stats"].attrs["compile_cache"],
                           "mu": tree["posterior"]["mu"].values.ravel().tolist()}}))
    """)
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_new_processes_loading_the_cache_draw_the_same(first, data, tmp_path):
    """Once the compiled model is cached, every process draws the same bits for a seed.
    The process that compiled it rounds differently in the last bits (its JIT-compiled
    graph against the cached object code; see feeler.calib.nuts), and NUTS trajectories
    amplify a last-bit difference: equal here to 1e-6 (measured: 1e-9 idle, up to 7e-9
    in one chain of a run under `make test-load`)."""
    one, two = _in_a_new_process(data, tmp_path), _in_a_new_process(data, tmp_path)
    assert one["cache"] == two["cache"] == "hit"
    assert one["mu"] == two["mu"]
    np.testing.assert_allclose(np.array(one["mu"]), first["posterior"]["mu"].values.ravel(), rtol=1e-6, atol=1e-9)


def test_var_names_cut_the_posterior(data):
    tree = sample_model(_model(data), draws=50, tune=50, chains=1, seed=3, var_names=["twice"])
    assert set(tree["posterior"].data_vars) == {"twice"}
    assert "mu_dim_0" not in tree["posterior"].dims


def test_stats_of_carries_the_timings_into_the_fit(first):
    stats = stats_of(first)
    assert set(stats) == {"diverging", "lp"} and stats["lp"].shape == (2, 600)
    tree = posterior_from_draws({"mu": first["posterior"]["mu"].values}, sample_stats=stats)
    assert tree["sample_stats"].attrs["compile_cache"] == "miss"
    assert tree["sample_stats"].attrs["sampling_seconds"] == first["sample_stats"].attrs["sampling_seconds"]


def test_shared_data_takes_the_uncached_compile(data):
    with pm.Model() as model:
        y = pm.Data("y_obs", data)
        mu = pm.Normal("mu", 0.0, PRIOR_SD, shape=data.shape[1])
        pm.Normal("y", mu, 1.0, observed=y)
    tree = sample_model(model, draws=400, tune=300, chains=2, seed=5)
    assert tree["sample_stats"].attrs["compile_cache"] == "off"
    mean, sd = _exact(data)
    x = tree["posterior"]["mu"].values.reshape(-1, 2)
    assert np.all(np.abs(x.mean(axis=0) - mean) <= 5 * sd / np.sqrt(200))


def test_without_nutpie_pymc_samples(data, monkeypatch):
    monkeypatch.setitem(sys.modules, "nutpie", None)          # import nutpie → ImportError
    tree = sample_model(_model(data), draws=200, tune=200, chains=2, seed=4)
    assert tree["sample_stats"].attrs["sampler"].startswith("pymc")
    assert tree["posterior"]["mu"].shape == (2, 200, 2) and "diverging" in tree["sample_stats"]


def test_available_cores_is_the_affinity_mask():
    assert 1 <= available_cores() <= (len(__import__("os").sched_getaffinity(0)))


def test_off_a_terminal_a_line_as_the_model_is_built_and_one_as_sampling_starts(data, capsys):
    """A NUTS psychophysics fit of 13-17 s printed nothing on stderr off a terminal (an
    outside audit): the first compile can take a minute. --no-progress (False) silences it."""
    capsys.readouterr()
    sample_model(_model(data), draws=50, tune=50, chains=1, seed=3)
    assert capsys.readouterr().err.splitlines() == [
        "NUTS: building the model (numba compiles it on a first run, then it is cached) ...",
        "NUTS: sampling 1 chain(s) of 50 warm-up and 50 kept draws ..."]
    sample_model(_model(data), draws=50, tune=50, chains=1, seed=3, progress=False)
    assert capsys.readouterr().err == ""


def test_a_sampling_run_nutpie_cut_short_is_an_interrupt_not_a_fit(data, monkeypatch):
    """nutpie catches Ctrl-C, aborts and returns the draws so far; the fits then failed on the
    short trace with a traceback (exit 1). Here nutpie returns 3 of the 40 draws asked for,
    as after a Ctrl-C: the runner raises KeyboardInterrupt (the CLI's exit 130)."""
    import nutpie

    real = nutpie.sample

    def cut_short(compiled, *, draws, **kw):
        return real(compiled, draws=3, **kw)

    monkeypatch.setattr(nutpie, "sample", cut_short)
    with pytest.raises(KeyboardInterrupt, match="NUTS sampling interrupted"):
        sample_model(_model(data), draws=40, tune=20, chains=2, seed=1, progress=False)


def test_a_ctrl_c_that_nutpie_swallows_is_raised_again(data, monkeypatch):
    """A SIGINT during sampling that nutpie catches while every chain still returns its full
    length (one chain done, another's tail NaN): the runner saw the signal and raises it."""
    import os
    import signal

    import nutpie

    real = nutpie.sample

    def interrupted(compiled, **kw):
        try:
            os.kill(os.getpid(), signal.SIGINT)           # Python's handler raises KeyboardInterrupt here
        except KeyboardInterrupt:
            pass                                          # as nutpie does: abort, return the draws so far
        return real(compiled, **kw)

    monkeypatch.setattr(nutpie, "sample", interrupted)
    with pytest.raises(KeyboardInterrupt, match="NUTS sampling interrupted"):
        sample_model(_model(data), draws=40, tune=20, chains=2, seed=1, progress=False)
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler      # the handler put back


def test_an_abort_that_fails_after_a_ctrl_c_is_the_interrupt(data, monkeypatch):
    """nutpie's abort right after Ctrl-C can raise ValueError('Sampler has no results to
    take'); with the signal seen, that is the interrupt. Without one, an error stays itself."""
    import os
    import signal

    import nutpie

    def interrupted(compiled, **kw):
        try:
            os.kill(os.getpid(), signal.SIGINT)
        except KeyboardInterrupt:
            raise ValueError("Sampler has no results to take") from None

    monkeypatch.setattr(nutpie, "sample", interrupted)
    with pytest.raises(KeyboardInterrupt, match="NUTS sampling interrupted"):
        sample_model(_model(data), draws=40, tune=20, chains=2, seed=1, progress=False)

    def broken(compiled, **kw):
        raise ValueError("a real error")

    monkeypatch.setattr(nutpie, "sample", broken)
    with pytest.raises(ValueError, match="a real error"):
        sample_model(_model(data), draws=40, tune=20, chains=2, seed=1, progress=False)
