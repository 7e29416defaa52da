"""Trust layer: summary, verdict rules (one failing case per rule), save/load, require_ok."""
from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from feeler.calib.fit import (FIT_FILES, DiagnosticWarning, FitResult, Verdict, load,
                              make_result, posterior_from_draws, require_ok, summarize)
from feeler.calib.progress import progress, show_progress
from feeler.errors import CalibrationFailed, DataFileError, OverwriteError

DIMS = {"C": ["disp_axis", "force_axis"]}


def _iid(rng, chains=4, draws=500):
    return {"C": rng.normal(size=(chains, draws, 3, 3)), "a": 2.0 + 0.5 * rng.normal(size=(chains, draws))}


def _ar1(rng, rho, chains, draws):
    x = np.empty((chains, draws))
    x[:, 0] = rng.normal(size=chains)
    for k in range(1, draws):
        x[:, k] = rho * x[:, k - 1] + np.sqrt(1 - rho**2) * rng.normal(size=chains)
    return x


def _fit(draws, backend="exact", **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DiagnosticWarning)
        return make_result(posterior_from_draws(draws, dims=DIMS, **kw), backend=backend,
                           priors={"a": "Normal(2, 1)"}, seconds=0.5)


def test_summary_of_independent_draws_matches_numpy_and_passes():
    rng = np.random.default_rng(1)
    draws = _iid(rng)
    with warnings.catch_warnings():
        warnings.simplefilter("error", DiagnosticWarning)
        res = make_result(posterior_from_draws(draws, dims=DIMS), backend="exact", priors={}, seconds=0)
    s = res.summary.set_index("name")
    assert list(s.index) == [f"C[{i},{j}]" for i in range(3) for j in range(3)] + ["a"]
    a = draws["a"].ravel()
    assert s.loc["a", "mean"] == pytest.approx(a.mean(), rel=1e-12)
    assert s.loc["a", "sd"] == pytest.approx(a.std(ddof=1), rel=1e-12)
    assert s.loc["a", "eti95_lb"] == pytest.approx(np.quantile(a, 0.025))
    assert s.loc["a", "eti89_ub"] == pytest.approx(np.quantile(a, 0.945))
    assert s.loc["C[1,2]", "mean"] == pytest.approx(draws["C"][:, :, 1, 2].mean())
    assert (s["ess_bulk"] > 1500).all() and (s["r_hat"] < 1.01).all()
    assert res.verdict == Verdict(ok=True, problems=())


def test_autocorrelated_short_chain_fails_ess_and_warns_naming_parameter():
    rng = np.random.default_rng(2)
    draws = {"tau_s": _ar1(rng, 0.98, 4, 200)}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", DiagnosticWarning)
        res = make_result(posterior_from_draws(draws), backend="nuts", priors={}, seconds=0)
    assert any("tau_s: bulk ESS" in str(w.message) for w in caught)
    assert not res.verdict.ok
    assert any(p.startswith("tau_s: bulk ESS") for p in res.verdict.problems)


def test_chains_stuck_in_different_places_fail_rhat():
    rng = np.random.default_rng(3)
    x = rng.normal(size=(4, 1000)) + np.array([0, 0, 0, 0.5])[:, None]
    res = _fit({"h": x}, backend="nuts")
    assert any(p.startswith("h: R-hat") for p in res.verdict.problems)
    ok = _fit({"h": rng.normal(size=(4, 1000))}, backend="nuts")
    assert ok.verdict.ok


def test_divergences_fail_the_verdict():
    rng = np.random.default_rng(4)
    div = np.zeros((4, 500), bool)
    div[2, 17] = True
    res = _fit(_iid(rng), backend="nuts", sample_stats={"diverging": div})
    assert res.verdict.problems == ("all parameters (C, a): 1 divergent transitions",)
    ok = _fit(_iid(rng), backend="nuts", sample_stats={"diverging": np.zeros((4, 500), bool)})
    assert ok.verdict.ok


def test_emcee_chain_shorter_than_50_autocorrelation_times_fails():
    rng = np.random.default_rng(5)
    short = _fit({"a": _ar1(rng, 0.9, 16, 400)}, backend="emcee")   # tau ≈ 19 → needs ~950
    assert any("a: emcee chain of 400 steps is shorter than 50" in p for p in short.verdict.problems)
    long = _fit({"a": _ar1(rng, 0.5, 16, 2000)}, backend="emcee")   # tau ≈ 3
    assert long.verdict.ok
    same_as_exact = _fit({"a": _ar1(rng, 0.9, 16, 400)}, backend="exact")
    assert not any("autocorrelation" in p for p in same_as_exact.verdict.problems)


def test_parameter_piling_against_prior_bound_is_flagged():
    rng = np.random.default_rng(6)
    piled = np.abs(rng.normal(0, 0.002, size=(4, 1000))) + 0.001   # τ pressed to lo = 0.001
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DiagnosticWarning)
        res = make_result(posterior_from_draws({"tau_s": piled}), backend="exact", priors={},
                          seconds=0, bounds={"tau_s": (0.001, 0.2)})
    assert res.verdict.problems == (res.verdict.problems[0],)
    assert res.verdict.problems[0].startswith("tau_s: posterior piles against its lower prior bound 0.001")
    inside = rng.uniform(0.05, 0.15, size=(4, 1000))
    res2 = make_result(posterior_from_draws({"tau_s": inside}), backend="exact", priors={},
                       seconds=0, bounds={"tau_s": (0.001, 0.2)})
    assert res2.verdict.ok


def test_piling_on_a_log_uniform_prior_is_measured_in_ln_tau():
    """A window τ with ln τ ~ Uniform(ln 0.5, ln 10) that the data do not constrain is not
    piling: on a linear strip (0.5-0.595 s) its prior alone holds 5.8 % of the draws and
    failed the verdict; in ln τ the strip holds 1 %. Draws pressed against 0.5 still fail."""
    rng = np.random.default_rng(7)
    prior_like = np.exp(rng.uniform(np.log(0.5), np.log(10.0), size=(4, 2000)))
    assert np.mean(prior_like <= 0.5 + 0.01 * 9.5) > 0.05           # the linear strip would flag it
    with warnings.catch_warnings():
        warnings.simplefilter("error", DiagnosticWarning)
        res = make_result(posterior_from_draws({"tau_s": prior_like}), backend="exact", priors={},
                          seconds=0, bounds={"tau_s": (0.5, 10.0, "log")})
    assert res.verdict.ok
    pressed = 0.5 * np.exp(np.abs(rng.normal(0, 0.05, size=(4, 2000))))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DiagnosticWarning)
        res = make_result(posterior_from_draws({"tau_s": pressed}), backend="exact", priors={},
                          seconds=0, bounds={"tau_s": (0.5, 10.0, "log")})
    strip = 0.5 * 20.0 ** 0.01                                         # 1 % of ln(10/0.5) above 0.5
    share = 100 * np.mean(pressed <= strip)                            # 2Φ(0.6) − 1 ≈ 45 %
    assert res.verdict.problems == ("tau_s: posterior piles against its lower prior bound 0.5 "
                                    f"({share:.0f} % of draws below {strip:.3g})",)


def test_a_few_undefined_draws_are_summarised_without_them_and_many_fail_once():
    """A derived quantity undefined at a few draws (the M2 line where the plates are not
    ordered: a = NaN at 2 of 4000 draws on an untuned three-plate fit) made every summary
    mean NaN, and the verdict said "no finite posterior draws" for ten entries. Up to 5 %
    are left out of the summary (equal to the summary of the other draws); more fail the
    verdict with one line naming the entries and the share."""
    rng = np.random.default_rng(3)
    a = 2.0 + 0.5 * rng.normal(size=(4, 1000))
    few = a.copy()
    few[1, 17] = few[3, 400] = np.nan
    with warnings.catch_warnings():
        warnings.simplefilter("error", DiagnosticWarning)
        res = make_result(posterior_from_draws({"a": few, "b": a}), backend="exact", priors={}, seconds=0)
    s = res.summary.set_index("name")
    kept = few[np.isfinite(few)]
    assert s.loc["a", "mean"] == pytest.approx(kept.mean(), rel=1e-12)
    assert s.loc["a", "sd"] == pytest.approx(kept.std(ddof=1), rel=1e-12)
    assert s.loc["a", "eti95_ub"] == pytest.approx(np.quantile(kept, 0.975))
    assert s.loc["a", "r_hat"] < 1.01 and s.loc["a", "ess_bulk"] > 1500
    assert res.verdict == Verdict(ok=True, problems=())
    many = a.copy()
    many[:, :60] = np.nan                                             # 6 % of the draws
    res = _fit({"a": many, "h": many + 1.0, "b": a})
    assert res.verdict.problems == ("a, h: up to 6 % of the posterior draws not finite (at most 5 % may be; "
                                    "these data leave them undefined there)",)
    assert np.isfinite(res.summary.set_index("name").loc["a", "mean"])
    res = _fit({"a": np.full((4, 1000), np.nan), "b": a})
    assert res.verdict.problems == ("a: no finite posterior draws (not defined by these data)",)


def test_require_ok():
    good = FitResult(None, pd.DataFrame(), Verdict(True))
    bad = FitResult(None, pd.DataFrame(), Verdict(False, ("a: R-hat 1.2 > 1.01", "h: bulk ESS 3 < 400")))
    assert require_ok(good) is good
    assert require_ok(bad, accept_failed=True) is bad
    with pytest.raises(CalibrationFailed, match=r"a: R-hat 1.2 > 1.01 \(\+1 more\); pass --accept-failed") as e:
        require_ok(bad)
    assert e.value.verdict is bad.verdict


def test_save_load_round_trip(tmp_path):
    rng = np.random.default_rng(7)
    res = _fit(_iid(rng), sample_stats={"diverging": np.zeros((4, 500), bool)},
               observed={"U_mm": rng.normal(size=(6, 3))})
    res.save(tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(FIT_FILES)
    back = load(tmp_path)
    pd.testing.assert_frame_equal(back.summary, res.summary, check_exact=False, rtol=1e-12)
    assert back.verdict == res.verdict
    assert back.priors == {"a": "Normal(2, 1)"} and back.backend == "exact" and back.seconds == 0.5
    for name, x in res.draws().items():
        np.testing.assert_array_equal(back.draws()[name], x)
    np.testing.assert_array_equal(back.posterior["observed_data"]["U_mm"].values,
                                  res.posterior["observed_data"]["U_mm"].values)
    assert json.loads((tmp_path / "verdict.json").read_text()) == {"ok": True, "problems": []}
    with pytest.raises(OverwriteError, match="posterior.nc"):
        res.save(tmp_path)
    res.save(tmp_path, force=True)
    # the fit's posterior.nc named instead of its directory (classify FIT/posterior.nc said
    # "FIT/posterior.nc/posterior.nc: missing"): read as its directory
    assert load(tmp_path / "posterior.nc").verdict == res.verdict


@pytest.fixture
def saved(tmp_path):
    _fit({"a": np.random.default_rng(8).normal(size=(4, 500))}).save(tmp_path)
    return tmp_path


@pytest.mark.parametrize("name, content, match", [
    ("posterior.nc", b"\x89HDF garbage", "posterior.nc: not a readable NetCDF"),
    ("summary.csv", b"name,mean\n\"a,1\n", "summary.csv: not a readable CSV"),
    ("summary.csv", b"name,mean\na,1\n", r"summary.csv: missing column\(s\) sd"),
    ("verdict.json", b"{\"ok\": true", "verdict.json: not a verdict"),
    ("verdict.json", b"{\"ok\": true}", "verdict.json: not a verdict"),
])
def test_corrupt_files_are_one_line_errors_naming_the_file(saved, name, content, match):
    (saved / name).write_bytes(content)
    with pytest.raises(DataFileError, match=match) as e:
        load(saved)
    assert "\n" not in str(e.value)


@pytest.mark.parametrize("cut, match", [
    (300, r"summary.csv: no row for C\[0,1\], C\[0,2\], C\[1,0\], C\[1,1\] and 5 more "
          r"\(9 of the posterior's 10 entries\); expected one row per posterior entry"),
    (-40, r"summary.csv: data row 10 has \d+ of the header's 12 fields; expected complete rows"),
])
def test_a_summary_cut_short_is_named_not_read_as_a_smaller_fit(tmp_path, cut, match):
    """A summary.csv cut short kept its header and read as a fit of one or two entries:
    the report then failed on a KeyError traceback (M1) or showed a two-row table as the
    fit's (M2). Every posterior entry needs its row, and every row all its fields."""
    rng = np.random.default_rng(9)
    _fit(_iid(rng)).save(tmp_path)
    text = (tmp_path / "summary.csv").read_bytes()
    (tmp_path / "summary.csv").write_bytes(text[:cut])
    with pytest.raises(DataFileError, match=match) as e:
        load(tmp_path)
    assert "\n" not in str(e.value)


def test_a_summary_is_read_once(saved, monkeypatch):
    """load reads summary.csv once (it read it twice: for the table, then for its rows' widths)."""
    import feeler.datasets as datasets

    reads, read_text = [], datasets.read_text
    monkeypatch.setattr(datasets, "read_text", lambda path: reads.append(Path(path).name) or read_text(path))
    load(saved)
    assert reads.count("summary.csv") == 1, reads


def test_missing_file(saved):
    (saved / "summary.csv").unlink()
    with pytest.raises(DataFileError, match="summary.csv: missing"):
        load(saved)


def test_posterior_from_draws_needs_chain_and_draw_dims():
    with pytest.raises(ValueError, match=r"draws\['a'\] must have leading \(chain, draw\)"):
        posterior_from_draws({"a": np.zeros(10)})


def test_progress_passthrough_and_bar():
    items = [1, 2, 3]
    assert progress(items, desc="x", enabled=False) is items
    assert list(progress(items, desc="x", enabled=True)) == items
    assert show_progress(True) and not show_progress(False)


def test_single_chain_cannot_show_convergence_and_fails():
    x = np.random.default_rng(9).normal(size=(1, 800))
    s = summarize(posterior_from_draws({"a": x}))
    assert s.loc[0, "name"] == "a" and s.loc[0, "mean"] == pytest.approx(x.mean())
    res = _fit({"a": x})
    assert not res.verdict.ok and res.verdict.problems[0].startswith("a: R-hat")
