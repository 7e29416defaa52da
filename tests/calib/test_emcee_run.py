"""emcee runs until its chains pass the verdict's diagnostics, or stops at a cap that fails clearly."""
import numpy as np
import pytest

from feeler.calib.diagnostics import diagnose
from feeler.calib.emcee_run import converged, run_until_converged
from feeler.calib.posterior import posterior_from_draws


def _sampler(seed=0, walkers=16):
    import emcee

    cov = np.eye(2)
    prec = np.linalg.inv(cov)

    def log_prob(x):
        return -0.5 * np.einsum("wi,ij,wj->w", x, prec, x)

    s = emcee.EnsembleSampler(walkers, 2, log_prob, vectorize=True)
    s.random_state = np.random.RandomState(seed).get_state()
    return s, np.random.default_rng(seed).normal(size=(walkers, 2))


def _verdict(sampler, burn, thin=1):
    chain = np.swapaxes(sampler.get_chain(discard=burn, thin=thin), 0, 1)
    tree = posterior_from_draws({"x": chain[..., 0], "y": chain[..., 1]})
    return diagnose(tree, backend="emcee")


def test_converged_tells_independent_from_sticky_chains():
    rng = np.random.default_rng(3)
    iid = rng.normal(size=(4000, 16, 2))
    assert converged(iid)[0]
    sticky = np.cumsum(rng.normal(size=(4000, 16, 2)), axis=0)          # random walks: never converged
    ok, tau = converged(sticky)
    assert not ok and tau > 50


@pytest.mark.slow
def test_runs_until_the_verdict_passes():
    s, p0 = _sampler()
    burn, notes, thin = run_until_converged(s, p0, chunk=500)
    assert notes == []
    ok, tau = converged(s.get_chain(discard=burn))
    assert ok and thin == int(tau // 4) > 1
    verdict = _verdict(s, burn, thin)               # the chain the fit keeps: thinned by a quarter of tau
    assert verdict.ok, verdict.problems
    kept = s.get_chain(discard=burn, thin=thin)
    assert kept.shape[0] == len(range(burn + thin - 1, s.iteration, thin))


def test_a_cap_fails_clearly(capsys):
    s, p0 = _sampler(1)
    burn, notes, thin = run_until_converged(s, p0, max_steps=300, chunk=100)
    assert thin == 1 and len(notes) == 1 and "cap of 300 steps" in notes[0] and "autocorrelation" in notes[0]
    assert not _verdict(s, burn).ok
    *lines, last = capsys.readouterr().err.splitlines()   # off a terminal: a line per chunk (100, 100, 100)
    assert [ln.split(",")[0] for ln in lines] == [f"emcee: {n} steps per walker" for n in (100, 200, 300)]
    assert all("longest tau" in ln and "not yet converged" in ln for ln in lines)
    # then the stage that turns the kept draws into a posterior (a minute of silence on the shipped M1 data)
    assert last == f"emcee: summarising the last 225 steps of its {s.nwalkers} walkers ({225 * s.nwalkers:,} " \
                   "draws: posterior, predictive check, R-hat, ESS) ..."
    run_until_converged(*_sampler(1), max_steps=200, chunk=100, progress=False)
    assert capsys.readouterr().err == ""                  # --no-progress: silent


def test_a_fixed_number_of_steps_runs_exactly():
    s, p0 = _sampler(2)
    burn, notes, thin = run_until_converged(s, p0, steps=400)
    assert (burn, notes, thin) == (100, [], 1) and s.iteration == 400
