"""What the M4 verdict checks: goodness of fit, prior–data conflict, units, levels."""
import numpy as np
import pandas as pd
import pytest
from scipy.stats import binom

from feeler.calib.psychometric.outputs import checks
from feeler.calib.psychometric.model.cells import make_cells
from feeler.calib.psychometric.fit import fit_psychometric, threshold_table
from feeler.calib.psychometric.model.priors import Priors
from feeler.calib.psychometric.model.task import Task
from feeler.errors import ArgumentError
from feeler.psydata import TRIAL_COLUMNS

pytestmark = pytest.mark.filterwarnings("ignore::feeler.calib.fit.DiagnosticWarning")
LEVELS = np.array([7.6, 8.4, 9.2, 10.0, 10.8, 11.6, 12.4])


def _fit(trials, **kw):
    return fit_psychometric(trials, rng=np.random.default_rng(0), draws=300, **kw)


def test_deviance_is_twice_the_log_likelihood_ratio_to_the_saturated_model():
    n, k, p = np.array([10, 20, 5]), np.array([3, 20, 0]), np.array([0.4, 0.9, 0.2])
    want = 2 * np.sum(binom.logpmf(k, n, k / n) - binom.logpmf(k, n, p))
    assert checks.deviance(n, k, p) == pytest.approx(want, rel=1e-12)
    assert checks.deviance(n, k, k / n) == 0.0


def test_data_forced_into_the_wrong_design_fail_the_fit_check():
    """2AFC proportions correct (floor ½) read as 'comparison judged higher' (floor 0):
    the misfit fails the verdict with its reason; fitted as 2AFC they pass."""
    rng = np.random.default_rng(12)
    k = rng.binomial(60, Task(2).p(LEVELS - 10.0 + 2.0, 2.0, 0.8, 0.02))
    rows = [("A", 2.0, 20.0, x - 8.0, 20.0, 60, int(kk)) for x, kk in zip(LEVELS, k)]
    wrong = pd.DataFrame(rows, columns=list(TRIAL_COLUMNS))
    result = _fit(wrong)
    assert not result.verdict.ok
    assert any("does not fit its data" in p and "--nafc" in p for p in result.verdict.problems)
    assert not threshold_table(result).gof_ok.iloc[0]
    right = _fit(wrong.rename(columns={"n_comparison_higher": "n_correct"}), nafc=2)
    assert right.verdict.ok and threshold_table(right).gof_ok.all()


def _forced_2afc(rng, subjects: int) -> pd.DataFrame:
    """2AFC counts correct (floor ½) of ``subjects`` subjects at two speeds, in the column of
    'comparison judged higher' (floor 0): the table of a fit without --nafc 2."""
    rows = []
    for s in range(subjects):
        for speed in (20.0, 40.0):
            k = rng.binomial(60, Task(2).p(LEVELS - 7.0, 3.0 + 0.3 * (speed == 40.0), 0.8, 0.02))
            rows += [(f"S{s + 1}", 3.0, speed, round(x - 7.0, 1), 20.0, 60, int(kk)) for x, kk in zip(LEVELS, k)]
    return pd.DataFrame(rows, columns=list(TRIAL_COLUMNS))


def test_a_likely_missing_nafc_leads_the_verdict():
    """Proportions correct fitted without --nafc 2: the verdict's first line says so, naming
    --nafc 2 (its hint '(--nafc?)' stood mid-line in each of ten misfit lines, the first of
    them after the summary table); the rest of the verdict is as it was, and with --nafc 2
    the fit passes."""
    wrong = _forced_2afc(np.random.default_rng(12), subjects=6)
    problems = _fit(wrong).verdict.problems
    assert problems[0].startswith(f"{checks.SLIP_PREFIX} 2: ") and "fit with --nafc 2" in problems[0], problems[0]
    misfits = [p for p in problems if "does not fit its data" in p]
    assert len(misfits) >= 5 and problems[1:] == tuple(misfits), problems          # the rows' own lines, after it
    assert not any(p.startswith(checks.SLIP_PREFIX) for p in problems[1:])
    right = _fit(wrong.rename(columns={"n_comparison_higher": "n_correct"}), nafc=2)
    assert not any(p.startswith(checks.SLIP_PREFIX) for p in right.verdict.problems)


def test_a_misfit_that_no_nafc_curve_fits_names_no_slip(simulate):
    """A typed count fails the fit however it is read: no --nafc line; nor does a good fit get one."""
    k = np.array([18, 3, 6, 10, 14, 17, 19])
    rows = [("A", 10.0, 20.0, x, 20.0, 20, int(kk)) for x, kk in zip(LEVELS, k)]
    problems = _fit(pd.DataFrame(rows, columns=list(TRIAL_COLUMNS))).verdict.problems
    assert problems and not any(p.startswith(checks.SLIP_PREFIX) for p in problems), problems
    trials, _ = simulate(300, n_subjects=3)
    assert not any(p.startswith(checks.SLIP_PREFIX) for p in _fit(trials).verdict.problems)


def test_a_typed_count_is_named_where_the_fit_fails():
    """One count typed wrong (18 for 1 of 20 at the lowest level): the misfit names that
    cell (it said only 'deviance 40.7 on 7 cells')."""
    levels = np.array([7.6, 8.4, 9.2, 10.0, 10.8, 11.6, 12.4])
    k = np.array([1, 3, 6, 10, 14, 17, 19])
    k[0] = 18
    rows = [("A", 10.0, 20.0, x, 20.0, 20, int(kk)) for x, kk in zip(levels, k)]
    result = _fit(pd.DataFrame(rows, columns=list(TRIAL_COLUMNS)))
    lines = [p for p in result.verdict.problems if "does not fit its data" in p]     # the subject and 'all'
    assert lines and all("most of it at 7.6 µm: 18 of 20, the curve expects " in q and "that cell's counts" in q
                         for q in lines)


def test_data_from_the_model_pass_the_fit_check(simulate):
    passed = 0
    for seed in range(4):
        trials, _ = simulate(300 + seed, n_subjects=3)
        table = threshold_table(_fit(trials))
        passed += int(table.gof_ok.all())
        assert table.gof_p.between(0, 1).all()
    assert passed >= 3


@pytest.mark.parametrize("scale, unit", [(1e-3, "mm"), (1e3, "nm")])
def test_heights_off_by_a_thousand_name_the_unit(simulate, scale, unit):
    trials, _ = simulate(41, n_subjects=2)
    scaled = trials.assign(standard_um=trials.standard_um * scale, comparison_um=trials.comparison_um * scale)
    result = _fit(scaled)
    assert not result.verdict.ok and f"given in {unit} (" in result.verdict.problems[0]
    assert result.verdict.problems[0].endswith(" → 7.6–12.4 µm)?")
    assert not checks.unit_problems(trials.comparison_um.to_numpy())


def test_speeds_in_mm_per_min_fail_naming_the_unit(simulate):
    """Speeds written as a stage's feed rate (mm/min: 1200 and 2400 for 20 and 40 mm/s)
    passed with verdict ok and went into every output as 1200 'mm/s'."""
    trials, _ = simulate(41, n_subjects=2)
    per_min = trials.assign(standard_speed_mm_s=trials.standard_speed_mm_s * 60,
                            comparison_speed_mm_s=trials.comparison_speed_mm_s * 60)
    result = _fit(per_min)
    speeds = [p for p in result.verdict.problems if p.startswith("speeds:")]
    assert not result.verdict.ok and len(speeds) == 1
    assert "given in mm/min, a stage's feed-rate unit (÷ 60 → 20–40 mm/s)" in speeds[0]
    assert not [p for p in _fit(trials).verdict.problems if p.startswith("speeds:")]


def test_priors_in_um_on_heights_in_mm_are_a_conflict_naming_the_unit(simulate):
    """Enough trials that the data outweigh the prior: σ sits ~10³ below the prior's."""
    trials, _ = simulate(41, n_subjects=1, n_trials=80)
    mm = trials.assign(standard_um=trials.standard_um / 1000, comparison_um=trials.comparison_um / 1000)
    result = _fit(mm, priors=Priors(pse_sd_um=3.0, sigma_um=1.5))
    conflicts = [p for p in result.verdict.problems if "prior–data conflict" in p]
    assert conflicts and "mm instead of µm" in conflicts[0]
    clean = _fit(trials, priors=Priors(pse_sd_um=3.0, sigma_um=1.5))
    assert not [p for p in clean.verdict.problems if "conflict" in p]


def test_a_pse_far_from_its_prior_is_a_conflict():
    r = Priors().resolve(make_cells(pd.DataFrame([("A", 10.0, 20.0, x, 20.0, 10, 5) for x in LEVELS],
                                                 columns=list(TRIAL_COLUMNS))))
    draws = {"pse": np.full(10, 30.0), "sigma": np.full(10, 1.2), "lapse": np.full(10, 0.02)}
    assert "location 30 µm lies 8.3 prior sds" in checks.conflict_problems("A", 0, r, draws)[0]
    draws["lapse"] = np.full(10, 0.45)
    assert any("lapse 0.450" in p for p in checks.conflict_problems("A", 0, r, draws))


def test_a_prior_that_holds_the_pse_where_the_data_would_not_is_a_conflict(simulate):
    """--prior-pse-sd 0.01 pinned every PSE at the prior's 10 µm and nothing was named (an
    outside audit): the posterior sits on its prior, so comparing the two shows no
    conflict. Refitting the location to the row's cells alone shows it; with the default
    prior the same data raise no such line."""
    trials, _ = simulate(3, n_subjects=1, n_trials=80)
    trials = trials.assign(comparison_um=trials.comparison_um - 1.0)        # the PSE ~1 µm above the standard
    held = _fit(trials, priors=Priors(pse_sd_um=0.01))
    drag = [p for p in held.verdict.problems if "the data alone put the PSE at" in p]
    assert drag and not held.verdict.ok and "--prior-pse-sd" in drag[0]
    assert not [p for p in _fit(trials).verdict.problems if "the data alone put" in p]
    x = LEVELS                                                                # exact: a curve at its own ML location
    n = np.full(x.size, 40)
    k = np.round(n * Task(2).p(x, 10.0, 1.0, 0.02)).astype(int)
    assert checks.drag_problems("A", Task(2), x, n, k, {"pse": 10.0, "sigma": 1.0, "lapse": 0.02}) == []
    assert "data alone put the PSE at 10" in checks.drag_problems("A", Task(2), x, n, k,
                                                                    {"pse": 8.5, "sigma": 1.0, "lapse": 0.02})[0]


def test_a_single_level_fails_with_its_reason(simulate):
    trials, _ = simulate(6, n_subjects=2)
    result = _fit(trials[trials.comparison_um == 10.8])
    assert not result.verdict.ok
    assert sum("a single tested level (10.8 µm)" in p for p in result.verdict.problems) == 6


def test_levels_that_do_not_bracket_the_pse_fail(simulate):
    trials, _ = simulate(7, n_subjects=1, n_trials=40)
    low = trials[trials.comparison_um <= 8.4]              # every level far below the PSE
    result = _fit(low)
    assert any("do not pin it down" in p for p in result.verdict.problems)


def test_refusals_at_the_api(simulate):
    trials, _ = simulate(8, n_subjects=1)
    with pytest.raises(ArgumentError, match="every row has n_trials = 0"):
        _fit(trials.assign(n_trials=0, n_comparison_higher=0))
    with pytest.raises(ArgumentError, match="at least 2 subjects"):
        _fit(trials, backend="nuts")
    with pytest.raises(ArgumentError, match="population"):
        _fit(trials, all_estimand="population")
    with pytest.raises(ArgumentError, match="lapse"):
        _fit(trials, lapse_per="trial")
    with pytest.raises(ArgumentError, match="number of alternatives"):
        _fit(trials.rename(columns={"n_comparison_higher": "n_correct"}))


def _counts(k, n=20, levels=LEVELS):
    return pd.DataFrame([("A", 10.0, 20.0, x, 20.0, n, int(kk)) for x, kk in zip(levels, k)],
                        columns=list(TRIAL_COLUMNS))


def _spread(result):
    return [p for p in result.verdict.problems if "spread" in p or "do not rise" in p]


def test_responses_that_step_between_two_levels_bound_the_spread_only_from_above():
    """0 of 20 below 10.4 µm, 20 of 20 above: any σ below the level spacing fits (the
    step's deviance is 0, at most the curve's). The fit said "verdict ok" with a
    threshold interval that came from the prior."""
    result = _fit(_counts([0, 0, 0, 0, 20, 20, 20]))
    (line,) = _spread(result)
    assert line.startswith("A [10 um, 20/20 mm/s]: the responses step at or between two adjacent tested levels")
    assert "deviance 0.00" in line and "closer together" in line


def test_a_step_on_the_standard_with_half_the_responses_there_bounds_the_spread_only_from_above():
    """0 of 20 below the standard, 10 of 20 at it, 20 of 20 above: the sharpest observer
    there is (a comparison equal to the standard is judged higher half the time whatever
    the spread). No step between two levels gives the half, so the check let it pass:
    verdict ok with DT 0.21 [0.08, 0.36] µm, an interval from the prior."""
    result = _fit(_counts([0, 0, 0, 10, 20, 20, 20]))
    (line,) = _spread(result)
    assert line.startswith("A [10 um, 20/20 mm/s]: the responses step at or between two adjacent tested levels")
    assert "deviance 0.00" in line
    # a half at a level that is not the standard is not a step there: a smooth curve
    assert not _spread(_fit(_counts([0, 1, 4, 10, 16, 19, 20])))


def test_responses_that_fall_as_the_comparison_rises_are_named_as_coded_the_other_way_round(simulate):
    """Counts of 'standard judged higher' in the comparison column: the rising curve fits
    no better than a flat line, and the check said the threshold lies beyond the tested
    levels ('test a wider range'), the wrong advice."""
    result = _fit(_counts([20, 19, 16, 10, 4, 1, 0]))
    lines = [p for p in result.verdict.problems if "fall as the comparison rises" in p]
    assert len(lines) == 1 and lines[0].startswith("A [10 um, 20/20 mm/s]: the responses fall as the comparison "
                                                   "rises across 7.6–12.4 µm (a falling curve fits with deviance ")
    assert "give n_trials minus them as n_comparison_higher" in lines[0]
    assert not any("do not rise" in p for p in result.verdict.problems)
    # the very wide curve such counts fit is no unit slip: heights in µm are not called nm (an outside audit)
    flipped = simulate(5, n_subjects=3, n_trials=80)[0]            # the pooled row: σ 193 µm, "in nm?"
    flipped = flipped.assign(n_comparison_higher=flipped.n_trials - flipped.n_comparison_higher)
    problems = _fit(flipped).verdict.problems
    assert any("σ" in p and "prior–data conflict" in p for p in problems)
    assert not any("instead of µm" in p for p in problems), problems
    # chance at every level falls no more than it rises: still 'do not rise'
    assert "do not rise" in _spread(_fit(_counts([11, 10, 12, 10, 9, 10, 9])))[0]


def test_responses_that_do_not_rise_bound_the_threshold_only_from_below():
    """Chance at every level (an observer who cannot tell these heights apart): a flat
    line fits as well, and the 75 % point lies beyond the tested levels."""
    result = _fit(_counts([9, 11, 10, 12, 9, 10, 11]))
    (line,) = _spread(result)
    assert "do not rise across the tested levels 7.6–12.4 µm (a flat line at 0.51" in line


@pytest.mark.parametrize("k, nafc, words", [
    (20, None, "A [10 um, 20/20 mm/s]: all 140 trials 'comparison judged higher' at the tested levels 7.6–12.4 µm: "
               "the PSE lies below them"),
    (0, None, "none of its 140 trials 'comparison judged higher' at the tested levels 7.6–12.4 µm: the PSE lies "
              "above them"),
    (20, 2, "all 140 trials correct at the tested levels 7.6–12.4 µm: the threshold lies below them"),
    (0, 2, "none of its 140 trials correct, where guessing alone gives 1/2: the responses are probably coded the "
           "other way round"),
])
def test_one_answer_throughout_names_where_the_function_lies(k, nafc, words):
    """A subject who pressed one key all session (or a range the function lies outside):
    said as such, not as 'a step and a flat line fit as well; more trials are needed'."""
    trials = _counts([k] * LEVELS.size)
    if nafc:
        trials = trials.rename(columns={"n_comparison_higher": "n_correct"})
    result = _fit(trials, **({"nafc": nafc} if nafc else {}))
    lines = [p for p in result.verdict.problems if words in p]
    assert not result.verdict.ok and len(lines) == 1, result.verdict.problems
    assert not any("more trials are needed" in p for p in result.verdict.problems)


def test_nafc_at_chance_everywhere_does_not_rise_rather_than_needs_more_trials():
    """2AFC at exactly 1/2 on 14 levels above the standard, 40 trials each (560): a flat line
    at the guess rate fits. A 'step' above every level is that same line, and it was counted
    as a step, so the fit said 'a step and a flat line fit as well; more trials are needed'."""
    levels = np.linspace(10.4, 15.6, 14)
    trials = _counts([20] * levels.size, n=40, levels=levels).rename(columns={"n_comparison_higher": "n_correct"})
    (line,) = _spread(_fit(trials, nafc=2))
    assert "do not rise across the tested levels" in line and "more trials" not in line, line


def _nafc_around_the_standard(k):
    return _counts(k, n=60).rename(columns={"n_comparison_higher": "n_correct"})


def test_nafc_comparisons_on_both_sides_of_the_standard_falling_towards_it_are_named():
    """2AFC counts 7.6-12.4 µm around a 10 µm standard, right more often the further from it
    (U-shaped): the verdict names the design first, not 'test a wider range'. Proportions that
    rise across the standard (a monotone curve, however the levels were chosen) do not fire it."""
    u_shaped = _fit(_nafc_around_the_standard([57, 50, 41, 30, 42, 51, 58]), nafc=2)
    first = u_shaped.verdict.problems[0]
    assert first.startswith("[10 um, 20/20 mm/s]: 2AFC proportion correct with comparisons on both sides of the "
                            "standard 10 µm (7.6–12.4 µm), falling as those below it near it"), first
    assert "give comparison_um as the distance from the standard" in first
    rising = _fit(_nafc_around_the_standard([31, 33, 38, 45, 52, 56, 58]), nafc=2)
    assert not any("both sides of the standard" in p for p in rising.verdict.problems), rising.verdict.problems


def test_seven_trials_pin_neither_side():
    """One trial per level, one of them against the rise: neither a step nor a flat line
    can be rejected."""
    result = _fit(_counts([0, 1, 0, 0, 1, 1, 1], n=1))
    (line,) = _spread(result)
    assert "cannot pin down the spread" in line and "its 7 trials" in line


def test_a_sampled_psychometric_function_is_not_a_step_or_a_line(simulate):
    """The shipped design (7 levels 0.8 µm apart, 20 trials, DT 0.95-2 µm): neither
    boundary model fits. 20 datasets of 6 subjects passed this check before it shipped."""
    trials, _ = simulate(7, n_subjects=6)
    assert _spread(_fit(trials)) == []


def test_the_likelihood_ratio_against_a_step_by_hand():
    """Counts a step fits exactly but for one trial: the step's deviance at lapse λ is, in
    closed form, D(λ) = 2[ln(1/(20·λ/2)) + 19 ln(19/(20(1 − λ/2)))] − 240 ln(1 − λ/2); the
    check takes its minimum over the lapses up to the curve's and tests the likelihood ratio
    against 2.71."""
    task = Task(None)
    n, k = np.full(LEVELS.size, 20), np.array([0, 0, 0, 1, 20, 20, 20])
    lam = np.linspace(0.0, 0.04, 11)[1:]
    closed = 2 * (np.log(1 / (20 * lam / 2)) + 19 * np.log(19 / (20 * (1 - lam / 2)))) - 240 * np.log(1 - lam / 2)
    base, scale, _ = task.base_scale_rest(lam)
    direct = [checks.deviance(n, k, b + s * (LEVELS > 10.4)) for b, s in zip(base, scale)]
    np.testing.assert_allclose(direct, closed, rtol=1e-12)
    best = closed.min()
    assert checks.spread_problems("A", task, LEVELS, n, k, best - 2.70, 0.04)         # within 2.71: a step fits
    assert not checks.spread_problems("A", task, LEVELS, n, k, best - 2.72, 0.04)     # beyond: it does not
